//! Convex polygon scan conversion with clipping.
//!
//! The fill rule makes polygons that share an edge tile without gaps and
//! without drawing any pixel twice: pixel (x, y) is drawn when the integer
//! point (x, y) lies inside the polygon, or on a left or top edge. In scan-line
//! terms: rows from the top vertex (included) to the bottom one (excluded), and
//! on each row from ceil(x_left) (included) to ceil(x_right) (excluded).
//!
//! Any `i32` vertices are accepted (huge, negative, duplicated, collinear,
//! either winding) without overflow or panic: each edge's first crossing is
//! computed exactly from the quotient and remainder of its slope (in 64-bit
//! integers, for any corners), and the next rows' are stepped from it by the
//! same quotient and remainder, with no division. Work is bounded by
//! the clip rectangle's rows, not the polygon's.

use crate::math::Point;

/// A half-open clip rectangle [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClipRect {
    /// The leftmost column drawn.
    pub x0: i32,
    /// The top row drawn.
    pub y0: i32,
    /// The column just right of the last one drawn.
    pub x1: i32,
    /// The row just below the last one drawn.
    pub y1: i32,
}

/// Fills the convex polygon `points`, calling `span(y, x_start, x_end)` for
/// each non-empty, clipped span [x_start, x_end) from top to bottom.
///
/// Non-convex input is filled between each row's outermost crossings: never
/// outside the clip rectangle, but not a faithful non-convex fill.
pub fn fill_convex_polygon(points: &[Point], clip: ClipRect, mut span: impl FnMut(i32, i32, i32)) {
    fill(points, clip, &mut span);
}

/// `fill_convex_polygon` behind one call per span through `span`: one copy
/// of the loops, not one per caller's closure (a copy cost the kernel file
/// 2 to 3.5 KiB), for an indirect call a span.
fn fill(points: &[Point], clip: ClipRect, span: &mut dyn FnMut(i32, i32, i32)) {
    if points.len() < 3 || clip.x0 >= clip.x1 || clip.y0 >= clip.y1 {
        return;
    }
    let top = points.iter().map(|p| p.y).min().unwrap_or(0).max(clip.y0);
    let bottom = points.iter().map(|p| p.y).max().unwrap_or(0).min(clip.y1);
    if top >= bottom {
        return;
    }
    // Each edge's crossing stepped from row to row, exactly: one division
    // per edge rather than two per edge on every row. A polygon with more
    // corners than the steps hold (none the models have) starts each edge
    // afresh on every row.
    let corners = points.len();
    let edge = |i: usize, from: i32, to: i32| {
        // The corner after corner i, the last closing on the first: a
        // compare, not a division by `corners`.
        let next = if i + 1 == corners { 0 } else { i + 1 };
        EdgeStep::new(points[i], points[next], from, to)
    };
    let mut edges = [EdgeStep::default(); STEPPED_EDGES];
    let stepped = corners <= STEPPED_EDGES;
    if stepped {
        for (i, step) in edges.iter_mut().enumerate().take(corners) {
            *step = edge(i, top, bottom);
        }
    }
    for y in top..bottom {
        let mut left = i64::MAX;
        let mut right = i64::MIN;
        let mut cross = |crossing: Option<i64>| {
            if let Some(x) = crossing {
                left = left.min(x);
                right = right.max(x);
            }
        };
        if stepped {
            edges[..corners]
                .iter_mut()
                .for_each(|step| cross(step.crossing(y)));
        } else {
            (0..corners).for_each(|i| cross(edge(i, y, y + 1).crossing(y)));
        }
        let x_start = left.max(i64::from(clip.x0));
        let x_end = right.min(i64::from(clip.x1));
        if x_start < x_end {
            // Both lie within the clip rectangle's i32 range.
            span(y, x_start as i32, x_end as i32);
        }
    }
}

/// ⌊n/d⌋ and n mod d (0 ≤ remainder < d) for d > 0: one truncating
/// division and a step down for a negative remainder, where `div_euclid`
/// and `rem_euclid` divide twice and handle a negative divisor too.
#[inline(always)]
fn floor_div_rem(n: i64, d: i64) -> (i64, i64) {
    let (quotient, remainder) = (n / d, n % d);
    if remainder < 0 {
        (quotient - 1, remainder + d)
    } else {
        (quotient, remainder)
    }
}

/// Edges a polygon may have for its crossings to be stepped.
const STEPPED_EDGES: usize = 8;

/// One edge's crossings with successive rows, from its first row inside the
/// fill to its last: x = ⌈upper.x + n/dy⌉ with n = (y − upper.y)·dx, kept as
/// the quotient and remainder of n/dy and stepped by those of dx/dy, so
/// each row's crossing is exact with no division. |x| stays within 2^33,
/// so nothing overflows.
#[derive(Clone, Copy, Default)]
struct EdgeStep {
    /// Rows covered and not yet stepped past: `next_row..end_row`.
    next_row: i32,
    end_row: i32,
    /// upper.x + ⌊n/dy⌋, and n mod dy.
    quotient: i64,
    remainder: i64,
    step_quotient: i64,
    step_remainder: i64,
    dy: i64,
}

impl EdgeStep {
    /// Edge a–b, over the rows of `top..bottom` it covers. An edge covers
    /// rows min(a.y, b.y) ..< max(a.y, b.y), so a shared vertex is counted
    /// once and horizontal edges not at all.
    fn new(a: Point, b: Point, top: i32, bottom: i32) -> EdgeStep {
        let (upper, lower) = if a.y < b.y { (a, b) } else { (b, a) };
        let (first, end) = (upper.y.max(top), lower.y.min(bottom));
        if first >= end {
            return EdgeStep::default();
        }
        let dx = i64::from(lower.x) - i64::from(upper.x);
        let dy = i64::from(lower.y) - i64::from(upper.y);
        let down = i64::from(first) - i64::from(upper.y);
        // ⌊n/dy⌋ with n = down·dx, from dx = q·dy + r (the per-row step):
        // n = down·q·dy + down·r, so ⌊n/dy⌋ = down·q + ⌊down·r/dy⌋ and
        // n mod dy = down·r mod dy. As down < dy, |down·q| < |dx| + dy <
        // 2^33, and 0 ≤ down·r < dy² < 2^64 fits a u64: exact for any
        // corners, with one more division and no i128.
        let (step_quotient, step_remainder) = floor_div_rem(dx, dy);
        let (dy_unsigned, below) = (dy as u64, down as u64 * step_remainder as u64);
        EdgeStep {
            next_row: first,
            end_row: end,
            quotient: i64::from(upper.x) + down * step_quotient + (below / dy_unsigned) as i64,
            remainder: (below % dy_unsigned) as i64,
            step_quotient,
            step_remainder,
            dy,
        }
    }

    /// The crossing with row `y` (rows are asked for in order), if the edge
    /// covers it.
    #[inline(always)]
    fn crossing(&mut self, y: i32) -> Option<i64> {
        if y != self.next_row || y >= self.end_row {
            return None;
        }
        let x = self.quotient + i64::from(self.remainder != 0);
        self.next_row += 1;
        self.quotient += self.step_quotient;
        self.remainder += self.step_remainder;
        if self.remainder >= self.dy {
            self.remainder -= self.dy;
            self.quotient += 1;
        }
        Some(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference;
    use std::vec;
    use std::vec::Vec;

    const SCREEN: ClipRect = ClipRect {
        x0: 0,
        y0: 0,
        x1: 320,
        y1: 240,
    };

    fn spans_to_pixels(points: &[Point], clip: ClipRect) -> Vec<(i32, i32)> {
        let mut pixels = Vec::new();
        let mut last_y = i32::MIN;
        fill_convex_polygon(points, clip, |y, x0, x1| {
            assert!(y > last_y, "spans must come top to bottom, one per row");
            last_y = y;
            assert!(x0 < x1 && clip.x0 <= x0 && x1 <= clip.x1 && clip.y0 <= y && y < clip.y1);
            pixels.extend((x0..x1).map(|x| (x, y)));
        });
        pixels
    }

    fn reference_pixels(points: &[Point], clip: ClipRect) -> Vec<(i32, i32)> {
        let mut pixels = Vec::new();
        reference::fill_pixels(points, clip, |x, y| pixels.push((x, y)));
        pixels.sort_by_key(|&(x, y)| (y, x));
        pixels
    }

    #[test]
    fn equals_the_reference_on_degenerate_polygons() {
        let cases: [&[Point]; 6] = [
            &[Point::new(5, 5), Point::new(5, 5), Point::new(5, 5)],
            &[Point::new(0, 0), Point::new(10, 10), Point::new(20, 20)],
            &[Point::new(0, 7), Point::new(30, 7), Point::new(12, 7)],
            &[
                Point::new(3, 0),
                Point::new(3, 0),
                Point::new(20, 9),
                Point::new(3, 18),
            ],
            &[
                Point::new(1, 1),
                Point::new(9, 1),
                Point::new(9, 1),
                Point::new(9, 8),
                Point::new(1, 8),
            ],
            &[Point::new(0, 0), Point::new(2, 1)],
        ];
        for polygon in cases {
            assert_eq!(
                spans_to_pixels(polygon, SCREEN),
                reference_pixels(polygon, SCREEN),
                "{polygon:?}"
            );
        }
    }

    #[test]
    fn huge_and_negative_coordinates_are_clipped_without_overflow() {
        let m = i32::MAX;
        let n = i32::MIN;
        let cases: [&[Point]; 4] = [
            &[
                Point::new(n, n),
                Point::new(m, n),
                Point::new(m, m),
                Point::new(n, m),
            ],
            &[Point::new(n, 0), Point::new(m, 1), Point::new(0, m)],
            &[Point::new(-5, n), Point::new(400, 120), Point::new(-5, m)],
            &[Point::new(m, m), Point::new(m - 1, m), Point::new(m, m - 1)],
        ];
        for polygon in cases {
            assert_eq!(
                spans_to_pixels(polygon, SCREEN),
                reference_pixels(polygon, SCREEN),
                "{polygon:?}"
            );
        }
        // The full screen is covered by the first.
        assert_eq!(spans_to_pixels(cases[0], SCREEN).len(), 320 * 240);
    }

    #[test]
    fn empty_and_inverted_clip_rectangles_draw_nothing() {
        let square = [
            Point::new(0, 0),
            Point::new(50, 0),
            Point::new(50, 50),
            Point::new(0, 50),
        ];
        for clip in [
            ClipRect {
                x0: 10,
                y0: 10,
                x1: 10,
                y1: 40,
            },
            ClipRect {
                x0: 40,
                y0: 10,
                x1: 10,
                y1: 40,
            },
            ClipRect {
                x0: 10,
                y0: 40,
                x1: 40,
                y1: 10,
            },
        ] {
            assert!(spans_to_pixels(&square, clip).is_empty());
        }
    }

    #[test]
    fn floor_div_rem_is_euclids_for_a_positive_divisor() {
        for n in (-40..=40).chain([i64::MIN + 1, i64::MAX, -(1 << 40) - 3, 1 << 40]) {
            for d in [1, 2, 3, 7, 39, 1 << 33, i64::MAX] {
                assert_eq!(
                    floor_div_rem(n, d),
                    (n.div_euclid(d), n.rem_euclid(d)),
                    "{n} / {d}"
                );
            }
        }
    }

    #[test]
    fn a_square_has_the_expected_pixels() {
        // [2, 6) x [1, 4): the right column and bottom row are excluded.
        let square = [
            Point::new(2, 1),
            Point::new(6, 1),
            Point::new(6, 4),
            Point::new(2, 4),
        ];
        let pixels = spans_to_pixels(&square, SCREEN);
        assert_eq!(pixels.len(), 4 * 3);
        assert_eq!(pixels[0], (2, 1));
        assert_eq!(*pixels.last().unwrap(), (5, 3));
    }

    /// Signed turns at every corner all agree (zero turns allowed): the
    /// reference's rule is the convex one, so only such polygons are compared.
    fn is_convex(points: &[Point]) -> bool {
        let n = points.len();
        let turns = (0..n).map(|i| {
            let (a, b, c) = (points[i], points[(i + 1) % n], points[(i + 2) % n]);
            i64::from(b.x - a.x) * i64::from(c.y - b.y)
                - i64::from(b.y - a.y) * i64::from(c.x - b.x)
        });
        let (mut positive, mut negative) = (false, false);
        for turn in turns {
            positive |= turn > 0;
            negative |= turn < 0;
        }
        !(positive && negative)
    }

    #[test]
    fn rotated_regular_polygons_equal_the_reference() {
        // Many corners, sub-pixel to screen-filling sizes, every orientation,
        // both windings, straddling the clip rectangle's sides.
        let clip = ClipRect {
            x0: -8,
            y0: 4,
            x1: 72,
            y1: 68,
        };
        let (mut compared, mut skipped) = (0, 0);
        for corners in 3..=8 {
            for radius in [0.7, 2.5, 6.3, 21.0, 47.5, 300.0] {
                for (cx, cy) in [(32.3, 36.6), (-6.0, 60.1), (70.5, 3.2)] {
                    for step in 0..24 {
                        let phase = f64::from(step) * 0.2618 + f64::from(corners) * 0.1;
                        let mut polygon: Vec<Point> = (0..corners)
                            .map(|k| {
                                let angle = phase
                                    + f64::from(k) * 2.0 * core::f64::consts::PI
                                        / f64::from(corners);
                                Point::new(
                                    libm::round(cx + radius * libm::cos(angle)) as i32,
                                    libm::round(cy + radius * libm::sin(angle)) as i32,
                                )
                            })
                            .collect();
                        if step % 2 == 1 {
                            polygon.reverse();
                        }
                        // Rounding a tiny polygon's corners can dent it.
                        if !is_convex(&polygon) {
                            skipped += 1;
                            continue;
                        }
                        compared += 1;
                        assert_eq!(
                            spans_to_pixels(&polygon, clip),
                            reference_pixels(&polygon, clip),
                            "{polygon:?}"
                        );
                    }
                }
            }
        }
        assert!(compared > 2400, "compared {compared}, skipped {skipped}");
    }

    /// Past eight corners each edge's crossing is started afresh on every
    /// row rather than stepped: the same pixels.
    #[test]
    fn polygons_of_many_corners_equal_the_reference() {
        for corners in 9..=16 {
            for radius in [9.5, 40.0, 130.0] {
                let polygon: Vec<Point> = (0..corners)
                    .map(|k| {
                        let angle =
                            0.3 + f64::from(k) * 2.0 * core::f64::consts::PI / f64::from(corners);
                        Point::new(
                            libm::round(150.0 + radius * libm::cos(angle)) as i32,
                            libm::round(110.0 + radius * libm::sin(angle)) as i32,
                        )
                    })
                    .collect();
                let pixels = spans_to_pixels(&polygon, SCREEN);
                assert!(!pixels.is_empty());
                assert_eq!(pixels, reference_pixels(&polygon, SCREEN), "{polygon:?}");
            }
        }
    }

    #[test]
    fn a_mesh_of_quads_and_triangles_covers_the_clip_rectangle_exactly_once() {
        // A jittered grid reaching past the clip rectangle on every side,
        // split into quads and both kinds of triangle pair, in both windings:
        // every shared edge in every direction, and each pixel must be drawn
        // by exactly one face.
        const SPACING: i32 = 16;
        const CELLS: usize = 10;
        let clip = ClipRect {
            x0: 5,
            y0: 3,
            x1: 139,
            y1: 127,
        };
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut jitter = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 7) as i32 - 3 // ±3 keeps every cell convex
        };
        let mut grid = [[Point::default(); CELLS + 1]; CELLS + 1];
        for (row, points) in grid.iter_mut().enumerate() {
            for (column, point) in points.iter_mut().enumerate() {
                *point = Point::new(
                    column as i32 * SPACING - 12 + jitter(),
                    row as i32 * SPACING - 12 + jitter(),
                );
            }
        }
        let mut count = std::collections::HashMap::new();
        let mut draw = |polygon: &mut Vec<Point>, reversed: bool| {
            if reversed {
                polygon.reverse();
            }
            for pixel in spans_to_pixels(polygon, clip) {
                *count.entry(pixel).or_insert(0) += 1;
            }
        };
        for row in 0..CELLS {
            for column in 0..CELLS {
                let (a, b) = (grid[row][column], grid[row][column + 1]);
                let (c, d) = (grid[row + 1][column + 1], grid[row + 1][column]);
                let reversed = (row + column) % 2 == 0;
                match (row * 7 + column * 3) % 3 {
                    0 => draw(&mut vec![a, b, c, d], reversed),
                    1 => {
                        draw(&mut vec![a, b, c], reversed);
                        draw(&mut vec![a, c, d], !reversed);
                    }
                    _ => {
                        draw(&mut vec![a, b, d], reversed);
                        draw(&mut vec![b, c, d], reversed);
                    }
                }
            }
        }
        let area = (clip.x1 - clip.x0) * (clip.y1 - clip.y0);
        assert_eq!(count.len(), area as usize, "gaps between faces");
        assert!(count.values().all(|&n| n == 1), "pixels drawn twice");
    }
}
