//! The kernel's clock: the time-stamp counter ([`tsc`]), read on demand. Its rate comes
//! from the first source that works on this machine (`clock::tsc_rate`):
//! CPUID, or a measurement against the ACPI PM timer, the HPET or PIT
//! channel 2, each polled (`clock::calibration`).
//!
//! Time comes from a free-running counter, not from counting interrupts, so
//! an emulator that merges or drops timer interrupts on a busy host cannot
//! make it run slow, and a machine without a PIT still has a clock. Before
//! `init`, and on a machine whose TSC does not advance, each reading moves
//! the clock on by a microsecond: every wait written against this clock ends.

pub mod hpet;
pub mod pit;
pub mod pm_timer;
pub mod tsc;

use crate::platform::acpi::Facts;
use crate::serial_println;
use clock::calibration::{self, Calibration, CalibrationError, Plan, Reference, TscClock};
use clock::tsc_rate::{find_tsc_rate, Candidates, CpuidTsc, Source, TscRate};
use core::sync::atomic::{AtomicU64, Ordering};
use hpet::Hpet;
use protocol::ClockReference;
use spin::Once;
use tsc::rdtsc;

static CLOCK: Once<TscClock> = Once::new();

/// The clock used before `init` or without a running TSC: one microsecond a
/// reading.
static COUNTED_MICROS: AtomicU64 = AtomicU64::new(0);

/// Finds the TSC's rate (at most a few hundred milliseconds; interrupts may
/// be on or off), logs each source tried and the one taken, and starts the
/// clock at zero.
pub fn init(facts: &Facts, physical_memory_offset: u64, only: Option<ClockReference>) -> TscRate {
    let hpet = facts
        .hpet
        .map(|physical| Hpet::new(physical, physical_memory_offset));
    let candidates = Candidates {
        cpuid: cpuid_tsc(),
        pm_timer: facts
            .pm_timer
            .map(|timer| Reference::pm_timer(timer.is_32_bit)),
        hpet: hpet.and_then(|hpet| hpet.start()),
        only: only.map(|reference| match reference {
            ClockReference::PmTimer => Source::PmTimer,
            ClockReference::Hpet => Source::Hpet,
            ClockReference::Pit => Source::Pit,
        }),
    };
    let tsc_at_start = rdtsc();
    let rate = find_tsc_rate(
        &candidates,
        |source, reference| measure(source, reference, facts, hpet),
        |skipped| serial_println!("{}", skipped),
    );
    serial_println!("{}", rate);
    if rdtsc() == tsc_at_start {
        serial_println!("clock: the TSC does not advance; each clock reading counts as 1 us");
    } else {
        CLOCK.call_once(|| TscClock {
            start: rdtsc(),
            tsc_hz: rate.hz.max(1),
        });
    }
    rate
}

fn measure(
    source: Source,
    reference: Reference,
    facts: &Facts,
    hpet: Option<Hpet>,
) -> Result<Calibration, CalibrationError> {
    match (source, facts.pm_timer, hpet) {
        (Source::PmTimer, Some(timer), _) => calibrate(reference, &mut || pm_timer::sample(timer)),
        (Source::Hpet, _, Some(hpet)) => calibrate(reference, &mut || hpet.sample()),
        (Source::Pit, _, _) => {
            pit::start_channel_2_countdown();
            let result = calibrate(reference, &mut pit::poll_channel_2);
            pit::stop_channel_2();
            result
        }
        _ => Err(CalibrationError::ReferenceStopped),
    }
}

/// `calibration::calibrate` built once for every reference: each sample
/// brackets its read with the TSC itself, so calling it through a pointer
/// costs the measurement nothing, and one copy instead of three saved
/// 7 KB of the kernel file.
#[inline(never)]
fn calibrate(
    reference: Reference,
    poll: &mut dyn FnMut() -> calibration::Sample,
) -> Result<Calibration, CalibrationError> {
    calibration::calibrate(reference, Plan::DEFAULT, poll)
}

/// CPUID leaves 15h and 16h, where the CPU has them.
fn cpuid_tsc() -> CpuidTsc {
    // Leaf 0 gives the highest basic leaf; no leaf above it is asked for.
    let max_leaf = core::arch::x86_64::__cpuid(0).eax;
    let leaf = |number: u32| (max_leaf >= number).then(|| core::arch::x86_64::__cpuid(number));
    CpuidTsc {
        leaf_15: leaf(0x15).map(|r| [r.eax, r.ebx, r.ecx]),
        base_mhz: leaf(0x16).map(|r| r.eax & 0xFFFF),
    }
}

/// Microseconds in `cycles` of the TSC (0 without a running clock).
pub fn cycles_to_micros(cycles: u64) -> u64 {
    CLOCK
        .get()
        .map_or(0, |clock| TscClock { start: 0, ..*clock }.micros(cycles))
}

/// Microseconds since `init`.
pub fn micros() -> u64 {
    match CLOCK.get() {
        Some(clock) => clock.micros(rdtsc()),
        None => COUNTED_MICROS.fetch_add(1, Ordering::Relaxed) + 1,
    }
}
