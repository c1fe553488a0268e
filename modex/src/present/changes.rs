//! Presenting only what changed: a flip that moves a cube across a 1280x800
//! screen should not cost 4 MB of framebuffer writes.
//!
//! How the changes are found: the presenter keeps the picture it presented
//! last (DAC indices, as scanned out) and that picture's encoded palette, and
//! diffs the new scan-out against them. A pixel is written again when its
//! index changed or its index's colour did. The alternative, having the
//! software VGA track the bytes the CPU wrote, would have to reason about
//! every other way the picture changes — a flip to another page, DAC loads
//! (the lighting ramps), the pixel mask, blanking, a mode change — and would
//! still rewrite pixels drawn over with the colour they had. The diff is
//! right by construction, and costs reading two 75 KiB buffers in RAM, which
//! is nothing next to writing the framebuffer over the bus.
//!
//! The first present, and any present whose picture size or framebuffer
//! layout differs from the last, writes everything, black borders included;
//! after that only changed pixels are written (each run of changed pixels in
//! a row as one span, scaled), so the borders are never written again and a
//! still picture costs nothing.

use core::ops::Range;

use super::{blit, encoded_palette, FramebufferLayout, PixelOrder, Placement};
use crate::soft::SoftVga;

/// The largest picture the presenter keeps: 80x25 text in 9x16 cells. Mode X
/// is 320x240; a picture larger than this is presented black.
pub const MAX_PICTURE_PIXELS: usize = 720 * 400;

/// What one present did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PresentReport {
    /// Bytes written to the framebuffer.
    pub bytes_written: usize,
    /// Whether everything was written (first present, new size or layout).
    pub full: bool,
}

/// Presents a software VGA's picture into a framebuffer, writing only what
/// changed since its last present. ~580 KiB: keep it in a static or a `Box`.
/// It assumes nobody else writes the framebuffer between presents (call
/// [`Presenter::forget`] if someone did).
#[derive(Clone)]
pub struct Presenter {
    current: [u8; MAX_PICTURE_PIXELS],
    shown: [u8; MAX_PICTURE_PIXELS],
    shown_palette: [[u8; 4]; 256],
    shown_size: (usize, usize),
    /// The layout presented into last, if `presented`. (A flag rather than
    /// an Option so that a new presenter is all zero bytes: a kernel's static
    /// one then costs nothing in its image, .bss rather than .data.)
    shown_layout: FramebufferLayout,
    presented: bool,
}

/// Leaves out the pictures and the palette, ~580 KiB.
impl core::fmt::Debug for Presenter {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Presenter")
            .field("shown_size", &self.shown_size)
            .field("shown_layout", &self.shown_layout)
            .field("presented", &self.presented)
            .finish_non_exhaustive()
    }
}

impl Default for Presenter {
    fn default() -> Self {
        Self::new()
    }
}

impl Presenter {
    /// A presenter that has presented nothing yet. `const` so a kernel can
    /// keep one in a static.
    pub const fn new() -> Self {
        Presenter {
            current: [0; MAX_PICTURE_PIXELS],
            shown: [0; MAX_PICTURE_PIXELS],
            shown_palette: [[0; 4]; 256],
            shown_size: (0, 0),
            shown_layout: FramebufferLayout {
                width: 0,
                height: 0,
                stride: 0,
                bytes_per_pixel: 0,
                order: PixelOrder::Rgb,
            },
            presented: false,
        }
    }

    /// The next present writes everything.
    pub fn forget(&mut self) {
        self.presented = false;
    }

    /// Presents `soft`'s picture into `out` laid out as `layout`, as
    /// [`super::present`] would, writing only the pixels that differ from the
    /// last present. Nothing is written outside `out`.
    pub fn present(
        &mut self,
        soft: &SoftVga,
        layout: &FramebufferLayout,
        out: &mut [u8],
    ) -> PresentReport {
        let (width, height) = soft.picture_size();
        let size = if width * height <= MAX_PICTURE_PIXELS {
            soft.scanout_indices(&mut self.current[..width * height])
        } else {
            (0, 0)
        };
        let pixels = size.0 * size.1;
        let palette = encoded_palette(soft, layout.order);
        let full = !self.presented || self.shown_layout != *layout || self.shown_size != size;
        let bytes_written = if full {
            let picture = &self.current[..pixels];
            blit(picture, size, layout, out, |row, column| {
                palette[usize::from(picture[row * size.0 + column])]
            });
            full_present_bytes(layout, out.len())
        } else {
            self.present_changes(size, &palette, layout, out)
        };
        self.shown[..pixels].copy_from_slice(&self.current[..pixels]);
        self.shown_palette = palette;
        self.shown_size = size;
        self.shown_layout = *layout;
        self.presented = true;
        PresentReport {
            bytes_written,
            full,
        }
    }

    fn present_changes(
        &self,
        (width, height): (usize, usize),
        palette: &[[u8; 4]; 256],
        layout: &FramebufferLayout,
        out: &mut [u8],
    ) -> usize {
        let mut recoloured = [false; 256];
        for (flag, (new, old)) in recoloured
            .iter_mut()
            .zip(palette.iter().zip(&self.shown_palette))
        {
            *flag = new != old;
        }
        let any_recoloured = recoloured.contains(&true);
        let placement = Placement::fit((width, height), (layout.width, layout.height));
        let mut written = 0;
        for row in 0..height {
            let new = &self.current[row * width..(row + 1) * width];
            let old = &self.shown[row * width..(row + 1) * width];
            // Most rows of most frames: one slice comparison, no pixel loop.
            if !any_recoloured && new == old {
                continue;
            }
            let changed = |x: usize| new[x] != old[x] || recoloured[usize::from(new[x])];
            let mut x = 0;
            while x < width {
                if !changed(x) {
                    x += 1;
                    continue;
                }
                let start = x;
                while x < width && changed(x) {
                    x += 1;
                }
                let pixel = |column: usize| palette[usize::from(new[column])];
                written += write_span(layout, &placement, row, start..x, pixel, out);
            }
        }
        written
    }
}

/// Bytes a full present writes: every visible pixel of every line that fits.
fn full_present_bytes(layout: &FramebufferLayout, out_len: usize) -> usize {
    if !(1..=4).contains(&layout.bytes_per_pixel) {
        return 0;
    }
    let visible_pixels = layout.visible_width();
    (0..layout.height)
        .map(|y| {
            let pixels = out_len.saturating_sub(y * layout.line_bytes()) / layout.bytes_per_pixel;
            pixels.min(visible_pixels) * layout.bytes_per_pixel
        })
        .sum()
}

/// Writes picture row `row`'s `columns`, scaled, on each screen line that
/// row covers, clipped to the visible screen and to `out`; returns the bytes
/// written.
fn write_span(
    layout: &FramebufferLayout,
    placement: &Placement,
    row: usize,
    columns: Range<usize>,
    pixel: impl Fn(usize) -> [u8; 4],
    out: &mut [u8],
) -> usize {
    let scale = placement.scale;
    let mut written = 0;
    for repeat in 0..scale {
        let y = placement.top + (row * scale + repeat) as isize;
        let Ok(y) = usize::try_from(y) else {
            continue;
        };
        if y >= layout.height {
            break;
        }
        let Some(line) = layout.visible_line(out, y) else {
            break;
        };
        written += match layout.bytes_per_pixel {
            1 => span_on_line::<1>(line, placement, columns.clone(), &pixel),
            2 => span_on_line::<2>(line, placement, columns.clone(), &pixel),
            3 => span_on_line::<3>(line, placement, columns.clone(), &pixel),
            4 => span_on_line::<4>(line, placement, columns.clone(), &pixel),
            _ => 0,
        };
    }
    written
}

/// One screen line's part of a span of `N`-byte pixels.
fn span_on_line<const N: usize>(
    line: &mut [u8],
    placement: &Placement,
    columns: Range<usize>,
    pixel: &impl Fn(usize) -> [u8; 4],
) -> usize {
    let scale = placement.scale as isize;
    let pixels = line.as_chunks_mut::<N>().0;
    let screen_width = pixels.len() as isize;
    let mut written = 0;
    for column in columns {
        let left = placement.left + column as isize * scale;
        let (from, to) = (
            left.clamp(0, screen_width),
            (left + scale).clamp(0, screen_width),
        );
        if from >= to {
            continue;
        }
        let encoded = pixel(column);
        let bytes: [u8; N] = core::array::from_fn(|i| encoded[i]);
        // Both ends are clamped to 0..=screen_width.
        pixels[from as usize..to as usize].fill(bytes);
        written += (to - from) as usize * N;
    }
    written
}
