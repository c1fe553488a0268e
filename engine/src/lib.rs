//! The portable 3-D core, in the order a vertex meets it: an object's vertices
//! are transformed from object space to world (= view) space, perspective
//! projected to screen coordinates, faces that point away from the viewer are
//! culled, and the rest are scan-converted into clipped horizontal spans.
//!
//! No hardware, no heap, no `unsafe`: the kernel and the host tests run the
//! very same code.

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs, missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod cull;
pub mod depth;
pub mod light;
pub mod math;
pub mod object;
pub mod project;
pub mod raster;
pub mod reference;
pub mod xform;

pub use cull::is_front_facing;
pub use depth::{DepthBand, DepthPlane, BANDS, BAND_ROWS};
pub use light::{outward_normal, quantize, Light};
pub use math::{Point, Vec3};
pub use object::{
    Face, FaceCounts, Model, Object, VisibleFace, MAX_FACE_VERTICES, MAX_VERTICES, NEAREST_DRAWN_Z,
};
pub use project::{project_to_screen, PROJECTION_RATIO, SCREEN_HEIGHT, SCREEN_WIDTH};
pub use raster::{fill_convex_polygon, ClipRect};
pub use xform::Xform;
