//! The report screen: what the kernel found out about the machine, the most
//! recent lines of its log, and all of it again as a QR code, so a phone can
//! turn the screen into text for an issue on PCs without a serial port.
//!
//! The kernel gathers the facts and the log lines; everything about how they
//! look is here, drawn through `ModeX` so it shows the same on a true VGA, on
//! the software VGA presented to a framebuffer, and in the host's tests.
//!
//! The report is drawn on the spare page 2, which the demo's double buffering
//! never uses: pages 0 and 1, and the renderer's shadows of them, are left as
//! they were, so leaving the report is only a flip back to the page that was
//! shown, and the picture from before returns exactly.
//!
//! Layout at 320x240: the facts across the top in the 6x10 font, one per row;
//! below them, in the 5x8 font on the left, a row saying where the log
//! window is and which keys work, then the log window, and the QR code in
//! the bottom right corner, one pixel per module, inside a four-module white
//! quiet zone. Every text is cut to its area's columns and drawn through a
//! target clipped to that area, so no value, however long, reaches another
//! area or leaves the page.

use embedded_graphics::mono_font::{ascii::FONT_5X8, ascii::FONT_6X10, MonoFont, MonoTextStyle};
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::Rectangle;
use embedded_graphics::text::{Baseline, Text};
use modex::{FlipReport, ImageCanvas, ModeX, Page, PageImage, PaletteIndex, Rgb6, VgaBus};
use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};
use qrcodegen_no_heap::{QrCode, QrCodeEcc, Version};

/// The page the report is drawn on and shown from.
pub const REPORT_PAGE: Page = Page::Two;
/// DAC entry of the background and the QR code's dark modules: black.
pub const BLACK: u8 = 0;
/// DAC entry of the text and the QR code's light modules: white.
pub const WHITE: u8 = 15;
const BLACK_RGB: Rgb6 = [0, 0, 0];
const WHITE_RGB: Rgb6 = [63, 63, 63];

/// Fact rows at most; further facts are left out.
pub const FACT_ROWS: usize = 12;
/// Characters of a fact row (6x10 font, 1-pixel margins).
pub const FACT_COLUMNS: usize = ((SCREEN_WIDTH - 2) / 6) as usize;
/// Rows of the log window (5x8 font).
pub const LOG_ROWS: usize = 13;
/// The largest QR code: version 23, 109 modules, 1,091 bytes of text.
pub const QR_MAX_VERSION: u8 = 23;
/// Modules of white around the code.
pub const QR_QUIET_MODULES: i32 = 4;
/// Pixels of the square kept for the code: the largest one and its quiet zone.
pub const QR_AREA_SIDE: i32 = 17 + 4 * QR_MAX_VERSION as i32 + 2 * QR_QUIET_MODULES;

const FACT_FONT: &MonoFont = &FONT_6X10;
const LOG_FONT: &MonoFont = &FONT_5X8;
const FACTS_TOP: i32 = 1;
/// The log area: the hint row, then the log window.
const LOG_AREA_TOP: i32 = FACTS_TOP + FACT_ROWS as i32 * 10 + 1;
const LOG_TOP: i32 = LOG_AREA_TOP + 8;
const LOG_LEFT: i32 = 1;
/// The QR area, bottom right.
pub const QR_AREA: Rectangle = Rectangle::new(
    Point::new(SCREEN_WIDTH - QR_AREA_SIDE, SCREEN_HEIGHT - QR_AREA_SIDE),
    Size::new(QR_AREA_SIDE as u32, QR_AREA_SIDE as u32),
);
/// Characters of a log row: what fits left of the QR area.
pub const LOG_COLUMNS: usize = ((SCREEN_WIDTH - QR_AREA_SIDE - 2 * LOG_LEFT) / 5) as usize;
const FACTS_AREA: Rectangle = Rectangle::new(
    Point::new(0, 0),
    Size::new(SCREEN_WIDTH as u32, LOG_AREA_TOP as u32),
);
const LOG_AREA: Rectangle = Rectangle::new(
    Point::new(0, LOG_AREA_TOP),
    Size::new(
        (SCREEN_WIDTH - QR_AREA_SIDE - 1) as u32,
        (SCREEN_HEIGHT - LOG_AREA_TOP) as u32,
    ),
);

// The areas never overlap, and the log window fits the screen.
const _: () = assert!(LOG_TOP + LOG_ROWS as i32 * 8 <= SCREEN_HEIGHT);
const _: () = assert!(FACTS_AREA.size.height as i32 <= QR_AREA.top_left.y);
const _: () = assert!(LOG_AREA.size.width as i32 <= QR_AREA.top_left.x);
const _: () = assert!(FACTS_TOP + FACT_ROWS as i32 * 10 <= LOG_AREA_TOP);

/// Bytes of QR text at most: version 23's capacity in byte mode at low error
/// correction.
pub const QR_TEXT_BYTES: usize = 1091;
const QR_BUFFER_BYTES: usize = Version::new(QR_MAX_VERSION).buffer_len();

/// Where the log window is in the log: lines `first..=last` (counted from 1,
/// oldest first) of `total`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LogPosition {
    /// The first line shown, from 1; 0 if none is.
    pub first: usize,
    /// The last line shown.
    pub last: usize,
    /// Lines in the log.
    pub total: usize,
}

/// What the report shows.
#[derive(Clone, Copy, Debug)]
pub struct Report<'a> {
    /// One fact a row: "firmware: BIOS", "cpu: ...". Only the first
    /// [`FACT_ROWS`] are shown.
    pub facts: &'a [&'a str],
    /// The log window, oldest first. Only the last [`LOG_ROWS`] are shown.
    pub log: &'a [&'a str],
    /// Where the window is in the log.
    pub position: LogPosition,
}

/// A display adapter's name by its PCI IDs, as far as known: the emulators'
/// adapters by device, others by maker; "unknown" otherwise.
pub fn pci_name(vendor: u16, device: u16) -> &'static str {
    match (vendor, device) {
        (0x1234, 0x1111) => "QEMU/Bochs VGA",
        (0x1b36, 0x0100) => "QEMU QXL",
        (0x15ad, 0x0405) => "VMware SVGA II",
        (0x1af4, 0x1050) => "virtio GPU",
        (0x1013, 0x00b8) => "Cirrus Logic GD5446",
        (0x80ee, 0xbeef) => "VirtualBox VGA",
        (0x8086, _) => "Intel",
        (0x10de, _) => "NVIDIA",
        (0x1002, _) => "AMD/ATI",
        (0x1013, _) => "Cirrus Logic",
        (0x102b, _) => "Matrox",
        (0x5333, _) => "S3",
        (0x1a03, _) => "ASPEED",
        _ => "unknown",
    }
}

/// Columns a fact's continuation rows are indented by.
pub const WRAP_INDENT: usize = 2;

/// Splits `text` into rows of at most `columns` characters at spaces, and
/// hands each to `row` with its indent: 0 for the first, [`WRAP_INDENT`] for
/// the rest (which then hold `columns - WRAP_INDENT`). A word longer than a
/// row, which has no space to break at, is cut where the row ends. Spaces at
/// a break are dropped; no other character is lost.
pub fn wrap(text: &str, columns: usize, mut row: impl FnMut(usize, &str)) {
    let mut rest = text;
    let mut indent = 0;
    loop {
        let room = columns.saturating_sub(indent).max(1);
        if rest.chars().count() <= room {
            row(indent, rest);
            return;
        }
        let end = fit(rest, room).len();
        // Break at the last space within the row; else cut the word.
        let cut = match rest[..end].rfind(' ') {
            Some(space) if space > 0 => space,
            _ => end,
        };
        row(indent, rest[..cut].trim_end());
        rest = rest[cut..].trim_start();
        if rest.is_empty() {
            return;
        }
        indent = WRAP_INDENT;
    }
}

/// The prefix of `text` that fits in `columns` characters.
pub fn fit(text: &str, columns: usize) -> &str {
    match text.char_indices().nth(columns) {
        Some((cut, _)) => &text[..cut],
        None => text,
    }
}

/// A line of text without a heap; what does not fit is cut.
struct TextBuffer<const N: usize> {
    bytes: [u8; N],
    len: usize,
}

impl<const N: usize> TextBuffer<N> {
    const fn new() -> Self {
        TextBuffer {
            bytes: [0; N],
            len: 0,
        }
    }

    fn as_str(&self) -> &str {
        // Only whole characters are copied in.
        core::str::from_utf8(&self.bytes[..self.len]).unwrap_or("")
    }
}

impl<const N: usize> core::fmt::Write for TextBuffer<N> {
    fn write_str(&mut self, text: &str) -> core::fmt::Result {
        let mut take = text.len().min(N - self.len);
        while !text.is_char_boundary(take) {
            take -= 1;
        }
        self.bytes[self.len..self.len + take].copy_from_slice(&text.as_bytes()[..take]);
        self.len += take;
        if take < text.len() {
            return Err(core::fmt::Error);
        }
        Ok(())
    }
}

/// The row above the log window: where the window is, and the keys.
pub fn hint_line(position: LogPosition, out: &mut impl core::fmt::Write) {
    let _ = core::write!(
        out,
        "log {}-{} of {}: arrows scroll, I leaves",
        position.first,
        position.last,
        position.total
    );
}

/// The report as text, for the QR code: the facts, one a line, then the log
/// window's lines, newest last. Log lines are left out, oldest first, until
/// the whole fits [`QR_TEXT_BYTES`]; facts and log lines are whole (the
/// screen wraps facts and cuts log lines). Returns the bytes written.
pub fn qr_text(report: &Report, out: &mut [u8]) -> usize {
    let facts = &report.facts[..report.facts.len().min(FACT_ROWS)];
    let log = &report.log[report.log.len().saturating_sub(LOG_ROWS)..];
    let limit = out.len().min(QR_TEXT_BYTES);
    let facts_bytes: usize = facts.iter().map(|f| f.len() + 1).sum();
    // The most recent log lines that fit after the facts.
    let mut room = limit.saturating_sub(facts_bytes);
    let mut first_log = log.len();
    while first_log > 0 && log[first_log - 1].len() < room {
        room -= log[first_log - 1].len() + 1;
        first_log -= 1;
    }
    let mut len = 0;
    let mut put = |text: &str| {
        for &byte in text.as_bytes().iter().chain(b"\n") {
            if len < limit {
                out[len] = byte;
                len += 1;
            }
        }
    };
    for fact in facts {
        put(fact);
    }
    for line in &log[first_log..] {
        put(line);
    }
    // No trailing newline after the last line.
    if len > 0 && out[len - 1] == b'\n' {
        len -= 1;
    }
    len
}

/// Encodes `text` (at most [`QR_TEXT_BYTES`]) and hands the code to `use_code`;
/// `None` if it does not fit version [`QR_MAX_VERSION`].
pub fn with_qr_code<T>(text: &[u8], use_code: impl FnOnce(&QrCode) -> T) -> Option<T> {
    let text = &text[..text.len().min(QR_TEXT_BYTES)];
    encode_qr::<QR_BUFFER_BYTES, T>(text, QR_MAX_VERSION, use_code)
}

/// Encodes `text` in byte mode, low error correction, as a code of at most
/// `max_version`, with the encoder's buffers (`BUFFER` bytes each, at least
/// `Version::new(max_version).buffer_len()`) on the stack, and hands the
/// code to `use_code`; `None` if it does not fit. No heap: the report
/// screen and the fault panel both use it.
pub fn encode_qr<const BUFFER: usize, T>(
    text: &[u8],
    max_version: u8,
    use_code: impl FnOnce(&QrCode) -> T,
) -> Option<T> {
    let mut data = [0u8; BUFFER];
    let mut out = [0u8; BUFFER];
    let len = text.len().min(BUFFER);
    data[..len].copy_from_slice(&text[..len]);
    let code = QrCode::encode_binary(
        &mut data,
        len,
        &mut out,
        QrCodeEcc::Low,
        Version::MIN,
        Version::new(max_version),
        None,
        true,
    )
    .ok()?;
    Some(use_code(&code))
}

/// Where the code of `size` modules sits: its top-left module, so that the
/// code and its quiet zone end at the screen's bottom-right corner.
pub fn qr_origin(size: i32) -> Point {
    let side = size + 2 * QR_QUIET_MODULES;
    Point::new(
        SCREEN_WIDTH - side + QR_QUIET_MODULES,
        SCREEN_HEIGHT - side + QR_QUIET_MODULES,
    )
}

/// The fact rows as drawn: each fact wrapped at [`FACT_COLUMNS`] ([`wrap`]),
/// one after the other, up to [`FACT_ROWS`] rows; `row` gets the row, the
/// indent and the text.
pub fn each_fact_row(facts: &[&str], mut row: impl FnMut(usize, usize, &str)) {
    let mut next = 0;
    for fact in facts {
        wrap(fact, FACT_COLUMNS, |indent, text| {
            if next < FACT_ROWS {
                row(next, indent, text);
            }
            next += 1;
        });
    }
}

/// Draws the report into `image` (a RAM image of a page).
pub fn draw(image: &mut PageImage, report: &Report) {
    image.fill(BLACK);
    let mut canvas = ImageCanvas::new(image);
    let fact_style = MonoTextStyle::new(FACT_FONT, PaletteIndex(WHITE));
    let log_style = MonoTextStyle::new(LOG_FONT, PaletteIndex(WHITE));
    {
        let mut facts = canvas.clipped(&FACTS_AREA);
        each_fact_row(report.facts, |row, indent, text| {
            let at = Point::new(1 + indent as i32 * 6, FACTS_TOP + row as i32 * 10);
            let _ = Text::with_baseline(text, at, fact_style, Baseline::Top).draw(&mut facts);
        });
    }
    {
        let mut log = canvas.clipped(&LOG_AREA);
        let mut hint = TextBuffer::<96>::new();
        hint_line(report.position, &mut hint);
        let at = Point::new(LOG_LEFT, LOG_AREA_TOP);
        let _ = Text::with_baseline(
            fit(hint.as_str(), LOG_COLUMNS),
            at,
            log_style,
            Baseline::Top,
        )
        .draw(&mut log);
        let shown = &report.log[report.log.len().saturating_sub(LOG_ROWS)..];
        for (row, line) in shown.iter().enumerate() {
            let at = Point::new(LOG_LEFT, LOG_TOP + row as i32 * 8);
            let _ = Text::with_baseline(fit(line, LOG_COLUMNS), at, log_style, Baseline::Top)
                .draw(&mut log);
        }
    }
    let mut text = [0u8; QR_TEXT_BYTES];
    let len = qr_text(report, &mut text);
    let mut qr = canvas.clipped(&QR_AREA);
    let drawn = with_qr_code(&text[..len], |code| draw_qr_code(&mut qr, code));
    if drawn.is_none() {
        // Cannot happen (the text is cut to what version 23 holds), but the
        // screen says so rather than leaving a hole.
        let _ = Text::with_baseline("no QR code", QR_AREA.top_left, log_style, Baseline::Top)
            .draw(&mut qr);
    }
}

fn draw_qr_code(target: &mut impl DrawTarget<Color = PaletteIndex>, code: &QrCode) {
    let size = code.size();
    let origin = qr_origin(size);
    let quiet = Rectangle::new(
        origin - Point::new(QR_QUIET_MODULES, QR_QUIET_MODULES),
        Size::new(
            (size + 2 * QR_QUIET_MODULES) as u32,
            (size + 2 * QR_QUIET_MODULES) as u32,
        ),
    );
    let _ = target.fill_solid(&quiet, PaletteIndex(WHITE));
    let modules = (0..size).flat_map(|y| (0..size).map(move |x| (x, y)));
    let _ = target.draw_iter(
        modules
            .filter(|&(x, y)| code.get_module(x, y))
            .map(|(x, y)| Pixel(origin + Point::new(x, y), PaletteIndex(BLACK))),
    );
}

/// Shows the report: black and white into their DAC entries, the report
/// drawn into `image` (scratch) and written to [`REPORT_PAGE`], which is then
/// shown. Pages 0 and 1 are not touched.
pub fn show<B: VgaBus>(vga: &mut ModeX<B>, image: &mut PageImage, report: &Report) -> FlipReport {
    vga.load_palette(BLACK, &[BLACK_RGB]);
    vga.load_palette(WHITE, &[WHITE_RGB]);
    draw(image, report);
    vga.write_page(REPORT_PAGE, image);
    vga.show_page(REPORT_PAGE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use modex::soft::SoftVga;
    use modex::{PAGE_BYTES, PAGE_PIXELS};
    use std::boxed::Box;
    use std::string::String;
    use std::vec::Vec;

    fn soft_vga_in_mode_x() -> Box<SoftVga> {
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        soft
    }

    fn screen(soft: &SoftVga) -> Vec<u8> {
        let mut pixels = std::vec![0; PAGE_PIXELS];
        assert_eq!(soft.scanout_indices(&mut pixels), (320, 240));
        pixels
    }

    fn qr_pixels(text: &[u8]) -> Vec<(Point, u8)> {
        with_qr_code(text, |code| {
            let origin = qr_origin(code.size());
            let mut pixels = Vec::new();
            for y in -QR_QUIET_MODULES..code.size() + QR_QUIET_MODULES {
                for x in -QR_QUIET_MODULES..code.size() + QR_QUIET_MODULES {
                    let dark = code.get_module(x, y);
                    pixels.push((origin + Point::new(x, y), if dark { BLACK } else { WHITE }));
                }
            }
            pixels
        })
        .expect("the text fits")
    }

    fn long_report_lines() -> (Vec<String>, Vec<String>) {
        let brand = "X".repeat(48); // a brand string with no terminator, in full
        let mut facts = std::vec![
            String::from("modex-cube 0.1.0, commit 0123456789ab"),
            String::from("firmware: UEFI"),
            std::format!("cpu: GenuineIntel, {brand}"),
        ];
        // Many PCI devices on one line, far longer than the screen.
        let mut adapters = String::from("adapter:");
        for n in 0..40 {
            adapters += &std::format!(" PCI {n:04x}:ffff (unknown)");
        }
        facts.push(adapters);
        facts.extend((0..20).map(|n| std::format!("fact {n}: {}", "y".repeat(200))));
        let log = (0..300)
            .map(|n| std::format!("line {n}: {}", "z".repeat(n % 130)))
            .collect();
        (facts, log)
    }

    #[test]
    fn long_values_never_draw_outside_the_report_page_or_over_the_code() {
        let (facts, log) = long_report_lines();
        let facts: Vec<&str> = facts.iter().map(String::as_str).collect();
        let log: Vec<&str> = log.iter().map(String::as_str).collect();
        let report = Report {
            facts: &facts,
            log: &log,
            position: LogPosition {
                first: 287,
                last: 300,
                total: 300,
            },
        };
        let mut soft = soft_vga_in_mode_x();
        let start = REPORT_PAGE.base();
        soft.set_write_guard(Some(start..start + PAGE_BYTES));
        let mut image = Box::new([0u8; PAGE_PIXELS]);
        show(&mut ModeX::new(&mut *soft), &mut image, &report);
        assert_eq!(soft.guard_violations(), 0, "{:?}", soft.first_violation());
        let shown = screen(&soft);
        assert!(
            shown == image[..],
            "page 2 is on screen and holds the image"
        );
        // The code is exactly the QR code of the report's text: no text
        // pixel landed on it.
        let mut text = [0u8; QR_TEXT_BYTES];
        let len = qr_text(&report, &mut text);
        assert!(len > 900, "the text fills the code: {len} bytes");
        for (point, colour) in qr_pixels(&text[..len]) {
            let index = (point.y * SCREEN_WIDTH + point.x) as usize;
            assert_eq!(shown[index], colour, "at {point:?}");
        }
        // Every text row stays inside its columns.
        each_fact_row(&facts, |_, indent, text| {
            assert!(indent + text.chars().count() <= FACT_COLUMNS, "{text:?}");
        });
    }

    #[test]
    fn facts_wrap_at_spaces_and_lose_no_word() {
        let columns = 20;
        let texts = [
            "short",
            "clock: TSC 1992.000 MHz by the PM timer, within 20 ppm",
            "a-word-longer-than-any-row-of-twenty and more",
            "exactly twenty chars",
            "   leading spaces and  double  spaces",
        ];
        for text in texts {
            let mut rows = std::vec::Vec::new();
            wrap(text, columns, |indent, row| {
                rows.push((indent, std::string::String::from(row)))
            });
            for (number, (indent, row)) in rows.iter().enumerate() {
                assert_eq!(*indent, if number == 0 { 0 } else { WRAP_INDENT });
                assert!(
                    indent + row.chars().count() <= columns,
                    "{row:?} of {text:?}"
                );
            }
            let words: std::vec::Vec<&str> = text.split_whitespace().collect();
            let joined = rows
                .iter()
                .map(|(_, row)| row.as_str())
                .collect::<std::vec::Vec<_>>()
                .join(" ");
            let rejoined: std::vec::Vec<&str> = joined.split_whitespace().collect();
            if text
                .split_whitespace()
                .all(|word| word.len() <= columns - WRAP_INDENT)
            {
                // No word cut: the rows hold exactly the words, in order.
                assert_eq!(rejoined, words, "{text:?}");
                // And no row ends mid-word.
                for (_, row) in &rows {
                    for word in row.split_whitespace() {
                        assert!(words.contains(&word), "{word:?} of {text:?}");
                    }
                }
            } else {
                assert_eq!(rejoined.concat(), words.concat(), "{text:?}");
            }
        }
    }

    #[test]
    fn the_qr_text_is_the_facts_then_the_newest_log_lines_that_fit() {
        let facts = ["one", "two"];
        let log = ["old", "middle", "new"];
        let report = Report {
            facts: &facts,
            log: &log,
            position: LogPosition::default(),
        };
        let mut out = [0u8; QR_TEXT_BYTES];
        let len = qr_text(&report, &mut out);
        assert_eq!(&out[..len], b"one\ntwo\nold\nmiddle\nnew");
        // With room for the facts and only the newest line.
        let mut small = [0u8; 12];
        let len = qr_text(&report, &mut small);
        assert_eq!(&small[..len], b"one\ntwo\nnew");
    }

    #[test]
    fn fit_cuts_at_a_character_count() {
        assert_eq!(fit("abcdef", 3), "abc");
        assert_eq!(fit("ab", 3), "ab");
        assert_eq!(fit("ééé", 2), "éé");
    }
}
