//! Perspective projection from view space to the screen, exactly as Abrash's
//! original program does it: the viewpoint at the origin looking toward -Z,
//! right-handed.

use crate::math::{Point, Vec3};
// The screen projected onto is the one the Mode X driver shows; its size is
// defined there, once.
pub(crate) use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};
/// Distance from the viewpoint to the projection plane over the plane's
/// width; negative because the view looks toward -Z.
pub const PROJECTION_RATIO: f64 = -2.0;
/// Projected coordinates are clamped to this magnitude, so a vertex at or
/// behind the viewpoint gives a far-off point rather than an overflow.
const PROJECTED_LIMIT: f64 = 1_000_000.0;

/// X = x/z · ratio · width/2, Y likewise; then rounded with floor(v + 0.5)
/// (floor, so negative values round the same way as positive ones), centred,
/// and Y flipped to increase downward.
pub fn project_to_screen(view: Vec3) -> Point {
    let scale = PROJECTION_RATIO * f64::from(SCREEN_WIDTH / 2);
    let clamp = |v: f64| {
        if v.is_nan() {
            0.0
        } else {
            v.clamp(-PROJECTED_LIMIT, PROJECTED_LIMIT)
        }
    };
    let x = clamp(view.x / view.z * scale);
    let y = clamp(view.y / view.z * scale);
    Point::new(
        floor_to_int(x + 0.5) + SCREEN_WIDTH / 2,
        -floor_to_int(y + 0.5) + SCREEN_HEIGHT / 2,
    )
}

/// ⌊v⌋ for |v| within the clamp above: truncate (one SSE2 conversion), then
/// one down if that went up, as it does for a negative fraction. The same
/// integer as `libm::floor(v) as i32`, which in software costs some thirty
/// instructions a call.
fn floor_to_int(v: f64) -> i32 {
    let truncated = v as i32;
    truncated - i32::from(f64::from(truncated) > v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projects_like_abrashs_program() {
        // (15, 15, -85): X = 15/-85 · -2 · 160 = 56.47 -> 56 -> 216; Y -> 120 - 56 = 64.
        assert_eq!(
            project_to_screen(Vec3::new(15.0, 15.0, -85.0)),
            Point::new(216, 64)
        );
        // Negative values round with floor(v + 0.5): -56.47 -> -56.
        assert_eq!(
            project_to_screen(Vec3::new(-15.0, -15.0, -85.0)),
            Point::new(104, 176)
        );
        // Exactly half rounds up in both directions: X = 0.5 -> 1, X = -0.5 -> 0.
        assert_eq!(project_to_screen(Vec3::new(0.5, 0.0, -320.0)).x, 161);
        assert_eq!(project_to_screen(Vec3::new(-0.5, 0.0, -320.0)).x, 160);
    }

    #[test]
    fn floor_to_int_is_floor() {
        let mut v = -PROJECTED_LIMIT - 0.5;
        for special in [
            -2.5, -2.0, -1.5, -0.5, -0.0, 0.0, 0.5, 1.0, 1.5, -1e-300, 1e-300,
        ] {
            assert_eq!(
                floor_to_int(special),
                libm::floor(special) as i32,
                "{special}"
            );
        }
        // Values across the whole clamped range, with every kind of fraction.
        while v <= PROJECTED_LIMIT + 0.5 {
            assert_eq!(floor_to_int(v), libm::floor(v) as i32, "{v}");
            assert_eq!(floor_to_int(-v), libm::floor(-v) as i32, "{v}");
            v += 12_345.678_9;
        }
    }

    #[test]
    fn a_vertex_at_the_viewpoint_does_not_overflow() {
        let p = project_to_screen(Vec3::new(1.0, -1.0, 0.0));
        assert!(p.x.abs() <= 1_000_200 && p.y.abs() <= 1_000_200, "{p:?}");
        assert_eq!(
            project_to_screen(Vec3::new(0.0, 0.0, 0.0)),
            Point::new(160, 120)
        );
    }
}
