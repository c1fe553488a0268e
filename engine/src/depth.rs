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
use modex::{PageSpans, PAGE_PIXELS};

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

/// The depth buffer: w of the nearest thing drawn at each pixel of the
/// frame so far, 0 (infinitely far) where nothing is. 300 KiB, so it lives
/// beside the renderer's frame images (in a static in the kernel, boxed on
/// the host), never on a stack. It covers the whole frame, so every face is
/// drawn into it once a frame (it once covered 40-row bands, when the
/// kernel kept the renderer on its stack, and every face meeting a band was
/// walked again for it).
#[derive(Clone)]
pub struct DepthBuffer {
    w: [u32; PAGE_PIXELS],
}

/// Leaves out the 300 KiB of depths.
impl core::fmt::Debug for DepthBuffer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("DepthBuffer").finish_non_exhaustive()
    }
}

impl Default for DepthBuffer {
    fn default() -> Self {
        Self::new()
    }
}

impl DepthBuffer {
    /// Nothing drawn. All zero, so that a buffer in a static lands in
    /// `.bss`, not in the kernel file.
    pub const fn new() -> Self {
        DepthBuffer {
            w: [0; PAGE_PIXELS],
        }
    }

    /// Back to nothing drawn. `written` marks at least every span tested
    /// since the buffer was last cleared (the frame's own marks serve: each
    /// span tested is marked there too); only those depths are cleared, not
    /// the frame.
    pub fn clear(&mut self, written: &PageSpans) {
        written.fill_lines(0..SCREEN_HEIGHT as usize, &mut self.w, 0);
    }

    /// The span [x0, x1) of row y on the plane: sets
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
        let start = y as usize * SCREEN_WIDTH as usize + x0 as usize;
        let nearest = &mut self.w[start..start + pixels.len()];
        let first_w = plane.at(x0, y);
        // w is linear along the span, so when both ends fit the buffer's
        // range every pixel between does, and none needs clamping. |a| and
        // w stay under 2^52 across the screen, so neither sum overflows.
        let last_w = first_w + plane.a * pixels.len().saturating_sub(1) as i64;
        if !(stores_unclamped(first_w) && stores_unclamped(last_w)) {
            nearer_clamped(nearest, pixels, first_w, plane.a, colour);
        } else if pixels.len() < SHORT_SPAN {
            nearer_in_range_short(nearest, pixels, first_w, plane.a, colour);
        } else {
            nearer_in_range(nearest, pixels, first_w, plane.a, colour);
        }
    }
}

/// Spans shorter than this take the depth test a pixel at a time: four
/// pixels a step do not pay for their set-up.
const SHORT_SPAN: usize = 8;

/// Whether w, stored, needs no clamp: 0 ≤ w >> STORED_SHIFT ≤ u32::MAX.
fn stores_unclamped(w: i64) -> bool {
    (0..=i64::from(u32::MAX)).contains(&(w >> STORED_SHIFT))
}

/// The depth test along a span whose every w stores unclamped (both ends
/// do, see `test_span`): `nearest` and `pixels` as there, w = `first_w` at
/// the first pixel and `step` more at each next. Branchless, so that LLVM
/// makes it four pixels a step in SSE2 (the kernel's target has it): w in
/// 64-bit lanes (`paddq`, `psrlq`: w ≥ 0 here, so the logical shift is the
/// arithmetic one), the compare and both selects in 32-bit lanes. The same
/// integers as `nearer_clamped`, so the same picture.
#[inline(always)]
fn nearer_in_range(nearest: &mut [u32], pixels: &mut [u8], first_w: i64, step: i64, colour: u8) {
    // Two's complement: adding the step's bits wraps to the exact sum, as
    // every w on the span is in 0..2^40.
    let (mut w, step) = (first_w as u64, step as u64);
    for (nearest, pixel) in nearest.iter_mut().zip(pixels) {
        let stored = (w >> STORED_SHIFT) as u32;
        let nearer = stored > *nearest;
        // Stored unconditionally, as a maximum: a store only where nearer
        // would be a branch a pixel again.
        *nearest = stored.max(*nearest);
        *pixel = if nearer { colour } else { *pixel };
        w = w.wrapping_add(step);
    }
}

/// `nearer_in_range` a pixel at a time, for a span too short for four
/// pixels a step to pay: a compare and a branch a pixel, no clamp. The
/// same integers, so the same picture.
fn nearer_in_range_short(
    nearest: &mut [u32],
    pixels: &mut [u8],
    first_w: i64,
    step: i64,
    colour: u8,
) {
    let (mut w, step) = (first_w as u64, step as u64);
    for (nearest, pixel) in nearest.iter_mut().zip(pixels) {
        let stored = (w >> STORED_SHIFT) as u32;
        if stored > *nearest {
            *nearest = stored;
            *pixel = colour;
        }
        w = w.wrapping_add(step);
    }
}

/// The depth test along any span, each pixel's w clamped to the buffer's
/// range: `nearest`, `pixels`, `first_w` and `step` as for
/// `nearer_in_range`.
fn nearer_clamped(nearest: &mut [u32], pixels: &mut [u8], first_w: i64, step: i64, colour: u8) {
    let mut w = first_w;
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
        w += step;
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

    /// The depth test four pixels a step, and the short spans' test with no
    /// clamp, give what the clamped test a pixel at a time gives, pixel for
    /// pixel and depth for depth, on spans of every length, in and out of
    /// the buffer's range, over depths drawn before.
    #[test]
    fn spans_in_range_match_the_test_a_pixel_at_a_time() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = move |below: u64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed % below
        };
        let mut depths = std::boxed::Box::new(DepthBuffer::new());
        let mut frame = [0u8; PAGE_PIXELS];
        let (mut unclamped_spans, mut short_unclamped_spans) = (0, 0);
        let mut previous = None;
        for round in 0..20_000 {
            // Around the range's ends now and then, where clamping starts.
            let c = match random(4) {
                0 => (1i64 << 40) - random(1 << 36) as i64,
                1 => random(1 << 36) as i64 - (1 << 30),
                _ => random(1 << 40) as i64,
            };
            let a = random(1 << 34) as i64 - (1 << 33);
            let plane = DepthPlane {
                a: a >> random(12),
                b: random(1 << 20) as i64 - (1 << 19),
                c,
            };
            let y = 80 + random(40) as i32;
            let x0 = random(320) as i32;
            let len = (random(if round % 2 == 0 { 12 } else { 64 }) as i32).min(320 - x0);
            // Now and then the last span again, in another colour: ties.
            let (plane, y, x0, len) = match previous {
                Some(last) if random(4) == 0 => last,
                _ => (plane, y, x0, len),
            };
            previous = Some((plane, y, x0, len));
            let row = y as usize * 320;
            let span = row + x0 as usize..row + (x0 + len) as usize;
            let colour = random(256) as u8;
            let first_w = plane.at(x0, y);
            let last_w = first_w + plane.a * i64::from((len - 1).max(0));
            if len > 0 && stores_unclamped(first_w) && stores_unclamped(last_w) {
                if len >= SHORT_SPAN as i32 {
                    unclamped_spans += 1;
                } else {
                    short_unclamped_spans += 1;
                }
            }
            let mut nearest = depths.w[span.clone()].to_vec();
            let mut expected = frame[span.clone()].to_vec();
            nearer_clamped(&mut nearest, &mut expected, first_w, plane.a, colour);
            depths.test_span(&plane, y, x0, &mut frame[span.clone()], colour);
            assert!(
                depths.w[span.clone()] == nearest[..],
                "depths differ: {plane:?} y {y} x {x0} len {len}"
            );
            assert!(
                frame[span] == expected[..],
                "pixels differ: {plane:?} y {y} x {x0} len {len}"
            );
        }
        assert!(unclamped_spans > 5_000, "{unclamped_spans} spans in range");
        assert!(
            short_unclamped_spans > 3_000,
            "{short_unclamped_spans} short spans in range"
        );
    }

    #[test]
    fn the_nearer_span_wins_and_ties_keep_the_first() {
        let mut depths = std::boxed::Box::new(DepthBuffer::new());
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
        depths.test_span(&far, 45, 10, &mut row[10..20], 1);
        depths.test_span(&near, 45, 15, &mut row[15..25], 2);
        depths.test_span(&far, 45, 0, &mut row[0..30], 3);
        depths.test_span(&near, 45, 15, &mut row[15..25], 4);
        let expected: std::vec::Vec<u8> = (0..30)
            .map(|x| match x {
                0..10 | 25..30 => 3,
                10..15 => 1,
                _ => 2, // a tie keeps what was drawn first
            })
            .collect();
        assert_eq!(&row[..30], &expected[..]);
        // Cleared, the next frame starts with nothing drawn.
        depths.clear(&PageSpans::all());
        depths.test_span(&far, 45, 10, &mut row[10..20], 5);
        assert_eq!(&row[10..20], &[5; 10]);
    }
}
