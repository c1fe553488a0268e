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
