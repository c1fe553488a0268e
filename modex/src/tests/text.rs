//! The text mode fallback: registers, font, characters and attributes where
//! QEMU's VGA keeps them.
//!
//! Odd/even addressing in the model (as in QEMU): CPU offset 2n is byte n of
//! plane 0 (character), 2n + 1 is byte n of plane 1 (attribute).

use super::{mode_x, power_on};
use crate::mode::TEXT_80X25;
use crate::regs::{Attribute, Crtc, Graphics};
use crate::soft::SoftVga;
use crate::ModeX;

/// A font whose every row is different: glyph g, row r = g * 3 + r * 29.
fn test_font() -> [[u8; 8]; 128] {
    core::array::from_fn(|glyph| core::array::from_fn(|row| (glyph * 3 + row * 29) as u8))
}

fn cell(soft: &SoftVga, row: usize, col: usize) -> (u8, u8) {
    let n = row * 80 + col;
    (soft.plane(0)[n], soft.plane(1)[n])
}

#[test]
fn set_text_mode_programs_the_standard_80x25_registers() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.set_text_mode(&test_font());
    let soft = vga.into_bus();
    assert!(!soft.vbe_enabled());
    assert_eq!(soft.misc_output(), 0x67);
    for register in Crtc::ALL {
        if matches!(register, Crtc::CursorLocationHigh | Crtc::CursorLocationLow) {
            continue;
        }
        let standard = [
            0x5F, 0x4F, 0x50, 0x82, 0x55, 0x81, 0xBF, 0x1F, 0x00, 0x4F, 0x0D, 0x0E, 0x00, 0x00,
            0x00, 0x00, 0x9C, 0x8E, 0x8F, 0x28, 0x1F, 0x96, 0xB9, 0xA3, 0xFF,
        ];
        assert_eq!(
            soft.crtc(register),
            standard[register.slot()],
            "{register:?}"
        );
    }
    // The cursor is parked past the last cell.
    assert_eq!(
        u16::from_be_bytes([
            soft.crtc(Crtc::CursorLocationHigh),
            soft.crtc(Crtc::CursorLocationLow)
        ]),
        2000
    );
    for (register, value) in TEXT_80X25.sequencer {
        assert_eq!(soft.sequencer(register), value, "{register:?}");
    }
    for (register, value) in TEXT_80X25.graphics {
        assert_eq!(soft.graphics(register), value, "{register:?}");
    }
    assert_eq!(
        soft.graphics(Graphics::Misc),
        0x0E,
        "text memory not back at B8000"
    );
    assert_eq!(soft.attribute(Attribute::Palette6), 0x14);
    assert_eq!(soft.dac_entry(0x14), [0x2A, 0x15, 0x00]);
    assert!(soft.video_enabled());
    assert_eq!(soft.timing().dot_clock_hz, 28_322_000);
}

#[test]
fn the_font_is_in_plane_2_with_rows_doubled() {
    let mut soft = power_on();
    let font = test_font();
    ModeX::new(&mut *soft).set_text_mode(&font);
    let plane = soft.plane(2);
    for glyph in 0..256 {
        for line in 0..32 {
            let expected = if glyph < 128 && line < 16 {
                font[glyph][line / 2]
            } else {
                0
            };
            assert_eq!(
                plane[glyph * 32 + line],
                expected,
                "glyph {glyph} line {line}"
            );
        }
    }
}

#[test]
fn text_mode_clears_the_screen_and_writes_characters_and_attributes() {
    let mut soft = power_on();
    let mut vga = ModeX::new(&mut *soft);
    vga.set_text_mode(&test_font());
    vga.write_text(0, 0, "Hello", 0x1F);
    vga.write_text(24, 75, "edge!cut", 0x4E);
    vga.write_text(3, 10, "é?", 0x07);
    let soft = vga.into_bus();
    for (col, byte) in "Hello".bytes().enumerate() {
        assert_eq!(cell(soft, 0, col), (byte, 0x1F));
    }
    assert_eq!(cell(soft, 0, 5), (b' ', 0x07), "blank after the text");
    for (col, byte) in "edge!".bytes().enumerate() {
        assert_eq!(cell(soft, 24, 75 + col), (byte, 0x4E));
    }
    assert_eq!(soft.plane(0)[2000], 0, "text past the last cell");
    assert_eq!(cell(soft, 3, 10), (b'?', 0x07));
    assert_eq!(cell(soft, 3, 11), (b'?', 0x07));
    assert_eq!(cell(soft, 3, 12), (b' ', 0x07));
    assert_eq!(cell(soft, 12, 40), (b' ', 0x07));
    assert_eq!(soft.graphics(Graphics::Misc), 0x0E);
    assert_eq!(
        soft.plane(2)[usize::from(b'H') * 32],
        test_font()[usize::from(b'H')][0],
        "font overwritten"
    );
}

#[test]
fn write_text_off_screen_writes_nothing() {
    let mut soft = power_on();
    let mut vga = ModeX::new(&mut *soft);
    vga.set_text_mode(&test_font());
    vga.bus_mut().reset_counts();
    vga.write_text(25, 0, "below", 0x07);
    vga.write_text(0, 80, "right", 0x07);
    assert_eq!(vga.bus().counts().vram_writes, 0);
}

#[test]
fn mode_x_comes_back_after_text_mode() {
    let mut soft = power_on();
    let mut vga = ModeX::new(&mut *soft);
    vga.set_text_mode(&test_font());
    vga.write_text(1, 1, "x", 0x07);
    vga.set_mode();
    vga.fill_rect(crate::Page::Zero, 1, 1, 3, 3, 9);
    let mut expected = super::Picture::filled(0);
    expected.fill_rect(1, 1, 3, 3, 9);
    super::assert_picture(
        &expected,
        &super::scanout(vga.bus()),
        "Mode X after text mode",
    );
}
