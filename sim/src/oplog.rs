//! A frame's bus operations one by one, each with the `modex` functions that
//! issued it, and their replay on a copy of the software VGA: what a
//! slow-motion view steps through.
//!
//! The driver names the function it is in through [`VgaBus::enter`] and
//! [`VgaBus::leave`]; [`Machine::frame_logged`](crate::machine::Machine::frame_logged)
//! keeps the names beside each operation. A run of the same operation (the
//! same read of Input Status 1 while a flip waits for retrace, say) is one
//! entry with a count, so a step does not take ten thousand clicks.

use modex::regs::Port;
use modex::soft::SoftVga;
use modex::VgaBus;

/// Function names kept per operation, outermost first; deeper calls are
/// counted but not named (the driver nests three at most).
pub const CALLER_DEPTH: usize = 4;

/// One operation of the [`VgaBus`] trait, with what a read returned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BusOp {
    /// An 8-bit OUT.
    WritePort8 {
        /// The port.
        port: Port,
        /// The byte written.
        value: u8,
    },
    /// A 16-bit OUT: the low byte to `port`, the high byte to the next.
    WritePort16 {
        /// The port.
        port: Port,
        /// The word written.
        value: u16,
    },
    /// An 8-bit IN.
    ReadPort8 {
        /// The port.
        port: Port,
        /// What the VGA answered.
        value: u8,
    },
    /// A 16-bit IN.
    ReadPort16 {
        /// The port.
        port: Port,
        /// What the VGA answered.
        value: u16,
    },
    /// A byte written through the CPU window (and the Map Mask).
    WriteVram8 {
        /// Offset in the 64 KiB window.
        offset: u16,
        /// The byte.
        value: u8,
    },
    /// A byte read through the CPU window (loading the latches).
    ReadVram8 {
        /// Offset in the 64 KiB window.
        offset: u16,
        /// What the VGA answered.
        value: u8,
    },
    /// `count` bytes of `value` from `offset` through the Map Mask.
    FillVram {
        /// Offset in the 64 KiB window.
        offset: u16,
        /// Bytes written.
        count: u16,
        /// The byte.
        value: u8,
    },
    /// Make what was written visible (the model lets a frame pass).
    Flush,
}

impl BusOp {
    /// Does the operation again on `vga`, as the driver did.
    pub fn replay(&self, vga: &mut SoftVga) {
        match *self {
            BusOp::WritePort8 { port, value } => vga.write_port8(port, value),
            BusOp::WritePort16 { port, value } => vga.write_port16(port, value),
            BusOp::ReadPort8 { port, .. } => {
                vga.read_port8(port);
            }
            BusOp::ReadPort16 { port, .. } => {
                vga.read_port16(port);
            }
            BusOp::WriteVram8 { offset, value } => vga.write_vram8(offset, value),
            BusOp::ReadVram8 { offset, .. } => {
                vga.read_vram8(offset);
            }
            BusOp::FillVram {
                offset,
                count,
                value,
            } => vga.fill_vram(offset, count, value),
            BusOp::Flush => vga.flush(),
        }
    }
}

/// The `modex` functions a bus operation was issued from, outermost first.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Callers {
    names: [&'static str; CALLER_DEPTH],
    depth: usize,
}

impl Callers {
    fn enter(&mut self, function: &'static str) {
        if let Some(slot) = self.names.get_mut(self.depth) {
            *slot = function;
        }
        self.depth += 1;
    }

    fn leave(&mut self) {
        self.depth = self.depth.saturating_sub(1);
    }

    /// The named functions, outermost first.
    pub fn names(&self) -> &[&'static str] {
        &self.names[..self.depth.min(CALLER_DEPTH)]
    }

    /// The function that issued the operation itself, if the driver named one.
    pub fn innermost(&self) -> Option<&'static str> {
        self.names().last().copied()
    }
}

/// One entry of a frame's log: an operation done `repeat` times in a row
/// from the same functions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoggedOp {
    /// The operation.
    pub op: BusOp,
    /// Where the driver was.
    pub callers: Callers,
    /// How many times in a row (at least 1).
    pub repeat: u32,
    /// The model's clock when the first of them started.
    pub start_ns: u64,
}

impl LoggedOp {
    /// Does the entry again on `vga`: its clock first brought to the entry's
    /// start (the machine may have let time pass between operations), then
    /// the operation `repeat` times.
    pub fn replay(&self, vga: &mut SoftVga) {
        if self.start_ns > vga.now_ns() {
            vga.advance_ns(self.start_ns - vga.now_ns());
        }
        for _ in 0..self.repeat {
            self.op.replay(vga);
        }
    }
}

/// The log a bus keeps while a frame is recorded.
#[derive(Clone, Debug, Default)]
pub(crate) struct OpLog {
    callers: Callers,
    entries: Option<Vec<LoggedOp>>,
}

impl OpLog {
    pub(crate) fn enter(&mut self, function: &'static str) {
        self.callers.enter(function);
    }

    pub(crate) fn leave(&mut self) {
        self.callers.leave();
    }

    /// Whether a frame is being recorded.
    pub(crate) fn recording(&self) -> bool {
        self.entries.is_some()
    }

    pub(crate) fn start(&mut self) {
        self.entries = Some(Vec::new());
    }

    pub(crate) fn take(&mut self) -> Vec<LoggedOp> {
        self.entries.take().unwrap_or_default()
    }

    /// Notes `op`, which started at `start_ns`, if a frame is being recorded.
    /// Inlined: every bus operation asks, and most frames are not recorded.
    /// (A recorded frame's waits on Input Status 1 come here read by read,
    /// thousands of them: `ClockedVga::poll_port8`.)
    #[inline]
    pub(crate) fn note(&mut self, op: BusOp, start_ns: u64) {
        if let Some(entries) = &mut self.entries {
            Self::record(entries, self.callers, op, start_ns);
        }
    }

    #[inline(never)]
    fn record(entries: &mut Vec<LoggedOp>, callers: Callers, op: BusOp, start_ns: u64) {
        if let Some(last) = entries.last_mut() {
            if last.op == op && last.callers == callers {
                last.repeat += 1;
                return;
            }
        }
        entries.push(LoggedOp {
            op,
            callers,
            repeat: 1,
            start_ns,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn callers_nest_and_deep_ones_are_counted_not_named() {
        let mut callers = Callers::default();
        assert_eq!(callers.innermost(), None);
        callers.enter("ModeX::set_mode");
        callers.enter("ModeX::show_page");
        assert_eq!(callers.names(), ["ModeX::set_mode", "ModeX::show_page"]);
        for _ in 0..CALLER_DEPTH {
            callers.enter("deep");
        }
        assert_eq!(callers.names().len(), CALLER_DEPTH);
        for _ in 0..CALLER_DEPTH {
            callers.leave();
        }
        assert_eq!(callers.innermost(), Some("ModeX::show_page"));
        callers.leave();
        callers.leave();
        callers.leave(); // one too many: stays empty
        assert_eq!(callers.names(), [] as [&str; 0]);
    }

    #[test]
    fn the_same_operation_in_a_row_is_one_entry_and_only_while_recording() {
        let mut log = OpLog::default();
        let status = BusOp::ReadPort8 {
            port: Port::INPUT_STATUS_1,
            value: 0,
        };
        log.note(status, 0);
        assert!(log.take().is_empty(), "not recording");
        log.start();
        log.enter("ModeX::show_page");
        log.note(status, 10);
        log.note(status, 20);
        log.note(
            BusOp::ReadPort8 {
                port: Port::INPUT_STATUS_1,
                value: 8,
            },
            30,
        );
        log.leave();
        log.note(status, 40);
        let entries = log.take();
        let summary: Vec<(u32, u64, Option<&str>)> = entries
            .iter()
            .map(|e| (e.repeat, e.start_ns, e.callers.innermost()))
            .collect();
        assert_eq!(
            summary,
            [
                (2, 10, Some("ModeX::show_page")),
                (1, 30, Some("ModeX::show_page")),
                (1, 40, None)
            ]
        );
    }
}
