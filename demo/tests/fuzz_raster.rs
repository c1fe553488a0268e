//! The rasterizer and clipper under attack: arbitrary vertices (huge,
//! negative, duplicated, collinear, in any order) and arbitrary clip
//! rectangles. Never a panic, never a span outside the clip rectangle, never a
//! write outside the page being drawn, and for convex input the very pixels of
//! the reference rasterizer.
//!
//! The case count is PROPTEST_CASES (CI runs the default below; raise it for a
//! longer hunt: `PROPTEST_CASES=100000 cargo test --test fuzz_raster`).

#[path = "common/fuzzing.rs"]
mod fuzzing;

use engine::{fill_convex_polygon, reference, ClipRect, Point};
use fuzzing::soft_vga_in_mode_x;
use modex::{ModeX, Page, PAGE_BYTES};
use proptest::prelude::*;

const DEFAULT_CASES: u32 = 2000;

fn config() -> ProptestConfig {
    fuzzing::proptest_config(DEFAULT_CASES)
}

fn any_coordinate() -> impl Strategy<Value = i32> {
    prop_oneof![
        -100i32..420,   // near the screen
        -5000i32..5000, // far off it
        any::<i32>(),   // anything at all
        Just(i32::MIN),
        Just(i32::MAX),
    ]
}

fn any_point() -> impl Strategy<Value = Point> {
    (any_coordinate(), any_coordinate()).prop_map(|(x, y)| Point::new(x, y))
}

/// Clip rectangles small enough for the reference to test every pixel,
/// including empty and inverted ones.
fn any_clip() -> impl Strategy<Value = ClipRect> {
    (-64i32..384, -64i32..304, -64i32..384, -64i32..304).prop_map(|(x0, y0, x1, y1)| ClipRect {
        x0,
        y0,
        x1,
        y1,
    })
}

/// The convex hull, so the reference's convex fill rule applies.
fn convex_hull(mut points: Vec<Point>) -> Vec<Point> {
    points.sort_by_key(|p| (p.x, p.y));
    points.dedup();
    let cross = |o: Point, a: Point, b: Point| {
        (i128::from(a.x) - i128::from(o.x)) * (i128::from(b.y) - i128::from(o.y))
            - (i128::from(a.y) - i128::from(o.y)) * (i128::from(b.x) - i128::from(o.x))
    };
    if points.len() < 3 {
        return points;
    }
    let mut hull: Vec<Point> = Vec::new();
    for pass in [points.clone(), points.iter().rev().copied().collect()] {
        let start = hull.len();
        for p in pass {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

fn spans(points: &[Point], clip: ClipRect) -> Vec<(i32, i32)> {
    let mut pixels = Vec::new();
    fill_convex_polygon(points, clip, |y, x0, x1| {
        assert!(
            clip.x0 <= x0 && x0 < x1 && x1 <= clip.x1 && clip.y0 <= y && y < clip.y1,
            "span outside the clip"
        );
        pixels.extend((x0..x1).map(|x| (x, y)));
    });
    pixels
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn any_polygon_stays_inside_the_clip_rectangle(points in prop::collection::vec(any_point(), 0..10), clip in any_clip()) {
        spans(&points, clip);
    }

    #[test]
    fn convex_polygons_equal_the_reference(points in prop::collection::vec(any_point(), 3..10), clip in any_clip()) {
        let hull = convex_hull(points);
        let mut expected = Vec::new();
        reference::fill_pixels(&hull, clip, |x, y| expected.push((x, y)));
        expected.sort_by_key(|&(x, y)| (y, x));
        prop_assert_eq!(spans(&hull, clip), expected);
    }

    #[test]
    fn drawing_through_mode_x_never_leaves_the_page(
        points in prop::collection::vec(any_point(), 0..10),
        page in 0u8..3,
        colour in any::<u8>(),
    ) {
        let mut soft = soft_vga_in_mode_x();
        let start = u16::from(page) * PAGE_BYTES;
        soft.set_write_guard(Some(start..start + PAGE_BYTES));
        let mut vga = ModeX::new(&mut *soft);
        let page = Page::ALL[usize::from(page)];
        let screen = ClipRect { x0: 0, y0: 0, x1: 320, y1: 240 };
        fill_convex_polygon(&points, screen, |y, x0, x1| vga.fill_span(page, y, x0, x1, colour));
        // The driver clips on its own too: spans straight from the fuzzer.
        for pair in points.windows(2) {
            vga.fill_span(page, pair[0].y, pair[0].x, pair[1].x, colour);
            vga.fill_rect(page, pair[0].x, pair[0].y, pair[1].x, pair[1].y, colour);
            vga.put_pixel(page, pair[1].x, pair[1].y, colour);
        }
        prop_assert_eq!(soft.guard_violations(), 0);
    }

    /// A fan of triangles from one corner tiles a convex polygon: together
    /// they must cover exactly its pixels, none twice (no gaps at shared
    /// edges, no seams drawn twice).
    #[test]
    fn polygons_sharing_edges_cover_their_union_exactly_once(points in prop::collection::vec(near_point(), 3..10)) {
        let hull = convex_hull(points);
        prop_assume!(hull.len() >= 3);
        let screen = ClipRect { x0: 0, y0: 0, x1: 320, y1: 240 };
        let mut seen = std::collections::HashSet::new();
        for i in 1..hull.len() - 1 {
            for pixel in spans(&[hull[0], hull[i], hull[i + 1]], screen) {
                prop_assert!(seen.insert(pixel), "pixel {:?} drawn twice", pixel);
            }
        }
        let whole = spans(&hull, screen);
        prop_assert_eq!(seen.len(), whole.len());
        prop_assert!(whole.iter().all(|p| seen.contains(p)));
    }
}

fn near_point() -> impl Strategy<Value = Point> {
    (-60i32..380, -60i32..300).prop_map(|(x, y)| Point::new(x, y))
}
