//! Page flips: the picture follows show_page, the latch happens at vertical
//! retrace, drawing into the back page never shows, and the waits are bounded.

use super::{assert_picture, mode_x, power_on, scanout, Picture};
use crate::regs::status;
use crate::regs::{Crtc, Port};
use crate::soft::PORT_ACCESS_NS;
use crate::{FlipReport, Page, VgaBus, PAGE_BYTES, STATUS_POLL_LIMIT};

#[test]
fn show_page_shows_that_page() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    for (page, color) in [(Page::Zero, 10), (Page::One, 11), (Page::Two, 12)] {
        vga.clear_page(page, color);
    }
    for page in [Page::One, Page::Two, Page::Zero, Page::Two] {
        assert_eq!(
            vga.show_page(page),
            FlipReport::default(),
            "a wait timed out"
        );
        assert_eq!(vga.bus().displayed_start(), page.base());
        assert_picture(
            &Picture::filled(10 + page.index()),
            &scanout(vga.bus()),
            "the page shown",
        );
    }
}

#[test]
fn show_page_returns_at_the_start_of_vertical_retrace() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let frames = vga.bus().frame_count();
    vga.show_page(Page::One);
    assert_eq!(vga.bus().frame_count(), frames + 1, "one retrace per flip");
    // Straight after the latch: still in vertical retrace.
    assert_ne!(
        vga.bus_mut().read_port8(Port::INPUT_STATUS_1) & status::VERTICAL_RETRACE,
        0
    );

    // Back-to-back flips are paced by the frame rate.
    let start = vga.bus().now_ns();
    for flip in 0..10u8 {
        vga.show_page(Page::ALL[usize::from(flip % 2)]);
    }
    assert_eq!(vga.bus().frame_count(), frames + 11);
    let frame_ns = vga.bus().timing().frame_ns();
    let elapsed = vga.bus().now_ns() - start;
    assert!(
        elapsed.abs_diff(10 * frame_ns) < frame_ns / 50,
        "10 flips took {elapsed} ns, frames are {frame_ns} ns"
    );
}

#[test]
fn the_start_address_takes_effect_at_the_next_vertical_retrace() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.show_page(Page::Zero);
    // Leave retrace, then write a new start address behind the driver's back.
    vga.bus_mut().advance_ns(1_000_000);
    let [high, low] = PAGE_BYTES.to_be_bytes();
    vga.bus_mut().write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::StartAddressHigh.index(), high]),
    );
    vga.bus_mut().write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::StartAddressLow.index(), low]),
    );
    assert_eq!(vga.bus().displayed_start(), 0, "latched before the retrace");
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(frame_ns);
    assert_eq!(vga.bus().displayed_start(), PAGE_BYTES);
}

#[test]
fn drawing_into_the_back_page_never_changes_the_picture() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::One, 5);
    vga.show_page(Page::One);
    let shown = scanout(vga.bus());
    for step in 0..40 {
        vga.fill_rect(
            Page::Zero,
            step * 7 - 20,
            step * 5,
            step * 7 + 30,
            step * 5 + 20,
            step as u8,
        );
        vga.fill_span(Page::Two, step, -5, 400, 200);
        vga.put_pixel(Page::Zero, step, step, 1);
        assert_picture(
            &shown,
            &scanout(vga.bus()),
            "page 1 while drawing page 0 and 2",
        );
    }
    vga.clear_page(Page::Zero, 99);
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(10 * frame_ns);
    assert_picture(&shown, &scanout(vga.bus()), "page 1 after frames went by");
}

/// A flip with the retrace bit stuck returns within its two bounded waits.
fn flip_with_retrace_stuck(stuck: bool) -> (FlipReport, u64) {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::One, 4);
    vga.bus_mut().set_retrace_stuck(Some(stuck));
    let start = vga.bus().now_ns();
    let report = vga.show_page(Page::One);
    let elapsed = vga.bus().now_ns() - start;
    // The CRT keeps time, so the flip still shows once a retrace comes.
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(frame_ns);
    assert_picture(&Picture::filled(4), &scanout(vga.bus()), "page 1");
    (report, elapsed)
}

#[test]
fn show_page_gives_up_when_the_retrace_bit_is_stuck_high() {
    let (report, elapsed) = flip_with_retrace_stuck(true);
    assert!(
        report.display_wait_timed_out && !report.retrace_wait_timed_out,
        "{report:?}"
    );
    assert!(
        elapsed <= (u64::from(STATUS_POLL_LIMIT) + 10) * PORT_ACCESS_NS,
        "took {elapsed} ns"
    );
}

#[test]
fn show_page_gives_up_when_the_retrace_bit_is_stuck_low() {
    let (report, elapsed) = flip_with_retrace_stuck(false);
    assert!(
        !report.display_wait_timed_out && report.retrace_wait_timed_out,
        "{report:?}"
    );
    assert!(report.timed_out());
    assert!(
        elapsed <= (2 * u64::from(STATUS_POLL_LIMIT) + 10) * PORT_ACCESS_NS,
        "took {elapsed} ns"
    );
}
