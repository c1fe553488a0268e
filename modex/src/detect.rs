//! Is a legacy VGA really there? UEFI-only machines and framebuffer-only
//! adapters (QEMU's `bochs-display`) leave the VGA ports undecoded, and writing
//! a mode to nothing shows nothing. So before the driver takes over, the probe
//! asks the hardware, by read-back, rather than assuming.
//!
//! What an absent device looks like: an undecoded port reads back whatever the
//! bus floats to, usually all ones (0xFF, pulled up), sometimes all zeros, and
//! on an ISA bus possibly the last value driven onto it (bus capacitance).

use crate::regs::{misc, Crtc, Graphics, IndexedPair, Port};
use crate::VgaBus;

/// What an undriven data bus reads on a PC: the pull-ups' all ones.
const FLOATING_BUS: u8 = 0xFF;

/// Written to each probed register and read back: together they set and clear
/// every bit, so a data line stuck high or low, or a bus that always reads the
/// same value, cannot pass.
const PROBE_PATTERNS: [u8; 2] = [0xA5, 0x5A];

/// Whether a VGA answers on the legacy ports, probed without disturbing it.
///
/// 1. Miscellaneous Output (read at 0x3CC) must not be 0xFF: no VGA mode sets
///    every bit (bit 4 does not exist), but a bus with nothing on it reads
///    exactly that. Nothing is written before this check passes, so a
///    framebuffer-only machine sees reads only. Its bit 0 also says where the
///    CRTC is (0x3D4 colour, 0x3B4 monochrome).
/// 2. The Graphics Controller's Bit Mask (index 8) must hold both patterns.
/// 3. The CRTC's Cursor Location Low (index 0x0F) must hold both patterns: a
///    second chip at a second address, which also checks that Misc Output told
///    the truth about the CRTC's address.
///
/// Both registers are harmless to change briefly (the Bit Mask matters only
/// while the CPU writes video memory; the cursor location only in text mode),
/// and both, and their index registers, are restored before returning.
pub fn legacy_vga_present<B: VgaBus>(bus: &mut B) -> bool {
    let misc_output = bus.read_port8(Port::MISC_OUTPUT_READ);
    if misc_output == FLOATING_BUS {
        return false;
    }
    let crtc_ports = if misc_output & misc::COLOR_IO_ADDRESSING != 0 {
        (Port::CRTC_INDEX, Port::CRTC_DATA)
    } else {
        (Port::CRTC_INDEX_MONO, Port::CRTC_DATA_MONO)
    };
    let graphics = IndexedPair::Graphics;
    let graphics_ports = (graphics.index_port(), graphics.data_port());
    register_holds_patterns(bus, graphics_ports, Graphics::BitMask.index())
        && register_holds_patterns(bus, crtc_ports, Crtc::CursorLocationLow.index())
}

/// Writes each probe pattern to register `index` of the index/data pair at
/// `(index_port, data_port)` and reads it back; restores the register and
/// the index register.
///
/// Between the write and the read the index is written again, so the data bus
/// last carried the index, not the pattern: a floating ISA bus that echoes the
/// last value driven onto it reads back the index and fails.
fn register_holds_patterns<B: VgaBus>(bus: &mut B, ports: (Port, Port), index: u8) -> bool {
    let (index_port, data_port) = ports;
    let saved_index = bus.read_port8(index_port);
    bus.write_port8(index_port, index);
    let saved_value = bus.read_port8(data_port);
    let holds = PROBE_PATTERNS.iter().all(|&pattern| {
        bus.write_port8(data_port, pattern);
        bus.write_port8(index_port, index);
        bus.read_port8(data_port) == pattern
    });
    bus.write_port8(index_port, index);
    bus.write_port8(data_port, saved_value);
    bus.write_port8(index_port, saved_index);
    holds
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::soft::SoftVga;
    use crate::ModeX;
    use std::boxed::Box;
    use std::vec::Vec;

    /// A bus with nothing on it: every read returns `value`; writes are logged.
    struct EmptyBus {
        reads_as: u8,
        writes: Vec<(u16, u8)>,
    }

    impl EmptyBus {
        fn reading(value: u8) -> Self {
            EmptyBus {
                reads_as: value,
                writes: Vec::new(),
            }
        }
    }

    impl VgaBus for EmptyBus {
        fn write_port8(&mut self, port: Port, value: u8) {
            self.writes.push((port.number(), value));
        }
        fn write_port16(&mut self, port: Port, value: u16) {
            let [low, high] = value.to_le_bytes();
            self.writes.push((port.number(), low));
            self.writes.push((port.number() + 1, high));
        }
        fn read_port8(&mut self, _port: Port) -> u8 {
            self.reads_as
        }
        fn write_vram8(&mut self, _offset: u16, _value: u8) {}
        fn read_vram8(&mut self, _offset: u16) -> u8 {
            self.reads_as
        }
    }

    /// An ISA bus with nothing on it that keeps the last value driven.
    struct EchoBus {
        last: u8,
    }

    impl VgaBus for EchoBus {
        fn write_port8(&mut self, _port: Port, value: u8) {
            self.last = value;
        }
        fn write_port16(&mut self, _port: Port, value: u16) {
            self.last = (value >> 8) as u8;
        }
        fn read_port8(&mut self, _port: Port) -> u8 {
            self.last
        }
        fn write_vram8(&mut self, _offset: u16, value: u8) {
            self.last = value;
        }
        fn read_vram8(&mut self, _offset: u16) -> u8 {
            self.last
        }
    }

    #[test]
    fn a_vga_at_power_on_is_found() {
        let mut soft = Box::new(SoftVga::new());
        assert!(legacy_vga_present(&mut *soft));
    }

    #[test]
    fn a_vga_in_mode_x_is_found() {
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        assert!(legacy_vga_present(&mut *soft));
    }

    #[test]
    fn a_vga_with_monochrome_addressing_is_found_at_0x3b4() {
        let mut soft = Box::new(SoftVga::new());
        let colour_misc = soft.misc_output();
        soft.write_port8(
            Port::MISC_OUTPUT_WRITE,
            colour_misc & !misc::COLOR_IO_ADDRESSING,
        );
        assert!(legacy_vga_present(&mut *soft));
    }

    #[test]
    fn the_probe_restores_every_register_it_touches() {
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        // Distinctive values and indices, so a restore to anything else shows.
        soft.write_port16(
            Port::CRTC_INDEX,
            u16::from_le_bytes([Crtc::CursorLocationLow.index(), 0x37]),
        );
        soft.write_port8(Port::CRTC_INDEX, Crtc::Offset.index());
        soft.write_port16(
            Port::GRAPHICS_INDEX,
            u16::from_le_bytes([Graphics::BitMask.index(), 0xC3]),
        );
        soft.write_port8(Port::GRAPHICS_INDEX, Graphics::Mode.index());
        let before = soft.clone();

        assert!(legacy_vga_present(&mut *soft));

        assert_eq!(soft.crtc(Crtc::CursorLocationLow), 0x37);
        assert_eq!(soft.graphics(Graphics::BitMask), 0xC3);
        assert_eq!(soft.read_port8(Port::CRTC_INDEX), Crtc::Offset.index());
        assert_eq!(
            soft.read_port8(Port::GRAPHICS_INDEX),
            Graphics::Mode.index()
        );
        for register in Crtc::ALL {
            assert_eq!(soft.crtc(register), before.crtc(register), "{register:?}");
        }
        for register in Graphics::ALL {
            assert_eq!(
                soft.graphics(register),
                before.graphics(register),
                "{register:?}"
            );
        }
        assert_eq!(soft.misc_output(), before.misc_output());
    }

    #[test]
    fn a_bus_that_floats_high_has_no_vga_and_is_never_written() {
        let mut bus = EmptyBus::reading(0xFF);
        assert!(!legacy_vga_present(&mut bus));
        assert_eq!(
            bus.writes,
            [],
            "a framebuffer-only machine must see reads only"
        );
    }

    #[test]
    fn a_bus_that_reads_zero_has_no_vga() {
        let mut bus = EmptyBus::reading(0x00);
        assert!(!legacy_vga_present(&mut bus));
    }

    #[test]
    fn a_bus_that_echoes_the_last_value_driven_has_no_vga() {
        assert!(!legacy_vga_present(&mut EchoBus { last: 0x00 }));
    }

    /// A VGA whose Graphics Controller answers but whose CRTC does not decode:
    /// one register holding its value is not enough.
    #[test]
    fn a_dead_crtc_fails_the_probe() {
        struct DeadCrtc(Box<SoftVga>);
        impl VgaBus for DeadCrtc {
            fn write_port8(&mut self, port: Port, value: u8) {
                if port != Port::CRTC_DATA {
                    self.0.write_port8(port, value);
                }
            }
            fn write_port16(&mut self, port: Port, value: u16) {
                self.0.write_port16(port, value);
            }
            fn read_port8(&mut self, port: Port) -> u8 {
                if port == Port::CRTC_DATA {
                    FLOATING_BUS
                } else {
                    self.0.read_port8(port)
                }
            }
            fn write_vram8(&mut self, offset: u16, value: u8) {
                self.0.write_vram8(offset, value);
            }
            fn read_vram8(&mut self, offset: u16) -> u8 {
                self.0.read_vram8(offset)
            }
        }
        let mut bus = DeadCrtc(Box::default());
        assert!(!legacy_vga_present(&mut bus));
        // And the Graphics Controller it did reach was put back.
        let power_on = Box::<SoftVga>::default();
        assert_eq!(
            bus.0.graphics(Graphics::BitMask),
            power_on.graphics(Graphics::BitMask)
        );
    }
}
