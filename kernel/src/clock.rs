//! A microsecond clock for the on-screen frame statistics: the time-stamp
//! counter, calibrated once against the PIT. The PIT alone ticks in whole
//! milliseconds, too coarse for frames that take a fraction of one.

use crate::pit;
use core::sync::atomic::{AtomicU64, Ordering};

/// TSC cycles per microsecond; 0 until calibrated (or if calibration failed),
/// when `micros` falls back to the PIT.
static CYCLES_PER_MICRO: AtomicU64 = AtomicU64::new(0);
const CALIBRATION_TICKS: u64 = 50;
/// No wait here lasts longer than this many cycles (over a second at 5 GHz),
/// even if the PIT's interrupts never come.
const WAIT_LIMIT_CYCLES: u64 = 5_000_000_000;

pub fn rdtsc() -> u64 {
    // SAFETY: RDTSC only reads the time-stamp counter.
    unsafe { core::arch::x86_64::_rdtsc() }
}

/// Waits for the PIT tick count to reach `tick`; false if it never did.
fn wait_for_tick(tick: u64) -> bool {
    let start = rdtsc();
    while pit::ticks() < tick {
        if rdtsc().wrapping_sub(start) > WAIT_LIMIT_CYCLES {
            return false;
        }
        core::hint::spin_loop();
    }
    true
}

/// Measures the TSC rate over 50 PIT ticks (about 50 ms; interrupts must be
/// on). Returns cycles per microsecond, or `None` if the PIT did not tick.
pub fn calibrate() -> Option<u64> {
    if !wait_for_tick(pit::ticks() + 1) {
        return None;
    }
    let (tick, tsc) = (pit::ticks(), rdtsc());
    if !wait_for_tick(tick + CALIBRATION_TICKS) {
        return None;
    }
    let elapsed_nanos = CALIBRATION_TICKS * pit::TICK_NANOS;
    let rate = ((rdtsc() - tsc) * 1000 / elapsed_nanos).max(1);
    CYCLES_PER_MICRO.store(rate, Ordering::Relaxed);
    Some(rate)
}

/// Microseconds since boot (since the TSC started, really: only differences
/// are meaningful).
pub fn micros() -> u64 {
    match CYCLES_PER_MICRO.load(Ordering::Relaxed) {
        0 => pit::millis() * 1000,
        rate => rdtsc() / rate,
    }
}
