//! The full presenter: scaling, placement, pixel orders, the model's picture.

use super::*;
use crate::regs::Port;
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
            let inside = (0..WIDTH as isize).contains(&px) && (0..HEIGHT as isize).contains(&py);
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
fn a_model_at_power_on_presents_a_black_text_screen() {
    // Text mode 3 with video memory cleared: every cell black on black.
    let soft = std::boxed::Box::new(SoftVga::new());
    let layout = layout(640, 480, PixelOrder::Rgb);
    let mut scratch = vec![0; MAX_PICTURE_PIXELS];
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
        vga.fill_rect(Page::Zero, x, y, x + 20, y + 15, colour);
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
    crate::VgaBus::write_port8(&mut *soft, Port::DAC_PIXEL_MASK, 0x0F);
    compare(&soft, "pixel mask 0x0F");
    crate::VgaBus::write_port8(&mut *soft, Port::ATTRIBUTE_INDEX, 0); // blanks the screen
    assert!(!soft.video_enabled());
    compare(&soft, "blanked");
}
