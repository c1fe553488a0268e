//! Showing a picture on a linear framebuffer, for machines without a legacy
//! VGA: the software VGA runs Mode X, and its scan-out is copied to the
//! framebuffer the firmware set up (UEFI GOP, or a VESA linear mode).
//!
//! The picture is scaled by the largest whole number that fits, so every VGA
//! pixel becomes the same square of framebuffer pixels, and centred with
//! black borders. A framebuffer smaller than the picture shows its centre
//! (scale 1, cropped). Nothing is written outside the given buffer.

use crate::soft::{dac_6_to_8, SoftVga};

/// How the bytes of one framebuffer pixel encode a colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelOrder {
    /// Red, green, blue: one byte each, a fourth byte zero. (With fewer than
    /// 3 bytes a pixel, the components that fit.)
    Rgb,
    /// Blue, green, red: one byte each, any further bytes zero (UEFI's usual
    /// 0x00RRGGBB in little-endian words).
    Bgr,
    /// Luminance in every byte of the pixel. For 8-bit grey that is the pixel;
    /// for a packed format nobody described it is at least a grey picture in
    /// every 8-bit-per-component layout.
    Grey,
}

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

    fn visible_width(&self) -> usize {
        self.width.min(self.stride)
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

/// The Rec. 601 luma weights in 1/256ths (0.299, 0.587, 0.114): the usual
/// weighting of a colour's brightness to the eye, and what monochrome VGA
/// BIOSes use to sum the DAC to grey. They add up to 256, so white stays 255.
const LUMA_WEIGHTS: [u32; 3] = [77, 150, 29];

/// The grey an RGB colour looks as bright as.
pub fn luma([red, green, blue]: [u8; 3]) -> u8 {
    let [wr, wg, wb] = LUMA_WEIGHTS;
    ((wr * u32::from(red) + wg * u32::from(green) + wb * u32::from(blue) + 128) >> 8) as u8
}

impl PixelOrder {
    /// The first four bytes of a pixel of colour `rgb`.
    fn encode(self, rgb: [u8; 3]) -> [u8; 4] {
        let [red, green, blue] = rgb;
        match self {
            PixelOrder::Rgb => [red, green, blue, 0],
            PixelOrder::Bgr => [blue, green, red, 0],
            PixelOrder::Grey => [luma(rgb); 4],
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
/// blanked). Outside 256-colour graphics modes (text mode, Bochs VBE on) the
/// model has no picture to show and the framebuffer goes black.
///
/// Indices rather than RGB: one byte a pixel to scan, and the palette is
/// encoded once for the framebuffer's pixel order instead of per pixel.
///
/// # Panics
/// If `scratch` cannot hold the displayed picture ([`crate::PAGE_PIXELS`] in
/// Mode X).
pub fn present(
    soft: &SoftVga,
    scratch: &mut [u8],
    layout: &FramebufferLayout,
    out: &mut [u8],
) -> Placement {
    let size = soft.scanout_indices(scratch);
    let mut palette = [[0u8; 4]; 256];
    if soft.video_enabled() {
        for (index, encoded) in (0..=u8::MAX).zip(palette.iter_mut()) {
            let rgb = soft
                .dac_entry(index & soft.dac_pixel_mask())
                .map(dac_6_to_8);
            *encoded = layout.order.encode(rgb);
        }
    }
    let (width, picture) = (size.0, &*scratch);
    blit(picture, size, layout, out, |row, column| {
        palette[usize::from(picture[row * width + column])]
    })
}

/// The scaling loop shared by both presenters: `pixel(row, column)` gives a
/// picture pixel's encoded bytes. Pixels of 1 to 4 bytes are handled (no
/// firmware reports more); for any other size nothing is drawn.
fn blit<T>(
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
    let line_bytes = layout.line_bytes();
    let visible_bytes = layout.visible_width() * layout.bytes_per_pixel;
    for y in 0..layout.height {
        let Some(line) = out.get_mut(y * line_bytes..) else {
            break;
        };
        let line_end = visible_bytes.min(line.len());
        let line = &mut line[..line_end];
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
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    const WIDTH: usize = 320;
    const HEIGHT: usize = 240;

    /// A picture where every pixel differs: red = x, green = y, blue = x ^ y
    /// (each mod 256).
    fn gradient() -> Vec<[u8; 3]> {
        (0..HEIGHT)
            .flat_map(|y| (0..WIDTH).map(move |x| [x as u8, y as u8, (x ^ y) as u8]))
            .collect()
    }

    fn layout(width: usize, height: usize, order: PixelOrder) -> FramebufferLayout {
        FramebufferLayout {
            width,
            height,
            stride: width,
            bytes_per_pixel: 4,
            order,
        }
    }

    /// The framebuffer pixel at (x, y), its bytes.
    fn pixel_at<'a>(out: &'a [u8], layout: &FramebufferLayout, x: usize, y: usize) -> &'a [u8] {
        let start = y * layout.line_bytes() + x * layout.bytes_per_pixel;
        &out[start..start + layout.bytes_per_pixel]
    }

    /// Presents the gradient onto a framebuffer filled with 0xEE (so unwritten
    /// bytes show) and checks every visible pixel against an independent
    /// per-pixel mapping.
    fn check_every_pixel(layout: &FramebufferLayout) -> (Placement, Vec<u8>) {
        let picture = gradient();
        let mut out = vec![0xEE; layout.required_bytes()];
        let placement = present_rgb(&picture, (WIDTH, HEIGHT), layout, &mut out);
        let scale = placement.scale as isize;
        for y in 0..layout.height {
            for x in 0..layout.width {
                let (px, py) = (
                    (x as isize - placement.left).div_euclid(scale),
                    (y as isize - placement.top).div_euclid(scale),
                );
                let inside =
                    (0..WIDTH as isize).contains(&px) && (0..HEIGHT as isize).contains(&py);
                let expected: Vec<u8> = if inside {
                    let rgb = picture[py as usize * WIDTH + px as usize];
                    let encoded = layout.order.encode(rgb);
                    (0..layout.bytes_per_pixel)
                        .map(|i| match layout.order {
                            PixelOrder::Grey => encoded[0],
                            _ => *encoded.get(i).unwrap_or(&0),
                        })
                        .collect()
                } else {
                    vec![0; layout.bytes_per_pixel]
                };
                assert_eq!(pixel_at(&out, layout, x, y), expected, "pixel ({x}, {y})");
            }
        }
        (placement, out)
    }

    #[test]
    fn scale_is_the_largest_whole_number_that_fits() {
        let fit = |w, h| Placement::fit((WIDTH, HEIGHT), (w, h));
        assert_eq!(
            fit(640, 480),
            Placement {
                scale: 2,
                left: 0,
                top: 0
            }
        );
        assert_eq!(
            fit(1280, 720),
            Placement {
                scale: 3,
                left: 160,
                top: 0
            }
        );
        assert_eq!(
            fit(1024, 768),
            Placement {
                scale: 3,
                left: 32,
                top: 24
            }
        );
        assert_eq!(
            fit(1280, 800),
            Placement {
                scale: 3,
                left: 160,
                top: 40
            }
        );
        assert_eq!(
            fit(320, 240),
            Placement {
                scale: 1,
                left: 0,
                top: 0
            }
        );
        assert_eq!(
            fit(200, 100),
            Placement {
                scale: 1,
                left: -60,
                top: -70
            }
        );
        assert_eq!(fit(0, 0).scale, 1);
        assert_eq!(Placement::fit((0, 0), (640, 480)).scale, 1);
    }

    #[test]
    fn twice_the_size_fills_the_screen() {
        let (placement, _) = check_every_pixel(&layout(640, 480, PixelOrder::Rgb));
        assert_eq!(placement.scale, 2);
    }

    #[test]
    fn a_wide_screen_gets_black_bars_left_and_right() {
        let layout = layout(1280, 720, PixelOrder::Bgr);
        let (placement, out) = check_every_pixel(&layout);
        assert_eq!(placement.scale, 3);
        assert_eq!(pixel_at(&out, &layout, 159, 0), [0, 0, 0, 0]);
        // Picture pixel (1, 0) is [1, 0, 1]: blue, green, red.
        assert_eq!(pixel_at(&out, &layout, 163, 0), [1, 0, 1, 0]);
        assert_eq!(
            pixel_at(&out, &layout, 160 + 960 - 1, 719),
            [0xEF ^ 0x3F, 0xEF, 0x3F, 0]
        );
        assert_eq!(pixel_at(&out, &layout, 160 + 960, 719), [0, 0, 0, 0]);
    }

    #[test]
    fn a_1024x768_screen_scales_by_3_centred_both_ways() {
        let (placement, _) = check_every_pixel(&layout(1024, 768, PixelOrder::Rgb));
        assert_eq!(
            (placement.scale, placement.left, placement.top),
            (3, 32, 24)
        );
    }

    #[test]
    fn the_same_size_is_copied_one_to_one() {
        let layout = layout(WIDTH, HEIGHT, PixelOrder::Rgb);
        let (_, out) = check_every_pixel(&layout);
        assert_eq!(pixel_at(&out, &layout, 7, 5), [7, 5, 7 ^ 5, 0]);
    }

    #[test]
    fn a_smaller_screen_shows_the_centre_and_nothing_outside_it() {
        let layout = layout(200, 100, PixelOrder::Rgb);
        let (placement, out) = check_every_pixel(&layout);
        assert_eq!(placement.scale, 1);
        // The centre of the picture: columns 60..260, rows 70..170.
        assert_eq!(pixel_at(&out, &layout, 0, 0), [60, 70, 60 ^ 70, 0]);
        assert_eq!(pixel_at(&out, &layout, 199, 99), [3, 169, 3 ^ 169, 0]);
        assert_eq!(out.len(), 200 * 100 * 4);
    }

    #[test]
    fn rgb_and_bgr_put_the_bytes_in_their_order() {
        let picture = vec![[0x11, 0x22, 0x33]; WIDTH * HEIGHT];
        for (order, expected) in [
            (PixelOrder::Rgb, [0x11, 0x22, 0x33, 0]),
            (PixelOrder::Bgr, [0x33, 0x22, 0x11, 0]),
        ] {
            let layout = layout(WIDTH, HEIGHT, order);
            let mut out = vec![0xEE; layout.required_bytes()];
            present_rgb(&picture, (WIDTH, HEIGHT), &layout, &mut out);
            assert_eq!(pixel_at(&out, &layout, 100, 100), expected, "{order:?}");
        }
    }

    #[test]
    fn three_byte_pixels_have_no_padding() {
        let layout = FramebufferLayout {
            bytes_per_pixel: 3,
            ..layout(800, 600, PixelOrder::Bgr)
        };
        let (placement, out) = check_every_pixel(&layout);
        assert_eq!(placement.scale, 2);
        assert_eq!(out.len(), 800 * 600 * 3);
    }

    #[test]
    fn grey_uses_the_rec_601_weights_in_every_byte() {
        assert_eq!(luma([255, 255, 255]), 255);
        assert_eq!(luma([0, 0, 0]), 0);
        assert_eq!(luma([255, 0, 0]), 77);
        assert_eq!(luma([0, 255, 0]), 149);
        assert_eq!(luma([0, 0, 255]), 29);
        for bytes_per_pixel in 1..=4 {
            let layout = FramebufferLayout {
                bytes_per_pixel,
                ..layout(640, 480, PixelOrder::Grey)
            };
            let (_, out) = check_every_pixel(&layout);
            // Picture pixel (100, 50) is [100, 50, 86] at (200..202, 100..102).
            let grey = ((77 * 100 + 150 * 50 + 29 * 86 + 128) >> 8) as u8;
            assert_eq!(
                pixel_at(&out, &layout, 201, 101),
                vec![grey; bytes_per_pixel]
            );
        }
    }

    #[test]
    fn padding_at_the_end_of_each_line_is_left_alone() {
        let layout = FramebufferLayout {
            stride: 700,
            ..layout(640, 480, PixelOrder::Rgb)
        };
        let (_, out) = check_every_pixel(&layout);
        for y in 0..479 {
            let padding = &out[y * layout.line_bytes() + 640 * 4..(y + 1) * layout.line_bytes()];
            assert!(
                padding.iter().all(|&b| b == 0xEE),
                "line {y}'s padding written"
            );
        }
    }

    #[test]
    fn a_buffer_shorter_than_the_layout_is_never_overrun() {
        let layout = layout(640, 480, PixelOrder::Rgb);
        let picture = gradient();
        for len in [0, 1, 3, 640 * 4 - 1, 640 * 4 * 100 + 7] {
            let mut out = vec![0xEE; len];
            present_rgb(&picture, (WIDTH, HEIGHT), &layout, &mut out);
        }
        let zero_bytes = FramebufferLayout {
            bytes_per_pixel: 0,
            ..layout
        };
        present_rgb(&picture, (WIDTH, HEIGHT), &zero_bytes, &mut [0; 16]);
    }

    #[test]
    fn a_model_not_in_a_graphics_mode_presents_black() {
        let soft = std::boxed::Box::new(SoftVga::new()); // text mode 3
        let layout = layout(640, 480, PixelOrder::Rgb);
        let mut scratch = vec![0; WIDTH * HEIGHT];
        let mut out = vec![0xEE; layout.required_bytes()];
        present(&soft, &mut scratch, &layout, &mut out);
        assert!(out.iter().all(|&b| b == 0));
    }

    /// `present` goes through the DAC itself; it must agree with the model's
    /// own RGB scan-out, pixel mask and blanking included.
    #[test]
    fn presenting_the_model_matches_presenting_its_rgb_scan_out() {
        use crate::{ModeX, Page};
        let mut soft = std::boxed::Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        for colour in 0..=255u8 {
            let x = i32::from(colour) % 16 * 20;
            let y = i32::from(colour) / 16 * 15;
            vga.fill_rect(Page(0), x, y, x + 20, y + 15, colour);
        }
        let layout = layout(1024, 768, PixelOrder::Bgr);
        let compare = |soft: &SoftVga, what: &str| {
            let mut rgb = vec![[0; 3]; WIDTH * HEIGHT];
            let size = soft.scanout_rgb(&mut rgb);
            let mut expected = vec![0xEE; layout.required_bytes()];
            present_rgb(&rgb, size, &layout, &mut expected);
            let mut indices = vec![0; WIDTH * HEIGHT];
            let mut actual = vec![0xEE; layout.required_bytes()];
            present(soft, &mut indices, &layout, &mut actual);
            assert!(actual == expected, "{what}");
        };
        compare(&soft, "the default palette");
        crate::VgaBus::write_port8(&mut *soft, crate::regs::DAC_PIXEL_MASK, 0x0F);
        compare(&soft, "pixel mask 0x0F");
        crate::VgaBus::write_port8(&mut *soft, crate::regs::ATTRIBUTE_INDEX, 0); // blanks the screen
        assert!(!soft.video_enabled());
        compare(&soft, "blanked");
    }
}
