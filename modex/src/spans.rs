//! Where a picture in RAM can differ from the background: the spans drawn
//! into it, kept as the groups of sixteen pixels (four byte addresses, the
//! unit the page update compares at once) that each line's spans touch.
//!
//! The renderer marks every span it fills in the frame it draws, and each
//! page keeps the marks of the frame it was last given. Everywhere else both
//! hold the background, so [`ModeX::update_page`](crate::ModeX::update_page)
//! compares only the union of the two and never reads the rest. The depth
//! buffer keeps marks of its own the same way, so that only the depths
//! written are cleared.

use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};
use core::ops::Range;

/// Pixels in a group: four addresses of four pixels, sixteen bytes of a
/// picture in RAM, which the page update compares with one instruction.
pub const GROUP_PIXELS: usize = 16;
/// The groups of a line: 20.
const GROUPS: usize = SCREEN_WIDTH as usize / GROUP_PIXELS;
/// The marks of a line, one bit per group.
type LineMarks = u32;

/// The marked groups of sixteen pixels of each of `LINES` lines of
/// `SCREEN_WIDTH` pixels: one bit per group, exact to the group, not a
/// bounding rectangle. Three spans apart on a line are three runs of bits.
///
/// A group is the page update's unit of reading: it compares sixteen
/// pixels at a time, so marks finer than a group would be read in whole
/// groups anyway, and coarser bookkeeping is four times smaller to merge,
/// copy and walk.
#[derive(Clone, PartialEq, Eq)]
pub struct LineSpans<const LINES: usize> {
    lines: [LineMarks; LINES],
}

/// The marks of a whole page's lines.
pub type PageSpans = LineSpans<{ SCREEN_HEIGHT as usize }>;

/// Every group of a line.
const LINE_GROUPS: LineMarks = (1 << GROUPS) - 1;
const WIDTH: usize = SCREEN_WIDTH as usize;
const _: () = assert!(WIDTH == GROUPS * GROUP_PIXELS && GROUPS <= LineMarks::BITS as usize);
const _: () = assert!(GROUP_PIXELS == 4 * (BYTES_PER_LINE as usize / GROUPS));

/// Counts the marked groups rather than listing 960 bytes of bits.
impl<const LINES: usize> core::fmt::Debug for LineSpans<LINES> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let marked: u32 = self.lines.iter().map(|bits| bits.count_ones()).sum();
        f.debug_struct("LineSpans")
            .field("marked_groups", &marked)
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

    /// Every pixel of every line: a picture nothing is known of.
    pub fn all() -> Self {
        let mut spans = Self::none();
        spans.mark_all();
        spans
    }

    /// Unmarks everything.
    pub fn clear(&mut self) {
        self.lines.fill(0);
    }

    /// Marks every pixel of every line.
    pub fn mark_all(&mut self) {
        self.lines.fill(LINE_GROUPS);
    }

    /// Marks the groups that pixels `pixels` of line `line` lie in.
    /// Pixels past the line's end, and lines past the last, are left out.
    /// (An empty range within a group marks that group: a mark says only
    /// that a pixel may differ, and the renderer marks no empty span.)
    #[inline]
    pub fn mark(&mut self, line: usize, pixels: Range<usize>) {
        let first = pixels.start / GROUP_PIXELS;
        let end = pixels.end.div_ceil(GROUP_PIXELS).min(GROUPS);
        if let (true, Some(bits)) = (first < end, self.lines.get_mut(line)) {
            *bits |= (1 << end) - (1 << first);
        }
    }

    /// Marks everything `other` marks.
    pub fn add(&mut self, other: &Self) {
        for (bits, more) in self.lines.iter_mut().zip(&other.lines) {
            *bits |= more;
        }
    }

    /// The marked groups of line `line`, bit i for pixels 16i to 16i + 15
    /// (none for a line past the last): what the page update walks.
    pub(crate) fn marked(&self, line: usize) -> LineMarks {
        self.lines.get(line).copied().unwrap_or(0)
    }

    /// The marked pixels of line `line`, as runs of neighbouring pixels,
    /// left to right, each a whole number of groups; runs that touch are
    /// one run.
    pub fn runs(&self, line: usize) -> impl Iterator<Item = Range<usize>> {
        let mut bits = self.marked(line);
        core::iter::from_fn(move || {
            if bits == 0 {
                return None;
            }
            // Adding the lowest set bit carries through the lowest run and
            // stops on the bit past it; at most 20 bits are set, so the sum
            // fits.
            let start = bits.trailing_zeros() as usize;
            let past = bits + bits.isolate_lowest_one();
            bits &= past;
            Some(GROUP_PIXELS * start..GROUP_PIXELS * past.trailing_zeros() as usize)
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
                if let Some(run) = pixels.get_mut(row * WIDTH + run.start..row * WIDTH + run.end) {
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
                let pixels = line * WIDTH + run.start..line * WIDTH + run.end;
                if let (Some(from), Some(to)) = (from.get(pixels.clone()), to.get_mut(pixels)) {
                    to.copy_from_slice(from);
                }
            }
        }
    }
}
