//! Depth for a per-pixel depth test: the reciprocal of a face's distance
//! along the view axis, as a function of the screen pixel.
//!
//! For a planar face, w = −1/z is an affine function of the screen
//! coordinates: with the eye at the origin and the plane n·P = d, dividing by
//! z gives n.x·(x/z) + n.y·(y/z) + n.z = d/z, and x/z and y/z are affine in
//! the screen X and Y. So w is computed exactly from the face's plane at each
//! pixel centre — no interpolation error along edges or spans — and nearer
//! points have larger w (w → 0 far away, w = 1 at z = −1).
//!
//! Why fixed point: integers cost one add and one compare a pixel, and the
//! buffer holds more than `f32` would in the same four bytes (below). (The
//! kernel was soft-float when this was written, where a per-pixel `f32` test
//! cost ten times the whole frame; it now has SSE2, but the integers stay
//! the cheaper and the finer.) The plane's coefficients are computed once per face in `f64` and
//! cut to 40 fractional bits; a span steps w by the integer a per pixel,
//! so the only error is a's truncation, under 320 · 2^-40 ≈ 3e-10 in w across
//! the screen. The buffer keeps w with 32 fractional bits in a `u32` (w = 1,
//! at z = −1, just fits), a resolution of 2.3e-10: z² times that in depth,
//! 2e-6 units at z = −100 and 4e-5 at z = −400 — finer than `f32` there, and
//! far finer than any two faces the scenes bring together.

use crate::math::Vec3;
use crate::project::{PROJECTION_RATIO, SCREEN_HEIGHT, SCREEN_WIDTH};
use modex::PageSpans;

/// Fractional bits of w in `DepthPlane`, and the bits dropped from that to
/// store w in the depth buffer (which keeps 32).
pub const W_FRACTION_BITS: u32 = 40;
const STORED_SHIFT: u32 = W_FRACTION_BITS - 32;
const W_ONE: f64 = (1u64 << W_FRACTION_BITS) as f64;
/// Coefficients beyond this (a plane seen almost edge-on, whose w would leave
/// the buffer's range within a pixel) are refused, so no sum can overflow.
const COEFFICIENT_LIMIT: f64 = (1u64 << 52) as f64;

/// w = a·x + b·y + c at screen pixel (x, y), in units of 2^-40.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DepthPlane {
    /// Change in w per pixel to the right.
    pub a: i64,
    /// Change in w per pixel down.
    pub b: i64,
    /// w at pixel (0, 0).
    pub c: i64,
}

impl DepthPlane {
    /// The plane through `point` with normal `normal` (view space, any
    /// length, either direction). `None` when the plane passes (nearly)
    /// through the eye: such a face is seen edge-on and culled anyway.
    pub fn new(normal: Vec3, point: Vec3) -> Option<DepthPlane> {
        let d = normal.dot(point);
        // |d| > 1e-9·|n|·|p|, squared so as to need no square root; written
        // so that a NaN anywhere also gives `None`.
        let scale2 = normal.dot(normal) * point.dot(point);
        if (d * d).partial_cmp(&(1e-18 * scale2)) != Some(core::cmp::Ordering::Greater) {
            return None;
        }
        // Screen X = cx + (x/z)·k, Y = cy − (y/z)·k with k = ratio · width/2
        // (see `project_to_screen`), so x/z = (X − cx)/k, y/z = −(Y − cy)/k.
        let k = PROJECTION_RATIO * f64::from(SCREEN_WIDTH / 2);
        let (cx, cy) = (f64::from(SCREEN_WIDTH / 2), f64::from(SCREEN_HEIGHT / 2));
        // w = −1/z = −(n.x·x/z + n.y·y/z + n.z)/d.
        let a = -normal.x / (k * d);
        let b = normal.y / (k * d);
        let c = -(normal.z - normal.x * cx / k + normal.y * cy / k) / d;
        let fixed = |v: f64| {
            let v = v * W_ONE;
            // Truncation, not rounding: an error under 2^-40, one
            // instruction.
            (v.abs() < COEFFICIENT_LIMIT).then_some(v as i64)
        };
        Some(DepthPlane {
            a: fixed(a)?,
            b: fixed(b)?,
            c: fixed(c)?,
        })
    }

    /// w at the centre of pixel (x, y), for any pixel of the screen (or a
    /// little beyond) without overflow: |a|, |b|, |c| < 2^52.
    pub fn at(&self, x: i32, y: i32) -> i64 {
        self.a * i64::from(x) + self.b * i64::from(y) + self.c
    }
}

/// Rows of the frame per depth band. The depth buffer covers a band of rows,
/// not the whole frame, and the frame is drawn band by band: 320 × 40 `u32`
/// are 50 KiB instead of 300 KiB for the whole frame, which matters because
/// the kernel keeps the renderer on its 1 MiB stack beside three 75 KiB
/// frame images. The cost is walking the visible faces once per band.
pub const BAND_ROWS: i32 = 40;
/// Depth bands in a frame: the frame is drawn this many times over, one band
/// at a time.
pub const BANDS: i32 = SCREEN_HEIGHT / BAND_ROWS;
const BAND_PIXELS: usize = (SCREEN_WIDTH * BAND_ROWS) as usize;

/// The depth buffer for one band of rows: w of the nearest thing drawn at
/// each pixel so far, 0 (infinitely far) where nothing is.
#[derive(Clone)]
pub struct DepthBand {
    first_row: i32,
    w: [u32; BAND_PIXELS],
}

/// Leaves out the 50 KiB of depths.
impl core::fmt::Debug for DepthBand {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DepthBand")
            .field("first_row", &self.first_row)
            .finish_non_exhaustive()
    }
}

impl Default for DepthBand {
    fn default() -> Self {
        Self::new()
    }
}

impl DepthBand {
    /// Band 0 (the frame's top rows), with nothing drawn.
    pub const fn new() -> Self {
        DepthBand {
            first_row: 0,
            w: [0; BAND_PIXELS],
        }
    }

    /// Starts band `band` (rows band·BAND_ROWS ..), with nothing drawn if
    /// the band was cleared after it was last drawn in.
    pub fn start(&mut self, band: i32) {
        self.first_row = band * BAND_ROWS;
    }

    /// Back to nothing drawn. `written` marks, in frame rows, at least every
    /// span tested since the band started (the frame's own marks serve:
    /// each span tested is marked there too); only those depths are
    /// cleared, not the band.
    pub fn clear(&mut self, written: &PageSpans) {
        let rows = self.first_row as usize..(self.first_row + BAND_ROWS) as usize;
        written.fill_lines(rows, &mut self.w, 0);
    }

    /// The band's rows as a clip rectangle.
    pub fn clip(&self) -> crate::raster::ClipRect {
        crate::raster::ClipRect {
            x0: 0,
            y0: self.first_row,
            x1: SCREEN_WIDTH,
            y1: self.first_row + BAND_ROWS,
        }
    }

    /// The span [x0, x1) of row y (inside the band) on the plane: sets
    /// `pixels` (the span's pixels in the frame, x0 first) to `colour`
    /// where the plane is nearer than everything drawn there so far, and
    /// remembers it as the nearest. Ties keep what was drawn first.
    pub fn test_span(
        &mut self,
        plane: &DepthPlane,
        y: i32,
        x0: i32,
        pixels: &mut [u8],
        colour: u8,
    ) {
        let local = (y - self.first_row) as usize;
        let start = local * SCREEN_WIDTH as usize + x0 as usize;
        let nearest = &mut self.w[start..start + pixels.len()];
        let mut w = plane.at(x0, y);
        for (nearest, pixel) in nearest.iter_mut().zip(pixels) {
            // w ≤ 0 is at or beyond infinity (a plane extended past its face
            // toward the horizon): never drawn. Nearer than z = −1 is
            // clamped; nothing drawn comes that near.
            let stored = (w >> STORED_SHIFT).clamp(0, i64::from(u32::MAX)) as u32;
            if stored > *nearest {
                *nearest = stored;
                *pixel = colour;
            }
            // Exact: integers, so the step adds no error.
            w += plane.a;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::project::project_to_screen;

    #[test]
    fn w_at_a_vertex_is_minus_one_over_its_z() {
        // A tilted plane; its vertices' projections must give back −1/z
        // (up to the projection's rounding to whole pixels, so compare at
        // the exact projected position instead).
        let corners = [
            Vec3::new(-20.0, 10.0, -80.0),
            Vec3::new(30.0, 15.0, -120.0),
            Vec3::new(5.0, -25.0, -95.0),
        ];
        let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        let plane = DepthPlane::new(normal, corners[0]).unwrap();
        for p in corners {
            let k = PROJECTION_RATIO * 160.0;
            let (x, y) = (160.0 + p.x / p.z * k, 120.0 - p.y / p.z * k);
            let w = (plane.a as f64 * x + plane.b as f64 * y + plane.c as f64) / W_ONE;
            assert!((w - (-1.0 / p.z)).abs() < 1e-9, "{w} vs {}", -1.0 / p.z);
            // And the rounded projection is within a pixel's worth.
            let s = project_to_screen(p);
            assert!((plane.at(s.x, s.y) as f64 / W_ONE + 1.0 / p.z).abs() < 1e-3);
        }
    }

    #[test]
    fn a_plane_through_the_eye_has_no_depth() {
        let n = Vec3::new(1.0, 0.0, 0.0);
        assert!(DepthPlane::new(n, Vec3::new(0.0, 3.0, -50.0)).is_none());
        assert!(
            DepthPlane::new(Vec3::new(f64::NAN, 0.0, 1.0), Vec3::new(0.0, 0.0, -5.0)).is_none()
        );
    }

    #[test]
    fn the_nearer_span_wins_and_ties_keep_the_first() {
        let mut band = DepthBand::new();
        band.start(1);
        let far = DepthPlane {
            a: 0,
            b: 0,
            c: 1 << 33,
        };
        let near = DepthPlane {
            a: 0,
            b: 0,
            c: 1 << 34,
        };
        let mut row = [0u8; 320];
        band.test_span(&far, 45, 10, &mut row[10..20], 1);
        band.test_span(&near, 45, 15, &mut row[15..25], 2);
        band.test_span(&far, 45, 0, &mut row[0..30], 3);
        band.test_span(&near, 45, 15, &mut row[15..25], 4);
        let expected: std::vec::Vec<u8> = (0..30)
            .map(|x| match x {
                0..10 | 25..30 => 3,
                10..15 => 1,
                _ => 2, // a tie keeps what was drawn first
            })
            .collect();
        assert_eq!(&row[..30], &expected[..]);
        assert_eq!(band.clip().y0, BAND_ROWS);
        // Cleared, the next band starts with nothing drawn.
        band.clear(&PageSpans::all());
        band.start(2);
        band.test_span(&far, 85, 10, &mut row[10..20], 5);
        assert_eq!(&row[10..20], &[5; 10]);
    }
}
