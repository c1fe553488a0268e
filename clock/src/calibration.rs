//! Calibrating the time-stamp counter (TSC) against a reference counter.
//!
//! The kernel's clock is the TSC, a free-running counter read on demand, so no
//! lost or merged timer interrupt can make it run slow. Its rate is measured
//! once, against a counter of known frequency: the ACPI PM timer (3.579545 MHz,
//! 24 or 32 bits, counting up), the HPET's main counter (its period in the
//! table, 32 or 64 bits, up) or PIT channel 2 (1.193182 MHz, 16 bits, counting
//! down with its gate open and no interrupt). The kernel polls the counter,
//! bracketing each read between two TSC reads. A read whose bracket is wide
//! (the CPU was held up, say an emulator's thread was descheduled) cannot say
//! when the count was taken, so only narrow brackets may start or end the
//! measurement. Between them, count deltas are summed modulo the counter's
//! width, which is right as long as successive reads are less than half a wrap
//! apart; a longer gap (seen from the TSC) starts the measurement again.
//!
//! Every reference must be seen to run before it is trusted: one whose count
//! has not changed after [`Plan::frozen_cycles`] TSC cycles (10 ms on any CPU
//! whose TSC runs at 1 GHz or more) is given up as stopped, and the whole
//! measurement is bounded by TSC cycles and by a count of polls.

/// The PIT's input clock in Hz.
pub const PIT_HZ: u64 = 1_193_182;
/// The ACPI PM timer's clock in Hz.
pub const PM_TIMER_HZ: u64 = 3_579_545;

/// A free-running counter of known frequency to measure the TSC against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reference {
    /// Counts per second.
    pub hz: u64,
    /// The counter's width: it wraps at 2^bits (1 to 64).
    pub bits: u32,
    /// Whether it counts down (the PIT) rather than up.
    pub counts_down: bool,
}

impl Reference {
    /// PIT channel 2 in mode 0: 16 bits, counting down.
    pub const PIT_CHANNEL_2: Reference = Reference {
        hz: PIT_HZ,
        bits: 16,
        counts_down: true,
    };

    /// The ACPI PM timer, 24 bits wide unless the FADT's TMR_VAL_EXT flag says 32.
    pub const fn pm_timer(is_32_bit: bool) -> Reference {
        Reference {
            hz: PM_TIMER_HZ,
            bits: if is_32_bit { 32 } else { 24 },
            counts_down: false,
        }
    }

    /// The HPET's main counter, from its period in femtoseconds (the
    /// capabilities register's upper half); `None` for a period the HPET
    /// specification does not allow (zero, or over 100 ns).
    pub fn hpet(period_femtos: u32, is_64_bit: bool) -> Option<Reference> {
        const MAX_PERIOD_FEMTOS: u32 = 100_000_000;
        if period_femtos == 0 || period_femtos > MAX_PERIOD_FEMTOS {
            return None;
        }
        Some(Reference {
            hz: 1_000_000_000_000_000 / u64::from(period_femtos),
            bits: if is_64_bit { 64 } else { 32 },
            counts_down: false,
        })
    }

    /// Counts from `earlier` to `later`, modulo the counter's width.
    fn ticks_between(&self, earlier: u64, later: u64) -> u64 {
        let elapsed = if self.counts_down {
            earlier.wrapping_sub(later)
        } else {
            later.wrapping_sub(earlier)
        };
        elapsed & self.mask()
    }

    fn mask(&self) -> u64 {
        match self.bits {
            0 => 0,
            bits @ 1..=63 => (1 << bits) - 1,
            _ => u64::MAX,
        }
    }

    /// Successive reads must be closer than this many counts, or the counter
    /// may have wrapped unseen: a little under half a wrap.
    fn max_gap_ticks(&self) -> u64 {
        (self.mask() / 20) * 9
    }

    /// Counts in `micros` microseconds.
    fn ticks_in_micros(&self, micros: u64) -> u64 {
        u64::try_from(u128::from(self.hz) * u128::from(micros) / 1_000_000).unwrap_or(u64::MAX)
    }
}

/// One poll of the reference: its count, and the TSC just before and after.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sample {
    /// The counter as read (only its low `bits` bits count).
    pub count: u64,
    /// The TSC before the read (or the latch command).
    pub tsc_before: u64,
    /// The TSC after the count was read.
    pub tsc_after: u64,
}

impl Sample {
    fn spread(&self) -> u64 {
        self.tsc_after.saturating_sub(self.tsc_before)
    }

    /// The best guess of when the count was taken: mid-bracket.
    fn midpoint(&self) -> u64 {
        self.tsc_before + self.spread() / 2
    }
}

/// The measured TSC rate and how far it can be trusted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calibration {
    /// TSC cycles per second.
    pub tsc_hz: u64,
    /// Reference counts the measurement spanned.
    pub reference_ticks: u64,
    /// The worst-case error in parts per million: the two brackets plus one
    /// reference count of quantisation.
    pub error_ppm: u64,
}

/// Why calibration gave up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibrationError {
    /// The count never changed: no such counter, or it is gated off.
    ReferenceStopped,
    /// The TSC never advanced.
    TscStopped,
    /// Every attempt was spoiled by long stalls between reads.
    TooManyStalls,
    /// The poll or cycle budget ran out before the measurement was long enough.
    OutOfTime,
}

impl CalibrationError {
    /// What it means, for the boot log.
    pub fn describe(self) -> &'static str {
        match self {
            CalibrationError::ReferenceStopped => "its count never changed",
            CalibrationError::TscStopped => "the TSC never advanced",
            CalibrationError::TooManyStalls => "every attempt was spoiled by stalls",
            CalibrationError::OutOfTime => {
                "it ran out of time before the measurement was long enough"
            }
        }
    }
}

/// How long to measure and how hard to try.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    /// How long to measure, in microseconds of the reference's time.
    pub measure_micros: u64,
    /// Polls in all before giving up: the bound that holds even if the TSC
    /// itself is stuck.
    pub max_polls: u32,
    /// TSC cycles in all before giving up.
    pub max_cycles: u64,
    /// A reference whose count has not changed after this many TSC cycles is
    /// given up as stopped.
    pub frozen_cycles: u64,
    /// Restarts after a stall before giving up.
    pub max_restarts: u32,
}

impl Plan {
    /// 200 ms; a stopped reference given up after 10 million TSC cycles
    /// (10 ms at 1 GHz, less on any faster CPU); everything within 3 billion
    /// cycles or 4 million polls; eight restarts.
    pub const DEFAULT: Plan = Plan {
        measure_micros: 200_000,
        max_polls: 4_000_000,
        max_cycles: 3_000_000_000,
        frozen_cycles: 10_000_000,
        max_restarts: 8,
    };
}

/// Polls to find the narrowest bracket this machine achieves before starting.
const WARM_UP_POLLS: u32 = 16;
/// A bracket this many times the narrowest one seen is still "narrow".
const NARROW_FACTOR: u64 = 4;
/// Microseconds of summed deltas before the running rate is trusted to spot
/// stalls.
const RATE_KNOWN_MICROS: u64 = 1_700;

/// Measures the TSC rate against `reference` by calling `poll` until the plan
/// is met.
pub fn calibrate(
    reference: Reference,
    plan: Plan,
    mut poll: impl FnMut() -> Sample,
) -> Result<Calibration, CalibrationError> {
    let target_ticks = reference.ticks_in_micros(plan.measure_micros).max(1);
    let rate_known_ticks = reference.ticks_in_micros(RATE_KNOWN_MICROS).max(1);
    let max_gap_ticks = reference.max_gap_ticks();

    let mut polls = 0u32;
    // The first sample, and whether the count has changed since.
    let mut first: Option<Sample> = None;
    let mut moved = false;
    // Every poll goes through here, so every bound is checked on every poll.
    let mut next = || -> Result<Sample, CalibrationError> {
        polls += 1;
        if polls > plan.max_polls {
            return Err(if moved {
                CalibrationError::OutOfTime
            } else {
                CalibrationError::ReferenceStopped
            });
        }
        let sample = poll();
        let first = *first.get_or_insert(sample);
        moved |= reference.ticks_between(first.count, sample.count) != 0;
        let cycles = sample.tsc_after.saturating_sub(first.tsc_before);
        if !moved && cycles > plan.frozen_cycles {
            return Err(CalibrationError::ReferenceStopped);
        }
        if cycles > plan.max_cycles {
            return Err(CalibrationError::OutOfTime);
        }
        Ok(sample)
    };

    let mut narrowest = u64::MAX;
    for _ in 0..WARM_UP_POLLS {
        narrowest = narrowest.min(next()?.spread().max(1));
    }
    let narrow = narrowest * NARROW_FACTOR;

    let mut restarts = 0;
    'attempt: loop {
        if restarts > plan.max_restarts {
            return Err(CalibrationError::TooManyStalls);
        }
        // A narrow bracket to start from.
        let start = loop {
            let sample = next()?;
            if sample.spread() <= narrow {
                break sample;
            }
        };
        let (mut previous, mut ticks) = (start, 0u64);
        loop {
            let sample = next()?;
            let delta = reference.ticks_between(previous.count, sample.count);
            let cycles = sample.midpoint().saturating_sub(start.midpoint());
            if ticks >= rate_known_ticks {
                // The gap since the last read, in reference counts, by the
                // rate so far.
                let gap = sample.tsc_after.saturating_sub(previous.tsc_before);
                let cycles_so_far = previous.midpoint().saturating_sub(start.midpoint());
                let gap_ticks =
                    u128::from(gap) * u128::from(ticks) / u128::from(cycles_so_far.max(1));
                if gap_ticks > u128::from(max_gap_ticks) {
                    restarts += 1;
                    continue 'attempt;
                }
            }
            ticks += delta;
            previous = sample;
            if ticks >= target_ticks && sample.spread() <= narrow {
                if cycles == 0 {
                    return Err(CalibrationError::TscStopped);
                }
                let tsc_hz = u128::from(cycles) * u128::from(reference.hz) / u128::from(ticks);
                let bracket_ppm = (start.spread() + sample.spread()) / 2 * 1_000_000 / cycles;
                let quantum_ppm = 1_000_000 / ticks + 1;
                return Ok(Calibration {
                    tsc_hz: u64::try_from(tsc_hz).unwrap_or(u64::MAX),
                    reference_ticks: ticks,
                    error_ppm: bracket_ppm + quantum_ppm,
                });
            }
        }
    }
}

/// A running clock from TSC readings: time since `start` at `tsc_hz`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TscClock {
    /// The TSC when the clock read zero.
    pub start: u64,
    /// TSC cycles per second (never zero).
    pub tsc_hz: u64,
}

impl TscClock {
    /// Microseconds at TSC reading `now` (0 before `start`).
    pub fn micros(&self, now: u64) -> u64 {
        let cycles = u128::from(now.saturating_sub(self.start));
        u64::try_from(cycles * 1_000_000 / u128::from(self.tsc_hz.max(1))).unwrap_or(u64::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A simulated machine: a TSC at `tsc_hz`, a reference counter starting
    /// at `first_count`, each poll taking `poll_cycles`, plus scripted stalls.
    struct Machine {
        reference: Reference,
        tsc_hz: u64,
        tsc: u64,
        first_count: u64,
        poll_cycles: u64,
        /// (poll number, cycles the CPU is held up inside that poll's bracket)
        stalls: Vec<(u32, u64)>,
        polls: u32,
        running: bool,
    }

    const TSC_START: u64 = 1_000_000;

    impl Machine {
        fn new(tsc_hz: u64) -> Self {
            Machine::with(Reference::PIT_CHANNEL_2, tsc_hz)
        }

        fn with(reference: Reference, tsc_hz: u64) -> Self {
            Machine {
                reference,
                tsc_hz,
                tsc: TSC_START,
                first_count: 0x1234,
                poll_cycles: 3_000,
                stalls: Vec::new(),
                polls: 0,
                running: true,
            }
        }

        fn count_at(&self, tsc: u64) -> u64 {
            if !self.running {
                return self.first_count;
            }
            let ticks = (u128::from(tsc - TSC_START) * u128::from(self.reference.hz)
                / u128::from(self.tsc_hz)) as u64;
            let count = if self.reference.counts_down {
                self.first_count.wrapping_sub(ticks)
            } else {
                self.first_count.wrapping_add(ticks)
            };
            count & self.reference.mask()
        }

        fn poll(&mut self) -> Sample {
            self.polls += 1;
            let tsc_before = self.tsc;
            let stall = self
                .stalls
                .iter()
                .find(|(at, _)| *at == self.polls)
                .map_or(0, |(_, cycles)| *cycles);
            // The count is read mid-way through the poll, after any stall.
            let latched = tsc_before + stall + self.poll_cycles / 2;
            self.tsc = tsc_before + stall + self.poll_cycles;
            Sample {
                count: self.count_at(latched),
                tsc_before,
                tsc_after: self.tsc,
            }
        }

        fn run(&mut self) -> Result<Calibration, CalibrationError> {
            self.run_with(Plan::DEFAULT)
        }

        fn run_with(&mut self, plan: Plan) -> Result<Calibration, CalibrationError> {
            let reference = self.reference;
            calibrate(reference, plan, || self.poll())
        }
    }

    fn ppm(measured: u64, truth: u64) -> u64 {
        measured.abs_diff(truth) * 1_000_000 / truth
    }

    #[test]
    fn measures_the_rate_within_its_stated_error() {
        for tsc_hz in [1_000_000_000, 2_893_000_123, 4_000_000_000] {
            let mut machine = Machine::new(tsc_hz);
            let result = machine.run().unwrap();
            assert!(ppm(result.tsc_hz, tsc_hz) <= result.error_ppm, "{result:?}");
            assert!(result.error_ppm < 100, "{result:?}");
            assert!(result.reference_ticks >= PIT_HZ / 5);
        }
    }

    #[test]
    fn every_reference_gives_the_rate_within_its_stated_error() {
        let references = [
            Reference::pm_timer(false),
            Reference::pm_timer(true),
            Reference::hpet(10_000_000, false).unwrap(), // 100 MHz
            Reference::hpet(69_841_279, true).unwrap(),  // 14.318 MHz
        ];
        for reference in references {
            let mut machine = Machine::with(reference, 2_300_000_000);
            let result = machine.run().unwrap();
            assert!(
                ppm(result.tsc_hz, 2_300_000_000) <= result.error_ppm,
                "{reference:?}: {result:?}"
            );
            assert!(result.error_ppm < 50, "{reference:?}: {result:?}");
        }
    }

    #[test]
    fn the_24_bit_pm_timer_wraps_without_losing_a_count() {
        let truth = 2_000_000_000;
        let mut machine = Machine::with(Reference::pm_timer(false), truth);
        // 100 ms before the wrap at 2^24: the measurement spans it.
        machine.first_count = 0xFF_FFFF - PM_TIMER_HZ / 10;
        let result = machine.run().unwrap();
        assert!(ppm(result.tsc_hz, truth) <= result.error_ppm, "{result:?}");
        // Read as 32 bits, the same counts would jump by 2^32 - 2^24 at the
        // wrap: the width matters.
        let wide = Reference::pm_timer(true);
        assert_eq!(wide.ticks_between(0xFF_FFFF, 0x00_0001), 0xFF00_0002);
        assert_eq!(
            Reference::pm_timer(false).ticks_between(0xFF_FFFF, 0x00_0001),
            2
        );
    }

    #[test]
    fn a_stall_inside_a_bracket_does_not_skew_the_result() {
        let mut machine = Machine::new(2_000_000_000);
        // 5 ms held up inside the bracket of the very first measured poll.
        machine.stalls.push((17, 10_000_000));
        let result = machine.run().unwrap();
        assert!(ppm(result.tsc_hz, 2_000_000_000) < 100, "{result:?}");
    }

    #[test]
    fn a_stall_longer_than_the_frozen_bound_is_not_a_stopped_counter() {
        // 20 ms held up right after the first poll: the count has moved by
        // the next one, so the counter is running, not frozen.
        let mut machine = Machine::new(2_000_000_000);
        machine.stalls.push((2, 40_000_000));
        let result = machine.run().unwrap();
        assert!(ppm(result.tsc_hz, 2_000_000_000) < 100, "{result:?}");
    }

    #[test]
    fn a_stall_long_enough_to_hide_a_wrap_restarts_the_measurement() {
        let truth = 2_000_000_000;
        let mut machine = Machine::new(truth);
        // 60 ms (more than one 65,536-tick wrap) between two polls, mid-way.
        machine.stalls.push((20_000, 120_000_000));
        let result = machine.run().unwrap();
        assert!(ppm(result.tsc_hz, truth) < 100, "{result:?}");

        // Without the restart the summed deltas would be 65,536 ticks short:
        // the same stall, with restarts forbidden, must not give a result.
        let mut machine = Machine::new(truth);
        machine.stalls.push((20_000, 120_000_000));
        let plan = Plan {
            max_restarts: 0,
            ..Plan::DEFAULT
        };
        assert_eq!(machine.run_with(plan), Err(CalibrationError::TooManyStalls));
    }

    #[test]
    fn a_frozen_counter_is_given_up_within_ten_milliseconds() {
        for tsc_hz in [1_000_000_000u64, 3_000_000_000] {
            for reference in [Reference::PIT_CHANNEL_2, Reference::pm_timer(false)] {
                let mut machine = Machine::with(reference, tsc_hz);
                machine.running = false;
                assert_eq!(machine.run(), Err(CalibrationError::ReferenceStopped));
                let spent = machine.tsc - TSC_START;
                // 10 ms at 1 GHz, and never more than 10 ms at a faster TSC.
                assert!(spent <= Plan::DEFAULT.frozen_cycles + machine.poll_cycles);
                assert!(spent * 1000 / tsc_hz <= 10, "{spent} cycles at {tsc_hz} Hz");
            }
        }
    }

    #[test]
    fn a_frozen_counter_and_a_stuck_tsc_end_on_the_poll_budget() {
        let mut machine = Machine::new(2_000_000_000);
        machine.running = false;
        machine.poll_cycles = 0;
        let plan = Plan {
            max_polls: 100_000,
            ..Plan::DEFAULT
        };
        assert_eq!(
            machine.run_with(plan),
            Err(CalibrationError::ReferenceStopped)
        );
        assert_eq!(machine.polls, 100_000);
    }

    #[test]
    fn the_poll_budget_bounds_the_wait() {
        let mut machine = Machine::new(2_000_000_000);
        let plan = Plan {
            max_polls: 1_000,
            ..Plan::DEFAULT
        };
        assert_eq!(machine.run_with(plan), Err(CalibrationError::OutOfTime));
        assert_eq!(machine.polls, 1_000);
    }

    #[test]
    fn the_cycle_budget_bounds_the_wait() {
        // Polls so slow (1 ms each) that 200 ms of measuring cannot fit in a
        // budget of 50 ms.
        let mut machine = Machine::new(1_000_000_000);
        machine.poll_cycles = 1_000_000;
        let plan = Plan {
            max_cycles: 50_000_000,
            ..Plan::DEFAULT
        };
        assert_eq!(machine.run_with(plan), Err(CalibrationError::OutOfTime));
        assert!(machine.tsc - TSC_START <= 51_000_000);
    }

    #[test]
    fn hpet_periods_outside_the_specification_are_refused() {
        assert_eq!(Reference::hpet(0, false), None);
        assert_eq!(Reference::hpet(100_000_001, false), None);
        assert_eq!(
            Reference::hpet(100_000_000, true).map(|r| r.hz),
            Some(10_000_000)
        );
    }

    #[test]
    fn the_clock_converts_cycles_to_microseconds() {
        let clock = TscClock {
            start: 500,
            tsc_hz: 3_000_000_000,
        };
        assert_eq!(clock.micros(400), 0);
        assert_eq!(clock.micros(500 + 3_000_000_000), 1_000_000);
        assert_eq!(clock.micros(500 + 4_500), 1);
        // A year of cycles at 3 GHz does not overflow.
        let year = 3_000_000_000u64 * 86_400 * 365;
        assert_eq!(clock.micros(500 + year), 86_400 * 365 * 1_000_000);
    }
}
