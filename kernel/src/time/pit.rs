//! The 8253/8254 Programmable Interval Timer, where the machine has one
//! (recent Intel platforms gate its clock). Channel 0 raises IRQ 0 about once
//! a millisecond to wake the CPU from `hlt`, which the kernel uses only while
//! it sees those ticks arrive; channel 2, gated on with the speaker off, is
//! the last of the references the TSC may be calibrated against.

use clock::calibration::Sample;
use core::sync::atomic::{AtomicU64, Ordering};
use x86_64::instructions::port::Port;

const CHANNEL_0_DATA: u16 = 0x40;
const CHANNEL_2_DATA: u16 = 0x42;
const MODE_COMMAND: u16 = 0x43;
/// Port B of the old 8255: bit 0 gates channel 2, bit 1 drives the speaker
/// from it, bit 5 reads channel 2's output.
const PORT_B: u16 = 0x61;
const PORT_B_CHANNEL_2_GATE: u8 = 0x01;
const PORT_B_SPEAKER_DATA: u8 = 0x02;
/// Channel 0, low byte then high byte, mode 2 (rate generator), binary.
const CHANNEL_0_RATE_GENERATOR: u8 = 0b0011_0100;
/// Channel 2, low byte then high byte, mode 0 (count down, no reload), binary.
const CHANNEL_2_COUNTDOWN: u8 = 0b1011_0000;
/// Channel 2, latch the count for reading.
const CHANNEL_2_LATCH: u8 = 0b1000_0000;
/// 1193 input clocks: one tick every 999.847 µs.
const DIVISOR: u16 = 1193;
/// Ticks are "arriving" while the last one is at most this old: ten periods.
const TICKING_WITHIN_MICROS: u64 = 10_000;

static TICKS: AtomicU64 = AtomicU64::new(0);
/// The kernel clock's reading at the last tick.
static LAST_TICK_MICROS: AtomicU64 = AtomicU64::new(0);

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

/// Runs `f` with channel 0 at the BIOS's rate, 18.2 Hz (mode 3, divisor
/// 65,536), as a real-mode BIOS call expects its tick; then at the kernel's
/// again. Call with interrupts off.
pub fn at_the_bios_rate<R>(f: impl FnOnce() -> R) -> R {
    /// Channel 0, low byte then high byte, mode 3 (square wave), binary.
    const CHANNEL_0_SQUARE_WAVE: u8 = 0b0011_0110;
    // SAFETY: programming PIT channel 0 only changes the rate of IRQ 0.
    unsafe {
        Port::<u8>::new(MODE_COMMAND).write(CHANNEL_0_SQUARE_WAVE);
        let mut data = Port::<u8>::new(CHANNEL_0_DATA);
        data.write(0); // 0 means 65,536
        data.write(0);
    }
    let result = f();
    init();
    result
}

/// Counts a tick and notes when it came; called from the IRQ 0 handler.
pub fn tick() {
    LAST_TICK_MICROS.store(crate::time::micros(), Ordering::Relaxed);
    TICKS.fetch_add(1, Ordering::Release);
}

/// Whether IRQ 0 has been seen to arrive lately: only then may the CPU `hlt`
/// and count on it to wake. (Ticks can also be lost under emulation, which is
/// why the clock reads the TSC and never counts them.)
pub fn ticking() -> bool {
    TICKS.load(Ordering::Acquire) > 0
        && crate::time::micros().saturating_sub(LAST_TICK_MICROS.load(Ordering::Relaxed))
            <= TICKING_WITHIN_MICROS
}

/// Whether IRQ 0 arrives: waits for one tick, at most 50 ms (50 of the
/// kernel's ticks). Call with interrupts on.
pub fn ticks_arrive() -> bool {
    const WITHIN_MICROS: u64 = 50_000;
    let seen = TICKS.load(Ordering::Acquire);
    let start = crate::time::micros();
    while crate::time::micros().saturating_sub(start) < WITHIN_MICROS {
        if TICKS.load(Ordering::Acquire) != seen {
            return true;
        }
        core::hint::spin_loop();
    }
    false
}

/// Opens channel 2's gate, speaker off, and starts it counting down from
/// 0xFFFF; it keeps counting (wrapping) until `stop_channel_2`.
pub fn start_channel_2_countdown() {
    // SAFETY: channel 2 and port B's gate and speaker bits drive only the PC
    // speaker, which stays off; the other port B bits are written back.
    unsafe {
        let mut port_b = Port::<u8>::new(PORT_B);
        let value = port_b.read();
        port_b.write((value | PORT_B_CHANNEL_2_GATE) & !PORT_B_SPEAKER_DATA);
        Port::<u8>::new(MODE_COMMAND).write(CHANNEL_2_COUNTDOWN);
        let mut data = Port::<u8>::new(CHANNEL_2_DATA);
        data.write(0xFF);
        data.write(0xFF);
    }
}

/// Closes channel 2's gate again.
pub fn stop_channel_2() {
    // SAFETY: as in `start_channel_2_countdown`.
    unsafe {
        let mut port_b = Port::<u8>::new(PORT_B);
        let value = port_b.read();
        port_b.write(value & !(PORT_B_CHANNEL_2_GATE | PORT_B_SPEAKER_DATA));
    }
}

/// Latches and reads channel 2's count, bracketed by two TSC reads.
pub fn poll_channel_2() -> Sample {
    let tsc_before = crate::time::tsc::rdtsc();
    // SAFETY: latching and reading channel 2's count has no side effect
    // beyond the PIT's read state, which this module alone uses.
    let count = unsafe {
        Port::<u8>::new(MODE_COMMAND).write(CHANNEL_2_LATCH);
        let mut data = Port::<u8>::new(CHANNEL_2_DATA);
        let low = data.read();
        let high = data.read();
        u16::from_le_bytes([low, high])
    };
    Sample {
        count: u64::from(count),
        tsc_before,
        tsc_after: crate::time::tsc::rdtsc(),
    }
}
