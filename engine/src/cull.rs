//! Backface removal in screen space, as Abrash's original program does it: a
//! face is drawn only if it is clockwise on the screen (y down), i.e. its
//! outward side faces the viewer. Integer screen coordinates make the test
//! exact.

use crate::math::Point;

/// True if the polygon (clockwise seen from outside, y down) faces the viewer.
///
/// Abrash's test: the z of the cross product of the first edge (v1 − v0) and
/// the last edge (v[n−1] − v0) must be positive. That fails when either edge
/// has zero length or the two are collinear (rounding can merge vertices), so
/// then the polygon's signed area decides, which uses every vertex.
pub fn is_front_facing(polygon: &[Point]) -> bool {
    if polygon.len() < 3 {
        return false;
    }
    let (v0, v1, last) = (polygon[0], polygon[1], polygon[polygon.len() - 1]);
    let first_edge_cross_last = cross(v0, v1, last);
    if first_edge_cross_last != 0 {
        return first_edge_cross_last > 0;
    }
    twice_signed_area(polygon) > 0
}

/// Twice the area, positive for clockwise on a y-down screen (the shoelace sum
/// with the sign chosen to agree with the cross-product test).
pub fn twice_signed_area(polygon: &[Point]) -> i128 {
    // Each edge a → b, starting with the closing one (exact integers: the
    // order does not matter). A product of two i32s lies within ±2^62, so
    // the difference of two within ±(2^63 − 2^31): i64; only the sum needs
    // i128.
    let Some(&last) = polygon.last() else {
        return 0;
    };
    let mut a = last;
    let mut sum = 0i128;
    for &b in polygon {
        sum += i128::from(i64::from(a.x) * i64::from(b.y) - i64::from(b.x) * i64::from(a.y));
        a = b;
    }
    sum
}

/// z of (a − origin) × (b − origin), exact for any i32 coordinates.
fn cross(origin: Point, a: Point, b: Point) -> i128 {
    let d = |p: Point| {
        (
            i64::from(p.x) - i64::from(origin.x),
            i64::from(p.y) - i64::from(origin.y),
        )
    };
    let ((ax, ay), (bx, by)) = (d(a), d(b));
    // Differences of i32s fit i64, and the product of two sign-extended
    // i64s is one widening multiplication, not an i128 one.
    i128::from(ax) * i128::from(by) - i128::from(ay) * i128::from(bx)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: i32, y: i32) -> Point {
        Point::new(x, y)
    }

    #[test]
    fn clockwise_on_screen_is_front_facing() {
        // y down: right, then down, then left is clockwise as seen.
        let clockwise = [p(0, 0), p(10, 0), p(10, 10), p(0, 10)];
        assert!(is_front_facing(&clockwise));
        let mut counter = clockwise;
        counter.reverse();
        assert!(!is_front_facing(&counter));
        assert!(twice_signed_area(&clockwise) > 0);
    }

    #[test]
    fn a_zero_length_first_edge_falls_back_to_the_area() {
        // v0 == v1: Abrash's cross product is 0 and would cull a visible face.
        let face = [p(0, 0), p(0, 0), p(10, 0), p(10, 10), p(0, 10)];
        assert!(is_front_facing(&face));
        let mut back = face;
        back.reverse();
        assert!(!is_front_facing(&back));
    }

    #[test]
    fn a_zero_length_last_edge_falls_back_to_the_area() {
        let face = [p(0, 0), p(10, 0), p(10, 10), p(0, 10), p(0, 0)];
        assert!(is_front_facing(&face));
    }

    #[test]
    fn collinear_first_and_last_edges_fall_back_to_the_area() {
        // v1 and v[n-1] on one line through v0, but the polygon has area.
        let face = [p(5, 0), p(10, 0), p(10, 10), p(0, 10), p(0, 0)];
        assert_eq!(cross(face[0], face[1], face[4]), 0);
        assert!(is_front_facing(&face));
    }

    #[test]
    fn degenerate_polygons_are_not_drawn() {
        assert!(!is_front_facing(&[p(0, 0), p(5, 5), p(10, 10)]));
        assert!(!is_front_facing(&[p(3, 3); 4]));
        assert!(!is_front_facing(&[p(0, 0), p(1, 1)]));
    }

    #[test]
    fn huge_coordinates_do_not_overflow() {
        let m = i32::MAX;
        assert!(is_front_facing(&[p(-m, -m), p(m, -m), p(m, m), p(-m, m)]));
    }
}
