//! Frame pacing on `requestAnimationFrame`: the browser calls back at its
//! own rate (60 Hz, 144 Hz, or slower when busy), and the page runs as many
//! frames of the model as its retrace period says are due, so the demo runs
//! at the software VGA's 59.7 Hz whatever the monitor. Behind by more than
//! [`MAX_CATCH_UP`] frames (a hidden tab, a slow machine), it runs that many
//! and starts afresh, as the desktop simulator's pacer does, instead of
//! rushing through the backlog.

/// The most frames one callback runs.
pub const MAX_CATCH_UP: u32 = 3;

/// When the next frame is due, on the browser's clock (milliseconds).
#[derive(Clone, Debug)]
pub struct Pacer {
    frame_ms: f64,
    next_due_ms: Option<f64>,
}

impl Pacer {
    /// A pacer for frames `frame_ns` apart (the model's retrace period).
    pub fn new(frame_ns: u64) -> Self {
        Pacer {
            // A model with no timing still makes progress.
            frame_ms: (frame_ns as f64 / 1e6).max(1.0),
            next_due_ms: None,
        }
    }

    /// The frames to run at `now_ms` (a `requestAnimationFrame` timestamp).
    /// The first call runs one.
    pub fn frames_due(&mut self, now_ms: f64) -> u32 {
        let Some(due) = self.next_due_ms else {
            self.next_due_ms = Some(now_ms + self.frame_ms);
            return 1;
        };
        if !now_ms.is_finite() || now_ms < due {
            return 0;
        }
        let behind = ((now_ms - due) / self.frame_ms).floor() + 1.0;
        if behind > f64::from(MAX_CATCH_UP) {
            self.next_due_ms = Some(now_ms + self.frame_ms);
            return MAX_CATCH_UP;
        }
        let frames = behind as u32;
        self.next_due_ms = Some(due + f64::from(frames) * self.frame_ms);
        frames
    }

    /// Forgets the schedule (after a pause): the next call runs one frame.
    pub fn restart(&mut self) {
        self.next_due_ms = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const FRAME_NS: u64 = 16_750_000;

    #[test]
    fn a_60_hz_browser_runs_one_frame_a_callback_on_average() {
        let mut pacer = Pacer::new(FRAME_NS);
        // A 60 Hz display calls back every 16.67 ms for ten seconds.
        let frames: u32 = (0..600)
            .map(|i| pacer.frames_due(f64::from(i) * 1000.0 / 60.0))
            .sum();
        // 10 s of a 59.70 Hz model: 597 frames (and the first at once).
        assert!((596..=598).contains(&frames), "{frames}");
    }

    #[test]
    fn a_144_hz_browser_skips_callbacks_and_a_30_hz_one_runs_two() {
        let mut pacer = Pacer::new(FRAME_NS);
        let fast: u32 = (0..1440)
            .map(|i| pacer.frames_due(f64::from(i) * 1000.0 / 144.0))
            .sum();
        assert!((596..=598).contains(&fast), "{fast}");
        let mut pacer = Pacer::new(FRAME_NS);
        let counts: Vec<u32> = (0..300)
            .map(|i| pacer.frames_due(f64::from(i) * 1000.0 / 30.0))
            .collect();
        assert!(counts[1..].iter().all(|&c| c == 1 || c == 2), "{counts:?}");
        assert!((596..=598).contains(&counts.iter().sum::<u32>()));
    }

    #[test]
    fn far_behind_it_catches_up_at_most_three_frames_then_starts_afresh() {
        let mut pacer = Pacer::new(FRAME_NS);
        assert_eq!(pacer.frames_due(0.0), 1);
        // A tab hidden for a second.
        assert_eq!(pacer.frames_due(1000.0), MAX_CATCH_UP);
        assert_eq!(pacer.frames_due(1001.0), 0);
        assert_eq!(pacer.frames_due(1000.0 + 16.75), 1);
        // Two frames late is caught up in full.
        assert_eq!(pacer.frames_due(1000.0 + 16.75 * 4.0), 3);
        pacer.restart();
        assert_eq!(pacer.frames_due(5000.0), 1);
        assert_eq!(pacer.frames_due(f64::NAN), 0);
    }
}
