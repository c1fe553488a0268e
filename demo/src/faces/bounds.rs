//! Screen rectangles around objects, to tell when two objects cannot cover
//! the same pixel: the scene's face list gives each object its rectangle,
//! the depth policy asks where they meet. Geometry only; depends on nothing
//! in the crate.

use core::ops::Range;
use engine::Point;

/// The smallest rectangle, edges included, holding every given point. A
/// convex polygon's fill never leaves the rectangle of its corners, so
/// neither does an object's drawing leave the rectangle of its vertices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ScreenBox {
    min: Point,
    max: Point,
}

impl ScreenBox {
    /// The rectangle around `points`, or `None` for no points.
    pub fn around(points: &[Point]) -> Option<ScreenBox> {
        let (first, rest) = points.split_first()?;
        Some(rest.iter().fold(
            ScreenBox {
                min: *first,
                max: *first,
            },
            |bounds, point| ScreenBox {
                min: Point::new(bounds.min.x.min(point.x), bounds.min.y.min(point.y)),
                max: Point::new(bounds.max.x.max(point.x), bounds.max.y.max(point.y)),
            },
        ))
    }

    /// The rows the box spans, as a half-open range.
    pub fn rows(&self) -> Range<i32> {
        self.min.y..self.max.y + 1
    }

    /// The rows where the two share pixels (touching edges count), if any.
    pub fn overlap_rows(&self, other: &ScreenBox) -> Option<Range<i32>> {
        let apart = self.max.x < other.min.x
            || other.max.x < self.min.x
            || self.max.y < other.min.y
            || other.max.y < self.min.y;
        (!apart).then(|| self.min.y.max(other.min.y)..self.max.y.min(other.max.y) + 1)
    }
}

/// The rows, as one range, where any two of the boxes share pixels.
pub fn overlap_rows<'a>(
    mut boxes: impl Iterator<Item = &'a ScreenBox> + Clone,
) -> Option<Range<i32>> {
    let mut rows = None;
    while let Some(a) = boxes.next() {
        for b in boxes.clone() {
            rows = hull(rows, a.overlap_rows(b));
        }
    }
    rows
}

/// The smallest range holding both.
pub fn hull(a: Option<Range<i32>>, b: Option<Range<i32>>) -> Option<Range<i32>> {
    match (a, b) {
        (Some(a), Some(b)) => Some(a.start.min(b.start)..a.end.max(b.end)),
        (a, b) => a.or(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed(points: &[(i32, i32)]) -> ScreenBox {
        let points: std::vec::Vec<Point> = points.iter().map(|&(x, y)| Point::new(x, y)).collect();
        ScreenBox::around(&points).unwrap()
    }

    #[test]
    fn the_box_holds_every_point_and_no_more() {
        let bounds = boxed(&[(5, 9), (-3, 4), (7, -2)]);
        assert_eq!(bounds, boxed(&[(-3, -2), (7, 9)]));
        assert_eq!(ScreenBox::around(&[]), None);
    }

    #[test]
    fn boxes_apart_do_not_overlap_and_touching_ones_do() {
        let left = boxed(&[(0, 0), (10, 10)]);
        let apart = boxed(&[(11, 0), (20, 10)]);
        let touching = boxed(&[(10, 10), (20, 20)]);
        let below = boxed(&[(0, 11), (10, 20)]);
        assert_eq!(left.overlap_rows(&apart), None);
        assert_eq!(apart.overlap_rows(&left), None);
        assert_eq!(left.overlap_rows(&touching), Some(10..11));
        assert_eq!(touching.overlap_rows(&left), Some(10..11));
        assert_eq!(left.overlap_rows(&below), None);
        assert_eq!(overlap_rows([left, apart, below].iter()), None);
        assert_eq!(overlap_rows([left, apart, touching].iter()), Some(10..11));
        assert_eq!(overlap_rows([left].iter()), None);
    }

    #[test]
    fn the_rows_of_several_overlaps_are_joined_into_one_range() {
        let a = boxed(&[(0, 0), (10, 10)]);
        let b = boxed(&[(5, 5), (15, 12)]);
        let c = boxed(&[(100, 50), (110, 60)]);
        let d = boxed(&[(105, 58), (120, 90)]);
        assert_eq!(overlap_rows([a, b, c, d].iter()), Some(5..61));
        assert_eq!(a.rows(), 0..11);
        assert_eq!(hull(None, Some(3..4)), Some(3..4));
        assert_eq!(hull(None, None), None);
    }
}
