//! Where a picture in RAM can differ from the background: the spans drawn
//! into it, kept as the byte addresses (quads of four pixels, the unit the
//! page update compares and writes) that each line's spans touch.
//!
//! The renderer marks every span it fills in the frame it draws, and each
//! page keeps the marks of the frame it was last given. Everywhere else both
//! hold the background, so [`ModeX::update_page`](crate::ModeX::update_page)
//! compares only the union of the two and never reads the rest. The depth
//! buffer keeps marks of its own the same way, so that only the depths
//! written are cleared.

use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};
use core::ops::Range;

/// The marked byte addresses of each of `LINES` lines of `SCREEN_WIDTH`
/// pixels: one bit per address, exact to the address, not a bounding
/// rectangle. Three spans on a line are three runs of bits.
#[derive(Clone, PartialEq, Eq)]
pub struct LineSpans<const LINES: usize> {
    lines: [u128; LINES],
}

/// The marks of a whole page's lines.
pub type PageSpans = LineSpans<{ SCREEN_HEIGHT as usize }>;

/// Every address of a line.
const LINE_ADDRESSES: u128 = (1 << BYTES_PER_LINE) - 1;
/// The addresses below n, for each n up to a line's end.
const ADDRESSES_BELOW: [u128; BYTES_PER_LINE as usize + 1] = {
    let mut below = [0; BYTES_PER_LINE as usize + 1];
    let mut n = 1;
    while n < below.len() {
        below[n] = (1 << n) - 1;
        n += 1;
    }
    below
};
const WIDTH: usize = SCREEN_WIDTH as usize;

/// Counts the marked addresses rather than listing 3.8 KiB of bits.
impl<const LINES: usize> core::fmt::Debug for LineSpans<LINES> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let marked: u32 = self.lines.iter().map(|bits| bits.count_ones()).sum();
        f.debug_struct("LineSpans")
            .field("marked_addresses", &marked)
            .finish()
    }
}

impl<const LINES: usize> Default for LineSpans<LINES> {
    fn default() -> Self {
        Self::none()
    }
}

impl<const LINES: usize> LineSpans<LINES> {
    /// Nothing marked: a picture that is all background.
    pub const fn none() -> Self {
        LineSpans { lines: [0; LINES] }
    }

    /// Every address of every line: a picture nothing is known of.
    pub fn all() -> Self {
        let mut spans = Self::none();
        spans.mark_all();
        spans
    }

    /// Unmarks everything.
    pub fn clear(&mut self) {
        self.lines.fill(0);
    }

    /// Marks every address of every line.
    pub fn mark_all(&mut self) {
        self.lines.fill(LINE_ADDRESSES);
    }

    /// Marks the addresses that pixels `pixels` of line `line` lie in.
    /// Pixels past the line's end, and lines past the last, are left out.
    /// (An empty range within an address marks that address: a mark says
    /// only that a pixel may differ, and the renderer marks no empty span.)
    #[inline]
    pub fn mark(&mut self, line: usize, pixels: Range<usize>) {
        let first = pixels.start / 4;
        let end = pixels.end.div_ceil(4).min(usize::from(BYTES_PER_LINE));
        if let (true, Some(bits)) = (first < end, self.lines.get_mut(line)) {
            // Two loads and a mask: the shifts of a u128 by a variable
            // count cost about twice that, and every span drawn is marked.
            *bits |= ADDRESSES_BELOW[end] & !ADDRESSES_BELOW[first];
        }
    }

    /// Marks everything `other` marks.
    pub fn add(&mut self, other: &Self) {
        for (bits, more) in self.lines.iter_mut().zip(&other.lines) {
            *bits |= more;
        }
    }

    /// The marked addresses of line `line`, bit i for address i (none for
    /// a line past the last): what the page update walks.
    pub(crate) fn marked(&self, line: usize) -> u128 {
        self.lines.get(line).copied().unwrap_or(0)
    }

    /// The marked addresses of line `line`, as runs of neighbouring
    /// addresses, left to right; runs that touch are one run.
    pub fn runs(&self, line: usize) -> impl Iterator<Item = Range<usize>> {
        let mut bits = self.marked(line);
        core::iter::from_fn(move || {
            if bits == 0 {
                return None;
            }
            // Adding the lowest set bit carries through the lowest run and
            // stops on the bit past it; at most 80 bits are set, so the sum
            // fits.
            let start = bits.trailing_zeros();
            let past = bits + bits.isolate_lowest_one();
            bits &= past;
            Some(start as usize..past.trailing_zeros() as usize)
        })
    }

    /// Sets every marked pixel of `pixels` (`LINES` lines of
    /// `SCREEN_WIDTH`, row by row) to `value`, and leaves the rest unread:
    /// how a picture goes back to the background, or a depth buffer back to
    /// nothing drawn, at the cost of what was drawn.
    pub fn fill<T: Copy>(&self, pixels: &mut [T], value: T) {
        self.fill_lines(0..LINES, pixels, value);
    }

    /// As [`LineSpans::fill`], for the lines `lines` only, `pixels` holding
    /// just those lines.
    pub fn fill_lines<T: Copy>(&self, lines: Range<usize>, pixels: &mut [T], value: T) {
        for (row, line) in lines.enumerate() {
            for run in self.runs(line) {
                if let Some(run) =
                    pixels.get_mut(row * WIDTH + 4 * run.start..row * WIDTH + 4 * run.end)
                {
                    run.fill(value);
                }
            }
        }
    }

    /// Copies every marked pixel of the lines `lines` of `from` into `to`
    /// (each `LINES` lines of `SCREEN_WIDTH`, row by row); the rest of `to`
    /// is left as it is.
    pub fn copy<T: Copy>(&self, lines: Range<usize>, from: &[T], to: &mut [T]) {
        for line in lines {
            for run in self.runs(line) {
                let pixels = line * WIDTH + 4 * run.start..line * WIDTH + 4 * run.end;
                if let (Some(from), Some(to)) = (from.get(pixels.clone()), to.get_mut(pixels)) {
                    to.copy_from_slice(from);
                }
            }
        }
    }
}
