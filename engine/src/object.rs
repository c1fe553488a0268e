//! A solid: shared vertices, faces that index them, and the object-to-world
//! transform. The screen position of each vertex is computed once per change
//! of the transform, and only then (the seed's RecalcXform flag): a frame that
//! moves nothing reuses them.

use crate::cull::is_front_facing;
use crate::math::{Point, Vec3};
use crate::project::project_to_screen;
use crate::xform::Xform;

pub const MAX_VERTICES: usize = 32;
pub const MAX_FACE_VERTICES: usize = 8;

/// One face: indices into the model's vertex list, clockwise seen from
/// outside, and a palette colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Face {
    pub vertices: &'static [usize],
    pub colour: u8,
}

/// The unchanging description of a solid, in object space.
#[derive(Debug)]
pub struct Model {
    pub vertices: &'static [Vec3],
    pub faces: &'static [Face],
}

/// A model placed in the world.
#[derive(Clone, Debug)]
pub struct Object {
    model: &'static Model,
    object_to_world: Xform,
    screen: [Point; MAX_VERTICES],
    recalc: bool,
    projections: u64,
}

impl Object {
    /// Panics if the model has more vertices, or a face more corners, than the
    /// fixed-size buffers hold, or a face names a vertex that is not there.
    pub fn new(model: &'static Model, object_to_world: Xform) -> Self {
        assert!(
            model.vertices.len() <= MAX_VERTICES,
            "model has too many vertices"
        );
        for face in model.faces {
            assert!(
                face.vertices.len() <= MAX_FACE_VERTICES,
                "face has too many vertices"
            );
            assert!(
                face.vertices.iter().all(|&v| v < model.vertices.len()),
                "face names a missing vertex"
            );
        }
        Object {
            model,
            object_to_world,
            screen: [Point::default(); MAX_VERTICES],
            recalc: true,
            projections: 0,
        }
    }

    pub fn model(&self) -> &'static Model {
        self.model
    }

    pub fn object_to_world(&self) -> &Xform {
        &self.object_to_world
    }

    /// Changes the transform; the vertices are projected again before the next
    /// frame.
    pub fn object_to_world_mut(&mut self) -> &mut Xform {
        self.recalc = true;
        &mut self.object_to_world
    }

    /// How many times the vertices have been transformed and projected.
    pub fn projections(&self) -> u64 {
        self.projections
    }

    /// The screen position of each vertex (view space is world space here).
    pub fn screen_vertices(&mut self) -> &[Point] {
        if self.recalc {
            for (screen, &vertex) in self.screen.iter_mut().zip(self.model.vertices) {
                *screen = project_to_screen(self.object_to_world.transform_point(vertex));
            }
            self.recalc = false;
            self.projections += 1;
        }
        &self.screen[..self.model.vertices.len()]
    }

    /// Calls `draw` with the screen polygon and colour of each face that faces
    /// the viewer, in face order.
    pub fn visible_faces(&mut self, mut draw: impl FnMut(&[Point], u8)) {
        let model = self.model;
        let screen = self.screen_vertices();
        let mut polygon = [Point::default(); MAX_FACE_VERTICES];
        for face in model.faces {
            let polygon = &mut polygon[..face.vertices.len()];
            for (corner, &index) in polygon.iter_mut().zip(face.vertices) {
                *corner = screen[index];
            }
            if is_front_facing(polygon) {
                draw(polygon, face.colour);
            }
        }
    }

    /// The view-space (= world-space) position of each vertex; for tests and
    /// for shading, not needed to draw.
    pub fn view_vertex(&self, index: usize) -> Vec3 {
        self.object_to_world
            .transform_point(self.model.vertices[index])
    }
}
