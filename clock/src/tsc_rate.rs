//! Where the TSC's rate comes from, on whatever the machine has.
//!
//! Recent Intel platforms gate the 8254 PIT's clock, so the PIT cannot be the
//! only reference. The sources are tried in order and the first that works is
//! taken:
//!
//! 1. CPUID leaf 15h, where it is complete: the crystal's frequency times the
//!    TSC/crystal ratio. With the crystal left as zero (as many client parts
//!    leave it) but leaf 16h giving the base frequency, the TSC runs at the
//!    base frequency (Intel SDM vol. 3B 18.7.3; Linux's `native_calibrate_tsc`
//!    does the same). Nothing is measured, so nothing can stall.
//! 2. The ACPI PM timer (FADT), 3.579545 MHz, which every ACPI PC has.
//! 3. The HPET's main counter (its own ACPI table).
//! 4. PIT channel 2, last.
//!
//! Each measured source must be seen to run (see `calibration`): a missing or
//! gated counter is given up within 10 ms and the next one tried. A machine
//! where none works still runs, on an assumed rate, and says so.

use crate::calibration::{Calibration, CalibrationError, Reference};
use core::fmt;

/// Where the TSC's rate came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// CPUID leaf 15h: the crystal frequency times the TSC/crystal ratio.
    CpuidCrystal,
    /// CPUID leaf 16h's base frequency (leaf 15h gives the ratio but no crystal).
    CpuidBaseFrequency,
    /// Measured against the ACPI PM timer.
    PmTimer,
    /// Measured against the HPET's main counter.
    Hpet,
    /// Measured against PIT channel 2.
    Pit,
    /// Nothing worked: a guess, so that the kernel still runs.
    Assumed,
}

impl Source {
    /// How the boot log names it.
    pub fn describe(self) -> &'static str {
        match self {
            Source::CpuidCrystal => "CPUID leaf 15h",
            Source::CpuidBaseFrequency => "CPUID leaf 16h's base frequency",
            Source::PmTimer => "the ACPI PM timer",
            Source::Hpet => "the HPET",
            Source::Pit => "PIT channel 2",
            Source::Assumed => "no reference (assumed)",
        }
    }
}

/// What CPUID says about the TSC, as read by the kernel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CpuidTsc {
    /// Leaf 15h's EAX (ratio denominator), EBX (ratio numerator) and ECX
    /// (crystal Hz), if the CPU has the leaf.
    pub leaf_15: Option<[u32; 3]>,
    /// Leaf 16h's EAX: the base frequency in MHz, if the CPU has the leaf.
    pub base_mhz: Option<u32>,
}

/// Why CPUID did not give the rate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CpuidGap {
    /// No leaf 15h (older CPUs, and most emulated ones).
    NoLeaf15,
    /// Leaf 15h is there but its ratio is zero: not enumerated.
    NoRatio,
    /// The ratio is there, but neither the crystal frequency nor the base
    /// frequency is.
    NoCrystal,
}

impl CpuidGap {
    /// What it means, for the boot log.
    pub fn describe(self) -> &'static str {
        match self {
            CpuidGap::NoLeaf15 => "the CPU has no leaf 15h",
            CpuidGap::NoRatio => "leaf 15h gives no TSC/crystal ratio",
            CpuidGap::NoCrystal => {
                "leaf 15h gives no crystal frequency and leaf 16h no base frequency"
            }
        }
    }
}

impl CpuidTsc {
    /// The TSC's rate by CPUID alone, where it is complete.
    pub fn tsc_hz(&self) -> Result<(u64, Source), CpuidGap> {
        let [denominator, numerator, crystal_hz] = self.leaf_15.ok_or(CpuidGap::NoLeaf15)?;
        if denominator == 0 || numerator == 0 {
            return Err(CpuidGap::NoRatio);
        }
        if crystal_hz != 0 {
            let hz = u64::from(crystal_hz) * u64::from(numerator) / u64::from(denominator);
            return Ok((hz, Source::CpuidCrystal));
        }
        match self.base_mhz {
            Some(mhz) if mhz != 0 => Ok((u64::from(mhz) * 1_000_000, Source::CpuidBaseFrequency)),
            _ => Err(CpuidGap::NoCrystal),
        }
    }
}

/// The references the machine's tables offer, besides CPUID and the PIT
/// (which has no table and is always tried last).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Candidates {
    /// What CPUID says.
    pub cpuid: CpuidTsc,
    /// The PM timer, if the FADT names one.
    pub pm_timer: Option<Reference>,
    /// The HPET, if its table is there and its period is valid.
    pub hpet: Option<Reference>,
    /// Only this measured source is to be tried (a boot option, so that the
    /// tests can drive each reference on a machine that has them all).
    pub only: Option<Source>,
}

/// The TSC's rate and where it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TscRate {
    /// TSC cycles per second.
    pub hz: u64,
    /// Where the figure came from.
    pub source: Source,
    /// The measurement's worst-case error; `None` for a nominal figure
    /// (CPUID's, or an assumed one).
    pub error_ppm: Option<u64>,
}

impl fmt::Display for TscRate {
    /// The boot log's line, e.g. `clock: TSC 2300000 kHz from the ACPI PM
    /// timer, error under 20 ppm`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "clock: TSC {} kHz from {}",
            self.hz / 1000,
            self.source.describe()
        )?;
        match (self.source, self.error_ppm) {
            (_, Some(ppm)) => write!(f, ", error under {ppm} ppm"),
            (Source::Assumed, None) => write!(f, "; every time the kernel shows is approximate"),
            (_, None) => write!(f, " (nominal: the crystal's own tolerance)"),
        }
    }
}

/// A source that was tried and passed over, for the boot log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Skipped {
    /// CPUID did not give the rate.
    Cpuid(CpuidGap),
    /// The ACPI tables name no such counter.
    NotInTables(Source),
    /// The measurement failed.
    Failed(Source, CalibrationError),
    /// A boot option asked for another source.
    NotAsked(Source),
}

impl fmt::Display for Skipped {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Skipped::Cpuid(gap) => write!(f, "clock: not from CPUID: {}", gap.describe()),
            Skipped::NotInTables(source) => {
                write!(
                    f,
                    "clock: not from {}: the ACPI tables name none",
                    source.describe()
                )
            }
            Skipped::NotAsked(source) => write!(
                f,
                "clock: not from {}: the boot option asks for another",
                source.describe()
            ),
            Skipped::Failed(source, error) => {
                write!(
                    f,
                    "clock: not from {}: {}",
                    source.describe(),
                    error.describe()
                )
            }
        }
    }
}

/// The TSC rate assumed when no source works: with it the kernel still
/// draws, its waits still end, and the log says the times are approximate.
pub const ASSUMED_TSC_HZ: u64 = 2_000_000_000;

/// Tries the sources in order and returns the first rate that works, telling
/// `skipped` about each one passed over. `calibrate` measures the TSC against
/// one reference (the kernel polls the counter; the host tests simulate it).
pub fn find_tsc_rate(
    candidates: &Candidates,
    mut calibrate: impl FnMut(Source, Reference) -> Result<Calibration, CalibrationError>,
    mut skipped: impl FnMut(Skipped),
) -> TscRate {
    match candidates.cpuid.tsc_hz() {
        _ if candidates.only.is_some() => skipped(Skipped::NotAsked(Source::CpuidCrystal)),
        Ok((hz, source)) => {
            return TscRate {
                hz,
                source,
                error_ppm: None,
            }
        }
        Err(gap) => skipped(Skipped::Cpuid(gap)),
    }
    let measured = [
        (Source::PmTimer, candidates.pm_timer),
        (Source::Hpet, candidates.hpet),
        (Source::Pit, Some(Reference::PIT_CHANNEL_2)),
    ];
    for (source, reference) in measured {
        if candidates.only.is_some_and(|only| only != source) {
            skipped(Skipped::NotAsked(source));
            continue;
        }
        let Some(reference) = reference else {
            skipped(Skipped::NotInTables(source));
            continue;
        };
        match calibrate(source, reference) {
            Ok(calibration) => {
                return TscRate {
                    hz: calibration.tsc_hz,
                    source,
                    error_ppm: Some(calibration.error_ppm),
                }
            }
            Err(error) => skipped(Skipped::Failed(source, error)),
        }
    }
    TscRate {
        hz: match candidates.cpuid.base_mhz {
            Some(mhz) if mhz != 0 => u64::from(mhz) * 1_000_000,
            _ => ASSUMED_TSC_HZ,
        },
        source: Source::Assumed,
        error_ppm: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::PIT_HZ;
    use std::string::ToString;
    use std::vec;
    use std::vec::Vec;

    fn measured(hz: u64) -> Result<Calibration, CalibrationError> {
        Ok(Calibration {
            tsc_hz: hz,
            reference_ticks: PIT_HZ / 5,
            error_ppm: 7,
        })
    }

    /// Runs the choice with `works` saying which measured sources succeed;
    /// returns the rate and the sources tried, in order.
    fn choose(candidates: &Candidates, works: &[Source]) -> (TscRate, Vec<Source>, Vec<Skipped>) {
        let mut tried = Vec::new();
        let mut skipped = Vec::new();
        let rate = find_tsc_rate(
            candidates,
            |source, _| {
                tried.push(source);
                if works.contains(&source) {
                    measured(2_300_000_000)
                } else {
                    Err(CalibrationError::ReferenceStopped)
                }
            },
            |skip| skipped.push(skip),
        );
        (rate, tried, skipped)
    }

    fn everything() -> Candidates {
        Candidates {
            cpuid: CpuidTsc::default(),
            pm_timer: Some(Reference::pm_timer(true)),
            hpet: Reference::hpet(10_000_000, true),
            only: None,
        }
    }

    #[test]
    fn sources_are_tried_in_order_and_the_first_that_works_is_taken() {
        let all = [Source::PmTimer, Source::Hpet, Source::Pit];
        let (rate, tried, _) = choose(&everything(), &all);
        assert_eq!(
            (rate.source, tried),
            (Source::PmTimer, vec![Source::PmTimer])
        );

        let (rate, tried, skipped) = choose(&everything(), &[Source::Hpet, Source::Pit]);
        assert_eq!(rate.source, Source::Hpet);
        assert_eq!(tried, [Source::PmTimer, Source::Hpet]);
        assert_eq!(
            skipped,
            [
                Skipped::Cpuid(CpuidGap::NoLeaf15),
                Skipped::Failed(Source::PmTimer, CalibrationError::ReferenceStopped)
            ]
        );

        // No PIT (pit=off) and no HPET (hpet=off): the PM timer alone.
        let no_hpet = Candidates {
            hpet: None,
            ..everything()
        };
        let (rate, tried, _) = choose(&no_hpet, &[Source::PmTimer]);
        assert_eq!(
            (rate.source, tried),
            (Source::PmTimer, vec![Source::PmTimer])
        );

        // Tables with neither: the PIT, last.
        let (rate, tried, skipped) = choose(&Candidates::default(), &[Source::Pit]);
        assert_eq!((rate.source, tried), (Source::Pit, vec![Source::Pit]));
        assert!(skipped.contains(&Skipped::NotInTables(Source::PmTimer)));
        assert!(skipped.contains(&Skipped::NotInTables(Source::Hpet)));
    }

    #[test]
    fn a_boot_option_can_ask_for_one_source() {
        let only_pit = Candidates {
            cpuid: CpuidTsc {
                leaf_15: Some([2, 188, 24_000_000]),
                base_mhz: None,
            },
            only: Some(Source::Pit),
            ..everything()
        };
        let all = [Source::PmTimer, Source::Hpet, Source::Pit];
        let (rate, tried, skipped) = choose(&only_pit, &all);
        assert_eq!((rate.source, tried), (Source::Pit, vec![Source::Pit]));
        assert!(skipped.contains(&Skipped::NotAsked(Source::PmTimer)));
    }

    #[test]
    fn a_complete_cpuid_leaf_is_taken_without_measuring() {
        let candidates = Candidates {
            cpuid: CpuidTsc {
                leaf_15: Some([2, 188, 24_000_000]),
                base_mhz: Some(2_200),
            },
            ..everything()
        };
        let (rate, tried, _) = choose(&candidates, &[Source::PmTimer]);
        assert_eq!(rate.hz, 2_256_000_000);
        assert_eq!(rate.source, Source::CpuidCrystal);
        assert!(tried.is_empty());
    }

    #[test]
    fn cpuid_15h_with_a_zero_crystal_frequency() {
        // The ratio without the crystal: the base frequency of leaf 16h.
        let base = CpuidTsc {
            leaf_15: Some([2, 176, 0]),
            base_mhz: Some(2_100),
        };
        assert_eq!(
            base.tsc_hz(),
            Ok((2_100_000_000, Source::CpuidBaseFrequency))
        );
        // Without leaf 16h either: not from CPUID, so measured.
        let neither = CpuidTsc {
            leaf_15: Some([2, 176, 0]),
            base_mhz: None,
        };
        assert_eq!(neither.tsc_hz(), Err(CpuidGap::NoCrystal));
        let candidates = Candidates {
            cpuid: neither,
            ..everything()
        };
        let (rate, _, skipped) = choose(&candidates, &[Source::PmTimer]);
        assert_eq!(rate.source, Source::PmTimer);
        assert_eq!(skipped, [Skipped::Cpuid(CpuidGap::NoCrystal)]);
        // A zero ratio is no answer at all.
        let zero_ratio = CpuidTsc {
            leaf_15: Some([0, 0, 24_000_000]),
            base_mhz: Some(2_100),
        };
        assert_eq!(zero_ratio.tsc_hz(), Err(CpuidGap::NoRatio));
    }

    #[test]
    fn with_no_working_source_the_rate_is_assumed_and_says_so() {
        let (rate, tried, skipped) = choose(&everything(), &[]);
        assert_eq!(tried, [Source::PmTimer, Source::Hpet, Source::Pit]);
        assert_eq!(skipped.len(), 4);
        assert_eq!(rate.source, Source::Assumed);
        assert_eq!(rate.hz, ASSUMED_TSC_HZ);
        assert!(rate.to_string().contains("approximate"), "{rate}");
    }

    #[test]
    fn the_boot_log_names_the_source_and_its_error_bound() {
        let rate = TscRate {
            hz: 2_300_000_123,
            source: Source::PmTimer,
            error_ppm: Some(20),
        };
        assert_eq!(
            rate.to_string(),
            "clock: TSC 2300000 kHz from the ACPI PM timer, error under 20 ppm"
        );
        assert_eq!(
            Skipped::Failed(Source::Pit, CalibrationError::ReferenceStopped).to_string(),
            "clock: not from PIT channel 2: its count never changed"
        );
    }
}
