//! A microsecond clock for the on-screen frame statistics. The PIT keeps the
//! time in whole ticks (999.847 µs), which is exact over seconds but too
//! coarse for frames that take a fraction of one; the time-stamp counter,
//! read at each tick and calibrated against the PIT, fills in within a tick.
//! So a frame rate measured over a second is as good as the PIT, whatever
//! the calibration's error, and only the sub-millisecond part leans on it.

use crate::pit;
use core::sync::atomic::{AtomicU64, Ordering};

/// TSC cycles per microsecond; 0 until calibrated (or if calibration failed),
/// when `micros` counts whole PIT ticks only.
static CYCLES_PER_MICRO: AtomicU64 = AtomicU64::new(0);
const CALIBRATION_TICKS: u64 = 50;
/// No wait here lasts longer than this many cycles (over a second at 5 GHz),
/// even if the PIT's interrupts never come.
const WAIT_LIMIT_CYCLES: u64 = 5_000_000_000;
const TICK_MICROS: u64 = pit::TICK_NANOS / 1000;

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

/// Microseconds since the PIT started: whole ticks, plus the TSC's count
/// since the last tick (never more than a tick, so the clock never runs
/// ahead of the next tick or backwards).
pub fn micros() -> u64 {
    let (ticks, stamp) = pit::ticks_and_tsc();
    let since_tick = match CYCLES_PER_MICRO.load(Ordering::Relaxed) {
        0 => 0,
        rate => (rdtsc().saturating_sub(stamp) / rate).min(TICK_MICROS),
    };
    ticks * pit::TICK_NANOS / 1000 + since_tick
}
