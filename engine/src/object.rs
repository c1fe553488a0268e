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

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A square card at z = 0 in object space, one face per side: the front
    /// (colour 1) is clockwise seen from +z, the back (colour 2) from -z.
    static CARD: Model = Model {
        vertices: &[
            Vec3::new(-10.0, 10.0, 0.0),
            Vec3::new(10.0, 10.0, 0.0),
            Vec3::new(10.0, -10.0, 0.0),
            Vec3::new(-10.0, -10.0, 0.0),
        ],
        faces: &[
            Face {
                vertices: &[0, 1, 2, 3],
                colour: 1,
            },
            Face {
                vertices: &[3, 2, 1, 0],
                colour: 2,
            },
        ],
    };

    fn drawn_colours(object: &mut Object) -> Vec<u8> {
        let mut colours = Vec::new();
        object.visible_faces(|_, colour| colours.push(colour));
        colours
    }

    #[test]
    fn vertices_are_projected_once_per_change_of_the_transform() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        assert_eq!(
            card.projections(),
            0,
            "nothing is projected before it is asked for"
        );
        drawn_colours(&mut card);
        drawn_colours(&mut card);
        card.screen_vertices();
        assert_eq!(card.projections(), 1);
        card.object_to_world_mut().translate(1.0, 0.0, 0.0);
        card.object_to_world_mut().append_rotation_z(0.1);
        assert_eq!(card.projections(), 1, "projection waits for the next frame");
        drawn_colours(&mut card);
        assert_eq!(card.projections(), 2);
    }

    #[test]
    fn screen_vertices_follow_the_transform() {
        // 10/50 · 320 = 64 pixels from the centre, y up in the world, down on screen.
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        assert_eq!(
            card.screen_vertices(),
            &[
                Point::new(96, 56),
                Point::new(224, 56),
                Point::new(224, 184),
                Point::new(96, 184)
            ]
        );
        card.object_to_world_mut().translate(0.0, 0.0, -50.0);
        assert_eq!(card.screen_vertices()[0], Point::new(128, 88));
    }

    #[test]
    fn only_the_side_facing_the_viewer_is_drawn() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        assert_eq!(drawn_colours(&mut card), [1]);
        card.object_to_world_mut()
            .append_rotation_y(core::f64::consts::PI);
        assert_eq!(drawn_colours(&mut card), [2]);
        // Edge-on, the card is a line on the screen: neither side is drawn.
        card.object_to_world_mut()
            .append_rotation_y(core::f64::consts::FRAC_PI_2);
        assert_eq!(drawn_colours(&mut card), [] as [u8; 0]);
    }

    #[test]
    fn visible_faces_hand_over_the_faces_corners_in_order() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        let screen = card.screen_vertices().to_vec();
        card.visible_faces(|polygon, _| assert_eq!(polygon, &screen[..]));
    }

    #[test]
    #[should_panic(expected = "face names a missing vertex")]
    fn a_face_naming_a_missing_vertex_is_refused() {
        static BROKEN: Model = Model {
            vertices: &[Vec3::new(0.0, 0.0, 0.0)],
            faces: &[Face {
                vertices: &[0, 1, 2],
                colour: 1,
            }],
        };
        Object::new(&BROKEN, Xform::identity());
    }
}
