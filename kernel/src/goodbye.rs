//! Leaving the demo: the VGA goes back to 80x25 text with a goodbye line, then
//! QEMU is powered off through isa-debug-exit; on a real PC (or a QEMU without
//! that device) the CPU halts with the line on screen.

use crate::{fault, qemu, serial_println};
use modex::{ModeX, VgaBus};

/// font8x8's glyphs keep the leftmost pixel in bit 0; the VGA's character
/// generator reads it from bit 7.
pub static FONT: [[u8; 8]; 128] = {
    let mut font = font8x8::legacy::BASIC_LEGACY;
    let mut glyph = 0;
    while glyph < font.len() {
        let mut row = 0;
        while row < 8 {
            font[glyph][row] = font[glyph][row].reverse_bits();
            row += 1;
        }
        glyph += 1;
    }
    font
};

const MESSAGE: &str = "modex-cube: goodbye. The machine can be switched off.";
const WHITE_ON_BLACK: u8 = 0x0F;

pub fn goodbye<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    if crate::legacy_vga::bios_text_mode() {
        // The card's BIOS set mode 3 and its own font, behind the driver's back.
        vga.invalidate_caches();
        serial_println!("demo: text mode 3 set by the video BIOS");
    } else {
        vga.set_text_mode(&FONT);
    }
    let column = (modex::TEXT_COLUMNS as usize - MESSAGE.len()) / 2;
    vga.write_text(modex::TEXT_ROWS / 2, column as u8, MESSAGE, WHITE_ON_BLACK);
    serial_println!(
        "{} ({} scancodes dropped by a full queue, {} serial characters dropped)",
        machine::protocol::line::GOODBYE,
        crate::keyboard::SCANCODES.dropped(),
        crate::serial::dropped()
    );
    qemu::exit(qemu::ExitCode::Success);
    fault::halt_forever()
}
