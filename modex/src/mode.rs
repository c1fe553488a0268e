//! Mode set: register tables for Mode X and 80x25 text, and the sequence that
//! programs them from whatever state the VGA was left in (a BIOS text mode, a
//! VBE linear framebuffer from the bootloader, or a crashed driver).

use crate::palette::{Rgb6, DEFAULT_PALETTE, EGA_TEXT_ATTRIBUTES};
use crate::regs::{crtc, gc, seq, Attribute, Crtc, Graphics, PlaneMask, Sequencer};
use crate::{ModeX, Page, VgaBus, CPU_WINDOW_BYTES};

/// Every register a mode set programs, each group as (register, value) pairs
/// in index order (the order they are written in); the constants below are
/// checked for that order when the crate compiles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeRegisters {
    /// Miscellaneous Output.
    pub misc_output: u8,
    /// The Sequencer; Reset is the running value.
    pub sequencer: [(Sequencer, u8); Sequencer::COUNT],
    /// The CRT Controller.
    pub crtc: [(Crtc, u8); Crtc::COUNT],
    /// The Graphics Controller.
    pub graphics: [(Graphics, u8); Graphics::COUNT],
    /// The Attribute Controller.
    pub attribute: [(Attribute, u8); Attribute::COUNT],
}

/// Defines, for one register group, the lookup of a register's value in a
/// table and the table as a plain array indexed by register index.
macro_rules! group_access {
    ($group:ident, $field:ident, $value:ident, $values:ident, $ordered:ident) => {
        /// The value the table gives this register.
        pub const fn $value(&self, register: $group) -> u8 {
            self.$field[register as usize].1
        }

        /// The group's values, indexed by register index.
        pub const fn $values(&self) -> [u8; $group::COUNT] {
            let mut values = [0; $group::COUNT];
            let mut slot = 0;
            while slot < $group::COUNT {
                values[slot] = self.$field[slot].1;
                slot += 1;
            }
            values
        }

        const fn $ordered(&self) -> bool {
            let mut slot = 0;
            while slot < $group::COUNT {
                if self.$field[slot].0 as usize != slot {
                    return false;
                }
                slot += 1;
            }
            true
        }
    };
}

impl ModeRegisters {
    group_access!(
        Sequencer,
        sequencer,
        sequencer_value,
        sequencer_values,
        sequencer_in_order
    );
    group_access!(Crtc, crtc, crtc_value, crtc_values, crtc_in_order);
    group_access!(
        Graphics,
        graphics,
        graphics_value,
        graphics_values,
        graphics_in_order
    );
    group_access!(
        Attribute,
        attribute,
        attribute_value,
        attribute_values,
        attribute_in_order
    );

    /// Whether every group lists each of its registers once, in index order.
    const fn in_index_order(&self) -> bool {
        self.sequencer_in_order()
            && self.crtc_in_order()
            && self.graphics_in_order()
            && self.attribute_in_order()
    }
}

const _: () = assert!(MODE_X.in_index_order() && TEXT_80X25.in_index_order());

/// The 16 palette registers mapping attribute n to colour `colours[n]`.
const fn palette_registers(colours: [u8; 16]) -> [(Attribute, u8); 16] {
    let mut pairs = [(Attribute::Palette0, 0); 16];
    let mut n = 0;
    while n < 16 {
        pairs[n] = (Attribute::ALL[n], colours[n]);
        n += 1;
    }
    pairs
}

/// The palette registers followed by the five control registers.
const fn attribute_table(
    palette: [u8; 16],
    mode_control: u8,
    overscan: u8,
    plane_enable: PlaneMask,
    panning: u8,
    colour_select: u8,
) -> [(Attribute, u8); Attribute::COUNT] {
    let palette = palette_registers(palette);
    let mut pairs = [(Attribute::Palette0, 0); Attribute::COUNT];
    let mut n = 0;
    while n < 16 {
        pairs[n] = palette[n];
        n += 1;
    }
    pairs[16] = (Attribute::ModeControl, mode_control);
    pairs[17] = (Attribute::OverscanColor, overscan);
    pairs[18] = (Attribute::ColorPlaneEnable, plane_enable.bits());
    pairs[19] = (Attribute::HorizontalPixelPanning, panning);
    pairs[20] = (Attribute::ColorSelect, colour_select);
    pairs
}

/// 320x240, 256 colours, unchained: the 640x480 60 Hz timing with every line
/// scanned twice, 80 bytes per line, so three pages fit in the 64 KiB window.
pub const MODE_X: ModeRegisters = ModeRegisters {
    // Colour I/O, RAM enabled, 25.175 MHz dot clock, negative sync (480 lines).
    misc_output: 0xE3,
    sequencer: [
        (Sequencer::Reset, seq::RESET_RUNNING),
        (Sequencer::ClockingMode, seq::CLOCKING_8_DOT),
        (Sequencer::MapMask, PlaneMask::ALL.bits()),
        (Sequencer::CharacterMapSelect, 0x00),
        // Chain-4 and odd/even off.
        (
            Sequencer::MemoryMode,
            seq::MEMORY_EXTENDED | seq::MEMORY_ODD_EVEN_DISABLE,
        ),
    ],
    crtc: [
        (Crtc::HorizontalTotal, 0x5F),
        (Crtc::HorizontalDisplayEnd, 0x4F),
        (Crtc::StartHorizontalBlanking, 0x50),
        (Crtc::EndHorizontalBlanking, 0x82),
        (Crtc::StartHorizontalRetrace, 0x54),
        (Crtc::EndHorizontalRetrace, 0x80),
        (Crtc::VerticalTotal, 0x0D),
        (Crtc::Overflow, 0x3E),
        (Crtc::PresetRowScan, 0x00),
        // Two scan lines per row (and line compare bit 9).
        (Crtc::MaximumScanLine, 0x41),
        (Crtc::CursorStart, 0x00),
        (Crtc::CursorEnd, 0x00),
        (Crtc::StartAddressHigh, 0x00),
        (Crtc::StartAddressLow, 0x00),
        (Crtc::CursorLocationHigh, 0x00),
        (Crtc::CursorLocationLow, 0x00),
        (Crtc::VerticalRetraceStart, 0xEA),
        // CRTC 0-7 protected again once written.
        (Crtc::VerticalRetraceEnd, 0xAC),
        (Crtc::VerticalDisplayEnd, 0xDF),
        // 40 words = 80 bytes per line.
        (Crtc::Offset, 0x28),
        // Doubleword addressing off.
        (Crtc::UnderlineLocation, 0x00),
        (Crtc::StartVerticalBlanking, 0xE7),
        (Crtc::EndVerticalBlanking, 0x06),
        // Byte addressing.
        (Crtc::ModeControl, 0xE3),
        // Never.
        (Crtc::LineCompare, 0xFF),
    ],
    graphics: [
        (Graphics::SetReset, 0x00),
        (Graphics::EnableSetReset, 0x00),
        (Graphics::ColorCompare, 0x00),
        (Graphics::DataRotate, 0x00),
        (Graphics::ReadMapSelect, 0x00),
        // Write mode 0, 256-colour shift.
        (Graphics::Mode, gc::MODE_SHIFT_256),
        // Graphics at A0000 (64 KiB).
        (Graphics::Misc, 0x05),
        // All planes compared.
        (Graphics::ColorDontCare, PlaneMask::ALL.bits()),
        (Graphics::BitMask, 0xFF),
    ],
    attribute: attribute_table(
        [
            0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0A, 0x0B, 0x0C, 0x0D,
            0x0E, 0x0F,
        ],
        0x41, // graphics, 8-bit colour
        0x00,
        PlaneMask::ALL,
        0x00,
        0x00,
    ),
};

/// BIOS mode 3: 80x25 colour text, 9x16 cells, 720x400 at 70 Hz; text at
/// B8000, the font in plane 2.
pub const TEXT_80X25: ModeRegisters = ModeRegisters {
    // Colour I/O, RAM enabled, 28.322 MHz dot clock, 400-line sync.
    misc_output: 0x67,
    sequencer: [
        (Sequencer::Reset, seq::RESET_RUNNING),
        // 9-dot characters.
        (Sequencer::ClockingMode, 0x00),
        // Planes 0 and 1: characters and attributes.
        (Sequencer::MapMask, 0x03),
        (Sequencer::CharacterMapSelect, 0x00),
        // Odd/even on.
        (Sequencer::MemoryMode, seq::MEMORY_EXTENDED),
    ],
    crtc: [
        (Crtc::HorizontalTotal, 0x5F),
        (Crtc::HorizontalDisplayEnd, 0x4F),
        (Crtc::StartHorizontalBlanking, 0x50),
        (Crtc::EndHorizontalBlanking, 0x82),
        (Crtc::StartHorizontalRetrace, 0x55),
        (Crtc::EndHorizontalRetrace, 0x81),
        (Crtc::VerticalTotal, 0xBF),
        (Crtc::Overflow, 0x1F),
        (Crtc::PresetRowScan, 0x00),
        // 16 scan lines per row.
        (Crtc::MaximumScanLine, 0x4F),
        (Crtc::CursorStart, 0x0D),
        (Crtc::CursorEnd, 0x0E),
        (Crtc::StartAddressHigh, 0x00),
        (Crtc::StartAddressLow, 0x00),
        (Crtc::CursorLocationHigh, 0x00),
        (Crtc::CursorLocationLow, 0x00),
        (Crtc::VerticalRetraceStart, 0x9C),
        (Crtc::VerticalRetraceEnd, 0x8E),
        (Crtc::VerticalDisplayEnd, 0x8F),
        (Crtc::Offset, 0x28),
        (Crtc::UnderlineLocation, 0x1F),
        (Crtc::StartVerticalBlanking, 0x96),
        (Crtc::EndVerticalBlanking, 0xB9),
        (Crtc::ModeControl, 0xA3),
        (Crtc::LineCompare, 0xFF),
    ],
    graphics: [
        (Graphics::SetReset, 0x00),
        (Graphics::EnableSetReset, 0x00),
        (Graphics::ColorCompare, 0x00),
        (Graphics::DataRotate, 0x00),
        (Graphics::ReadMapSelect, 0x00),
        // Host odd/even.
        (Graphics::Mode, gc::MODE_HOST_ODD_EVEN),
        // Text at B8000 with odd maps chained to even.
        (Graphics::Misc, 0x0E),
        (Graphics::ColorDontCare, PlaneMask::ALL.bits()),
        (Graphics::BitMask, 0xFF),
    ],
    attribute: attribute_table(
        EGA_TEXT_ATTRIBUTES,
        0x0C, // text, line graphics, blink
        0x00,
        PlaneMask::ALL,
        0x08,
        0x00,
    ),
};

/// Mode 3 with 8-dot cells (640x400, the 25.175 MHz clock keeps the line
/// rate), 512 characters (attribute bit 3 clear picks map B, loaded 8 KiB
/// into plane 2; set picks map A, the font) and blinking off (attribute bit 7
/// is a bright background). The fault panel draws its QR code with map B.
pub const TEXT_80X25_TWO_MAPS: ModeRegisters = {
    let mut mode = TEXT_80X25;
    // Colour I/O, RAM enabled, 25.175 MHz dot clock, 400-line sync.
    mode.misc_output = 0x63;
    mode.sequencer[Sequencer::ClockingMode as usize].1 = seq::CLOCKING_8_DOT;
    // Map A at 0 (bits 5, 3-2), map B at 8 KiB (bits 4, 1-0).
    mode.sequencer[Sequencer::CharacterMapSelect as usize].1 = 0x10;
    // Text, line graphics, no blink.
    mode.attribute[Attribute::ModeControl.slot()].1 = 0x04;
    // 8-dot cells are not panned.
    mode.attribute[Attribute::HorizontalPixelPanning.slot()].1 = 0x00;
    mode
};
const _: () = assert!(TEXT_80X25_TWO_MAPS.in_index_order());

/// The CPU window is cleared in two fills because a fill's count is 16 bits.
const CLEAR_CHUNK_BYTES: u16 = 0x8000;

impl<B: VgaBus> ModeX<B> {
    /// Sets Mode X from any prior state: the card's extensions off, every VGA register
    /// programmed, the DAC loaded with the default palette, all four planes
    /// cleared to colour 0, and Page::Zero shown (start address latched).
    pub fn set_mode(&mut self) {
        self.issued_by("ModeX::set_mode", |vga| {
            vga.program(&MODE_X);
            vga.load_palette(0, &DEFAULT_PALETTE);
            vga.clear_video_memory();
            // Also waits until the start address has been latched by a retrace.
            vga.show_page(Page::Zero);
        })
    }

    /// Programs every register of `mode`, from any prior state.
    pub(crate) fn program(&mut self, mode: &ModeRegisters) {
        self.issued_by("ModeX::program", |vga| {
            let io = &mut vga.io;
            io.invalidate_caches();

            // An extended mode (a VBE linear framebuffer left by the bootloader)
            // would override the standard VGA registers.
            io.reset_extensions();

            // The dot clock (Misc Output) and the character clock (Clocking Mode)
            // may only change while the sequencer is held in synchronous reset.
            // Misc Output also selects colour I/O addressing, which the CRTC
            // writes below rely on.
            io.write_sequencer(Sequencer::Reset, seq::RESET_SYNCHRONOUS);
            io.write_sequencer(
                Sequencer::ClockingMode,
                mode.sequencer_value(Sequencer::ClockingMode),
            );
            io.write_misc_output(mode.misc_output);
            for (register, value) in mode.sequencer {
                if !matches!(register, Sequencer::Reset | Sequencer::ClockingMode) {
                    io.write_sequencer(register, value);
                }
            }
            io.write_sequencer(Sequencer::Reset, seq::RESET_RUNNING);

            // CRTC 0-7 are write-protected until Vertical Retrace End bit 7 is
            // clear; the table's own value (written after them) may protect them again.
            let retrace_end = mode.crtc_value(Crtc::VerticalRetraceEnd);
            io.write_crtc(Crtc::VerticalRetraceEnd, retrace_end & !crtc::PROTECT_0_7);
            for (register, value) in mode.crtc {
                io.write_crtc(register, value);
            }

            for (register, value) in mode.graphics {
                io.write_graphics(register, value);
            }

            io.reset_attribute_flip_flop();
            for (register, value) in mode.attribute {
                io.write_attribute(register, value);
            }
            io.show_video();
        })
    }

    /// Loads DAC entries `first`, `first + 1`, ... with `colours` and opens the
    /// DAC Pixel Mask fully. Entries that would run past 255 are left out: the
    /// DAC's index would wrap round and overwrite entry 0 onwards.
    pub fn load_palette(&mut self, first: u8, colours: &[Rgb6]) {
        self.issued_by("ModeX::load_palette", |vga| {
            let room = 256 - usize::from(first);
            vga.io.load_dac(first, &colours[..colours.len().min(room)]);
        })
    }

    /// Clears all four planes through the whole CPU window.
    fn clear_video_memory(&mut self) {
        self.issued_by("ModeX::clear_video_memory", |vga| {
            vga.io.set_map_mask(PlaneMask::ALL);
            for chunk in 0..(CPU_WINDOW_BYTES / u32::from(CLEAR_CHUNK_BYTES)) as u16 {
                vga.io
                    .fill_vram(chunk * CLEAR_CHUNK_BYTES, CLEAR_CHUNK_BYTES, 0);
            }
        })
    }
}
