//! Filled rectangles, spans, pixels and page clears in unchained memory.
//!
//! A horizontal run of pixels covers whole 4-pixel columns (one byte in each
//! plane) in its middle, written with all planes enabled, one byte per four
//! pixels; at its ragged ends the Map Mask enables only the covered planes.

use crate::regs::PlaneMask;
use crate::{ModeX, Page, VgaBus, BYTES_PER_LINE, PAGE_BYTES, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Pixels per byte address: one in each plane.
const PIXELS_PER_BYTE: i32 = 4;

/// Bytes on consecutive lines written through one Map Mask: a ragged edge
/// column or the whole-column middle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Run {
    /// First byte within the line.
    byte: u16,
    /// Bytes per line.
    bytes: u16,
    /// Map Mask.
    planes: PlaneMask,
}

/// The runs that cover [x0, x1) on a line, left to right; 0 < x1 - x0 and
/// both within the screen.
fn runs(x0: i32, x1: i32) -> [Option<Run>; 3] {
    let first = x0 / PIXELS_PER_BYTE;
    let last = (x1 - 1) / PIXELS_PER_BYTE;
    // Planes from x0's onwards, and up to and including x1 - 1's.
    let left_planes = PlaneMask::from_plane((x0 % PIXELS_PER_BYTE) as u8);
    let right_planes = PlaneMask::up_to_plane(((x1 - 1) % PIXELS_PER_BYTE) as u8);
    let column = |byte: i32, planes| Run {
        byte: byte as u16,
        bytes: 1,
        planes,
    };

    if first == last {
        return [Some(column(first, left_planes & right_planes)), None, None];
    }
    let (left, middle_start) = if left_planes == PlaneMask::ALL {
        (None, first)
    } else {
        (Some(column(first, left_planes)), first + 1)
    };
    let (right, middle_end) = if right_planes == PlaneMask::ALL {
        (None, last + 1)
    } else {
        (Some(column(last, right_planes)), last)
    };
    let middle = (middle_end > middle_start).then(|| Run {
        byte: middle_start as u16,
        bytes: (middle_end - middle_start) as u16,
        planes: PlaneMask::ALL,
    });
    [left, middle, right]
}

/// The part of [lo, hi) within [0, limit), if any.
fn clip(lo: i32, hi: i32, limit: i32) -> Option<(i32, i32)> {
    let (lo, hi) = (lo.max(0), hi.min(limit));
    (lo < hi).then_some((lo, hi))
}

/// Offset of line `y` (on screen) of `page` in the CPU window.
fn line_offset(page: Page, y: i32) -> u16 {
    page.base() + y as u16 * BYTES_PER_LINE
}

impl<B: VgaBus> ModeX<B> {
    /// Fills the half-open rectangle [x0, x1) x [y0, y1) of `page`, clipped to
    /// the screen; an empty or inverted rectangle draws nothing.
    ///
    /// # Example
    ///
    /// Four pixels a byte: a rectangle 5 to 11 wide writes its ragged edge
    /// columns through a narrower Map Mask, and its middle whole.
    ///
    /// ```
    /// use modex::soft::SoftVga;
    /// use modex::{ModeX, Page};
    ///
    /// let mut soft = Box::new(SoftVga::new());
    /// let mut vga = ModeX::new(&mut *soft);
    /// vga.set_mode();
    /// let before = vga.bus().counts();
    /// vga.fill_rect(Page::Zero, 5, 0, 11, 1, 9); // columns 5..11 of line 0
    /// let after = vga.bus().counts();
    /// // Bytes 1 (planes 1-3) and 2 (planes 0-2): two Map Masks, two bytes.
    /// assert_eq!(after.vram_writes - before.vram_writes, 2);
    /// assert_eq!(after.port_writes - before.port_writes, 2);
    /// let mut screen = vec![0u8; 320 * 240];
    /// soft.scanout_indices(&mut screen);
    /// assert_eq!(&screen[4..12], &[0, 9, 9, 9, 9, 9, 9, 0]);
    /// ```
    pub fn fill_rect(&mut self, page: Page, x0: i32, y0: i32, x1: i32, y1: i32, color: u8) {
        self.issued_by("ModeX::fill_rect", |vga| {
            let (Some((x0, x1)), Some((y0, y1))) =
                (clip(x0, x1, SCREEN_WIDTH), clip(y0, y1, SCREEN_HEIGHT))
            else {
                return;
            };
            vga.fill_runs(line_offset(page, y0), (y1 - y0) as u16, runs(x0, x1), color);
        })
    }

    /// Fills the half-open span [x0, x1) of line `y` of `page`, clipped to the screen.
    pub fn fill_span(&mut self, page: Page, y: i32, x0: i32, x1: i32, color: u8) {
        self.issued_by("ModeX::fill_span", |vga| {
            // Checked first, so that y + 1 cannot overflow.
            if (0..SCREEN_HEIGHT).contains(&y) {
                vga.fill_rect(page, x0, y, x1, y + 1, color);
            }
        })
    }

    /// Sets one pixel, if it is on the screen.
    pub fn put_pixel(&mut self, page: Page, x: i32, y: i32, color: u8) {
        self.issued_by("ModeX::put_pixel", |vga| {
            if (0..SCREEN_WIDTH).contains(&x) && (0..SCREEN_HEIGHT).contains(&y) {
                vga.io
                    .set_map_mask(PlaneMask::plane((x % PIXELS_PER_BYTE) as u8));
                vga.io
                    .write_vram8(line_offset(page, y) + (x / PIXELS_PER_BYTE) as u16, color);
            }
        })
    }

    /// Sets one pixel, if it is on the screen, the way a driver without a
    /// register cache does: the Map Mask written (index and value in one OUT)
    /// before the pixel whether or not it already selects the pixel's plane.
    /// The baseline that [`ModeX::put_pixel`] and the span fills are measured
    /// against.
    pub fn put_pixel_uncached(&mut self, page: Page, x: i32, y: i32, color: u8) {
        self.issued_by("ModeX::put_pixel_uncached", |vga| {
            if (0..SCREEN_WIDTH).contains(&x) && (0..SCREEN_HEIGHT).contains(&y) {
                vga.io
                    .write_map_mask(PlaneMask::plane((x % PIXELS_PER_BYTE) as u8));
                vga.io
                    .write_vram8(line_offset(page, y) + (x / PIXELS_PER_BYTE) as u16, color);
            }
        })
    }

    /// Fills the whole of `page` with `color`.
    pub fn clear_page(&mut self, page: Page, color: u8) {
        self.issued_by("ModeX::clear_page", |vga| {
            vga.io.set_map_mask(PlaneMask::ALL);
            vga.io.fill_vram(page.base(), PAGE_BYTES, color);
        })
    }

    /// Writes each run down `lines` lines from `top`, one Map Mask per run.
    /// The runs go right to left when the Map Mask already suits the right
    /// edge, as after a previous span with the same ragged ends.
    fn fill_runs(&mut self, top: u16, lines: u16, mut runs: [Option<Run>; 3], color: u8) {
        let last_planes = runs.iter().rev().flatten().next().map(|run| run.planes);
        if last_planes.is_some() && self.io.map_mask() == last_planes {
            runs.reverse();
        }
        for run in runs.into_iter().flatten() {
            self.io.set_map_mask(run.planes);
            for line in 0..lines {
                self.io
                    .fill_vram(top + line * BYTES_PER_LINE + run.byte, run.bytes, color);
            }
        }
    }
}
