//! The software VGA's text scan-out, checked dot by dot against an
//! independent reading of the VGA's rules: glyph rows from plane 2, 9-dot
//! cells with a background ninth dot, 16 lines a row from Maximum Scan Line,
//! colours through the attribute palette to DAC indices.

use super::{mode_x, power_on};
use crate::palette::EGA_PALETTE;
use crate::regs::{Crtc, Port, Sequencer};
use crate::soft::{dac_6_to_8, SoftVga};
use crate::{ModeX, VgaBus};
use std::vec;
use std::vec::Vec;

/// Every glyph row different: glyph g, row r = g * 5 + r * 37.
fn font() -> [[u8; 8]; 128] {
    core::array::from_fn(|glyph| core::array::from_fn(|row| (glyph * 5 + row * 37) as u8))
}

/// Mode 3's attribute palette: colour nibble -> DAC index.
const MODE_3_PALETTE: [u8; 16] = [
    0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x14, 0x07, 0x38, 0x39, 0x3A, 0x3B, 0x3C, 0x3D, 0x3E, 0x3F,
];

fn text_screen(soft: &mut SoftVga, writes: &[(u8, u8, &str, u8)]) {
    let mut vga = ModeX::new(&mut *soft);
    vga.set_mode();
    vga.set_text_mode(&font());
    for &(row, column, text, attribute) in writes {
        vga.write_text(row, column, text, attribute);
    }
}

fn scan(soft: &SoftVga) -> (usize, usize, Vec<u8>) {
    let mut dots = vec![0; 720 * 400];
    let (width, height) = soft.scanout_indices(&mut dots);
    (width, height, dots)
}

/// The dots of one cell, by the rules, for `cell_height` lines of a font
/// whose rows are each shown twice.
fn expected_cell(character: u8, attribute: u8, cell_width: usize) -> Vec<Vec<u8>> {
    let glyph = font()[usize::from(character)];
    let (fg, bg) = (
        MODE_3_PALETTE[usize::from(attribute & 0x0F)],
        // Blinking is on in mode 3: the background has three bits.
        MODE_3_PALETTE[usize::from((attribute >> 4) & 0x07)],
    );
    (0..16)
        .map(|line| {
            (0..cell_width)
                .map(|dot| {
                    let lit = dot < 8 && glyph[line / 2] & (0x80 >> dot) != 0;
                    if lit {
                        fg
                    } else {
                        bg
                    }
                })
                .collect()
        })
        .collect()
}

fn cell_dots(
    dots: &[u8],
    width: usize,
    row: usize,
    column: usize,
    cell_width: usize,
) -> Vec<Vec<u8>> {
    (0..16)
        .map(|line| {
            let start = (row * 16 + line) * width + column * cell_width;
            dots[start..start + cell_width].to_vec()
        })
        .collect()
}

#[test]
fn text_mode_shows_80x25_cells_of_9x16_dots() {
    let mut soft = power_on();
    text_screen(&mut soft, &[(2, 3, "A", 0x4F), (24, 79, "z", 0x1E)]);
    let (width, height, dots) = scan(&soft);
    assert_eq!((width, height), (720, 400));
    assert_eq!(soft.picture_size(), (720, 400));
    assert_eq!(
        cell_dots(&dots, width, 2, 3, 9),
        expected_cell(b'A', 0x4F, 9)
    );
    assert_eq!(
        cell_dots(&dots, width, 24, 79, 9),
        expected_cell(b'z', 0x1E, 9)
    );
    // set_text_mode fills the screen with light grey blanks.
    assert_eq!(
        cell_dots(&dots, width, 0, 0, 9),
        expected_cell(b' ', 0x07, 9)
    );
}

#[test]
fn eight_dot_cells_when_the_sequencer_says_so() {
    let mut soft = power_on();
    text_screen(&mut soft, &[(10, 40, "Hi", 0x2C)]);
    soft.write_port16(
        Port::SEQUENCER_INDEX,
        u16::from_le_bytes([Sequencer::ClockingMode.index(), 0x01]),
    );
    let (width, height, dots) = scan(&soft);
    assert_eq!((width, height), (640, 400));
    assert_eq!(
        cell_dots(&dots, width, 10, 41, 8),
        expected_cell(b'i', 0x2C, 8)
    );
}

#[test]
fn rows_are_maximum_scan_line_plus_one_lines_high() {
    let mut soft = power_on();
    text_screen(&mut soft, &[(1, 0, "M", 0x0F)]);
    // 8 lines a row: 50 rows of the same 400 lines; cell 80 (row 1) is at y 8.
    soft.write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::MaximumScanLine.index(), 0x47]),
    );
    let (width, height, dots) = scan(&soft);
    assert_eq!((width, height), (720, 400));
    let glyph = font()[usize::from(b'M')];
    for line in 0..8 {
        let row = &dots[(8 + line) * width..][..8];
        let expected: Vec<u8> = (0..8)
            .map(|dot| {
                if glyph[line / 2] & (0x80 >> dot) != 0 {
                    0x3F
                } else {
                    0
                }
            })
            .collect();
        assert_eq!(row, &expected[..], "line {line}");
    }
}

#[test]
fn text_colours_reach_the_screen_through_the_dac() {
    let mut soft = power_on();
    text_screen(&mut soft, &[(0, 0, "\u{7f}", 0x6E)]);
    let mut rgb = vec![[0u8; 3]; 720 * 400];
    soft.scanout_rgb(&mut rgb);
    // The ninth dot of a cell is background: brown (EGA 6 -> DAC 0x14).
    assert_eq!(rgb[8], EGA_PALETTE[0x14].map(dac_6_to_8));
    let mut colours: Vec<[u8; 3]> = rgb[..9].to_vec();
    colours.sort();
    colours.dedup();
    assert!(colours
        .iter()
        .all(|c| [EGA_PALETTE[0x14], EGA_PALETTE[0x3E]]
            .map(|e| e.map(dac_6_to_8))
            .contains(c)));
}

#[test]
fn leaving_text_mode_brings_the_graphics_picture_back() {
    let mut soft = power_on();
    text_screen(&mut soft, &[(0, 0, "x", 0x07)]);
    let mut vga = mode_x(&mut soft);
    vga.set_mode();
    assert_eq!(vga.bus().picture_size(), (320, 240));
}

#[test]
fn the_block_map_shows_each_bit_as_a_square_of_4x4_dots() {
    let mut soft = power_on();
    let mut vga = ModeX::new(&mut *soft);
    vga.set_mode();
    vga.set_text_mode_with_blocks(&font());
    // Every block character, black on bright white (bit 3 clear: map B,
    // blinking off: a 4-bit background); a font character beside them.
    for character in 0..=255u8 {
        vga.write_characters(character / 80, character % 80, &[character], 0xF0);
    }
    vga.write_text(10, 0, "A", 0x4F);
    let (width, height, dots) = scan(&soft);
    assert_eq!((width, height), (640, 400));
    let (black, white) = (MODE_3_PALETTE[0], MODE_3_PALETTE[15]);
    for character in 0..=255u8 {
        let (row, column) = (usize::from(character / 80), usize::from(character % 80));
        let cell = cell_dots(&dots, width, row, column, 8);
        for (line, dots) in cell.iter().enumerate() {
            for (dot, &colour) in dots.iter().enumerate() {
                let bit = (line / 4) * 2 + dot / 4;
                let expected = if character & (1 << bit) != 0 {
                    black
                } else {
                    white
                };
                assert_eq!(
                    colour, expected,
                    "character {character} line {line} dot {dot}"
                );
            }
        }
    }
    // Attribute bit 3 set: the font, in 8-dot cells.
    assert_eq!(
        cell_dots(&dots, width, 10, 0, 8),
        expected_cell(b'A', 0x4F, 8)
    );
    // The blank screen is the font's spaces, white on black, not blocks.
    assert_eq!(
        cell_dots(&dots, width, 20, 5, 8),
        expected_cell(b' ', 0x0F, 8)
    );
}
