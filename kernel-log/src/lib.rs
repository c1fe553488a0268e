//! The kernel's log kept in memory: every line that goes to serial is also
//! kept here, in a fixed ring of lines (no allocation), so the report screen
//! and the fault panel can show it on PCs that have no serial port.
//!
//! The ring holds `LINES` lines of at most `BYTES` bytes each. When it is
//! full, the oldest line is dropped and counted; a longer line is cut at
//! `BYTES` and counted. Text arrives in pieces (`core::fmt::Write`), and a
//! line is complete at its `\n`. Only printable ASCII is kept (anything else
//! becomes `?`), so every line is valid text of a known length, whatever the
//! writer sent.
//!
//! Every index is taken modulo the capacity and every length is clamped, so
//! even a ring whose update was cut short (a fault in the middle of a write,
//! after which the fault handler reads it anyway) can only yield a garbled
//! line, never a read out of bounds.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

use core::fmt;

/// The kernel's ring: 256 lines of up to 120 bytes (about 31 KiB).
pub type KernelLog = LogRing<256, 120>;

/// One line of text built without a heap: its first `len` bytes, all
/// printable ASCII (anything else becomes `?`), text past `BYTES` cut. The log's lines, the
/// statistics lines of the on-screen display and the fault panel's lines are
/// all this one type.
#[derive(Clone, Copy)]
pub struct LogLine<const BYTES: usize> {
    bytes: [u8; BYTES],
    len: usize,
}

impl<const BYTES: usize> LogLine<BYTES> {
    /// An empty line.
    pub const fn new() -> Self {
        LogLine {
            // Never read past `len`; zeros keep an empty log's static in
            // .bss, out of the kernel file.
            bytes: [0; BYTES],
            len: 0,
        }
    }

    /// The line's text.
    pub fn as_str(&self) -> &str {
        let len = self.len.min(BYTES);
        // Only printable ASCII is ever stored, so this cannot fail.
        core::str::from_utf8(&self.bytes[..len]).unwrap_or("?")
    }

    /// Appends `byte` (non-printable bytes become `?`); false if the line is
    /// full and the byte was cut.
    fn push(&mut self, byte: u8) -> bool {
        if self.len >= BYTES {
            return false;
        }
        self.bytes[self.len] = printable(byte);
        self.len += 1;
        true
    }
}

impl<const BYTES: usize> core::ops::Deref for LogLine<BYTES> {
    type Target = str;
    fn deref(&self) -> &str {
        self.as_str()
    }
}

impl<const BYTES: usize> Default for LogLine<BYTES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const BYTES: usize> fmt::Debug for LogLine<BYTES> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Debug::fmt(self.as_str(), f)
    }
}

impl<const BYTES: usize> fmt::Write for LogLine<BYTES> {
    /// Appends `text`; what does not fit is cut.
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for byte in text.bytes() {
            if !self.push(byte) {
                break;
            }
        }
        Ok(())
    }
}

/// `byte` if it is printable ASCII, else `?`.
pub const fn printable(byte: u8) -> u8 {
    if byte.is_ascii_graphic() || byte == b' ' {
        byte
    } else {
        b'?'
    }
}

/// The text of a fixed-size field such as CPUID's brand string: up to the
/// first NUL (or the whole field if it has none), then up to the first byte
/// that is not printable ASCII, without leading or trailing spaces. Never
/// reads past `bytes`.
pub fn text_of_field(bytes: &[u8]) -> &str {
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    let field = &bytes[..end];
    let printable = field
        .iter()
        .position(|&b| printable(b) != b)
        .unwrap_or(field.len());
    // All ASCII up to `printable`, so this cannot fail.
    core::str::from_utf8(&field[..printable])
        .unwrap_or("")
        .trim()
}

/// Where a [`LogRing::window`] is: lines `first..=last` (from 1, oldest
/// first; `first` is 0 for an empty window) of `total`, scrolled back
/// `scroll` lines from the newest.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Window {
    /// Lines back from the newest, as clamped.
    pub scroll: usize,
    /// The first line in the window, from 1.
    pub first: usize,
    /// The last line in the window.
    pub last: usize,
    /// Lines not skipped.
    pub total: usize,
}

/// A fixed ring of the last `LINES` complete lines, plus the one being written.
#[derive(Clone)]
pub struct LogRing<const LINES: usize, const BYTES: usize> {
    lines: [LogLine<BYTES>; LINES],
    /// The slot the next complete line goes into.
    next: usize,
    /// Complete lines held, at most `LINES`.
    held: usize,
    /// The line being written, until its `\n`.
    partial: LogLine<BYTES>,
    partial_cut: bool,
    dropped: u64,
    cut: u64,
}

impl<const LINES: usize, const BYTES: usize> fmt::Debug for LogRing<LINES, BYTES> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LogRing")
            .field("held", &self.held)
            .field("dropped", &self.dropped)
            .field("cut", &self.cut)
            .finish_non_exhaustive()
    }
}

impl<const LINES: usize, const BYTES: usize> Default for LogRing<LINES, BYTES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const LINES: usize, const BYTES: usize> LogRing<LINES, BYTES> {
    /// An empty ring; `const`, so the kernel's lives in a static.
    pub const fn new() -> Self {
        LogRing {
            lines: [const { LogLine::new() }; LINES],
            next: 0,
            held: 0,
            partial: LogLine::new(),
            partial_cut: false,
            dropped: 0,
            cut: 0,
        }
    }

    /// Complete lines held.
    pub fn len(&self) -> usize {
        self.held.min(LINES)
    }

    /// No complete line yet.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Lines dropped because the ring was full (the oldest go first).
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Lines cut because they were longer than `BYTES`.
    pub fn cut(&self) -> u64 {
        self.cut
    }

    /// The `back`th line from the newest (0 is the newest), if held.
    pub fn newest(&self, back: usize) -> Option<&str> {
        if LINES == 0 || back >= self.len() {
            return None;
        }
        let slot = (self.next % LINES + LINES - 1 - back) % LINES;
        Some(self.lines[slot].as_str())
    }

    /// The lines, newest first.
    pub fn newest_first(&self) -> impl Iterator<Item = &str> {
        (0..self.len()).filter_map(move |back| self.newest(back))
    }

    /// The lines, oldest first.
    pub fn oldest_first(&self) -> impl Iterator<Item = &str> {
        (0..self.len())
            .rev()
            .filter_map(move |back| self.newest(back))
    }

    /// The `nth` newest line (0 is the newest) that starts with `prefix`.
    pub fn latest_with_prefix(&self, prefix: &str, nth: usize) -> Option<&str> {
        self.latest_with_any_prefix(&[prefix], nth)
    }

    /// The `nth` newest line that starts with one of `prefixes`.
    pub fn latest_with_any_prefix(&self, prefixes: &[&str], nth: usize) -> Option<&str> {
        self.newest_first()
            .filter(|line| prefixes.iter().any(|prefix| line.starts_with(prefix)))
            .nth(nth)
    }

    /// A window of `rows` lines, scrolled back `scroll` lines from the newest
    /// (clamped so the window stays full where the log allows), leaving out
    /// the lines `skip` picks: `each` gets its lines, oldest first.
    pub fn window<'a>(
        &'a self,
        skip: impl Fn(&str) -> bool,
        scroll: usize,
        rows: usize,
        mut each: impl FnMut(&'a str),
    ) -> Window {
        let total = self.oldest_first().filter(|line| !skip(line)).count();
        let scroll = scroll.min(total.saturating_sub(rows));
        let shown = rows.min(total - scroll);
        // Counted from the oldest, the window is [total - scroll - shown, total - scroll).
        let start = total - scroll - shown;
        for line in self
            .oldest_first()
            .filter(|line| !skip(line))
            .skip(start)
            .take(shown)
        {
            each(line);
        }
        Window {
            scroll,
            first: if shown == 0 { 0 } else { start + 1 },
            last: start + shown,
            total,
        }
    }

    /// The `nth` oldest line that starts with one of `prefixes`.
    pub fn earliest_with_any_prefix(&self, prefixes: &[&str], nth: usize) -> Option<&str> {
        self.oldest_first()
            .filter(|line| prefixes.iter().any(|prefix| line.starts_with(prefix)))
            .nth(nth)
    }

    /// Adds one byte of text; `\n` completes the line, `\r` is ignored.
    pub fn push_byte(&mut self, byte: u8) {
        match byte {
            b'\n' => self.complete_line(),
            b'\r' => {}
            _ => {
                if !self.partial.push(byte) {
                    self.partial_cut = true;
                }
            }
        }
    }

    fn complete_line(&mut self) {
        if self.partial_cut {
            self.cut += 1;
        }
        if LINES > 0 {
            let slot = self.next % LINES;
            self.lines[slot] = self.partial;
            self.next = (slot + 1) % LINES;
            if self.held >= LINES {
                self.dropped += 1;
            } else {
                self.held += 1;
            }
        } else {
            self.dropped += 1;
        }
        self.partial = LogLine::new();
        self.partial_cut = false;
    }
}

impl<const LINES: usize, const BYTES: usize> fmt::Write for LogRing<LINES, BYTES> {
    fn write_str(&mut self, text: &str) -> fmt::Result {
        for byte in text.bytes() {
            self.push_byte(byte);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::fmt::Write;
    use std::string::String;
    use std::vec::Vec;

    fn lines<const L: usize, const B: usize>(ring: &LogRing<L, B>) -> Vec<String> {
        ring.oldest_first().map(String::from).collect()
    }

    #[test]
    fn lines_are_kept_in_order_until_the_ring_is_full() {
        let mut ring = LogRing::<4, 16>::new();
        assert!(ring.is_empty());
        writeln!(ring, "one").unwrap();
        write!(ring, "t").unwrap();
        write!(ring, "wo\r\n").unwrap();
        assert_eq!(lines(&ring), ["one", "two"]);
        assert_eq!(ring.newest(0), Some("two"));
        assert_eq!(ring.newest(1), Some("one"));
        assert_eq!(ring.newest(2), None);
        assert_eq!(ring.dropped(), 0);
    }

    #[test]
    fn the_ring_wraps_dropping_and_counting_the_oldest() {
        let mut ring = LogRing::<4, 16>::new();
        for n in 0..11 {
            writeln!(ring, "line {n}").unwrap();
        }
        assert_eq!(ring.len(), 4);
        assert_eq!(ring.dropped(), 7);
        assert_eq!(lines(&ring), ["line 7", "line 8", "line 9", "line 10"]);
        let newest: Vec<&str> = ring.newest_first().collect();
        assert_eq!(newest, ["line 10", "line 9", "line 8", "line 7"]);
        // Many more turns: the count keeps going, the order holds.
        for n in 11..1003 {
            writeln!(ring, "line {n}").unwrap();
        }
        assert_eq!(ring.dropped(), 999);
        assert_eq!(
            lines(&ring),
            ["line 999", "line 1000", "line 1001", "line 1002"]
        );
    }

    #[test]
    fn a_long_line_is_cut_and_counted_and_the_next_starts_clean() {
        let mut ring = LogRing::<4, 8>::new();
        writeln!(ring, "{}", "x".repeat(1000)).unwrap();
        writeln!(ring, "short").unwrap();
        assert_eq!(lines(&ring), ["xxxxxxxx", "short"]);
        assert_eq!(ring.cut(), 1);
    }

    #[test]
    fn only_printable_ascii_is_kept() {
        let mut ring = LogRing::<4, 32>::new();
        writeln!(ring, "tab\there é\u{7}").unwrap();
        // 'é' is two bytes of UTF-8: each becomes '?'.
        assert_eq!(lines(&ring), ["tab?here ???"]);
    }

    #[test]
    fn a_partial_line_is_not_shown_until_complete() {
        let mut ring = LogRing::<4, 32>::new();
        write!(ring, "half").unwrap();
        assert!(ring.is_empty());
        writeln!(ring).unwrap();
        assert_eq!(lines(&ring), ["half"]);
    }

    #[test]
    fn the_latest_line_with_a_prefix_is_found() {
        let mut ring = LogRing::<8, 32>::new();
        for line in ["clock: slow", "vga: a", "clock: fast", "vga: b", "other"] {
            writeln!(ring, "{line}").unwrap();
        }
        assert_eq!(ring.latest_with_prefix("clock:", 0), Some("clock: fast"));
        assert_eq!(ring.latest_with_prefix("vga:", 1), Some("vga: a"));
        assert_eq!(ring.latest_with_prefix("vga:", 2), None);
        assert_eq!(ring.latest_with_prefix("usb:", 0), None);
        assert_eq!(
            ring.latest_with_any_prefix(&["usb:", "clock:"], 0),
            Some("clock: fast")
        );
        assert_eq!(
            ring.earliest_with_any_prefix(&["vga:", "clock:"], 1),
            Some("vga: a")
        );
    }

    #[test]
    fn the_window_scrolls_within_the_log_and_skips_what_it_is_told() {
        let mut ring = LogRing::<8, 32>::new();
        for n in 1..=10 {
            writeln!(ring, "line {n}").unwrap();
            writeln!(ring, "echo {n}").unwrap();
        }
        // Held: line 7, echo 7, ... line 10, echo 10; echoes skipped.
        let echo = |line: &str| line.starts_with("echo");
        let mut seen = Vec::new();
        let window = ring.window(echo, 0, 3, |line| seen.push(String::from(line)));
        assert_eq!(seen, ["line 8", "line 9", "line 10"]);
        assert_eq!(
            window,
            Window {
                scroll: 0,
                first: 2,
                last: 4,
                total: 4
            }
        );
        seen.clear();
        let window = ring.window(echo, 99, 3, |line| seen.push(String::from(line)));
        assert_eq!(seen, ["line 7", "line 8", "line 9"]);
        assert_eq!((window.scroll, window.first, window.last), (1, 1, 3));
        // A window taller than the log shows it all.
        seen.clear();
        let window = ring.window(echo, 5, 30, |line| seen.push(String::from(line)));
        assert_eq!(seen.len(), 4);
        assert_eq!((window.scroll, window.first, window.last), (0, 1, 4));
        let empty = LogRing::<8, 32>::new();
        let window = empty.window(echo, 3, 3, |_| panic!("nothing to show"));
        assert_eq!(window, Window::default());
    }

    #[test]
    fn a_garbled_ring_still_reads_within_bounds() {
        // As a fault handler might find it after a write cut short.
        let mut ring = LogRing::<4, 8>::new();
        ring.next = usize::MAX;
        ring.held = usize::MAX;
        ring.lines[1].len = usize::MAX;
        assert_eq!(ring.len(), 4);
        let all: Vec<&str> = ring.newest_first().collect();
        assert_eq!(all.len(), 4);
        assert!(all.iter().all(|line| line.len() <= 8));
        writeln!(ring, "ok").unwrap();
        assert_eq!(ring.newest(0), Some("ok"));
    }

    #[test]
    fn fields_are_cut_at_the_first_nul_or_unprintable_byte() {
        let mut brand = [0u8; 48];
        brand[..12].copy_from_slice(b"  QEMU CPU  ");
        assert_eq!(text_of_field(&brand), "QEMU CPU");
        // No terminator at all: the whole field, and never past it.
        let full = [b'A'; 48];
        assert_eq!(text_of_field(&full), "A".repeat(48));
        let odd = [b'o', b'k', 0xFF, b'x', 0];
        assert_eq!(text_of_field(&odd), "ok");
        assert_eq!(text_of_field(&[]), "");
    }
}
