//! Mode set: register tables for Mode X and 80x25 text, and the sequence that
//! programs them from whatever state the VGA was left in (a BIOS text mode, a
//! VBE linear framebuffer from the bootloader, or a crashed driver).

use crate::palette::{Rgb6, DEFAULT_PALETTE};
use crate::regs::{
    ac, crtc, gc, seq, ALL_PLANES, ATTRIBUTE_INDEX, DAC_DATA, DAC_PIXEL_MASK, DAC_WRITE_INDEX,
    INPUT_STATUS_1, MISC_OUTPUT_WRITE,
};
use crate::{ModeX, Page, VgaBus, CPU_WINDOW_BYTES};

/// Every register a mode set programs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeRegisters {
    /// Miscellaneous Output.
    pub misc_output: u8,
    /// Sequencer registers 0..=4; register 0 (Reset) is the running value.
    pub sequencer: [u8; seq::COUNT],
    /// CRTC registers 0x00..=0x18.
    pub crtc: [u8; crtc::COUNT],
    /// Graphics Controller registers 0..=8.
    pub graphics: [u8; gc::COUNT],
    /// Attribute Controller registers 0x00..=0x14.
    pub attribute: [u8; ac::COUNT],
}

/// 320x240, 256 colours, unchained: the 640x480 60 Hz timing with every line
/// scanned twice, 80 bytes per line, so three pages fit in the 64 KiB window.
pub const MODE_X: ModeRegisters = ModeRegisters {
    // Colour I/O, RAM enabled, 25.175 MHz dot clock, negative sync (480 lines).
    misc_output: 0xE3,
    // 8-dot characters; all planes; chain-4 and odd/even off.
    sequencer: [seq::RESET_RUNNING, 0x01, ALL_PLANES, 0x00, 0x06],
    crtc: [
        0x5F, 0x4F, 0x50, 0x82, 0x54,
        0x80, // horizontal: total, display end, blanking, retrace
        0x0D, 0x3E, // vertical total, overflow
        0x00, 0x41, // preset row scan; two scan lines per row (and line compare bit 9)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, // cursor shape, start address, cursor location
        0xEA, 0xAC, 0xDF, // vertical retrace start/end (CRTC 0-7 protected), display end
        0x28, // offset: 40 words = 80 bytes per line
        0x00, // underline: doubleword addressing off
        0xE7, 0x06, // vertical blanking
        0xE3, // mode control: byte addressing
        0xFF, // line compare: never
    ],
    // Write mode 0, 256-colour shift, graphics at A0000 (64 KiB), all planes compared.
    graphics: [0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x05, 0x0F, 0xFF],
    attribute: [
        0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0A, 0x0B, 0x0C, 0x0D, 0x0E,
        0x0F, 0x41, // graphics, 8-bit colour
        0x00, ALL_PLANES, 0x00, 0x00,
    ],
};

/// BIOS mode 3: 80x25 colour text, 9x16 cells, 720x400 at 70 Hz; text at
/// B8000, the font in plane 2.
pub const TEXT_80X25: ModeRegisters = ModeRegisters {
    // Colour I/O, RAM enabled, 28.322 MHz dot clock, 400-line sync.
    misc_output: 0x67,
    // 9-dot characters; planes 0 and 1 (characters and attributes); odd/even on.
    sequencer: [seq::RESET_RUNNING, 0x00, 0x03, 0x00, 0x02],
    crtc: [
        0x5F, 0x4F, 0x50, 0x82, 0x55, 0x81, 0xBF, 0x1F, 0x00, 0x4F, 0x0D, 0x0E, 0x00, 0x00, 0x00,
        0x00, 0x9C, 0x8E, 0x8F, 0x28, 0x1F, 0x96, 0xB9, 0xA3, 0xFF,
    ],
    // Host odd/even, text at B8000 with odd maps chained to even.
    graphics: [0x00, 0x00, 0x00, 0x00, 0x00, 0x10, 0x0E, 0x0F, 0xFF],
    attribute: [
        0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x14, 0x07, 0x38, 0x39, 0x3A, 0x3B, 0x3C, 0x3D, 0x3E,
        0x3F, 0x0C, // text, line graphics, blink
        0x00, ALL_PLANES, 0x08, 0x00,
    ],
};

/// The CPU window is cleared in two fills because a fill's count is 16 bits.
const CLEAR_CHUNK_BYTES: u16 = 0x8000;

impl<B: VgaBus> ModeX<B> {
    /// Sets Mode X from any prior state: the card's extensions off, every VGA register
    /// programmed, the DAC loaded with the default palette, all four planes
    /// cleared to colour 0, and Page::Zero shown (start address latched).
    pub fn set_mode(&mut self) {
        self.program(&MODE_X);
        self.load_palette(0, &DEFAULT_PALETTE);
        self.clear_video_memory();
        // Also waits until the start address has been latched by a retrace.
        self.show_page(Page::Zero);
    }

    /// Programs every register of `mode`, from any prior state.
    pub(crate) fn program(&mut self, mode: &ModeRegisters) {
        self.invalidate_caches();

        // An extended mode (a VBE linear framebuffer left by the bootloader)
        // would override the standard VGA registers.
        self.reset_extensions();

        // The dot clock (Misc Output) and the character clock (Clocking Mode)
        // may only change while the sequencer is held in synchronous reset.
        // Misc Output also selects colour I/O addressing, which the CRTC
        // writes below rely on.
        self.write_sequencer(seq::RESET, seq::RESET_SYNCHRONOUS);
        self.write_sequencer(
            seq::CLOCKING_MODE,
            mode.sequencer[usize::from(seq::CLOCKING_MODE)],
        );
        self.bus.write_port8(MISC_OUTPUT_WRITE, mode.misc_output);
        for index in seq::MAP_MASK..=seq::MEMORY_MODE {
            self.write_sequencer(index, mode.sequencer[usize::from(index)]);
        }
        self.write_sequencer(seq::RESET, seq::RESET_RUNNING);

        // CRTC 0-7 are write-protected until Vertical Retrace End bit 7 is
        // clear; the table's own value (written after them) may protect them again.
        let retrace_end = mode.crtc[usize::from(crtc::VERTICAL_RETRACE_END)];
        self.write_crtc(crtc::VERTICAL_RETRACE_END, retrace_end & !crtc::PROTECT_0_7);
        for (index, &value) in (0..).zip(mode.crtc.iter()) {
            self.write_crtc(index, value);
        }

        for (index, &value) in (0..).zip(mode.graphics.iter()) {
            self.write_graphics(index, value);
        }

        // Reading Input Status 1 puts the attribute flip-flop in its index state.
        self.bus.read_port8(INPUT_STATUS_1);
        for (index, &value) in (0..).zip(mode.attribute.iter()) {
            self.write_attribute(index, value);
        }
        // Palette Address Source back on: the screen shows video again.
        self.bus
            .write_port8(ATTRIBUTE_INDEX, ac::PALETTE_ADDRESS_SOURCE);
    }

    /// Loads DAC entries `first`, `first + 1`, ... with `colours` and opens the
    /// DAC Pixel Mask fully. Entries that would run past 255 are left out: the
    /// DAC's index would wrap round and overwrite entry 0 onwards.
    pub fn load_palette(&mut self, first: u8, colours: &[Rgb6]) {
        let room = 256 - usize::from(first);
        self.bus.write_port8(DAC_PIXEL_MASK, 0xFF);
        // DAC Write Index once; it advances by itself after each entry's
        // third component written to DAC Data.
        self.bus.write_port8(DAC_WRITE_INDEX, first);
        for component in colours.iter().take(room).flatten() {
            self.bus.write_port8(DAC_DATA, *component);
        }
    }

    /// Clears all four planes through the whole CPU window.
    fn clear_video_memory(&mut self) {
        self.set_map_mask(ALL_PLANES);
        for chunk in 0..(CPU_WINDOW_BYTES / u32::from(CLEAR_CHUNK_BYTES)) as u16 {
            self.bus
                .fill_vram(chunk * CLEAR_CHUNK_BYTES, CLEAR_CHUNK_BYTES, 0);
        }
    }
}
