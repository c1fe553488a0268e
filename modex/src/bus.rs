//! The interface between the driver and a VGA: byte port I/O, one 16-bit OUT
//! for an index/data pair, and the CPU's 64 KiB window at 0xA0000.
//!
//! Ports are [`Port`]s, not numbers: a bus can only be asked about the VGA's
//! ports and Bochs VBE's, which is what lets the kernel's bus over `in`/`out`
//! promise, by construction, that it touches nothing else.

use crate::regs::Port;

/// Size of the CPU window onto video memory at 0xA0000.
pub const CPU_WINDOW_BYTES: u32 = 0x1_0000;

/// A VGA as the CPU sees it.
///
/// Every method is one bus operation (a fill is one per byte), so a software
/// implementation can count and time them.
///
/// # Example
///
/// A bus that logs its port writes and has no memory, as a test might use:
///
/// ```
/// use modex::regs::{Port, Sequencer};
/// use modex::{legacy_vga_present, VgaBus};
///
/// #[derive(Default)]
/// struct Log(Vec<(u16, u8)>);
///
/// impl VgaBus for Log {
///     fn write_port8(&mut self, port: Port, value: u8) {
///         self.0.push((port.number(), value));
///     }
///     fn write_port16(&mut self, port: Port, value: u16) {
///         let [index, data] = value.to_le_bytes();
///         self.0.push((port.number(), index));
///         self.0.push((port.number() + 1, data));
///     }
///     fn read_port8(&mut self, _port: Port) -> u8 {
///         0xFF // nothing drives the bus
///     }
///     fn write_vram8(&mut self, _offset: u16, _value: u8) {}
///     fn read_vram8(&mut self, _offset: u16) -> u8 {
///         0xFF
///     }
/// }
///
/// let mut bus = Log::default();
/// bus.write_port16(Port::SEQUENCER_INDEX, u16::from_le_bytes([Sequencer::MapMask.index(), 0x0F]));
/// assert_eq!(bus.0, [(0x3C4, 2), (0x3C5, 0x0F)]);
/// // A bus on which nothing answers has no VGA, and the probe only read it.
/// assert!(!legacy_vga_present(&mut bus));
/// assert_eq!(bus.0.len(), 2);
/// ```
pub trait VgaBus {
    /// One 8-bit OUT.
    fn write_port8(&mut self, port: Port, value: u8);
    /// One 16-bit OUT: low byte to `port`, high byte to `port + 1` (index/data
    /// pairs in one bus op). Ports with 16-bit registers (Bochs VBE DISPI at
    /// 0x1CE/0x1CF) take the value whole.
    fn write_port16(&mut self, port: Port, value: u16);
    /// One 8-bit IN.
    fn read_port8(&mut self, port: Port) -> u8;
    /// One 16-bit IN, for 16-bit registers (Bochs VBE DISPI's data port,
    /// which answers only 16-bit reads). Default: two 8-bit reads, `port`
    /// then the port after it (an unnamed one reads as a floating bus, 0xFF),
    /// for buses with no 16-bit registers.
    fn read_port16(&mut self, port: Port) -> u16 {
        let low = self.read_port8(port);
        let high = port.data().map_or(0xFF, |next| self.read_port8(next));
        u16::from_le_bytes([low, high])
    }
    /// `offset` is within the 64 KiB CPU window at 0xA0000.
    fn write_vram8(&mut self, offset: u16, value: u8);
    /// `offset` is within the 64 KiB CPU window at 0xA0000. On a VGA every
    /// read also loads the four latches.
    fn read_vram8(&mut self, offset: u16) -> u8;
    /// Writes `value` to `count` consecutive CPU addresses from `offset` (a
    /// fill through the current Map Mask); addresses past the end of the window
    /// are dropped. Default: a loop of `write_vram8`. The hardware bus may use
    /// wider stores.
    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        let end = (u32::from(offset) + u32::from(count)).min(CPU_WINDOW_BYTES);
        for address in u32::from(offset)..end {
            // `address` < CPU_WINDOW_BYTES, so it fits.
            self.write_vram8(address as u16, value);
        }
    }
    /// Makes what has been written visible now. A VGA scans its memory out
    /// continuously, so by default this does nothing; a software VGA mirrored
    /// to a framebuffer presents (after text is written, say, which no page
    /// flip follows).
    fn flush(&mut self) {}
    /// Microseconds by the machine's clock, if the bus has one. It bounds
    /// the driver's waits on Input Status 1 by time
    /// ([`STATUS_WAIT_MICROS`](crate::STATUS_WAIT_MICROS)), so it must keep
    /// advancing (the kernel's clock counts a microsecond a reading where
    /// the TSC stands still). Default: `None`, and a wait counts each status
    /// read as a microsecond, what one takes on an ISA card.
    fn now_micros(&mut self) -> Option<u64> {
        None
    }
    /// Reads `port` until a read gives `value` in the bits of `mask`, or
    /// until `limit_micros` have passed: true if a read did. The driver's
    /// waits on Input Status 1 for the display and the retrace. Default:
    /// [`poll_by_reads`], one [`VgaBus::read_port8`] after another. A
    /// software VGA may answer for a stretch of reads at once, where it
    /// knows they would all read the same, as long as it ends where those
    /// reads would have left it.
    fn poll_port8(&mut self, port: Port, mask: u8, value: u8, limit_micros: u64) -> bool {
        poll_by_reads(self, port, mask, value, limit_micros)
    }
    /// The driver starts `function`, a [`ModeX`](crate::ModeX) method named
    /// as `ModeX::fill_rect`: the bus operations until the matching
    /// [`VgaBus::leave`] are its (calls nest). A slow-motion view records
    /// the names beside the operations; every other bus keeps this default,
    /// which does nothing and inlines to nothing, so the tag costs the
    /// kernel's bus no code.
    #[inline(always)]
    fn enter(&mut self, _function: &'static str) {}
    /// The function of the innermost [`VgaBus::enter`] has returned.
    #[inline(always)]
    fn leave(&mut self) {}
}

/// A borrowed bus is a bus, so a large software VGA can stay in its `Box`.
impl<T: VgaBus + ?Sized> VgaBus for &mut T {
    fn write_port8(&mut self, port: Port, value: u8) {
        (**self).write_port8(port, value);
    }
    fn write_port16(&mut self, port: Port, value: u16) {
        (**self).write_port16(port, value);
    }
    fn read_port8(&mut self, port: Port) -> u8 {
        (**self).read_port8(port)
    }
    fn read_port16(&mut self, port: Port) -> u16 {
        (**self).read_port16(port)
    }
    fn write_vram8(&mut self, offset: u16, value: u8) {
        (**self).write_vram8(offset, value);
    }
    fn read_vram8(&mut self, offset: u16) -> u8 {
        (**self).read_vram8(offset)
    }
    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        (**self).fill_vram(offset, count, value);
    }
    fn flush(&mut self) {
        (**self).flush();
    }
    fn now_micros(&mut self) -> Option<u64> {
        (**self).now_micros()
    }
    fn poll_port8(&mut self, port: Port, mask: u8, value: u8, limit_micros: u64) -> bool {
        (**self).poll_port8(port, mask, value, limit_micros)
    }
    #[inline(always)]
    fn enter(&mut self, function: &'static str) {
        (**self).enter(function);
    }
    #[inline(always)]
    fn leave(&mut self) {
        (**self).leave();
    }
}

/// [`VgaBus::poll_port8`] a read at a time: reads `port` until a read gives
/// `value` in the bits of `mask`, or until `limit_micros` have passed by the
/// bus's clock (by a count of reads, a microsecond each, on a bus without
/// one, what a read takes on an ISA card); true if a read did.
pub fn poll_by_reads<B: VgaBus + ?Sized>(
    bus: &mut B,
    port: Port,
    mask: u8,
    value: u8,
    limit_micros: u64,
) -> bool {
    let start = bus.now_micros();
    let mut reads: u64 = 0;
    loop {
        if bus.read_port8(port) & mask == value {
            return true;
        }
        reads += 1;
        let waited = match (start, bus.now_micros()) {
            (Some(start), Some(now)) => now.saturating_sub(start),
            _ => reads,
        };
        if waited >= limit_micros {
            return false;
        }
    }
}
