//! The PS/2 keyboard's hardware: the 8042's ports, and where its bytes go.
//! What to do with the controller is `keyboard::i8042`, tested on the host;
//! this shell gives it the real ports.
//!
//! Bytes are taken by IRQ 1 and also by a poll from the frame and idle
//! loops, so keys work where the firmware left IRQ 1 undelivered. Both take
//! a byte with `i8042::take_byte` (status, then data only if a byte is
//! there), the poll with interrupts off: on the one CPU the two never
//! overlap, so each byte is taken once, and `SCANCODES` (one producer at a
//! time) stays sound.

use crate::serial_println;
use core::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use demo::facts::Ps2;
use keyboard::i8042::{self, Failure, FirmwareSays, Taken};
use keyboard::scancode_queue::ScancodeQueue;
use x86_64::instructions::port::Port;

const DATA_PORT: u16 = 0x60;
const STATUS_PORT: u16 = 0x64; // reads: status; writes: controller commands
/// Bytes one poll takes at most: the keyboard's own buffer is 16.
const POLL_LIMIT: usize = 16;

pub static SCANCODES: ScancodeQueue = ScancodeQueue::new();

/// A controller answered and was set up: only then do the loops poll it.
static PRESENT: AtomicBool = AtomicBool::new(false);

/// Keyboard bytes taken by IRQ 1 and by the poll, for the goodbye line.
static TAKEN_BY_IRQ: AtomicU64 = AtomicU64::new(0);
static TAKEN_BY_POLL: AtomicU64 = AtomicU64::new(0);

/// Keyboard bytes taken so far: by IRQ 1, and by the loops' poll.
pub fn taken() -> (u64, u64) {
    (
        TAKEN_BY_IRQ.load(Ordering::Relaxed),
        TAKEN_BY_POLL.load(Ordering::Relaxed),
    )
}

/// The 8042 at its ISA ports.
struct RealPorts;

impl i8042::Ports for RealPorts {
    fn read_status(&mut self) -> u8 {
        // SAFETY: reading the 8042 status register has no side effects.
        unsafe { Port::<u8>::new(STATUS_PORT).read() }
    }

    fn read_data(&mut self) -> u8 {
        // SAFETY: reading port 0x60 takes the byte in the output buffer (the
        // callers have seen the status say one is there) and nothing else.
        unsafe { Port::<u8>::new(DATA_PORT).read() }
    }

    fn write_data(&mut self, byte: u8) {
        // SAFETY: the caller has seen the input buffer empty; the byte goes
        // to the keyboard or is a command's argument.
        unsafe { Port::<u8>::new(DATA_PORT).write(byte) };
    }

    fn write_command(&mut self, byte: u8) {
        // SAFETY: the caller has seen the input buffer empty; the 8042
        // commands `keyboard::i8042` sends change only the controller.
        unsafe { Port::<u8>::new(STATUS_PORT).write(byte) };
    }
}

/// Probes and sets the controller up, whatever the firmware said (logged as
/// a hint, with what the probe found), and says how it went for the report.
/// Runs before interrupts are enabled.
pub fn init(firmware: FirmwareSays) -> Ps2 {
    let result = i8042::init_with_firmware_hint(firmware, &mut RealPorts, &mut |line| {
        serial_println!("{}", line)
    });
    match result {
        Ok(_) => {
            PRESENT.store(true, Ordering::Release);
            Ps2::Ready
        }
        Err(problem) => {
            serial_println!("keyboard: {}; PS/2 not used", problem);
            match problem {
                Failure::Absent => Ps2::Absent,
                other => Ps2::Failed(other.message()),
            }
        }
    }
}

/// IRQ 1. It can be stale (a byte already taken by the poll, or an answer
/// `init` polled with interrupts off): `take_byte` then finds none.
pub fn on_interrupt() {
    if let Some(Taken::Keyboard(byte)) = i8042::take_byte(&mut RealPorts) {
        TAKEN_BY_IRQ.fetch_add(1, Ordering::Relaxed);
        SCANCODES.push(byte);
    }
}

/// Takes what the controller holds, without waiting for IRQ 1: from the
/// frame and idle loops, with interrupts enabled or not.
pub fn poll() {
    if !PRESENT.load(Ordering::Relaxed) {
        return;
    }
    x86_64::instructions::interrupts::without_interrupts(|| {
        for _ in 0..POLL_LIMIT {
            match i8042::take_byte(&mut RealPorts) {
                Some(Taken::Keyboard(byte)) => {
                    TAKEN_BY_POLL.fetch_add(1, Ordering::Relaxed);
                    SCANCODES.push(byte);
                }
                Some(Taken::Aux(_)) => {}
                None => break,
            }
        }
    });
}

/// Takes a keyboard byte if the controller holds one, with no interrupt: for
/// the fault handler's loop, where IRQs are off.
pub fn poll_byte() -> Option<u8> {
    match i8042::take_byte(&mut RealPorts) {
        Some(Taken::Keyboard(byte)) => Some(byte),
        _ => None,
    }
}
