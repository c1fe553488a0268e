//! The two text screens the kernel can end on — the goodbye line and the
//! fault panel — drawn through the 80x25 text mode of `modex`. Here rather
//! than in the kernel so that the host tests draw exactly the same screens on
//! the software VGA and compare them with what QEMU shows.

use crate::report::fit;
use modex::{ModeX, VgaBus, TEXT_COLUMNS, TEXT_ROWS};
use qrcodegen_no_heap::{QrCode, Version};

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
pub const REPORT_LINES: usize = protocol::line::FAULT_ROWS;
const WHITE_ON_RED: u8 = 0x4F;
/// The QR code's cells: bright white background (blinking is off), black
/// foreground, attribute bit 3 clear so the characters are blocks (map B).
const CODE_ON_WHITE: u8 = 0xF0;
const PANEL_HEADING: &str = "modex-cube stopped. The report (also on serial and in the QR code):";
const PANEL_FOOTER: [&str; 2] = [
    "Stopped. Ctrl+Alt+Del (PS/2 keyboard)",
    "or the reset button restarts.",
];
/// Lines of the kernel's log the fault panel shows under the report.
pub const PANEL_LOG_LINES: usize = 16;
const PANEL_LOG_HEADING: &str = "The log before the fault:";
/// Rows: the heading, the report's lines across the screen, then the footer
/// and the log on the left of the QR code.
const REPORT_ROW: u8 = 1;
const LOWER_ROW: u8 = REPORT_ROW + REPORT_LINES as u8;
const PANEL_LOG_ROW: u8 = LOWER_ROW + 4;
const TEXT_COLUMN: u8 = 1;
/// The QR code's cells: the lower right of the screen, white, the code
/// centred in them; each cell is 2x4 modules.
pub const CODE_COLUMN: u8 = 41;
const CODE_CELLS_WIDE: u8 = TEXT_COLUMNS - CODE_COLUMN;
const CODE_CELLS_HIGH: u8 = TEXT_ROWS - LOWER_ROW;
const MODULES_WIDE: i32 = 2 * CODE_CELLS_WIDE as i32;
const MODULES_HIGH: i32 = 4 * CODE_CELLS_HIGH as i32;
/// Characters of a line left of the code.
pub const LOWER_TEXT_COLUMNS: usize = (CODE_COLUMN - TEXT_COLUMN - 1) as usize;
/// The largest code: version 13, 69 modules, which with a four-module
/// quiet zone each side fits the code's cells.
pub const PANEL_QR_MAX_VERSION: u8 = 13;
const QUIET_MODULES: i32 = 4;
const LARGEST_CODE: i32 = 17 + 4 * PANEL_QR_MAX_VERSION as i32;
const _: () = assert!(LARGEST_CODE + 2 * QUIET_MODULES <= MODULES_WIDE);
const _: () = assert!(LARGEST_CODE + 2 * QUIET_MODULES <= MODULES_HIGH);
const _: () = assert!(PANEL_LOG_ROW as usize + PANEL_LOG_LINES <= TEXT_ROWS as usize);
/// Bytes of QR text at most: version 13's capacity in byte mode at low
/// error correction.
pub const PANEL_QR_TEXT_BYTES: usize = 425;
/// Bytes of a fact or fault line in the QR text at most.
const QR_LINE_BYTES: usize = 120;
const QR_BUFFER_BYTES: usize = Version::new(PANEL_QR_MAX_VERSION).buffer_len();

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

/// The text the fault panel's QR code carries: the report's `lines` (empty
/// ones left out), then as many `facts` as fit (the build, the CPU, the
/// firmware, the display), each whole, then the newest lines of `log` that
/// fit, oldest first; a line longer than 120 bytes is cut. At most
/// [`PANEL_QR_TEXT_BYTES`]; returns the bytes written to `out`.
pub fn fault_qr_text(lines: &[&str], facts: &[&str], log: &[&str], out: &mut [u8]) -> usize {
    let limit = out.len().min(PANEL_QR_TEXT_BYTES);
    let cut = |text: &str| crate::report::fit(text, QR_LINE_BYTES).len();
    // Appends a line (after a newline unless first) if it fits whole.
    let put = |out: &mut [u8], len: &mut usize, text: &str| -> bool {
        let text = &text.as_bytes()[..cut(text)];
        let separator = usize::from(*len > 0);
        if *len + separator + text.len() > limit {
            return false;
        }
        if separator == 1 {
            out[*len] = b'\n';
        }
        out[*len + separator..*len + separator + text.len()].copy_from_slice(text);
        *len += separator + text.len();
        true
    };
    let mut len = 0;
    for text in lines.iter().chain(facts).filter(|t| !t.is_empty()) {
        if !put(out, &mut len, text) {
            break;
        }
    }
    // The newest log lines that fit, written oldest first.
    let mut room = limit.saturating_sub(len);
    let mut first = log.len();
    while first > 0 && cut(log[first - 1]) < room {
        room -= cut(log[first - 1]) + 1;
        first -= 1;
    }
    for text in &log[first..] {
        put(out, &mut len, text);
    }
    len
}

/// Switches to text mode and shows the fault panel: a heading, the report's
/// lines across the screen (an empty line leaves its row blank), then on
/// the left how to go on and the last [`PANEL_LOG_LINES`] of `log` (oldest
/// first), on the right `qr_text` as a QR code (black on white, one block
/// character a 2x4 modules, a quiet zone of at least four modules); text
/// white on red, each line cut at its area's edge. Then flushes. It programs
/// every register from scratch, so it works whatever state the interrupted
/// code left the VGA in. No heap; the encoder's buffers (about 1.2 KiB) are
/// on the stack.
pub fn fault_panel<B: VgaBus>(
    vga: &mut ModeX<B>,
    lines: &[&str; REPORT_LINES],
    log: &[&str],
    qr_text: &[u8],
) {
    vga.set_text_mode_with_blocks(&FONT);
    vga.write_text(0, TEXT_COLUMN, PANEL_HEADING, WHITE_ON_RED);
    for (row, line) in (REPORT_ROW..).zip(lines) {
        vga.write_text(row, TEXT_COLUMN, line, WHITE_ON_RED);
    }
    let left = |text| fit(text, LOWER_TEXT_COLUMNS);
    for (row, line) in (LOWER_ROW..).zip(PANEL_FOOTER) {
        vga.write_text(row, TEXT_COLUMN, left(line), WHITE_ON_RED);
    }
    if !log.is_empty() {
        vga.write_text(
            PANEL_LOG_ROW - 1,
            TEXT_COLUMN,
            left(PANEL_LOG_HEADING),
            WHITE_ON_RED,
        );
    }
    let tail = &log[log.len().saturating_sub(PANEL_LOG_LINES)..];
    for (row, line) in (PANEL_LOG_ROW..).zip(tail) {
        vga.write_text(row, TEXT_COLUMN, left(line), WHITE_ON_RED);
    }
    draw_code(vga, qr_text);
    vga.bus_mut().flush();
}

/// Encodes `text` (cut at [`PANEL_QR_TEXT_BYTES`]) and writes the code's
/// cells; the cells stay white if it does not encode.
fn draw_code<B: VgaBus>(vga: &mut ModeX<B>, text: &[u8]) {
    let text = &text[..text.len().min(PANEL_QR_TEXT_BYTES)];
    let drawn =
        crate::report::encode_qr::<QR_BUFFER_BYTES, ()>(text, PANEL_QR_MAX_VERSION, |code| {
            draw_code_cells(vga, Some(code))
        });
    if drawn.is_none() {
        draw_code_cells(vga, None);
    }
}

/// Writes the cells of `code` (all white for none), centred in its area.
fn draw_code_cells<B: VgaBus>(vga: &mut ModeX<B>, code: Option<&QrCode>) {
    let (size, dark) = match code {
        Some(code) => (code.size(), Some(code)),
        None => (0, None),
    };
    let origin = ((MODULES_WIDE - size) / 2, (MODULES_HIGH - size) / 2);
    let mut cells = [0u8; CODE_CELLS_WIDE as usize];
    for cell_row in 0..CODE_CELLS_HIGH {
        for (cell_column, cell) in (0..).zip(cells.iter_mut()) {
            *cell = (0..8).fold(0u8, |blocks, bit| {
                let x = cell_column * 2 + bit % 2 - origin.0;
                let y = i32::from(cell_row) * 4 + bit / 2 - origin.1;
                let is_dark = dark.is_some_and(|code| code.get_module(x, y));
                blocks | (u8::from(is_dark) << bit)
            });
        }
        vga.write_characters(LOWER_ROW + cell_row, CODE_COLUMN, &cells, CODE_ON_WHITE);
    }
}
