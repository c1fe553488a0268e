//! Counting the vertical retraces a spinning demo misses.
//!
//! Each flip waits for the start of a vertical retrace, so flips that keep up
//! are one refresh apart. A longer gap means retraces went by without a new
//! frame: a gap of about n refreshes missed n - 1 of them.

/// One refresh of Mode X: 800 dots by 527 lines (Abrash's Vertical Total of
/// 0x20D, two lines more than BIOS 640x480's) at 25.175 MHz, 16,747 µs
/// (59.71 Hz).
pub const FRAME_MICROS: u64 = 16_747;

/// Flips, missed retraces and timed-out waits while frames keep coming.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Pacing {
    /// Flips counted.
    pub flips: u64,
    /// Retraces that passed without a flip while the demo was drawing.
    pub missed: u64,
    /// Flips whose wait for the display or for retrace hit its bound.
    pub wait_timeouts: u64,
    /// Flips that followed another flip (not a pause): each closes a gap.
    pub gaps: u64,
    /// The time those gaps add up to, in microseconds: `gaps + missed`
    /// refreshes should fill it, whatever the host's load.
    pub gap_micros: u64,
    last_flip_micros: Option<u64>,
}

impl Pacing {
    /// Counts a flip made at `now_micros`.
    pub fn flipped(&mut self, now_micros: u64, timed_out: bool) {
        if let Some(last) = self.last_flip_micros {
            self.missed += missed_between(last, now_micros);
            self.gaps += 1;
            self.gap_micros += now_micros.saturating_sub(last);
        }
        self.last_flip_micros = Some(now_micros);
        self.flips += 1;
        self.wait_timeouts += u64::from(timed_out);
    }

    /// Nothing to draw: the next flip starts a new run, not a late frame.
    pub fn idle(&mut self) {
        self.last_flip_micros = None;
    }
}

/// Retraces missed between flips at `earlier` and `later` (microseconds): the
/// gap rounded to whole refreshes, less the one a flip is allowed.
pub fn missed_between(earlier: u64, later: u64) -> u64 {
    let gap = later.saturating_sub(earlier);
    ((gap + FRAME_MICROS / 2) / FRAME_MICROS).saturating_sub(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flips_one_refresh_apart_miss_nothing() {
        let mut pacing = Pacing::default();
        for frame in 0..600 {
            // Up to a third of a frame of jitter either way.
            let jitter = (frame % 3) * FRAME_MICROS / 3;
            pacing.flipped(frame * FRAME_MICROS + jitter, false);
        }
        assert_eq!(pacing.flips, 600);
        assert_eq!(pacing.missed, 0);
    }

    #[test]
    fn a_late_frame_counts_the_retraces_it_skipped() {
        assert_eq!(missed_between(0, FRAME_MICROS), 0);
        assert_eq!(missed_between(0, 2 * FRAME_MICROS), 1);
        assert_eq!(missed_between(0, 2 * FRAME_MICROS - FRAME_MICROS / 3), 1);
        assert_eq!(missed_between(0, 5 * FRAME_MICROS + 100), 4);
        assert_eq!(missed_between(100, 0), 0);
    }

    #[test]
    fn gaps_and_missed_retraces_fill_the_time_between_flips() {
        let mut pacing = Pacing::default();
        let mut now = 0;
        for frame in 0..1000u64 {
            // Mostly on time, every seventh frame two or three refreshes late.
            now += match frame % 7 {
                0 => 3 * FRAME_MICROS + 200,
                3 => 2 * FRAME_MICROS - 300,
                _ => FRAME_MICROS + 40,
            };
            pacing.flipped(now, false);
        }
        let refreshes = pacing.gap_micros as f64 / FRAME_MICROS as f64;
        let counted = (pacing.gaps + pacing.missed) as f64;
        assert!((counted / refreshes - 1.0).abs() < 0.01, "{pacing:?}");
        assert_eq!(pacing.gaps, 999);
    }

    #[test]
    fn idle_time_is_not_a_missed_retrace() {
        let mut pacing = Pacing::default();
        pacing.flipped(0, false);
        pacing.idle();
        pacing.flipped(10 * FRAME_MICROS, true);
        pacing.flipped(11 * FRAME_MICROS, false);
        assert_eq!(
            (pacing.flips, pacing.missed, pacing.wait_timeouts),
            (3, 0, 1)
        );
    }
}
