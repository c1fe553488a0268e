//! The object-to-world transform: a 3x3 rotation and a translation, stored as
//! the top three rows of a 4x4 row-major matrix as in Abrash's listing
//! (`m[row][col]`, translation in column 3; the fourth row is always 0 0 0 1).

use crate::math::Vec3;

/// A rigid motion (rotation, then translation), optionally scaled; see the
/// module documentation for the layout.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Xform {
    m: [[f64; 4]; 3],
}

impl Default for Xform {
    fn default() -> Self {
        Self::identity()
    }
}

impl Xform {
    /// No rotation, no translation: the default.
    pub const fn identity() -> Self {
        Xform {
            m: [
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 0.0, 0.0],
                [0.0, 0.0, 1.0, 0.0],
            ],
        }
    }

    /// A translation by (x, y, z) and no rotation.
    pub const fn translation(x: f64, y: f64, z: f64) -> Self {
        Xform {
            m: [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, y], [0.0, 0.0, 1.0, z]],
        }
    }

    /// A uniform scale. A transform holding one is no longer orthonormal, so
    /// keep it out of transforms that are reorthonormalized: concatenate it
    /// last, `concat(&moved_and_turned, &scaling(k))`.
    pub const fn scaling(factor: f64) -> Self {
        Xform {
            m: [
                [factor, 0.0, 0.0, 0.0],
                [0.0, factor, 0.0, 0.0],
                [0.0, 0.0, factor, 0.0],
            ],
        }
    }

    /// Entry (row, column) of the 4x4 matrix.
    pub fn get(&self, row: usize, column: usize) -> f64 {
        match row {
            0..=2 => self.m[row][column],
            _ => f64::from(u8::from(column == 3)),
        }
    }

    /// `a * b`: applying the result is applying `b`, then `a`.
    pub fn concat(a: &Xform, b: &Xform) -> Xform {
        let mut m = [[0.0; 4]; 3];
        for (row, out) in m.iter_mut().enumerate() {
            for (column, value) in out.iter_mut().enumerate() {
                *value = (0..4).map(|k| a.get(row, k) * b.get(k, column)).sum();
            }
        }
        Xform { m }
    }

    /// Applies the rotation (and any scale), then the translation, to `v`:
    /// object space to world space.
    pub fn transform_point(&self, v: Vec3) -> Vec3 {
        let row = |r: &[f64; 4]| r[0] * v.x + r[1] * v.y + r[2] * v.z + r[3];
        Vec3::new(row(&self.m[0]), row(&self.m[1]), row(&self.m[2]))
    }

    /// The translation: where the transform takes the origin.
    pub fn translation_part(&self) -> Vec3 {
        Vec3::new(self.m[0][3], self.m[1][3], self.m[2][3])
    }

    /// Moves the transform's result by (dx, dy, dz) in world space; the
    /// rotation is unchanged.
    pub fn translate(&mut self, dx: f64, dy: f64, dz: f64) {
        self.m[0][3] += dx;
        self.m[1][3] += dy;
        self.m[2][3] += dz;
    }

    /// Rotates by `angle` radians about the world X axis, on top of whatever
    /// rotation is there: rows 1 and 2 of the rotation change, nothing else
    /// (Abrash's AppendRotationX; the translation is kept).
    pub fn append_rotation_x(&mut self, angle: f64) {
        self.rotate_rows(1, 2, angle);
    }

    /// About the world Y axis: rows 2 and 0 change.
    pub fn append_rotation_y(&mut self, angle: f64) {
        self.rotate_rows(2, 0, angle);
    }

    /// About the world Z axis: rows 0 and 1 change.
    pub fn append_rotation_z(&mut self, angle: f64) {
        self.rotate_rows(0, 1, angle);
    }

    /// Left-multiplies the rotation by a plane rotation mixing rows `a` and
    /// `b`: a' = cos·a − sin·b, b' = sin·a + cos·b, columns 0-2 only.
    fn rotate_rows(&mut self, a: usize, b: usize, angle: f64) {
        let (sin, cos) = (libm::sin(angle), libm::cos(angle));
        for column in 0..3 {
            let (ra, rb) = (self.m[a][column], self.m[b][column]);
            self.m[a][column] = cos * ra - sin * rb;
            self.m[b][column] = sin * ra + cos * rb;
        }
    }

    fn rotation_row(&self, row: usize) -> Vec3 {
        Vec3::new(self.m[row][0], self.m[row][1], self.m[row][2])
    }

    fn set_rotation_row(&mut self, row: usize, v: Vec3) {
        self.m[row][0] = v.x;
        self.m[row][1] = v.y;
        self.m[row][2] = v.z;
    }

    /// Makes the rotation orthonormal again (Gram-Schmidt on its rows), undoing
    /// the drift of many incremental rotations, which would otherwise shear
    /// and scale the object. Abrash warns of the drift and leaves it.
    pub fn reorthonormalize(&mut self) {
        let r0 = self.rotation_row(0);
        let r0 = r0 * (1.0 / r0.length());
        let r1 = self.rotation_row(1);
        let r1 = r1 - r0 * r0.dot(r1);
        let r1 = r1 * (1.0 / r1.length());
        // The third row is fixed by the first two (keeping the handedness).
        let r2 = r0.cross(r1);
        self.set_rotation_row(0, r0);
        self.set_rotation_row(1, r1);
        self.set_rotation_row(2, r2);
    }

    /// The largest entry of |R·Rᵀ − I| for the rotation R: zero when
    /// orthonormal.
    pub fn orthonormality_error(&self) -> f64 {
        let mut worst: f64 = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let expected = if i == j { 1.0 } else { 0.0 };
                let dot = self.rotation_row(i).dot(self.rotation_row(j));
                worst = worst.max(libm::fabs(dot - expected));
            }
        }
        worst
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    fn rotation(axis: usize, angle: f64) -> Xform {
        let (s, c) = (libm::sin(angle), libm::cos(angle));
        let mut r = Xform::identity();
        let (a, b) = [(1, 2), (2, 0), (0, 1)][axis];
        r.m[a][a] = c;
        r.m[a][b] = -s;
        r.m[b][a] = s;
        r.m[b][b] = c;
        r
    }

    fn assert_close(a: &Xform, b: &Xform) {
        for row in 0..3 {
            for column in 0..4 {
                assert!(
                    (a.get(row, column) - b.get(row, column)).abs() < 1e-12,
                    "{a:?} != {b:?}"
                );
            }
        }
    }

    #[test]
    fn incremental_rotations_equal_the_full_matrix_product() {
        let mut xform = Xform::translation(3.0, -4.0, -100.0);
        xform.append_rotation_y(0.3);
        let start = xform;
        for (axis, angle) in [(0, 0.2), (1, -0.7), (2, 1.1), (0, PI / 30.0)] {
            let before = xform;
            match axis {
                0 => xform.append_rotation_x(angle),
                1 => xform.append_rotation_y(angle),
                _ => xform.append_rotation_z(angle),
            }
            let mut expected = Xform::concat(&rotation(axis, angle), &before);
            // Only the rotation is rotated: the translation stays put.
            expected.m[0][3] = before.m[0][3];
            expected.m[1][3] = before.m[1][3];
            expected.m[2][3] = before.m[2][3];
            assert_close(&xform, &expected);
        }
        assert_eq!(xform.translation_part(), start.translation_part());
    }

    #[test]
    fn rotation_about_y_turns_x_toward_minus_z() {
        let mut xform = Xform::identity();
        xform.append_rotation_y(PI / 2.0);
        let v = xform.transform_point(Vec3::new(1.0, 0.0, 0.0));
        assert!((v.x).abs() < 1e-12 && (v.z + 1.0).abs() < 1e-12, "{v:?}");
    }

    #[test]
    fn a_million_small_rotations_stay_orthonormal_with_reorthonormalization() {
        let mut xform = Xform::translation(0.0, 0.0, -100.0);
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for step in 0..1_000_000u32 {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let angle = (seed % 1000) as f64 / 1000.0 * 0.2 - 0.1;
            match seed % 3 {
                0 => xform.append_rotation_x(angle),
                1 => xform.append_rotation_y(angle),
                _ => xform.append_rotation_z(angle),
            }
            if step % 64 == 63 {
                xform.reorthonormalize();
            }
        }
        assert!(
            xform.orthonormality_error() < 1e-6,
            "{}",
            xform.orthonormality_error()
        );
        assert_eq!(xform.translation_part(), Vec3::new(0.0, 0.0, -100.0));
    }

    #[test]
    fn without_reorthonormalization_the_drift_is_measurable() {
        // The check must be able to fail: skew the matrix and see it.
        let mut xform = Xform::identity();
        xform.m[0][1] = 0.01;
        assert!(xform.orthonormality_error() > 1e-3);
        xform.reorthonormalize();
        assert!(xform.orthonormality_error() < 1e-12);
    }
}
