//! The presenter of changes writes only what changed, and leaves what a full
//! present would (the property test with random steps and layouts is
//! `tests/present_changes.rs`: proptest cannot be a dev-dependency here
//! without turning on `std` features in the kernel's build).

use super::*;
use crate::{ModeX, Page, VgaBus};
use std::boxed::Box;
use std::vec;
use std::vec::Vec;

fn mode_x() -> Box<SoftVga> {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    soft
}

fn layout(
    width: usize,
    height: usize,
    bytes_per_pixel: usize,
    order: PixelOrder,
) -> FramebufferLayout {
    FramebufferLayout {
        width,
        height,
        stride: width,
        bytes_per_pixel,
        order,
    }
}

/// A full present onto a fresh buffer of `len` bytes filled with 0xEE.
fn full(soft: &SoftVga, layout: &FramebufferLayout, len: usize) -> Vec<u8> {
    let mut out = vec![0xEE; len];
    let mut scratch = vec![0; MAX_PICTURE_PIXELS];
    present(soft, &mut scratch, layout, &mut out);
    out
}

#[test]
fn a_still_picture_costs_nothing_and_one_pixel_costs_its_square() {
    let mut soft = mode_x();
    let layout = layout(1280, 800, 4, PixelOrder::Bgr);
    let mut out = vec![0xEE; layout.required_bytes()];
    let mut presenter = Box::new(Presenter::new());
    let first = presenter.present(&soft, &layout, &mut out);
    assert!(first.full);
    assert_eq!(first.bytes_written, 1280 * 800 * 4);
    let again = presenter.present(&soft, &layout, &mut out);
    assert_eq!((again.bytes_written, again.full), (0, false));
    ModeX::new(&mut *soft).put_pixel(Page::Zero, 10, 20, 15);
    let one = presenter.present(&soft, &layout, &mut out);
    assert_eq!(one.bytes_written, 3 * 3 * 4, "scale 3, 4 bytes a pixel");
    assert_eq!(out, full(&soft, &layout, out.len()));
}

#[test]
fn the_borders_are_written_once() {
    let mut soft = mode_x();
    let layout = layout(1280, 800, 4, PixelOrder::Bgr);
    let mut out = vec![0xEE; layout.required_bytes()];
    let mut presenter = Box::new(Presenter::new());
    presenter.present(&soft, &layout, &mut out);
    // Mark the borders (left 160 columns, top 40 lines) to see any rewrite.
    out[..40 * 1280 * 4].fill(0x55);
    for line in out.as_chunks_mut::<{ 1280 * 4 }>().0 {
        line[..160 * 4].fill(0x55);
    }
    let mut vga = ModeX::new(&mut *soft);
    vga.fill_rect(Page::One, 0, 0, 320, 240, 9);
    vga.show_page(Page::One);
    let report = presenter.present(&soft, &layout, &mut out);
    assert_eq!(
        report.bytes_written,
        960 * 720 * 4,
        "the whole picture, no border"
    );
    assert!(out[..40 * 1280 * 4].iter().all(|&b| b == 0x55));
    assert!(out
        .as_chunks::<{ 1280 * 4 }>()
        .0
        .iter()
        .all(|line| line[..160 * 4].iter().all(|&b| b == 0x55)));
}

#[test]
fn a_palette_change_rewrites_the_pixels_of_that_colour_only() {
    let mut soft = mode_x();
    let mut vga = ModeX::new(&mut *soft);
    vga.fill_rect(Page::Zero, 10, 10, 20, 15, 200);
    let layout = layout(640, 480, 4, PixelOrder::Rgb);
    let mut out = vec![0; layout.required_bytes()];
    let mut presenter = Box::new(Presenter::new());
    presenter.present(&soft, &layout, &mut out);
    ModeX::new(&mut *soft).load_palette(200, &[[63, 0, 0]]);
    let report = presenter.present(&soft, &layout, &mut out);
    assert_eq!(report.bytes_written, 10 * 5 * 2 * 2 * 4);
    assert_eq!(out, full(&soft, &layout, out.len()));
}

/// Mode X's double buffering: the start address changes at every flip, yet
/// each present scans only the tiles drawn into since that page was shown
/// and those where the two pages differed at the last flip.
#[test]
fn a_flip_scans_only_the_tiles_either_page_changed() {
    let mut soft = mode_x();
    let layout = layout(1280, 800, 4, PixelOrder::Bgr);
    let mut out = vec![0xEE; layout.required_bytes()];
    let mut presenter = Box::new(Presenter::new());
    assert!(presenter.present(&soft, &layout, &mut out).full);
    let mut shown = Page::Zero;
    // A dot moving right along row 20, one column a frame, both pages
    // erased and redrawn as a game would.
    for frame in 0..8 {
        let hidden = shown.other();
        let mut vga = ModeX::new(&mut *soft);
        vga.fill_rect(hidden, 0, 20, 320, 21, 0);
        vga.put_pixel(hidden, 100 + frame, 20, 15);
        vga.show_page(hidden);
        shown = hidden;
        let report = presenter.present(&soft, &layout, &mut out);
        assert!(!report.full);
        // Page 1 was never shown: all of it. Then row 20 only: its five
        // tiles (the erase wrote all of them).
        let expected = if frame == 0 { 320 * 240 } else { 320 };
        assert_eq!(report.pixels_scanned, expected, "frame {frame}");
        assert_eq!(out, full(&soft, &layout, out.len()), "frame {frame}");
    }
    // A flip back to a page nobody drew into since: only the tiles where
    // the pages differ, row 20's dot's.
    ModeX::new(&mut *soft).show_page(shown.other());
    let report = presenter.present(&soft, &layout, &mut out);
    assert_eq!(report.pixels_scanned, 64);
    assert_eq!(report.bytes_written, 2 * 3 * 3 * 4, "two dots, scale 3");
    assert_eq!(out, full(&soft, &layout, out.len()));
    // Nothing drawn, no flip: nothing scanned.
    let report = presenter.present(&soft, &layout, &mut out);
    assert_eq!((report.pixels_scanned, report.bytes_written), (0, 0));
}

/// A start address no present showed before (a scroll) is all new.
#[test]
fn a_new_start_address_scans_everything() {
    let mut soft = mode_x();
    let layout = layout(640, 480, 4, PixelOrder::Rgb);
    let mut out = vec![0; layout.required_bytes()];
    let mut presenter = Box::new(Presenter::new());
    presenter.present(&soft, &layout, &mut out);
    let mut vga = ModeX::new(&mut *soft);
    vga.fill_rect(Page::Zero, 0, 0, 320, 240, 3);
    vga.fill_rect(Page::Zero, 0, 100, 320, 101, 9);
    let start = u16::from_le_bytes([80, 0]); // one row down
    let bus = vga.bus_mut();
    bus.write_port16(
        crate::regs::Port::CRTC_INDEX,
        u16::from_le_bytes([crate::regs::Crtc::StartAddressLow.index(), start as u8]),
    );
    soft.let_a_frame_pass();
    let report = presenter.present(&soft, &layout, &mut out);
    assert_eq!(report.pixels_scanned, 320 * 240);
    assert_eq!(out, full(&soft, &layout, out.len()));
}

/// The word trick finds exactly the nonzero bytes, for every pattern of
/// zero and nonzero bytes and values that test each bit of a byte.
#[test]
fn nonzero_bytes_are_found_exactly() {
    use super::changes::nonzero_bytes;
    for pattern in 0..=255u32 {
        for value in [0x01u8, 0x7F, 0x80, 0xFF, 0x40] {
            let bytes: [u8; 8] =
                core::array::from_fn(|k| if pattern & 1 << k != 0 { value } else { 0 });
            assert_eq!(
                nonzero_bytes(u64::from_le_bytes(bytes)),
                pattern,
                "{bytes:?}"
            );
        }
    }
}

/// A plane's differing quads land on its pixels: bit `k` to bit `4k`, for
/// every pattern of 16 quads.
#[test]
fn every_fourth_bit_spreads_each_quad_to_its_pixel() {
    use super::changes::every_fourth_bit;
    for bits in 0..=u16::MAX {
        let expected = (0..16)
            .filter(|k| bits & 1 << k != 0)
            .fold(0u64, |spread, k| spread | 1 << (4 * k));
        assert_eq!(every_fourth_bit(bits), expected, "{bits:#06x}");
    }
}

/// The runs of set bits are exactly the maximal runs, lowest first, the
/// top bit and a full word included.
#[test]
fn runs_of_bits_are_the_maximal_runs() {
    use super::changes::for_each_run_of_bits;
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut words = vec![0, u64::MAX, 1, 1 << 63, 0x8000_0000_0000_0001, 0xF0F0];
    for _ in 0..2_000 {
        // xorshift: patterns of every density, fixed so every run is the same.
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        words.push(state & state >> 3);
        words.push(state | state << 5);
    }
    for bits in words {
        let mut runs = Vec::new();
        for_each_run_of_bits(bits, |run| runs.push(run));
        let mut expected = Vec::new();
        let mut start = None;
        for k in 0..=64 {
            let set = k < 64 && bits & 1 << k != 0;
            match (set, start) {
                (true, None) => start = Some(k),
                (false, Some(first)) => {
                    expected.push(first..k);
                    start = None;
                }
                _ => {}
            }
        }
        assert_eq!(runs, expected, "{bits:#018x}");
    }
}

/// A Mode X picture 8 pixels wider than whole tiles (328: its rows' last
/// tile two quads), a picture larger than the screen (cropped on every
/// side) and a framebuffer cut short inside a line: presenting changes
/// still leaves exactly what a full present leaves.
#[test]
fn short_tiles_cropped_pictures_and_short_buffers_match_a_full_present() {
    let mut soft = mode_x();
    {
        let mut vga = ModeX::new(&mut *soft);
        // 82 characters of 4 pixels: 328 pixels, Offset 41 words.
        let bus = vga.bus_mut();
        // Registers 0-7 unprotected first (Vertical Retrace End bit 7).
        bus.write_port8(
            crate::regs::Port::CRTC_INDEX,
            crate::regs::Crtc::VerticalRetraceEnd.index(),
        );
        let retrace_end = bus.read_port8(crate::regs::Port::CRTC_DATA);
        bus.write_port8(crate::regs::Port::CRTC_DATA, retrace_end & 0x7F);
        for (index, value) in [
            (crate::regs::Crtc::HorizontalDisplayEnd, 81u8),
            (crate::regs::Crtc::Offset, 41),
        ] {
            bus.write_port16(
                crate::regs::Port::CRTC_INDEX,
                u16::from_le_bytes([index.index(), value]),
            );
        }
    }
    soft.let_a_frame_pass();
    assert_eq!(soft.picture_size().0, 328);
    let layouts = [
        layout(1000, 700, 4, PixelOrder::Bgr),
        layout(300, 200, 3, PixelOrder::Rgb),
    ];
    for layout in layouts {
        for cut in [0, 1, 2 * layout.line_bytes() + 5] {
            let length = layout.required_bytes() - cut;
            let mut out = vec![0xEE; length];
            let mut presenter = Box::new(Presenter::new());
            presenter.present(&soft, &layout, &mut out);
            for (step, colour) in (1..6u8).enumerate() {
                // Planes chosen by the step, at the right edge (the short
                // tile and the one before) and the top left corner.
                let mut vga = ModeX::new(&mut *soft);
                let bus = vga.bus_mut();
                bus.write_port16(
                    crate::regs::Port::SEQUENCER_INDEX,
                    u16::from_le_bytes([crate::regs::Sequencer::MapMask.index(), colour]),
                );
                for row in (step * 7..240).step_by(3) {
                    for quad in (77 - step..82).chain(0..step) {
                        bus.write_vram8((row * 82 + quad) as u16, colour * 17);
                    }
                }
                soft.let_a_frame_pass();
                presenter.present(&soft, &layout, &mut out);
                let expected = full(&soft, &layout, length);
                let first_difference = out.iter().zip(&expected).position(|(a, b)| a != b);
                assert_eq!(first_difference, None, "{layout:?}, {cut} bytes short");
            }
        }
    }
}

/// Every colour of a distinct palette as a 20x15 block on page 0, and the
/// framebuffer layout the kernel makes of what a loader described.
fn every_colour() -> Box<SoftVga> {
    let mut soft = mode_x();
    let mut vga = ModeX::new(&mut *soft);
    let palette: Vec<[u8; 3]> = (0..=255u8)
        .map(|i| [i % 64, i.wrapping_mul(7) % 64, i.wrapping_mul(13) % 64])
        .collect();
    vga.load_palette(0, &palette);
    for colour in 0..=255u8 {
        let (x, y) = (i32::from(colour % 16) * 20, i32::from(colour / 16) * 15);
        vga.fill_rect(Page::Zero, x, y, x + 20, y + 15, colour);
    }
    soft
}

/// A framebuffer a loader describes by its components' bit offsets, as the
/// kernel lays it out (`FirmwareFramebuffer::layout`).
fn described(bytes_per_pixel: usize, red: u8, green: u8, blue: u8) -> FramebufferLayout {
    let described = FirmwareFramebuffer {
        byte_len: 1024 * 768 * bytes_per_pixel,
        width: 1024,
        height: 768,
        stride: 1024,
        bytes_per_pixel,
        format: FirmwareFormat::BitOffsets { red, green, blue },
    };
    let choice = described.layout().expect("a well-formed framebuffer");
    assert!(!choice.grey_instead, "{described:?} is understood");
    choice.layout
}

/// Presents `soft` through the presenter of changes onto `layout` and onto
/// a 1024x768 4-byte RGB framebuffer, a pixel changed, then again; after
/// each, every pixel of `layout` must be `from_rgb` of the RGB one's bytes,
/// and the changes must leave what a full present does.
fn draws_the_rgb_picture(
    mut soft: Box<SoftVga>,
    layout: FramebufferLayout,
    from_rgb: fn(&[u8]) -> Vec<u8>,
) {
    let rgb = self::layout(1024, 768, 4, PixelOrder::Rgb);
    let mut out = vec![0xEE; layout.required_bytes()];
    let mut reference = vec![0xEE; rgb.required_bytes()];
    let (mut presenter, mut rgb_presenter) =
        (Box::new(Presenter::new()), Box::new(Presenter::new()));
    for step in 0..2 {
        if step == 1 {
            ModeX::new(&mut *soft).put_pixel(Page::Zero, 100, 100, 77);
        }
        presenter.present(&soft, &layout, &mut out);
        rgb_presenter.present(&soft, &rgb, &mut reference);
        let n = layout.bytes_per_pixel;
        for (index, (pixel, rgb_pixel)) in out.chunks(n).zip(reference.chunks(4)).enumerate() {
            assert_eq!(
                pixel,
                from_rgb(rgb_pixel),
                "step {step}, pixel ({}, {})",
                index % 1024,
                index / 1024
            );
        }
        assert_eq!(out, full(&soft, &layout, out.len()), "step {step}");
    }
    // Not a picture of nothing: the colours reached the framebuffer.
    assert!(reference.chunks(4).filter(|p| p[..3] != [0, 0, 0]).count() > 900 * 700);
}

/// OVMF's 24-bit mode on a Cirrus, as the loader hands it on: red, green,
/// blue at bits 16, 8 and 0 of a 3-byte pixel (blue, green, red in byte
/// order).
#[test]
fn a_24_bit_bgr_bit_mask_shows_the_picture_of_a_32_bit_framebuffer() {
    draws_the_rgb_picture(every_colour(), described(3, 16, 8, 0), |rgb| {
        vec![rgb[2], rgb[1], rgb[0]]
    });
}

/// An order nobody names: red in the low byte, blue in the middle, green on
/// top of a 3-byte pixel.
#[test]
fn a_24_bit_mask_in_an_unusual_order_shows_the_same_picture() {
    draws_the_rgb_picture(every_colour(), described(3, 0, 16, 8), |rgb| {
        vec![rgb[0], rgb[2], rgb[1]]
    });
}

/// The colours in the top three bytes of a 4-byte pixel, the low byte
/// reserved (left zero).
#[test]
fn a_32_bit_mask_with_the_colours_on_top_shows_the_same_picture() {
    draws_the_rgb_picture(every_colour(), described(4, 24, 16, 8), |rgb| {
        vec![0, rgb[2], rgb[1], rgb[0]]
    });
}
