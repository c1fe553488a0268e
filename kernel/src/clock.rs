//! The kernel's clock: the time-stamp counter, read on demand and calibrated
//! once against PIT channel 2 by polling (see `machine::calibration`).
//!
//! Time comes from a free-running counter, not from counting interrupts, so
//! an emulator that merges or drops timer interrupts on a busy host cannot
//! make it run slow. The PIT's interrupt is kept for waking the CPU from `hlt`
//! only. If calibration fails, the clock falls back to counting PIT ticks.

use crate::pit;
use machine::calibration::{self, Calibration, CalibrationError, Plan, TscClock};
use spin::Once;

static CLOCK: Once<TscClock> = Once::new();

pub fn rdtsc() -> u64 {
    // SAFETY: RDTSC only reads the time-stamp counter.
    unsafe { core::arch::x86_64::_rdtsc() }
}

/// Measures the TSC's rate (about 200 ms; interrupts may be on or off) and
/// starts the clock at zero.
pub fn init() -> Result<Calibration, CalibrationError> {
    pit::start_channel_2_countdown();
    let result = calibration::calibrate(Plan::DEFAULT, pit::poll_channel_2);
    pit::stop_channel_2();
    let calibration = result?;
    CLOCK.call_once(|| TscClock {
        start: rdtsc(),
        tsc_hz: calibration.tsc_hz,
    });
    Ok(calibration)
}

/// Microseconds since `init`.
pub fn micros() -> u64 {
    match CLOCK.get() {
        Some(clock) => clock.micros(rdtsc()),
        None => pit::ticks() * pit::TICK_NANOS / 1000,
    }
}
