//! A plain, slow reference rasterizer: every pixel of the clip rectangle is
//! tested against every edge. It shares no code with the scan converter, so
//! agreement between the two means something. For tests only: the
//! `test-support` feature.

use crate::cull::twice_signed_area;
use crate::math::Point;
use crate::raster::ClipRect;

/// Calls `pixel(x, y)` for each pixel the fill rule draws: the integer point
/// strictly inside every edge, or on an edge that is a left or a top edge.
/// Zero-area polygons draw nothing.
pub fn fill_pixels(points: &[Point], clip: ClipRect, mut pixel: impl FnMut(i32, i32)) {
    let orientation = twice_signed_area(points).signum();
    if points.len() < 3 || orientation == 0 {
        return;
    }
    for y in clip.y0..clip.y1 {
        for x in clip.x0..clip.x1 {
            if inside(points, orientation, x, y) {
                pixel(x, y);
            }
        }
    }
}

fn inside(points: &[Point], orientation: i128, x: i32, y: i32) -> bool {
    let n = points.len();
    (0..n).all(|i| {
        let (a, b) = (points[i], points[(i + 1) % n]);
        let (ex, ey) = (
            i128::from(b.x) - i128::from(a.x),
            i128::from(b.y) - i128::from(a.y),
        );
        if ex == 0 && ey == 0 {
            return true; // a repeated vertex is no edge
        }
        // Positive on the polygon's inner side, whichever way it winds.
        let side = orientation
            * (ex * (i128::from(y) - i128::from(a.y)) - ey * (i128::from(x) - i128::from(a.x)));
        if side != 0 {
            return side > 0;
        }
        // On the edge's line: drawn only for left edges (the inside lies toward
        // +x) and top edges (horizontal, the inside lies toward +y).
        let inside_toward_plus_x = -orientation * ey > 0;
        let top = ey == 0 && orientation * ex > 0;
        inside_toward_plus_x || top
    })
}
