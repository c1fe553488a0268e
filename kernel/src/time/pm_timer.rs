//! The ACPI power-management timer: a free-running 3.579545 MHz counter in
//! the chipset, 24 or 32 bits, at the I/O port the FADT names. Reading it has
//! no side effect, so it is only ever read.

use crate::platform::acpi::PmTimer;
use clock::calibration::Sample;
use x86_64::instructions::port::Port;

/// Reads the count, bracketed by two TSC reads.
pub fn sample(timer: PmTimer) -> Sample {
    let tsc_before = crate::time::tsc::rdtsc();
    // SAFETY: the FADT names this port as the PM timer; reading it has no
    // side effect.
    let count = unsafe { Port::<u32>::new(timer.port).read() };
    Sample {
        count: u64::from(count),
        tsc_before,
        tsc_after: crate::time::tsc::rdtsc(),
    }
}
