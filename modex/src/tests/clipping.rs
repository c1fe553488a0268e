//! Clipping: nothing outside the page drawn on is ever written, whatever the
//! coordinates, and what is drawn is the clipped reference.

use super::{assert_picture, mode_x, page_pixels, page_range, power_on, Picture};
use crate::Page;

const BACKGROUND: u8 = 1;
const INK: u8 = 250;

const AWKWARD_RECTANGLES: [(i32, i32, i32, i32); 16] = [
    (-10, -10, 5, 5),                         // top left corner
    (315, 235, 400, 400),                     // bottom right corner
    (-100, 50, 1000, 51),                     // wider than the screen
    (i32::MIN, i32::MIN, i32::MAX, i32::MAX), // everything
    (i32::MIN, 0, -1, 240),                   // entirely left
    (320, 0, i32::MAX, 240),                  // entirely right
    (0, i32::MIN, 320, 0),                    // entirely above
    (0, 240, 320, i32::MAX),                  // entirely below
    (50, 50, 50, 60),                         // empty width
    (50, 50, 60, 50),                         // empty height
    (60, 50, 50, 70),                         // inverted x
    (50, 70, 60, 50),                         // inverted y
    (i32::MAX, i32::MAX, i32::MIN, i32::MIN), // inverted everything
    (319, 239, 320, 240),                     // the last pixel
    (-3, 100, 2, 101),                        // ragged right edge after clipping
    (318, 100, 10_000, 101),                  // ragged left edge before clipping
];

#[test]
fn rectangles_are_clipped_to_the_page_drawn_on() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    for page in Page::ALL {
        for (x0, y0, x1, y1) in AWKWARD_RECTANGLES {
            for other in Page::ALL {
                vga.clear_page(other, BACKGROUND);
            }
            vga.bus_mut().set_write_guard(Some(page_range(page)));
            vga.fill_rect(page, x0, y0, x1, y1, INK);
            let what = std::format!("fill_rect({x0}, {y0}, {x1}, {y1}) on page {}", page.index());
            assert_eq!(
                vga.bus().guard_violations(),
                0,
                "{what}: first stray write at {:?}",
                vga.bus().first_violation()
            );
            let mut expected = Picture::filled(BACKGROUND);
            expected.fill_rect(x0, y0, x1, y1, INK);
            assert_picture(&expected, &page_pixels(vga.bus(), page), &what);
        }
    }
}

#[test]
fn spans_are_clipped_to_the_page_drawn_on() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let spans = [
        (-1, 0, 320),
        (240, 0, 320),
        (i32::MIN, 0, 10),
        (i32::MAX, 0, 10),
        (0, i32::MIN, i32::MAX),
        (239, -5, 3),
        (120, 317, i32::MAX),
        (7, 40, 40),
        (7, 41, 40),
    ];
    for (y, x0, x1) in spans {
        vga.clear_page(Page::One, BACKGROUND);
        vga.bus_mut().set_write_guard(Some(page_range(Page::One)));
        vga.fill_span(Page::One, y, x0, x1, INK);
        let what = std::format!("fill_span({y}, {x0}, {x1})");
        assert_eq!(vga.bus().guard_violations(), 0, "{what}");
        let mut expected = Picture::filled(BACKGROUND);
        expected.fill_rect(x0, y, x1, y.saturating_add(1), INK);
        assert_picture(&expected, &page_pixels(vga.bus(), Page::One), &what);
    }
}

#[test]
fn the_guard_catches_a_stray_write() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.bus_mut().set_write_guard(Some(page_range(Page::One)));
    vga.fill_rect(Page::Zero, 0, 0, 8, 2, INK);
    assert_eq!(vga.bus().guard_violations(), 4);
    assert_eq!(vga.bus().first_violation(), Some(0));
}
