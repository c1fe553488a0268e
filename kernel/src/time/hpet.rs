//! The High Precision Event Timer's main counter, as a reference to measure
//! the TSC against. Only the counter is used: no comparator, no interrupt.
//! Its registers are memory-mapped below 4 GiB, inside the bootloader's map
//! of physical memory (which is write-back by the page tables, but the
//! firmware's MTRRs make that range uncached, as for every MMIO range).

use clock::calibration::{Reference, Sample};

/// General Capabilities and ID: bits 63-32 the period in femtoseconds, bit 13
/// set for a 64-bit main counter.
const CAPABILITIES: u64 = 0x000;
const COUNTER_64_BIT: u64 = 1 << 13;
/// General Configuration: bit 0 lets the main counter run.
const CONFIGURATION: u64 = 0x010;
const ENABLE: u64 = 1;
const MAIN_COUNTER: u64 = 0x0F0;

/// An HPET's register block, by its virtual address.
#[derive(Clone, Copy, Debug)]
pub struct Hpet {
    registers: u64,
}

impl Hpet {
    /// The HPET at `physical` (from its ACPI table).
    pub fn new(physical: u64, physical_memory_offset: u64) -> Self {
        Hpet {
            registers: physical_memory_offset + physical,
        }
    }

    fn read(&self, register: u64) -> u64 {
        // SAFETY: the ACPI HPET table puts the register block here, inside the
        // bootloader's map of physical memory; these reads have no side effect.
        unsafe { core::ptr::read_volatile((self.registers + register) as *const u64) }
    }

    /// The main counter as a reference, if its period is one the
    /// specification allows; starts the counter if the firmware left it
    /// stopped (the comparators stay off, so no interrupt can follow).
    pub fn start(&self) -> Option<Reference> {
        let capabilities = self.read(CAPABILITIES);
        let reference = Reference::hpet(
            (capabilities >> 32) as u32,
            capabilities & COUNTER_64_BIT != 0,
        )?;
        let configuration = self.read(CONFIGURATION);
        if configuration & ENABLE == 0 {
            // SAFETY: setting ENABLE_CNF only lets the main counter run; the
            // legacy-replacement bit and every comparator are left as they were.
            unsafe {
                core::ptr::write_volatile(
                    (self.registers + CONFIGURATION) as *mut u64,
                    configuration | ENABLE,
                )
            };
        }
        Some(reference)
    }

    /// Reads the main counter, bracketed by two TSC reads.
    pub fn sample(&self) -> Sample {
        let tsc_before = crate::time::tsc::rdtsc();
        let count = self.read(MAIN_COUNTER);
        Sample {
            count,
            tsc_before,
            tsc_after: crate::time::tsc::rdtsc(),
        }
    }
}
