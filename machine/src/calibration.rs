//! Calibrating the time-stamp counter (TSC) against PIT channel 2.
//!
//! The kernel's clock is the TSC, a free-running counter read on demand, so no
//! lost or merged timer interrupt can make it run slow. Its rate is measured
//! once, against the PIT's 1.193182 MHz input clock: channel 2 counts down
//! with its gate open and no interrupt, and the kernel polls its count,
//! bracketing each read between two TSC reads. A read whose bracket is wide
//! (the CPU was held up, say an emulator's thread was descheduled) cannot say
//! when the count was taken, so only narrow brackets may start or end the
//! measurement. Between them, count deltas are summed modulo 2^16, which is
//! right as long as successive reads are less than 55 ms apart; a longer gap
//! (seen from the TSC) starts the measurement again.

/// The PIT's input clock in Hz.
pub const PIT_HZ: u64 = 1_193_182;

/// One poll of PIT channel 2: its count, and the TSC just before and after.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sample {
    /// The counter as latched (it counts down and wraps from 0 to 0xFFFF).
    pub count: u16,
    /// The TSC before the latch command.
    pub tsc_before: u64,
    /// The TSC after the count was read.
    pub tsc_after: u64,
}

impl Sample {
    fn spread(&self) -> u64 {
        self.tsc_after.saturating_sub(self.tsc_before)
    }

    /// The best guess of when the count was latched: mid-bracket.
    fn midpoint(&self) -> u64 {
        self.tsc_before + self.spread() / 2
    }
}

/// The measured TSC rate and how far it can be trusted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Calibration {
    /// TSC cycles per second.
    pub tsc_hz: u64,
    /// PIT input clocks the measurement spanned.
    pub pit_ticks: u64,
    /// The worst-case error in parts per million: the two brackets plus one
    /// PIT tick of quantisation.
    pub error_ppm: u64,
}

/// Why calibration gave up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibrationError {
    /// The count never changed: no PIT, or its gate is closed.
    PitStopped,
    /// The TSC never advanced.
    TscStopped,
    /// Every attempt was spoiled by long stalls between reads.
    TooManyStalls,
    /// The poll budget ran out before the measurement was long enough.
    OutOfPolls,
}

/// How long to measure and how hard to try.
#[derive(Clone, Copy, Debug)]
pub struct Plan {
    /// PIT input clocks to measure over (238,636 is 200 ms).
    pub pit_ticks: u64,
    /// Polls in all before giving up (every wait in the kernel is bounded).
    pub max_polls: u32,
    /// Restarts after a stall before giving up.
    pub max_restarts: u32,
}

impl Plan {
    /// 200 ms, at most a few million polls, eight restarts.
    pub const DEFAULT: Plan = Plan {
        pit_ticks: PIT_HZ / 5,
        max_polls: 20_000_000,
        max_restarts: 8,
    };
}

/// Polls to find the narrowest bracket this machine achieves before starting.
const WARM_UP_POLLS: u32 = 16;
/// A bracket this many times the narrowest one seen is still "narrow".
const NARROW_FACTOR: u64 = 4;
/// Successive reads must be closer than this many PIT ticks (of 65,536), or
/// the count may have wrapped unseen.
const MAX_GAP_TICKS: u64 = 30_000;
/// Deltas summed before the running rate is trusted to spot stalls.
const RATE_KNOWN_TICKS: u64 = 2_000;

/// Measures the TSC rate by calling `poll` until the plan is met.
pub fn calibrate(
    plan: Plan,
    mut poll: impl FnMut() -> Sample,
) -> Result<Calibration, CalibrationError> {
    let mut polls = 0u32;
    let mut next = || {
        polls += 1;
        (polls <= plan.max_polls).then(&mut poll)
    };

    let mut narrowest = u64::MAX;
    let mut first = None;
    for _ in 0..WARM_UP_POLLS {
        let sample = next().ok_or(CalibrationError::OutOfPolls)?;
        narrowest = narrowest.min(sample.spread().max(1));
        first.get_or_insert(sample);
    }
    let first = first.ok_or(CalibrationError::OutOfPolls)?;
    let narrow = narrowest * NARROW_FACTOR;

    let mut restarts = 0;
    let mut moved = false;
    'attempt: loop {
        if restarts > plan.max_restarts {
            return Err(CalibrationError::TooManyStalls);
        }
        // A narrow bracket to start from.
        let start = loop {
            let sample = next().ok_or(CalibrationError::OutOfPolls)?;
            moved |= sample.count != first.count;
            if sample.spread() <= narrow {
                break sample;
            }
        };
        let (mut previous, mut ticks) = (start, 0u64);
        loop {
            let sample = next().ok_or(if moved {
                CalibrationError::OutOfPolls
            } else {
                CalibrationError::PitStopped
            })?;
            let delta = u64::from(previous.count.wrapping_sub(sample.count));
            moved |= delta != 0;
            let cycles = sample.midpoint().saturating_sub(start.midpoint());
            if ticks >= RATE_KNOWN_TICKS {
                // The gap since the last read, in PIT ticks, by the rate so far.
                let gap = sample.tsc_after.saturating_sub(previous.tsc_before);
                let cycles_so_far = previous.midpoint().saturating_sub(start.midpoint());
                if gap.saturating_mul(ticks) / cycles_so_far.max(1) > MAX_GAP_TICKS {
                    restarts += 1;
                    continue 'attempt;
                }
            }
            ticks += delta;
            previous = sample;
            if ticks >= plan.pit_ticks && sample.spread() <= narrow {
                if cycles == 0 {
                    return Err(CalibrationError::TscStopped);
                }
                let tsc_hz = u128::from(cycles) * u128::from(PIT_HZ) / u128::from(ticks);
                let bracket_ppm = (start.spread() + sample.spread()) / 2 * 1_000_000 / cycles;
                let quantum_ppm = 1_000_000 / ticks + 1;
                return Ok(Calibration {
                    tsc_hz: u64::try_from(tsc_hz).unwrap_or(u64::MAX),
                    pit_ticks: ticks,
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

    /// A simulated machine: a TSC at `tsc_hz`, the PIT counting down from
    /// `first_count`, each poll taking `poll_cycles`, plus scripted stalls.
    struct Machine {
        tsc_hz: u64,
        tsc: u64,
        first_count: u16,
        poll_cycles: u64,
        /// (poll number, cycles the CPU is held up inside that poll's bracket)
        stalls: Vec<(u32, u64)>,
        polls: u32,
        pit_running: bool,
    }

    impl Machine {
        fn new(tsc_hz: u64) -> Self {
            Machine {
                tsc_hz,
                tsc: 1_000_000,
                first_count: 0x1234,
                poll_cycles: 3_000,
                stalls: Vec::new(),
                polls: 0,
                pit_running: true,
            }
        }

        fn count_at(&self, tsc: u64) -> u16 {
            if !self.pit_running {
                return self.first_count;
            }
            let ticks = u128::from(tsc - 1_000_000) * u128::from(PIT_HZ) / u128::from(self.tsc_hz);
            self.first_count.wrapping_sub(ticks as u16)
        }

        fn poll(&mut self) -> Sample {
            self.polls += 1;
            let tsc_before = self.tsc;
            let stall = self
                .stalls
                .iter()
                .find(|(at, _)| *at == self.polls)
                .map_or(0, |(_, cycles)| *cycles);
            // The count is latched mid-way through the poll, after any stall.
            let latched = tsc_before + stall + self.poll_cycles / 2;
            self.tsc = tsc_before + stall + self.poll_cycles;
            Sample {
                count: self.count_at(latched),
                tsc_before,
                tsc_after: self.tsc,
            }
        }
    }

    fn run(machine: &mut Machine) -> Result<Calibration, CalibrationError> {
        calibrate(Plan::DEFAULT, || machine.poll())
    }

    fn ppm(measured: u64, truth: u64) -> u64 {
        measured.abs_diff(truth) * 1_000_000 / truth
    }

    #[test]
    fn measures_the_rate_within_its_stated_error() {
        for tsc_hz in [1_000_000_000, 2_893_000_123, 4_000_000_000] {
            let mut machine = Machine::new(tsc_hz);
            let result = run(&mut machine).unwrap();
            assert!(ppm(result.tsc_hz, tsc_hz) <= result.error_ppm, "{result:?}");
            assert!(result.error_ppm < 100, "{result:?}");
            assert!(result.pit_ticks >= Plan::DEFAULT.pit_ticks);
        }
    }

    #[test]
    fn a_stall_inside_a_bracket_does_not_skew_the_result() {
        let mut machine = Machine::new(2_000_000_000);
        // 5 ms held up inside the bracket of the very first measured poll.
        machine.stalls.push((17, 10_000_000));
        let result = run(&mut machine).unwrap();
        assert!(ppm(result.tsc_hz, 2_000_000_000) < 100, "{result:?}");
    }

    #[test]
    fn a_stall_long_enough_to_hide_a_wrap_restarts_the_measurement() {
        let truth = 2_000_000_000;
        let mut machine = Machine::new(truth);
        // 60 ms (more than one 65,536-tick wrap) between two polls, mid-way.
        machine.stalls.push((20_000, 120_000_000));
        let result = run(&mut machine).unwrap();
        assert!(ppm(result.tsc_hz, truth) < 100, "{result:?}");

        // Without the restart the summed deltas would be 65,536 ticks short:
        // the same stall, with restarts forbidden, must not give a result.
        let mut machine = Machine::new(truth);
        machine.stalls.push((20_000, 120_000_000));
        let plan = Plan {
            max_restarts: 0,
            ..Plan::DEFAULT
        };
        assert_eq!(
            calibrate(plan, || machine.poll()),
            Err(CalibrationError::TooManyStalls)
        );
    }

    #[test]
    fn a_stopped_pit_is_reported_not_waited_for() {
        let mut machine = Machine::new(2_000_000_000);
        machine.pit_running = false;
        let plan = Plan {
            max_polls: 100_000,
            ..Plan::DEFAULT
        };
        assert_eq!(
            calibrate(plan, || machine.poll()),
            Err(CalibrationError::PitStopped)
        );
        assert!(machine.polls <= 100_001);
    }

    #[test]
    fn the_poll_budget_bounds_the_wait() {
        let mut machine = Machine::new(2_000_000_000);
        let plan = Plan {
            max_polls: 1_000,
            ..Plan::DEFAULT
        };
        assert_eq!(
            calibrate(plan, || machine.poll()),
            Err(CalibrationError::OutOfPolls)
        );
        assert_eq!(machine.polls, 1_000);
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
