//! Showing a picture on a linear framebuffer, for UEFI boots and machines
//! without a legacy VGA: the software VGA runs Mode X (or text mode), and its
//! scan-out is copied to the framebuffer the firmware set up (UEFI GOP, or a
//! VESA linear mode): in full by [`present`], or only what changed by
//! [`Presenter`]. Pixels are encoded as `encode` describes.
//!
//! The picture is scaled by the largest whole number that fits, so every VGA
//! pixel becomes the same square of framebuffer pixels, and centred with
//! black borders. A framebuffer smaller than the picture shows its centre
//! (scale 1, cropped). Nothing is written outside the given buffer.

use crate::soft::{dac_6_to_8, SoftVga};

mod changes;
mod encode;
mod layout;

pub use changes::{PresentReport, Presenter, MAX_PICTURE_PIXELS};
pub use encode::{luma, Channel, FirmwareFormat, PackedFormat, PixelOrder};
pub use layout::{FirmwareFramebuffer, LayoutChoice, LayoutRefusal};

/// A linear framebuffer's geometry and pixel encoding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FramebufferLayout {
    /// Visible pixels per line.
    pub width: usize,
    /// Visible lines.
    pub height: usize,
    /// Pixels from the start of one line to the start of the next (at least
    /// `width`; a smaller stride is treated as the visible width).
    pub stride: usize,
    /// Bytes per pixel, 1 to 4 (any other size: nothing is drawn).
    pub bytes_per_pixel: usize,
    /// How a pixel's bytes encode a colour.
    pub order: PixelOrder,
}

impl FramebufferLayout {
    /// Bytes from the start of one line to the start of the next.
    pub fn line_bytes(&self) -> usize {
        self.stride * self.bytes_per_pixel
    }

    /// Bytes of the framebuffer the picture may write: up to the last visible
    /// pixel of the last line.
    pub fn required_bytes(&self) -> usize {
        match self.height {
            0 => 0,
            lines => (lines - 1) * self.line_bytes() + self.visible_width() * self.bytes_per_pixel,
        }
    }

    pub(crate) fn visible_width(&self) -> usize {
        self.width.min(self.stride)
    }

    /// Line `y`'s visible pixels within `out`, whole pixels only: a buffer
    /// cut short mid-pixel leaves that pixel alone, whoever draws the line.
    pub(crate) fn visible_line<'a>(&self, out: &'a mut [u8], y: usize) -> Option<&'a mut [u8]> {
        let line = out.get_mut(y * self.line_bytes()..)?;
        let pixels = self
            .visible_width()
            .min(line.len() / self.bytes_per_pixel.max(1));
        Some(&mut line[..pixels * self.bytes_per_pixel])
    }
}

/// Where a picture lands on a screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Placement {
    /// Each picture pixel becomes `scale` x `scale` screen pixels (at least 1).
    pub scale: usize,
    /// Screen column of the picture's left edge; negative when cropped.
    pub left: isize,
    /// Screen line of the picture's top edge; negative when cropped.
    pub top: isize,
}

impl Placement {
    /// The largest whole scale at which a `picture` fits on `screen` (at least
    /// 1), centred; an odd leftover pixel goes to the right or bottom border.
    pub fn fit(picture: (usize, usize), screen: (usize, usize)) -> Self {
        let (picture_width, picture_height) = picture;
        let (screen_width, screen_height) = screen;
        let scale = match (
            screen_width.checked_div(picture_width),
            screen_height.checked_div(picture_height),
        ) {
            (Some(across), Some(down)) => across.min(down).max(1),
            _ => 1,
        };
        let centre = |screen: usize, picture: usize| {
            // Framebuffer sizes are far below isize::MAX.
            (screen as isize - (picture * scale) as isize) / 2
        };
        Placement {
            scale,
            left: centre(screen_width, picture_width),
            top: centre(screen_height, picture_height),
        }
    }
}

/// Draws `picture` (`size.0 * size.1` RGB pixels, row by row) into the
/// framebuffer `out` laid out as `layout`, scaled and centred by
/// [`Placement::fit`], borders black. Rows past the end of `out` are skipped.
///
/// # Panics
/// If `picture` holds fewer than `size.0 * size.1` pixels.
pub fn present_rgb(
    picture: &[[u8; 3]],
    size: (usize, usize),
    layout: &FramebufferLayout,
    out: &mut [u8],
) -> Placement {
    let width = size.0;
    let order = layout.order;
    blit(picture, size, layout, out, |row, column| {
        order.encode(picture[row * width + column])
    })
}

/// Scans out the software VGA's DAC indices into `scratch` and presents them
/// through its DAC as [`present_rgb`] does (the same colours as
/// [`SoftVga::scanout_rgb`]: pixel mask applied, black while video is
/// blanked). Text modes show their 720x400 (or 640x400) text; with no picture
/// at all (Bochs VBE on, graphics modes other than 256-colour) the
/// framebuffer goes black. [`Presenter`] does the same writing only changes.
///
/// Indices rather than RGB: one byte a pixel to scan, and the palette is
/// encoded once for the framebuffer's pixel order instead of per pixel.
///
/// # Panics
/// If `scratch` cannot hold the displayed picture ([`crate::PAGE_PIXELS`] in
/// Mode X, [`MAX_PICTURE_PIXELS`] for 80x25 text).
pub fn present(
    soft: &SoftVga,
    scratch: &mut [u8],
    layout: &FramebufferLayout,
    out: &mut [u8],
) -> Placement {
    let size = soft.scanout_indices(scratch);
    let palette = encoded_palette(soft, layout.order);
    let (width, picture) = (size.0, &*scratch);
    blit(picture, size, layout, out, |row, column| {
        palette[usize::from(picture[row * width + column])]
    })
}

/// Each DAC index's colour encoded for the framebuffer, as the model shows it
/// now: through the pixel mask, all black while video is blanked.
pub(crate) fn encoded_palette(soft: &SoftVga, order: PixelOrder) -> [[u8; 4]; 256] {
    let mut palette = [[0u8; 4]; 256];
    if soft.video_enabled() {
        for (index, encoded) in (0..=u8::MAX).zip(palette.iter_mut()) {
            let rgb = soft
                .dac_entry(index & soft.dac_pixel_mask())
                .map(dac_6_to_8);
            *encoded = order.encode(rgb);
        }
    }
    palette
}

/// The scaling loop shared by both presenters: `pixel(row, column)` gives a
/// picture pixel's encoded bytes. Pixels of 1 to 4 bytes are handled (no
/// firmware reports more); for any other size nothing is drawn.
pub(crate) fn blit<T>(
    picture: &[T],
    size: (usize, usize),
    layout: &FramebufferLayout,
    out: &mut [u8],
    pixel: impl Fn(usize, usize) -> [u8; 4],
) -> Placement {
    let (picture_width, picture_height) = size;
    assert!(
        picture.len() >= picture_width * picture_height,
        "a {picture_width}x{picture_height} picture needs that many pixels, got {}",
        picture.len()
    );
    let placement = Placement::fit(size, (layout.width, layout.height));
    for y in 0..layout.height {
        let Some(line) = layout.visible_line(out, y) else {
            break;
        };
        let Some(row) = source_row(y, &placement, picture_height) else {
            line.fill(0);
            continue;
        };
        let row_pixel = |column| pixel(row, column);
        match layout.bytes_per_pixel {
            1 => draw_line::<1>(line, picture_width, row_pixel, &placement),
            2 => draw_line::<2>(line, picture_width, row_pixel, &placement),
            3 => draw_line::<3>(line, picture_width, row_pixel, &placement),
            4 => draw_line::<4>(line, picture_width, row_pixel, &placement),
            _ => return placement,
        }
    }
    placement
}

/// The picture row screen line `y` shows, if any.
fn source_row(y: usize, placement: &Placement, picture_height: usize) -> Option<usize> {
    let dot = y as isize - placement.top;
    let row = usize::try_from(dot).ok()? / placement.scale;
    (row < picture_height).then_some(row)
}

/// One screen line of `N`-byte pixels: black left of the picture, each of the
/// row's `width` pixels `scale` times, black right of it. `N` is a constant so
/// each pixel is one store: this loop runs a million times a frame.
fn draw_line<const N: usize>(
    line: &mut [u8],
    width: usize,
    pixel: impl Fn(usize) -> [u8; 4],
    placement: &Placement,
) {
    let scale = placement.scale;
    let mut pixels = line.as_chunks_mut::<N>().0.iter_mut();
    let left_border = usize::try_from(placement.left).unwrap_or(0);
    pixels.by_ref().take(left_border).for_each(|p| *p = [0; N]);
    // Scaled columns of the picture cropped off the left edge.
    let mut dot = usize::try_from(-placement.left).unwrap_or(0);
    for column in dot / scale..width {
        let encoded = pixel(column);
        let bytes: [u8; N] = core::array::from_fn(|i| encoded[i]);
        let repeats = (column + 1) * scale - dot;
        pixels.by_ref().take(repeats).for_each(|p| *p = bytes);
        dot += repeats;
    }
    pixels.for_each(|p| *p = [0; N]);
}

#[cfg(test)]
mod changes_tests;
#[cfg(test)]
mod tests;
