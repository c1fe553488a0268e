//! The two text screens the kernel can end on — the goodbye line and the
//! fault panel — drawn through the 80x25 text mode of `modex`. Here rather
//! than in the kernel so that the host tests draw exactly the same screens on
//! the software VGA and compare them with what QEMU shows.

use modex::{ModeX, VgaBus, TEXT_COLUMNS, TEXT_ROWS};

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

/// The goodbye line, centred on the middle row.
pub const GOODBYE: &str = "modex-cube: goodbye. The machine can be switched off.";
const WHITE_ON_BLACK: u8 = 0x0F;

/// The fault panel's lines of report, below its heading.
pub const REPORT_LINES: usize = machine::protocol::line::FAULT_ROWS;
const WHITE_ON_RED: u8 = 0x4F;
const PANEL_HEADING: &str = "modex-cube stopped. The report (also on serial):";
const PANEL_FOOTER: &str = "Stopped. Ctrl+Alt+Del (PS/2 keyboard) or the reset button restarts.";
/// Lines of the kernel's log the fault panel shows under the report.
pub const PANEL_LOG_LINES: usize = 13;
const PANEL_LOG_HEADING: &str = "The last lines of the log, before the fault:";
const PANEL_LOG_ROW: u8 = 11;

/// Switches to text mode and shows the goodbye line, then flushes (a
/// framebuffer display presents it).
pub fn goodbye<B: VgaBus>(vga: &mut ModeX<B>) {
    vga.set_text_mode(&FONT);
    goodbye_line(vga);
}

/// Writes the goodbye line on a VGA already in 80x25 text (set by the video
/// BIOS, say), then flushes.
pub fn goodbye_line<B: VgaBus>(vga: &mut ModeX<B>) {
    let column = (usize::from(TEXT_COLUMNS) - GOODBYE.len()) / 2;
    vga.write_text(TEXT_ROWS / 2, column as u8, GOODBYE, WHITE_ON_BLACK);
    vga.bus_mut().flush();
}

/// Switches to text mode and shows the fault panel: a heading, the report's
/// lines (an empty line leaves its row blank), how to go on, and the last
/// [`PANEL_LOG_LINES`] of `log` (oldest first; each cut at the screen's
/// edge), white on red, then flushes. It programs every register from
/// scratch, so it works whatever state the interrupted code left the VGA in.
pub fn fault_panel<B: VgaBus>(vga: &mut ModeX<B>, lines: &[&str; REPORT_LINES], log: &[&str]) {
    vga.set_text_mode(&FONT);
    vga.write_text(1, 2, PANEL_HEADING, WHITE_ON_RED);
    for (row, line) in (3..).zip(lines) {
        vga.write_text(row, 2, line, WHITE_ON_RED);
    }
    vga.write_text(3 + REPORT_LINES as u8 + 1, 2, PANEL_FOOTER, WHITE_ON_RED);
    if !log.is_empty() {
        vga.write_text(PANEL_LOG_ROW - 1, 2, PANEL_LOG_HEADING, WHITE_ON_RED);
    }
    let tail = &log[log.len().saturating_sub(PANEL_LOG_LINES)..];
    for (row, line) in (PANEL_LOG_ROW..).zip(tail) {
        vga.write_text(row, 2, line, WHITE_ON_RED);
    }
    vga.bus_mut().flush();
}
