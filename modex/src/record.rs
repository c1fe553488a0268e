//! A bus that records every operation, in order, for tests that compare
//! two ways of drawing operation by operation (`test-support` only).

use crate::bus::VgaBus;
use crate::regs::Port;
use alloc::vec::Vec;

/// One bus operation as [`Recorder`] keeps it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Operation {
    /// An 8-bit OUT: port, value.
    Out8(u16, u8),
    /// A 16-bit OUT: port, value.
    Out16(u16, u16),
    /// One byte written to video memory: offset, value.
    Write(u16, u8),
    /// A fill of `count` bytes from `offset` with `value`.
    Fill {
        /// The first offset.
        offset: u16,
        /// How many bytes.
        count: u16,
        /// The byte written to each.
        value: u8,
    },
}

/// Every write to the bus, in order; reads are answered, not recorded.
/// Input Status 1 always reports retrace (0x09: display disabled and
/// vertical retrace), so a flip's wait ends at once; video memory reads 0.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Recorder(pub Vec<Operation>);

impl VgaBus for Recorder {
    fn write_port8(&mut self, port: Port, value: u8) {
        self.0.push(Operation::Out8(port.number(), value));
    }
    fn write_port16(&mut self, port: Port, value: u16) {
        self.0.push(Operation::Out16(port.number(), value));
    }
    fn read_port8(&mut self, _port: Port) -> u8 {
        0x09
    }
    fn write_vram8(&mut self, offset: u16, value: u8) {
        self.0.push(Operation::Write(offset, value));
    }
    fn read_vram8(&mut self, _offset: u16) -> u8 {
        0
    }
    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        self.0.push(Operation::Fill {
            offset,
            count,
            value,
        });
    }
}
