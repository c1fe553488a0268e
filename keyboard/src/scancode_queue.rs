//! A fixed-size, lock-free queue of scancode bytes between one producer (the
//! keyboard interrupt) and one consumer (the render loop).
//!
//! It never blocks and never overflows: a byte that arrives when the queue is
//! full is dropped and counted, so a burst of keys costs at most the keys that
//! did not fit, and the count says so.

use core::sync::atomic::{AtomicU64, AtomicU8, AtomicUsize, Ordering};

/// Bytes the queue holds before it drops new ones.
pub const CAPACITY: usize = 256;

/// Scancodes from the keyboard interrupt to the main loop: one producer, one
/// consumer, no lock.
pub struct ScancodeQueue {
    bytes: [AtomicU8; CAPACITY],
    /// Total bytes ever pushed (wrapping); only the producer stores it.
    written: AtomicUsize,
    /// Total bytes ever popped (wrapping); only the consumer stores it.
    read: AtomicUsize,
    dropped: AtomicU64,
}

impl core::fmt::Debug for ScancodeQueue {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ScancodeQueue")
            .field("len", &self.len())
            .field("dropped", &self.dropped())
            .finish_non_exhaustive()
    }
}

impl ScancodeQueue {
    /// An empty queue.
    pub const fn new() -> Self {
        ScancodeQueue {
            bytes: [const { AtomicU8::new(0) }; CAPACITY],
            written: AtomicUsize::new(0),
            read: AtomicUsize::new(0),
            dropped: AtomicU64::new(0),
        }
    }

    /// Producer side. Returns false (and counts the byte) when the queue is full.
    pub fn push(&self, byte: u8) -> bool {
        let written = self.written.load(Ordering::Relaxed);
        let read = self.read.load(Ordering::Acquire);
        if written.wrapping_sub(read) >= CAPACITY {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return false;
        }
        self.bytes[written % CAPACITY].store(byte, Ordering::Relaxed);
        self.written
            .store(written.wrapping_add(1), Ordering::Release);
        true
    }

    /// Consumer side.
    pub fn pop(&self) -> Option<u8> {
        let read = self.read.load(Ordering::Relaxed);
        let written = self.written.load(Ordering::Acquire);
        if read == written {
            return None;
        }
        let byte = self.bytes[read % CAPACITY].load(Ordering::Relaxed);
        self.read.store(read.wrapping_add(1), Ordering::Release);
        Some(byte)
    }

    /// Bytes waiting.
    pub fn len(&self) -> usize {
        let written = self.written.load(Ordering::Acquire);
        written.wrapping_sub(self.read.load(Ordering::Acquire))
    }

    /// No bytes waiting.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

impl Default for ScancodeQueue {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bytes_come_out_in_order() {
        let queue = ScancodeQueue::new();
        for byte in 0..10u8 {
            assert!(queue.push(byte));
        }
        assert_eq!(queue.len(), 10);
        for byte in 0..10u8 {
            assert_eq!(queue.pop(), Some(byte));
        }
        assert_eq!(queue.pop(), None);
        assert!(queue.is_empty());
    }

    #[test]
    fn a_full_queue_drops_and_counts_instead_of_overwriting() {
        let queue = ScancodeQueue::new();
        for i in 0..CAPACITY + 50 {
            let accepted = queue.push(i as u8);
            assert_eq!(accepted, i < CAPACITY);
        }
        assert_eq!(queue.dropped(), 50);
        assert_eq!(queue.len(), CAPACITY);
        // The oldest bytes survive intact; none were overwritten.
        for i in 0..CAPACITY {
            assert_eq!(queue.pop(), Some(i as u8));
        }
        assert_eq!(queue.pop(), None);
    }

    #[test]
    fn indices_wrap_without_losing_bytes() {
        let queue = ScancodeQueue::new();
        for round in 0..10 * CAPACITY {
            assert!(queue.push(round as u8));
            assert_eq!(queue.pop(), Some(round as u8));
        }
        assert_eq!(queue.dropped(), 0);
    }

    #[test]
    fn producer_and_consumer_threads_agree() {
        extern crate std;
        use std::sync::Arc;
        let queue = Arc::new(ScancodeQueue::new());
        let producer = {
            let queue = Arc::clone(&queue);
            std::thread::spawn(move || {
                let mut sent = 0u32;
                while sent < 100_000 {
                    if queue.push(sent as u8) {
                        sent += 1;
                    }
                }
            })
        };
        let mut expected = 0u32;
        while expected < 100_000 {
            if let Some(byte) = queue.pop() {
                assert_eq!(byte, expected as u8);
                expected += 1;
            }
        }
        producer.join().unwrap();
    }
}
