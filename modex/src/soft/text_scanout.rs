//! Text-mode scan-out: the picture a VGA makes of alphanumeric mode, so that
//! the goodbye screen and the fault panel (`ModeX::set_text_mode`) can be
//! shown on a framebuffer as well as on a real VGA.
//!
//! As on the VGA (and QEMU, the reference): the character and its attribute
//! of each cell sit at the same offset of planes 0 and 1 (odd/even writes
//! put them there), starting at the CRTC start address, Offset * 2 cells
//! apart from row to row; the glyphs sit in plane 2, 32 bytes a character,
//! one byte a scan line, bit 7 leftmost. A cell is 8 or 9 dots wide as the
//! sequencer's Clocking Mode says and Maximum Scan Line + 1 lines high. A
//! dot's colour is the attribute's foreground or background nibble through
//! the Attribute Controller's palette registers and Color Select, giving a
//! DAC index (the DAC then gives the colour, as in graphics modes).
//!
//! The ninth dot repeats the eighth for the line-graphics characters
//! 0xB0-0xDF when Mode Control enables it (QEMU's range; IBM's is 0xC0-0xDF),
//! and is background otherwise. With blinking enabled, attribute bit 7 means
//! blink, the background has 3 bits and blinking text is shown in its "on"
//! phase. Not modelled: the cursor (our text screens park it off screen),
//! underline, the 16-dot double-width clock, panning and line compare.

use crate::regs::{crtc, gc, seq, Attribute, Crtc, Graphics, Sequencer};

use super::memory::PLANE_BYTES;
use super::SoftVga;

/// Attribute Mode Control bits.
const MODE_GRAPHICS: u8 = 0x01;
const MODE_LINE_GRAPHICS: u8 = 0x04;
const MODE_BLINK: u8 = 0x08;
const MODE_P54_SELECT: u8 = 0x80;
/// The characters whose ninth dot repeats the eighth, with line graphics on.
const LINE_GRAPHICS_CHARACTERS: core::ops::RangeInclusive<u8> = 0xB0..=0xDF;
/// Plane 2 keeps 32 scan lines of glyph per character.
const GLYPH_SLOT_BYTES: usize = 32;
/// Character map selects count in units of 8 KiB of plane 2.
const FONT_MAP_BYTES: usize = 8192;
/// The Offset register counts words: two cells each in odd/even mode.
const CELLS_PER_OFFSET_UNIT: usize = 2;

/// The displayed text's layout.
pub(super) struct TextRaster {
    columns: usize,
    rows: usize,
    cell_width: usize,
    cell_height: usize,
    cells_per_row: usize,
    start: usize,
    /// Plane 2 offsets of the fonts picked by attribute bit 3 clear and set.
    font_bases: [usize; 2],
}

impl TextRaster {
    /// Width and height of the picture in dots.
    pub(super) fn size(&self) -> (usize, usize) {
        (self.columns * self.cell_width, self.rows * self.cell_height)
    }
}

/// Where a character map select field puts its font in plane 2: the two low
/// bits (at `low_shift`) pick a 16 KiB step, the high bit (at `high_shift`)
/// 8 KiB more.
fn font_base(select: u8, low_shift: u8, high_shift: u8) -> usize {
    let low = usize::from((select >> low_shift) & 0b11);
    let high = usize::from((select >> high_shift) & 1);
    (low * 2 + high) * FONT_MAP_BYTES
}

impl SoftVga {
    /// The text layout, if the VGA is in an alphanumeric mode (Graphics Misc
    /// and Attribute Mode Control both say text) with Bochs VBE off.
    pub(super) fn text_raster(&self) -> Option<TextRaster> {
        let registers = &self.registers;
        let text = registers.graphics(Graphics::Misc) & gc::MISC_GRAPHICS == 0
            && registers.attribute[Attribute::ModeControl.slot()] & MODE_GRAPHICS == 0;
        if registers.vbe_enabled() || !text {
            return None;
        }
        let cell_width = if registers.sequencer(Sequencer::ClockingMode) & seq::CLOCKING_8_DOT != 0
        {
            8
        } else {
            9
        };
        let cell_height =
            usize::from(registers.crtc(Crtc::MaximumScanLine) & crtc::MAXIMUM_SCAN_LINE_MASK) + 1;
        let scan_lines = usize::from(registers.vertical_display_end()) + 1;
        let select = registers.sequencer(Sequencer::CharacterMapSelect);
        Some(TextRaster {
            columns: usize::from(registers.crtc(Crtc::HorizontalDisplayEnd)) + 1,
            rows: scan_lines / cell_height,
            cell_width,
            cell_height,
            cells_per_row: usize::from(registers.crtc(Crtc::Offset)) * CELLS_PER_OFFSET_UNIT,
            start: usize::from(self.displayed_start),
            // Attribute bit 3 clear picks map B (bits 4, 1-0), set picks map A (5, 3-2).
            font_bases: [font_base(select, 0, 4), font_base(select, 2, 5)],
        })
    }

    /// The DAC index of attribute colour `nibble` (0..=15): the palette
    /// register, with bits 4-5 (Mode Control P54S) and 6-7 from Color Select.
    fn text_colour(&self, nibble: u8) -> u8 {
        let attribute = &self.registers.attribute;
        let palette = attribute[usize::from(nibble & 0x0F)];
        let select = attribute[Attribute::ColorSelect.slot()];
        if attribute[Attribute::ModeControl.slot()] & MODE_P54_SELECT != 0 {
            ((select & 0x0F) << 4) | (palette & 0x0F)
        } else {
            ((select & 0x0C) << 4) | (palette & 0x3F)
        }
    }

    /// Calls `put(first dot number, DAC indices)` for each line of each cell
    /// of the text picture.
    pub(super) fn scan_text(&self, raster: &TextRaster, mut put: impl FnMut(usize, &[u8])) {
        let planes = &self.memory.planes;
        let mode = self.registers.attribute[Attribute::ModeControl.slot()];
        let (width, _) = raster.size();
        for row in 0..raster.rows {
            for column in 0..raster.columns {
                let cell = (raster.start + row * raster.cells_per_row + column) % PLANE_BYTES;
                let (character, attribute) = (planes[0][cell], planes[1][cell]);
                let background = if mode & MODE_BLINK != 0 {
                    (attribute >> 4) & 0x07
                } else {
                    attribute >> 4
                };
                let colours = [
                    self.text_colour(background),
                    self.text_colour(attribute & 0x0F),
                ];
                let font = raster.font_bases[usize::from((attribute >> 3) & 1)];
                let glyph = font + usize::from(character) * GLYPH_SLOT_BYTES;
                let ninth_repeats =
                    mode & MODE_LINE_GRAPHICS != 0 && LINE_GRAPHICS_CHARACTERS.contains(&character);
                for line in 0..raster.cell_height {
                    let bits = planes[2][(glyph + line) % PLANE_BYTES];
                    let y = row * raster.cell_height + line;
                    let dots: [u8; 9] = core::array::from_fn(|dot| {
                        let lit = match dot {
                            0..=7 => bits & (0x80 >> dot) != 0,
                            _ => ninth_repeats && bits & 1 != 0,
                        };
                        colours[usize::from(lit)]
                    });
                    put(
                        y * width + column * raster.cell_width,
                        &dots[..raster.cell_width],
                    );
                }
            }
        }
    }
}
