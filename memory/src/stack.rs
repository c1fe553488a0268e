//! The kernel stack's high-water mark. At boot the kernel paints its unused
//! stack with [`PAINT`]; the stack grows down, so however deep it has ever
//! reached, the paint from the bottom up to that point is intact, and the
//! first word that is not paint marks the deepest use. The kernel reads the
//! words; this module decides what they mean and how the line reads.
//!
//! # Example
//!
//! ```
//! use memory::stack::{unpainted_from, StackUse, PAINT};
//!
//! // A 64-byte stack whose top three words were used.
//! let words = [PAINT, PAINT, PAINT, PAINT, PAINT, 7, 0, PAINT];
//! let used = StackUse::new(64, unpainted_from(words));
//! assert_eq!(used.used, 24);
//! assert_eq!(used.to_string(), "stack: 24 of 64 bytes used at most (37%)");
//! assert_eq!(StackUse::parse(&used.to_string()), Some(used));
//! assert!(used.at_most_half());
//! ```

use core::fmt;
use core::ops::Range;

/// The word the unused stack is painted with: unlikely as an address, a
/// count or a float, so a frame rarely leaves it in place by chance.
pub const PAINT: u64 = 0x57AC_C0DE_57AC_C0DE;

/// Bytes per painted word.
pub const WORD_BYTES: u64 = 8;

/// Bytes below the painter's own frame left unpainted: the painting loop and
/// anything it calls stay above this.
pub const PAINT_MARGIN: u64 = 4096;

/// The addresses to paint, given the stack's bottom and length and the
/// address of a local variable of the painting function (just above where
/// the stack is in use): from the bottom up to [`PAINT_MARGIN`] below that
/// local, word-aligned, and nothing if the local is not inside the stack.
pub fn paint_range(bottom: u64, len: u64, local: u64) -> Range<u64> {
    let top = bottom.saturating_add(len);
    if !(bottom..top).contains(&local) {
        return bottom..bottom;
    }
    let end = local.saturating_sub(PAINT_MARGIN) & !(WORD_BYTES - 1);
    bottom..end.max(bottom)
}

/// How many bytes from the bottom of the stack still hold the paint: the
/// words from the bottom up until the first that is not [`PAINT`].
pub fn unpainted_from(words: impl IntoIterator<Item = u64>) -> u64 {
    words.into_iter().take_while(|&word| word == PAINT).count() as u64 * WORD_BYTES
}

/// The most of the stack ever used.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StackUse {
    /// Bytes used at the deepest point (the stack's size less the paint left).
    pub used: u64,
    /// The stack's size in bytes.
    pub size: u64,
}

impl StackUse {
    /// The line's start, for finding it on serial.
    pub const PREFIX: &'static str = "stack: ";

    /// The use of a stack of `size` bytes whose lowest `still_painted` bytes
    /// were never touched.
    pub fn new(size: u64, still_painted: u64) -> StackUse {
        StackUse {
            used: size.saturating_sub(still_painted),
            size,
        }
    }

    /// Whether at most half the stack was ever used: the margin the kernel
    /// keeps, so that a deeper frame than any test has seen still fits.
    pub fn at_most_half(&self) -> bool {
        self.used.saturating_mul(2) <= self.size
    }

    /// The use a line from [`fmt::Display`] reports, if `line` holds one.
    pub fn parse(line: &str) -> Option<StackUse> {
        let rest = &line[line.find(Self::PREFIX)? + Self::PREFIX.len()..];
        let mut words = rest.split(' ');
        let used = words.next()?.parse().ok()?;
        let size = words.nth(1)?.parse().ok()?;
        Some(StackUse { used, size })
    }
}

impl fmt::Display for StackUse {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let percent = self.used.saturating_mul(100) / self.size.max(1);
        write!(
            f,
            "{}{} of {} bytes used at most ({}%)",
            Self::PREFIX,
            self.used,
            self.size,
            percent
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn paint_stops_a_margin_below_the_painter() {
        let bottom = 0x10_0000;
        let range = paint_range(bottom, 0x10_0000, 0x1F_F123);
        assert_eq!(range.start, bottom);
        assert_eq!(range.end, (0x1F_F123 - PAINT_MARGIN) & !7);
        // A local outside the stack (another stack, a bad address): nothing.
        assert!(paint_range(bottom, 0x1000, 0x5000).is_empty());
        assert!(paint_range(bottom, 0x1000, bottom - 8).is_empty());
        // A local too near the bottom to leave the margin: nothing either.
        assert!(paint_range(bottom, 0x1000, bottom + 16).is_empty());
    }

    #[test]
    fn the_first_word_that_is_not_paint_ends_the_untouched_part() {
        assert_eq!(unpainted_from([PAINT, PAINT, 0, PAINT]), 16);
        assert_eq!(unpainted_from([1, PAINT]), 0);
        assert_eq!(unpainted_from([PAINT; 4]), 32);
    }

    #[test]
    fn more_than_half_is_caught() {
        assert!(StackUse::new(1024, 512).at_most_half());
        assert!(!StackUse::new(1024, 504).at_most_half());
        assert_eq!(StackUse::new(1024, 2048).used, 0);
    }

    #[test]
    fn the_line_reads_back() {
        let used = StackUse::new(1 << 20, 700_000);
        let line = std::format!("[serial] {used}");
        assert_eq!(StackUse::parse(&line), Some(used));
        assert_eq!(StackUse::parse("stack: many"), None);
        assert_eq!(StackUse::parse("kernel: initialised"), None);
        assert!(used.to_string().starts_with(StackUse::PREFIX));
    }
}
