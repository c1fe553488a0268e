//! Rectangles, spans, pixels and page clears against a per-pixel reference,
//! and the bus traffic of the Map Mask strategy.

use super::{assert_picture, mode_x, page_pixels, page_range, power_on, scanout, Picture};
use crate::regs::{PlaneMask, Sequencer};
use crate::{Page, PAGE_BYTES};

const BACKGROUND: u8 = 3;
const INK: u8 = 200;
/// Colours for the pages not drawn on, to catch stray writes.
const OTHER_PAGES: u8 = 77;

/// Every left alignment and width 1..=12, at a few heights and places.
fn alignment_cases() -> impl Iterator<Item = (i32, i32, i32, i32)> {
    let places = [(0, 0, 1), (4, 17, 3), (101, 238, 2), (308, 100, 7)];
    places.into_iter().flat_map(|(x_base, y, height)| {
        (0..4).flat_map(move |alignment| {
            (1..=12).map(move |width| {
                let x0 = x_base + alignment;
                (x0, y, x0 + width, y + height)
            })
        })
    })
}

#[test]
fn fill_rect_matches_the_reference_at_every_alignment_and_width() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::One, OTHER_PAGES);
    vga.clear_page(Page::Two, OTHER_PAGES);
    for (x0, y0, x1, y1) in alignment_cases() {
        vga.clear_page(Page::Zero, BACKGROUND);
        vga.bus_mut().set_write_guard(Some(page_range(Page::Zero)));
        vga.fill_rect(Page::Zero, x0, y0, x1, y1, INK);
        let mut expected = Picture::filled(BACKGROUND);
        expected.fill_rect(x0, y0, x1, y1, INK);
        let what = std::format!("fill_rect({x0}, {y0}, {x1}, {y1})");
        assert_picture(&expected, &scanout(vga.bus()), &what);
        assert_eq!(
            vga.bus().guard_violations(),
            0,
            "{what} wrote outside page 0"
        );
    }
    assert_picture(
        &Picture::filled(OTHER_PAGES),
        &page_pixels(vga.bus(), Page::One),
        "page 1",
    );
    assert_picture(
        &Picture::filled(OTHER_PAGES),
        &page_pixels(vga.bus(), Page::Two),
        "page 2",
    );
}

#[test]
fn fill_span_matches_the_reference_at_every_alignment_and_width() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    for (x0, y, x1, _) in alignment_cases() {
        vga.clear_page(Page::Zero, BACKGROUND);
        vga.fill_span(Page::Zero, y, x0, x1, INK);
        let mut expected = Picture::filled(BACKGROUND);
        expected.fill_rect(x0, y, x1, y + 1, INK);
        assert_picture(
            &expected,
            &scanout(vga.bus()),
            &std::format!("fill_span({y}, {x0}, {x1})"),
        );
    }
}

#[test]
fn overlapping_fills_compose_like_the_reference() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let mut expected = Picture::filled(0);
    let mut random = super::XorShift(99);
    for _ in 0..300 {
        let x0 = i32::from(random.next_u8()) + i32::from(random.next_u8() % 70) - 10;
        let y0 = i32::from(random.next_u8()) - 10;
        let (w, h) = (
            i32::from(random.next_u8() % 90),
            i32::from(random.next_u8() % 60),
        );
        let color = random.next_u8();
        vga.fill_rect(Page::Zero, x0, y0, x0 + w, y0 + h, color);
        expected.fill_rect(x0, y0, x0 + w, y0 + h, color);
    }
    assert_picture(&expected, &scanout(vga.bus()), "300 random rectangles");
}

#[test]
fn put_pixel_sets_exactly_one_pixel_in_every_plane() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let mut expected = Picture::filled(0);
    for (i, (x, y)) in [
        (0, 0),
        (1, 0),
        (2, 0),
        (3, 0),
        (319, 239),
        (158, 120),
        (77, 3),
    ]
    .into_iter()
    .enumerate()
    {
        let color = 10 + i as u8;
        vga.put_pixel(Page::Zero, x, y, color);
        expected.fill_rect(x, y, x + 1, y + 1, color);
        assert_picture(
            &expected,
            &scanout(vga.bus()),
            &std::format!("put_pixel({x}, {y})"),
        );
    }
    vga.bus_mut().reset_counts();
    for (x, y) in [(-1, 0), (320, 0), (0, -1), (0, 240), (i32::MIN, i32::MAX)] {
        vga.put_pixel(Page::Zero, x, y, 1);
    }
    assert_eq!(
        vga.bus().counts().vram_writes,
        0,
        "an off-screen pixel was written"
    );
}

#[test]
fn clear_page_fills_that_page_only() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::Zero, 1);
    vga.clear_page(Page::One, 2);
    vga.clear_page(Page::Two, 3);
    for (page, color) in [(Page::Zero, 1), (Page::One, 2), (Page::Two, 3)] {
        assert_picture(
            &Picture::filled(color),
            &page_pixels(vga.bus(), page),
            "cleared page",
        );
    }
    assert_picture(&Picture::filled(1), &scanout(vga.bus()), "shown page 0");
}

#[test]
fn the_middle_of_a_span_costs_one_byte_per_four_pixels() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let cases = [
        ((0, 320), 80),
        ((1, 11), 3),
        ((4, 8), 1),
        ((5, 7), 1),
        ((3, 5), 2),
        ((2, 318), 80),
    ];
    for ((x0, x1), bytes) in cases {
        vga.bus_mut().reset_counts();
        vga.fill_span(Page::Zero, 5, x0, x1, 1);
        assert_eq!(vga.bus().counts().vram_writes, bytes, "span [{x0}, {x1})");
    }
}

#[test]
fn map_mask_is_not_rewritten_when_it_would_not_change() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);

    // Whole columns only, after a clear: the Map Mask is already all planes.
    vga.clear_page(Page::Zero, 0);
    vga.bus_mut().reset_counts();
    vga.fill_span(Page::Zero, 1, 8, 40, 5);
    vga.fill_span(Page::Zero, 2, 8, 40, 5);
    assert_eq!(
        vga.bus().counts().port_writes,
        0,
        "aligned spans rewrote the Map Mask"
    );

    // Two spans inside one column with the same planes: one Map Mask write.
    vga.bus_mut().reset_counts();
    vga.fill_span(Page::Zero, 3, 9, 11, 5);
    vga.fill_span(Page::Zero, 4, 9, 11, 5);
    assert_eq!(vga.bus().counts().port_writes, 1);

    // Ragged at both ends: left, middle, right; the next span with the same
    // edges starts from the right edge's mask, so needs only two writes.
    vga.bus_mut().reset_counts();
    vga.fill_span(Page::Zero, 5, 1, 19, 5);
    assert_eq!(vga.bus().counts().port_writes, 3);
    vga.bus_mut().reset_counts();
    vga.fill_span(Page::Zero, 6, 1, 19, 5);
    assert_eq!(vga.bus().counts().port_writes, 2);

    // A rectangle changes the Map Mask once per edge or middle, not per line.
    vga.bus_mut().reset_counts();
    vga.fill_rect(Page::Zero, 1, 10, 19, 200, 6);
    assert!(vga.bus().counts().port_writes <= 3);

    let mut expected = Picture::filled(0);
    expected.fill_rect(8, 1, 40, 3, 5);
    expected.fill_rect(9, 3, 11, 5, 5);
    expected.fill_rect(1, 5, 19, 7, 5);
    expected.fill_rect(1, 10, 19, 200, 6);
    assert_picture(&expected, &scanout(vga.bus()), "the spans");
    assert_eq!(
        vga.bus().sequencer(Sequencer::MapMask) & PlaneMask::ALL.bits(),
        vga.io.map_mask().unwrap().bits()
    );
}

#[test]
fn a_page_is_exactly_its_19200_bytes() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.bus_mut().set_write_guard(Some(page_range(Page::Two)));
    vga.bus_mut().reset_counts();
    vga.fill_rect(Page::Two, 0, 0, 320, 240, 9);
    assert_eq!(vga.bus().guard_violations(), 0);
    assert_eq!(vga.bus().counts().vram_writes, u64::from(PAGE_BYTES));
    assert_picture(
        &Picture::filled(9),
        &page_pixels(vga.bus(), Page::Two),
        "page 2",
    );
}
