//! Non-maskable interrupts: what System Control Port B (I/O port 0x61) says
//! caused one, and how many the log may tell of.
//!
//! A PC raises an NMI for a memory parity or PCI SERR# error (port 0x61 bit
//! 7), an ISA I/O channel check (bit 6), a watchdog, or a platform event the
//! chipset routes there; in the last two cases the port says nothing, as
//! Linux's "NMI received for unknown reason" does. None of them is the
//! kernel's fault, so the kernel counts each one, logs it, and carries on.
//!
//! The handler itself only counts and keeps the port's byte (it may have
//! interrupted the code that holds the serial port or the log), and the
//! frame loop tells the log. A source that keeps firing (a stuck SERR#)
//! could fill the log in a second, so [`NmiLog`] lets at most
//! [`NMI_LINES_PER_SECOND`] lines through a second, says once that it stops,
//! and then says how many went untold.

use core::fmt;

/// System Control Port B, read in the NMI handler.
pub const SYSTEM_CONTROL_PORT_B: u16 = 0x61;
/// Port B, bit 7: memory parity or PCI SERR# (PCHK).
pub const PORT_B_SERR: u8 = 1 << 7;
/// Port B, bit 6: ISA I/O channel check (IOCHK#).
pub const PORT_B_IOCHK: u8 = 1 << 6;
/// Port B, bit 3 written as 1: I/O channel checks off (and the latch cleared).
pub const PORT_B_IOCHK_DISABLE: u8 = 1 << 3;
/// Port B, bit 2 written as 1: parity and SERR# checks off (and the latch cleared).
pub const PORT_B_SERR_DISABLE: u8 = 1 << 2;
/// The bits of port B that are written back as they were read: the speaker
/// and PIT channel 2's gate (bits 0 and 1) and the two check enables.
const PORT_B_WRITABLE: u8 = 0x0F;

/// The lines about NMIs that reach the log in any one second.
pub const NMI_LINES_PER_SECOND: u32 = 5;

/// What port B said when an NMI came.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NmiReason(pub u8);

impl NmiReason {
    /// The byte to write to port B to clear and briefly disable the checks
    /// that latched, before [`NmiReason::reenable`] (Linux's `pci_serr_error`
    /// and `io_check_error`); `None` when neither latched.
    pub fn acknowledge(self) -> Option<u8> {
        let mut value = self.0 & PORT_B_WRITABLE;
        if self.0 & PORT_B_SERR != 0 {
            value |= PORT_B_SERR_DISABLE;
        }
        if self.0 & PORT_B_IOCHK != 0 {
            value |= PORT_B_IOCHK_DISABLE;
        }
        (self.0 & (PORT_B_SERR | PORT_B_IOCHK) != 0).then_some(value)
    }

    /// The byte that turns the checks back on after [`NmiReason::acknowledge`].
    pub fn reenable(self) -> u8 {
        self.0 & PORT_B_WRITABLE & !(PORT_B_SERR_DISABLE | PORT_B_IOCHK_DISABLE)
    }
}

impl fmt::Display for NmiReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.0 & PORT_B_SERR != 0, self.0 & PORT_B_IOCHK != 0) {
            (true, true) => f.write_str("memory parity or PCI SERR#, and I/O channel check")?,
            (true, false) => f.write_str("memory parity or PCI SERR#")?,
            (false, true) => f.write_str("I/O channel check")?,
            (false, false) => f.write_str("unknown (a watchdog or platform event)")?,
        }
        write!(f, "; port 0x61 = {:#04x}", self.0)
    }
}

/// What the log should say this pass of the frame loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NmiNews {
    /// `new` NMIs since the last line, the last with `reason`; `total` since boot.
    Received {
        /// NMIs not yet told of.
        new: u64,
        /// Since boot.
        total: u64,
        /// Port B at the last of them.
        reason: NmiReason,
    },
    /// The second's lines are used up: the next are not logged one by one.
    StormPaused {
        /// Since boot.
        total: u64,
    },
    /// After a pause: `untold` NMIs were not logged.
    Untold {
        /// Not logged while paused.
        untold: u64,
        /// Since boot.
        total: u64,
    },
}

impl fmt::Display for NmiNews {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            NmiNews::Received {
                new: 1,
                total,
                reason,
            } => {
                write!(f, "{NMI_RECEIVED}reason {reason} ({total} since boot)")
            }
            NmiNews::Received { new, total, reason } => write!(
                f,
                "{NMI_RECEIVED}{new} since the last line, the last with reason {reason} \
                 ({total} since boot)"
            ),
            NmiNews::StormPaused { total } => write!(
                f,
                "NMI storm: more than {NMI_LINES_PER_SECOND} lines in a second; the next \
                 are counted, not logged ({total} since boot)"
            ),
            NmiNews::Untold { untold, total } => write!(
                f,
                "NMI storm: {untold} NMIs were not logged ({total} since boot)"
            ),
        }
    }
}

/// How every line about an NMI starts.
pub const NMI_RECEIVED: &str = "NMI received: ";

/// The frame loop's side of the NMI count: what has been told, and the
/// storm bound.
#[derive(Clone, Copy, Debug, Default)]
pub struct NmiLog {
    told: u64,
    window_start: u64,
    lines_in_window: u32,
    paused: bool,
}

const MICROS_PER_SECOND: u64 = 1_000_000;

impl NmiLog {
    /// Nothing told yet.
    pub const fn new() -> Self {
        NmiLog {
            told: 0,
            window_start: 0,
            lines_in_window: 0,
            paused: false,
        }
    }

    /// What to log, given the handler's count `total` and last `reason`, at
    /// `now` microseconds; `None` when there is nothing to say.
    pub fn news(&mut self, total: u64, reason: NmiReason, now: u64) -> Option<NmiNews> {
        if now.saturating_sub(self.window_start) >= MICROS_PER_SECOND {
            self.window_start = now;
            self.lines_in_window = 0;
            if self.paused {
                self.paused = false;
                let untold = total - self.told;
                self.told = total;
                if untold > 0 {
                    self.lines_in_window = 1;
                    return Some(NmiNews::Untold { untold, total });
                }
            }
        }
        if total <= self.told || self.paused {
            return None;
        }
        if self.lines_in_window >= NMI_LINES_PER_SECOND {
            self.paused = true;
            return Some(NmiNews::StormPaused { total });
        }
        self.lines_in_window += 1;
        let new = total - self.told;
        self.told = total;
        Some(NmiNews::Received { new, total, reason })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;
    use std::vec::Vec;

    #[test]
    fn the_reason_names_the_latched_checks() {
        assert_eq!(
            NmiReason(0x20).to_string(),
            "unknown (a watchdog or platform event); port 0x61 = 0x20"
        );
        assert_eq!(
            NmiReason(0x80).to_string(),
            "memory parity or PCI SERR#; port 0x61 = 0x80"
        );
        assert_eq!(
            NmiReason(0x41).to_string(),
            "I/O channel check; port 0x61 = 0x41"
        );
    }

    #[test]
    fn a_latched_check_is_cleared_and_turned_back_on_keeping_the_speaker_bits() {
        // SERR# latched, speaker gate and data on.
        let reason = NmiReason(0x80 | 0x03);
        assert_eq!(reason.acknowledge(), Some(0x03 | PORT_B_SERR_DISABLE));
        assert_eq!(reason.reenable(), 0x03);
        let both = NmiReason(0xC0 | 0x01);
        assert_eq!(
            both.acknowledge(),
            Some(0x01 | PORT_B_SERR_DISABLE | PORT_B_IOCHK_DISABLE)
        );
        // Nothing latched: port B is left alone.
        assert_eq!(NmiReason(0x20).acknowledge(), None);
    }

    #[test]
    fn each_nmi_is_told_once() {
        let mut log = NmiLog::default();
        let reason = NmiReason(0);
        assert_eq!(log.news(0, reason, 10), None);
        assert_eq!(
            log.news(1, reason, 20),
            Some(NmiNews::Received {
                new: 1,
                total: 1,
                reason
            })
        );
        assert_eq!(log.news(1, reason, 30), None);
        assert_eq!(
            log.news(3, reason, 40),
            Some(NmiNews::Received {
                new: 2,
                total: 3,
                reason
            })
        );
    }

    #[test]
    fn a_storm_is_told_in_a_few_lines_a_second() {
        let mut log = NmiLog::default();
        let reason = NmiReason(0x80);
        let mut lines = Vec::new();
        // One NMI every millisecond for three seconds, the loop looking after each.
        for ms in 1..=3000u64 {
            if let Some(news) = log.news(ms, reason, ms * 1000) {
                lines.push(news);
            }
        }
        let per_second = NMI_LINES_PER_SECOND as usize + 1;
        assert!(lines.len() <= 3 * per_second + 1, "{lines:?}");
        assert_eq!(
            lines[NMI_LINES_PER_SECOND as usize],
            NmiNews::StormPaused { total: 6 }
        );
        // The next second starts by telling how many went untold.
        assert!(
            matches!(lines[NMI_LINES_PER_SECOND as usize + 1], NmiNews::Untold { untold, total }
                if untold > 900 && total - untold == 5),
            "{lines:?}"
        );
        // Nothing is lost: once the storm stops, the count adds up.
        let last_total = match *lines.last().unwrap() {
            NmiNews::Received { total, .. } | NmiNews::Untold { total, .. } => total,
            NmiNews::StormPaused { total } => total,
        };
        let after = log.news(3000, reason, 5_000_000);
        let told = match after {
            Some(NmiNews::Untold { total, .. }) => total,
            None => last_total,
            other => panic!("{other:?}"),
        };
        assert_eq!(told, 3000);
    }

    #[test]
    fn the_lines_say_what_happened() {
        let reason = NmiReason(0);
        assert_eq!(
            NmiNews::Received {
                new: 1,
                total: 3,
                reason
            }
            .to_string(),
            "NMI received: reason unknown (a watchdog or platform event); port 0x61 = 0x00 \
             (3 since boot)"
        );
        assert!(NmiNews::Untold {
            untold: 7,
            total: 20
        }
        .to_string()
        .contains("7 NMIs were not logged"));
    }
}
