//! The portable 3-D core, in the order a vertex meets it: an object's vertices
//! are transformed from object space to world (= view) space, perspective
//! projected to screen coordinates, faces that point away from the viewer are
//! culled, and the rest are scan-converted into clipped horizontal spans.
//!
//! No hardware, no heap, no `unsafe`: the kernel and the host tests run the
//! very same code. The `test-support` feature adds what only tests need: the
//! `reference` rasterizer and `Object::projections`.
//!
//! # Example
//!
//! A square card with a face on each side, placed in front of the viewer:
//! only the side turned toward the viewer is drawn, and it fills the screen
//! square its corners project to.
//!
//! ```
//! use engine::{fill_convex_polygon, ClipRect, Face, FaceCounts, Model, Object};
//! use engine::{Point, Vec3, Xform};
//!
//! // Faces run clockwise seen from outside: the front (colour 1) from +z,
//! // the back (colour 2) from -z.
//! static CARD: Model = Model {
//!     vertices: &[
//!         Vec3::new(-10.0, 10.0, 0.0),
//!         Vec3::new(10.0, 10.0, 0.0),
//!         Vec3::new(10.0, -10.0, 0.0),
//!         Vec3::new(-10.0, -10.0, 0.0),
//!     ],
//!     faces: &[Face::new(&[0, 1, 2, 3], 1), Face::new(&[3, 2, 1, 0], 2)],
//! };
//!
//! // 50 units away; the viewer looks toward -z.
//! let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
//! let mut front = Vec::new();
//! let counts = card.visible_faces(|polygon, colour| {
//!     assert_eq!(colour, 1);
//!     front.extend_from_slice(polygon);
//! });
//! assert_eq!(counts, FaceCounts { drawn: 1, culled: 1 });
//! // x/z · -2 · 160 = 10/-50 · -320: 64 pixels either side of (160, 120).
//! let corners = [(96, 56), (224, 56), (224, 184), (96, 184)].map(|(x, y)| Point::new(x, y));
//! assert_eq!(front, corners);
//!
//! // Spans exclude their right end and the bottom row: 128 × 128 pixels.
//! let screen = ClipRect { x0: 0, y0: 0, x1: 320, y1: 240 };
//! let mut pixels = 0;
//! fill_convex_polygon(&front, screen, |_y, x0, x1| pixels += x1 - x0);
//! assert_eq!(pixels, 128 * 128);
//!
//! // Half a turn about the vertical axis, and the back is the side drawn.
//! card.object_to_world_mut().append_rotation_y(core::f64::consts::PI);
//! let counts = card.visible_faces(|_, colour| assert_eq!(colour, 2));
//! assert_eq!(counts.drawn, 1);
//! ```

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod cull;
pub mod depth;
pub mod light;
pub mod math;
pub mod object;
pub mod project;
pub mod raster;
#[cfg(any(test, feature = "test-support"))]
pub mod reference;
pub mod xform;

pub use cull::is_front_facing;
pub use depth::{DepthBuffer, DepthPlane};
pub use light::{outward_normal, quantize, Light};
pub use math::{Point, Vec3};
pub use object::{
    Face, FaceCounts, Model, Object, VisibleFace, MAX_FACE_VERTICES, MAX_VERTICES, NEAREST_DRAWN_Z,
};
pub use project::{project_to_screen, PROJECTION_RATIO};
pub use raster::{fill_convex_polygon, ClipRect};
pub use xform::Xform;
