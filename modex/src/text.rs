//! The fallback 80x25 colour text mode, set from scratch without the BIOS,
//! with a caller-supplied 8x8 font shown in 9x16 cells (or in 8x16 cells
//! beside a second character map of blocks, for the fault panel's QR code).

use crate::mode::{ModeRegisters, TEXT_80X25, TEXT_80X25_TWO_MAPS};
use crate::palette::EGA_PALETTE;
use crate::regs::{seq, Crtc, Graphics, PlaneMask, Sequencer};
use crate::{ModeX, VgaBus};

/// Text columns.
pub const TEXT_COLUMNS: u8 = 80;
/// Text rows.
pub const TEXT_ROWS: u8 = 25;

const CELLS: u16 = TEXT_COLUMNS as u16 * TEXT_ROWS as u16;
/// Each cell is a character byte (plane 0) and an attribute byte (plane 1),
/// interleaved even/odd in the CPU's view.
const BYTES_PER_CELL: u16 = 2;
/// The font's glyphs are 8 rows high; each is shown twice to fill 16 scan lines.
const GLYPH_ROWS: usize = 8;
const SCAN_LINES_PER_GLYPH_ROW: u16 = 2;
/// Plane 2 has room for 32 scan lines per character whatever the cell height.
const GLYPH_SLOT_BYTES: u16 = 32;
const GLYPH_SLOTS: u16 = 256;
/// The font covers ASCII; other characters show as this.
const REPLACEMENT_CHARACTER: u8 = b'?';
const BLANK: u8 = b' ';
/// Block rows of a block character, and scan lines of each.
const BLOCK_ROWS: u16 = 4;
const BLOCK_LINES: u16 = 4;
/// Light grey on black.
const DEFAULT_ATTRIBUTE: u8 = 0x07;
/// White on black, for the blank screen with the block map: attribute bit 3
/// set, so blanks are the font's spaces, not blocks.
const DEFAULT_ATTRIBUTE_WITH_BLOCKS: u8 = 0x0F;

/// Planes 0 and 1: characters and attributes.
const TEXT_PLANES: PlaneMask = PlaneMask::from_bits_truncate(0x03);
/// Plane 2: the font.
const FONT_PLANE_INDEX: u8 = 2;
const FONT_PLANE: PlaneMask = PlaneMask::plane(FONT_PLANE_INDEX);

/// Memory Mode for the font load: sequential addressing, no odd/even, no chain-4.
const MEMORY_MODE_SEQUENTIAL: u8 = seq::MEMORY_EXTENDED | seq::MEMORY_ODD_EVEN_DISABLE;
/// Graphics Misc while the CPU touches text memory: A0000 (64 KiB), because
/// the bus reaches only that window. The text mode's own B8000 is restored
/// after each access, so other code can use the standard address.
const MISC_TEXT_AT_A0000: u8 = 0x06;
/// Graphics Misc for the font load: A0000 (64 KiB), no odd/even chaining.
const MISC_FONT_AT_A0000: u8 = 0x04;

impl<B: VgaBus> ModeX<B> {
    /// Switches to 80x25 colour text from any state, without the BIOS: the
    /// standard mode 3 registers and EGA palette, `font` (128 ASCII glyphs,
    /// row bit 7 leftmost) in plane 2 with each row shown twice, a blank
    /// light-grey screen, and the cursor parked off screen.
    pub fn set_text_mode(&mut self, font: &[[u8; GLYPH_ROWS]; 128]) {
        self.issued_by("ModeX::set_text_mode", |vga| {
            vga.enter_text_mode(&TEXT_80X25, font, false);
        })
    }

    /// As [`ModeX::set_text_mode`], but with 8-dot cells (640x400),
    /// blinking off (attribute bit 7 is a bright background) and a second
    /// character map of blocks: with attribute bit 3 clear, character `n`
    /// is a 2-wide, 4-tall block of squares of 4x4 dots, square `k` (left to
    /// right, then top to bottom) in the foreground colour if bit `k` of `n`
    /// is set. Attributes with bit 3 set show `font`; the blank screen is
    /// white on black spaces of the font. Each cell can so carry eight
    /// modules of a QR code.
    pub fn set_text_mode_with_blocks(&mut self, font: &[[u8; GLYPH_ROWS]; 128]) {
        self.issued_by("ModeX::set_text_mode_with_blocks", |vga| {
            vga.enter_text_mode(&TEXT_80X25_TWO_MAPS, font, true);
        })
    }

    /// Writes raw character codes (any of 256, no translation) at (`row`,
    /// `col`) with `attribute`, cut at the end of the line.
    pub fn write_characters(&mut self, row: u8, col: u8, characters: &[u8], attribute: u8) {
        self.issued_by("ModeX::write_characters", |vga| {
            if row >= TEXT_ROWS || col >= TEXT_COLUMNS {
                return;
            }
            let start =
                (u16::from(row) * u16::from(TEXT_COLUMNS) + u16::from(col)) * BYTES_PER_CELL;
            let room = usize::from(TEXT_COLUMNS - col);
            vga.with_text_window(|vga| {
                vga.io.set_map_mask(TEXT_PLANES);
                for (offset, &character) in (start..)
                    .step_by(usize::from(BYTES_PER_CELL))
                    .zip(characters.iter().take(room))
                {
                    // Odd/even addressing: the even byte goes to plane 0, the odd to plane 1.
                    vga.io.write_vram8(offset, character);
                    vga.io.write_vram8(offset + 1, attribute);
                }
            });
        })
    }

    fn enter_text_mode(
        &mut self,
        mode: &ModeRegisters,
        font: &[[u8; GLYPH_ROWS]; 128],
        blocks: bool,
    ) {
        self.program(mode);
        self.load_palette(0, &EGA_PALETTE);
        self.load_font(font, blocks);
        let blank_attribute = if blocks {
            DEFAULT_ATTRIBUTE_WITH_BLOCKS
        } else {
            DEFAULT_ATTRIBUTE
        };
        // Character and attribute pairs through both planes, as text is
        // written: odd/even addressing sends each byte to its plane. (Filling
        // each plane alone relies on odd/even too, and Bochs, which does not
        // model it, would show the attribute plane's fill as characters.)
        self.with_text_window(|vga| {
            vga.io.set_map_mask(TEXT_PLANES);
            for cell in 0..CELLS {
                vga.io.write_vram8(cell * BYTES_PER_CELL, BLANK);
                vga.io
                    .write_vram8(cell * BYTES_PER_CELL + 1, blank_attribute);
            }
        });
        let [high, low] = CELLS.to_be_bytes();
        self.io.write_crtc(Crtc::CursorLocationHigh, high);
        self.io.write_crtc(Crtc::CursorLocationLow, low);
    }

    /// Writes `text` at (`row`, `col`) in text mode with `attribute`
    /// (background << 4 | foreground), cut at the end of the line. Characters
    /// outside ASCII show as '?'; a position off screen writes nothing.
    pub fn write_text(&mut self, row: u8, col: u8, text: &str, attribute: u8) {
        self.issued_by("ModeX::write_text", |vga| {
            let mut glyphs = [0u8; TEXT_COLUMNS as usize];
            let mut count = 0;
            for (glyph, character) in glyphs.iter_mut().zip(text.chars()) {
                *glyph = if character.is_ascii() {
                    character as u8
                } else {
                    REPLACEMENT_CHARACTER
                };
                count += 1;
            }
            vga.write_characters(row, col, &glyphs[..count], attribute);
        })
    }

    /// Map B of [`ModeX::set_text_mode_with_blocks`], 8 KiB into plane 2
    /// (Character Map Select 0x10), while plane 2 is sequential memory.
    fn load_block_map(&mut self) {
        let base = GLYPH_SLOTS * GLYPH_SLOT_BYTES;
        self.io.fill_vram(base, GLYPH_SLOTS * GLYPH_SLOT_BYTES, 0);
        for character in 0..GLYPH_SLOTS {
            let slot = base + character * GLYPH_SLOT_BYTES;
            for block_row in 0..BLOCK_ROWS {
                let bits = character >> (2 * block_row);
                let left = if bits & 1 != 0 { 0xF0 } else { 0 };
                let right = if bits & 2 != 0 { 0x0F } else { 0 };
                self.io
                    .fill_vram(slot + block_row * BLOCK_LINES, BLOCK_LINES, left | right);
            }
        }
    }

    /// Runs `access` with text memory mapped at A0000.
    fn with_text_window(&mut self, access: impl FnOnce(&mut Self)) {
        let misc = TEXT_80X25.graphics_value(Graphics::Misc);
        self.io.set_graphics(Graphics::Misc, MISC_TEXT_AT_A0000);
        access(self);
        self.io.set_graphics(Graphics::Misc, misc);
    }

    /// Loads the font into plane 2 (glyph n at n * 32), rows doubled and the
    /// unused slots blank, then restores text addressing.
    fn load_font(&mut self, font: &[[u8; GLYPH_ROWS]; 128], blocks: bool) {
        self.issued_by("ModeX::load_font", |vga| {
            // Plane 2 as plain sequential memory, the way the BIOS loads fonts.
            vga.io
                .write_sequencer(Sequencer::Reset, seq::RESET_SYNCHRONOUS);
            vga.io.write_map_mask(FONT_PLANE);
            vga.io
                .write_sequencer(Sequencer::MemoryMode, MEMORY_MODE_SEQUENTIAL);
            vga.io.write_sequencer(Sequencer::Reset, seq::RESET_RUNNING);
            vga.io
                .write_graphics(Graphics::ReadMapSelect, FONT_PLANE_INDEX);
            vga.io.write_graphics(Graphics::Mode, 0x00);
            vga.io.write_graphics(Graphics::Misc, MISC_FONT_AT_A0000);

            vga.io.fill_vram(0, GLYPH_SLOTS * GLYPH_SLOT_BYTES, 0);
            for (slot, glyph) in (0..)
                .step_by(usize::from(GLYPH_SLOT_BYTES))
                .zip(font.iter())
            {
                for (row, &bits) in (0..)
                    .step_by(usize::from(SCAN_LINES_PER_GLYPH_ROW))
                    .zip(glyph.iter())
                {
                    vga.io.fill_vram(slot + row, SCAN_LINES_PER_GLYPH_ROW, bits);
                }
            }
            if blocks {
                vga.load_block_map();
            }

            // Back to the text mode's odd/even addressing.
            vga.io
                .write_sequencer(Sequencer::Reset, seq::RESET_SYNCHRONOUS);
            for register in [Sequencer::MapMask, Sequencer::MemoryMode] {
                vga.io
                    .write_sequencer(register, TEXT_80X25.sequencer_value(register));
            }
            vga.io.write_sequencer(Sequencer::Reset, seq::RESET_RUNNING);
            for register in [Graphics::ReadMapSelect, Graphics::Mode, Graphics::Misc] {
                vga.io
                    .write_graphics(register, TEXT_80X25.graphics_value(register));
            }
        })
    }
}
