//! The 8253/8254 Programmable Interval Timer as the kernel's clock: channel 0
//! raises IRQ 0 about once a millisecond.

use core::sync::atomic::{AtomicU64, Ordering};
use x86_64::instructions::port::Port;

const CHANNEL_0_DATA: u16 = 0x40;
const MODE_COMMAND: u16 = 0x43;
/// Channel 0, low byte then high byte, mode 2 (rate generator), binary.
const CHANNEL_0_RATE_GENERATOR: u8 = 0b0011_0100;
/// The PIT's input clock in Hz.
pub const INPUT_HZ: u64 = 1_193_182;
/// 1193 input clocks: one tick every 999.847 µs.
const DIVISOR: u16 = 1193;
pub const TICK_NANOS: u64 = DIVISOR as u64 * 1_000_000_000 / INPUT_HZ;

static TICKS: AtomicU64 = AtomicU64::new(0);
/// The time-stamp counter at the last tick.
static TICK_TSC: AtomicU64 = AtomicU64::new(0);

pub fn init() {
    let [low, high] = DIVISOR.to_le_bytes();
    // SAFETY: programming PIT channel 0 only changes the rate of IRQ 0.
    unsafe {
        Port::<u8>::new(MODE_COMMAND).write(CHANNEL_0_RATE_GENERATOR);
        let mut data = Port::<u8>::new(CHANNEL_0_DATA);
        data.write(low);
        data.write(high);
    }
}

/// Counts a tick; called from the IRQ 0 handler.
pub fn tick() {
    TICK_TSC.store(crate::clock::rdtsc(), Ordering::Relaxed);
    TICKS.fetch_add(1, Ordering::Relaxed);
}

/// The tick count and the time-stamp counter when the last tick came. Read
/// with interrupts off, so that no tick comes between the two reads.
pub fn ticks_and_tsc() -> (u64, u64) {
    x86_64::instructions::interrupts::without_interrupts(|| {
        (
            TICKS.load(Ordering::Relaxed),
            TICK_TSC.load(Ordering::Relaxed),
        )
    })
}

pub fn ticks() -> u64 {
    TICKS.load(Ordering::Relaxed)
}

/// Milliseconds since `init`.
pub fn millis() -> u64 {
    ticks() * TICK_NANOS / 1_000_000
}
