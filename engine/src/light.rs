//! Flat shading by a distant light (Ammeraal and Zhang's "colouring individual
//! faces"): each face gets one brightness, from the angle between its outward
//! normal and the direction towards the light, both in view space.

use crate::math::Vec3;

/// The outward unit normal of a planar face whose corners run clockwise seen
/// from outside, as every face here does. Newell's method sums over all
/// edges, so a degenerate first edge or a slightly non-planar face still gives
/// the right direction; a face with no area gives the zero vector.
pub fn outward_normal(corners: impl Iterator<Item = Vec3>) -> Vec3 {
    let newell = newell_normal(corners);
    // Newell's normal follows the right-hand rule: it points towards the side
    // from which the corners run counter-clockwise, i.e. inward here.
    let length = newell.length();
    if length == 0.0 {
        Vec3::default()
    } else {
        newell * (-1.0 / length)
    }
}

/// Newell's normal, not scaled to unit length (no square root: the depth
/// test needs only the plane, and the kernel computes without an FPU).
pub fn newell_normal(mut corners: impl Iterator<Item = Vec3>) -> Vec3 {
    let mut newell = Vec3::default();
    let Some(first) = corners.next() else {
        return newell;
    };
    // Each edge a → b in turn, the closing one last: one pass over the
    // corners rather than a second, cycled, iterator beside the first.
    let mut add_edge = |a: Vec3, b: Vec3| {
        newell.x += (a.y - b.y) * (a.z + b.z);
        newell.y += (a.z - b.z) * (a.x + b.x);
        newell.z += (a.x - b.x) * (a.y + b.y);
    };
    let mut a = first;
    for b in corners {
        add_edge(a, b);
        a = b;
    }
    add_edge(a, first);
    newell
}

/// A light at infinity, given by where it stands as seen from the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Turn about the view Y axis, radians; 0 is straight behind the viewer,
    /// negative is to the left.
    yaw: f64,
    /// Height above the horizontal plane, radians, within ±π/2.
    pitch: f64,
    /// The share of full brightness that every face gets, lit or not.
    ambient: f64,
}

impl Light {
    /// `yaw` and `pitch` place the light (see the fields); `ambient` is clamped
    /// to 0..=1 and the diffuse part makes up the rest.
    pub fn new(yaw: f64, pitch: f64, ambient: f64) -> Self {
        Light {
            yaw: wrap_angle(yaw),
            pitch: pitch.clamp(-core::f64::consts::FRAC_PI_2, core::f64::consts::FRAC_PI_2),
            ambient: ambient.clamp(0.0, 1.0),
        }
    }

    /// Turn about the view Y axis, radians in −π..=π; 0 is straight behind
    /// the viewer, negative is to the left.
    pub fn yaw(&self) -> f64 {
        self.yaw
    }

    /// Height above the horizontal plane, radians in −π/2..=π/2.
    pub fn pitch(&self) -> f64 {
        self.pitch
    }

    /// Turns the light about the view's vertical axis (positive: to the
    /// right) and up or down (positive: up; it stops overhead or underfoot).
    pub fn turn(&mut self, yaw: f64, pitch: f64) {
        *self = Light::new(self.yaw + yaw, self.pitch + pitch, self.ambient);
    }

    /// The unit vector from the scene towards the light.
    pub fn towards_light(&self) -> Vec3 {
        let horizontal = libm::cos(self.pitch);
        Vec3::new(
            horizontal * libm::sin(self.yaw),
            libm::sin(self.pitch),
            horizontal * libm::cos(self.yaw),
        )
    }

    /// Brightness 0..=1 of a face with this outward unit normal: the ambient
    /// share plus the diffuse share times the cosine of the angle of
    /// incidence, which is zero for a face turned away from the light.
    pub fn intensity(&self, normal: Vec3) -> f64 {
        let incidence = normal.dot(self.towards_light()).max(0.0);
        (self.ambient + (1.0 - self.ambient) * incidence).clamp(0.0, 1.0)
    }
}

/// The level 0..levels-1 that an intensity 0..=1 rounds to (NaN counts as 0).
pub fn quantize(intensity: f64, levels: u8) -> u8 {
    let top = f64::from(levels.saturating_sub(1));
    let level = libm::floor(intensity.clamp(0.0, 1.0) * top + 0.5);
    if level.is_nan() {
        0
    } else {
        level as u8
    }
}

fn wrap_angle(angle: f64) -> f64 {
    let turn = 2.0 * core::f64::consts::PI;
    let wrapped = angle - turn * libm::floor(angle / turn + 0.5);
    if wrapped.is_finite() {
        wrapped
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};

    fn close(a: Vec3, b: Vec3) -> bool {
        (a - b).length() < 1e-12
    }

    #[test]
    fn the_normal_of_a_clockwise_square_points_out_of_the_side_it_is_seen_from() {
        // Seen from +z (x right, y up), this square runs clockwise.
        let square = [
            Vec3::new(-1.0, 1.0, 5.0),
            Vec3::new(1.0, 1.0, 5.0),
            Vec3::new(1.0, -1.0, 5.0),
            Vec3::new(-1.0, -1.0, 5.0),
        ];
        assert!(close(
            outward_normal(square.iter().copied()),
            Vec3::new(0.0, 0.0, 1.0)
        ));
        assert!(close(
            outward_normal(square.iter().rev().copied()),
            Vec3::new(0.0, 0.0, -1.0)
        ));
    }

    #[test]
    fn a_repeated_corner_or_a_face_without_area_does_not_break_the_normal() {
        let with_repeat = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
            Vec3::new(2.0, 0.0, 0.0),
        ];
        assert!(close(
            outward_normal(with_repeat.iter().copied()),
            Vec3::new(0.0, 0.0, 1.0)
        ));
        let line = [Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 1.0)];
        assert_eq!(outward_normal(line.iter().copied()), Vec3::default());
    }

    /// The depth test's planes, and so the pictures, rest on these bits:
    /// the edges summed in order, c0→c1 … the closing edge last.
    #[test]
    fn newells_normal_sums_the_edges_in_order_to_the_bit() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % 20_000) as f64 / 7.0 - 1_400.0
        };
        for corners in 0..=8 {
            for _ in 0..50 {
                let points: std::vec::Vec<Vec3> = (0..corners)
                    .map(|_| Vec3::new(next(), next(), next()))
                    .collect();
                let mut expected = Vec3::default();
                for i in 0..corners {
                    let (a, b) = (points[i], points[(i + 1) % corners]);
                    expected.x += (a.y - b.y) * (a.z + b.z);
                    expected.y += (a.z - b.z) * (a.x + b.x);
                    expected.z += (a.x - b.x) * (a.y + b.y);
                }
                let newell = newell_normal(points.iter().copied());
                let bits = |v: Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
                assert_eq!(bits(newell), bits(expected), "{points:?}");
            }
        }
    }

    #[test]
    fn the_default_light_of_ammeraal_and_zhang_comes_from_upper_left_front() {
        // Their s = (-1, 1, 1)/√3.
        let light = Light::new(-FRAC_PI_4, libm::asin(1.0 / libm::sqrt(3.0)), 0.25);
        let s = 1.0 / libm::sqrt(3.0);
        assert!(close(light.towards_light(), Vec3::new(-s, s, s)));
    }

    #[test]
    fn intensity_is_ambient_plus_diffuse_times_the_cosine() {
        let light = Light::new(0.0, 0.0, 0.25); // straight behind the viewer
        let facing = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(light.intensity(facing), 1.0);
        assert_eq!(light.intensity(-facing), 0.25, "turned away: ambient only");
        assert_eq!(light.intensity(Vec3::new(1.0, 0.0, 0.0)), 0.25);
        let sixty_degrees = Vec3::new(libm::sin(PI / 3.0), 0.0, libm::cos(PI / 3.0));
        assert!((light.intensity(sixty_degrees) - (0.25 + 0.75 * 0.5)).abs() < 1e-12);
    }

    #[test]
    fn turning_the_light_moves_it_and_it_stops_overhead() {
        let mut light = Light::new(0.0, 0.0, 0.2);
        light.turn(FRAC_PI_2, 0.0);
        assert!(close(light.towards_light(), Vec3::new(1.0, 0.0, 0.0)));
        for _ in 0..20 {
            light.turn(0.0, 0.3);
        }
        assert_eq!(light.pitch(), FRAC_PI_2);
        assert!(close(light.towards_light(), Vec3::new(0.0, 1.0, 0.0)));
        light.turn(7.0 * PI, 0.0);
        assert!(
            light.yaw().abs() <= PI,
            "yaw stays wrapped: {}",
            light.yaw()
        );
    }

    #[test]
    fn quantize_rounds_to_the_nearest_level_and_tolerates_nonsense() {
        assert_eq!(quantize(0.0, 32), 0);
        assert_eq!(quantize(1.0, 32), 31);
        assert_eq!(quantize(0.5, 32), 16); // 15.5 rounds up
        assert_eq!(quantize(0.49, 32), 15);
        assert_eq!(quantize(7.0, 32), 31);
        assert_eq!(quantize(-1.0, 32), 0);
        assert_eq!(quantize(f64::NAN, 32), 0);
        assert_eq!(quantize(1.0, 0), 0);
    }
}
