//! A solid: shared vertices, faces that index them, and the object-to-world
//! transform. The view-space and screen position of each vertex are computed
//! once per change of the transform, and only then (the RecalcXform flag of
//! Abrash's listing): a frame that moves nothing reuses them.

use crate::cull::is_front_facing;
use crate::depth::DepthPlane;
use crate::light::{newell_normal, outward_normal};
use crate::math::{Point, Vec3};
use crate::project::project_to_screen;
use crate::xform::Xform;
use core::sync::atomic::{AtomicU64, Ordering};

/// Most vertices a model may have: an object keeps its projected vertices in
/// fixed-size arrays, as there is no heap.
pub const MAX_VERTICES: usize = 32;
/// Most corners a face may have, for the same reason.
pub const MAX_FACE_VERTICES: usize = 8;
/// An object with any vertex nearer than this (view z above it; the viewer
/// looks toward -Z) is not drawn at all: there is no near-plane clipping, and
/// a vertex at or behind the eye has no meaningful projection.
pub const NEAREST_DRAWN_Z: f64 = -1.0;

/// One face: indices into the model's vertex list, clockwise seen from
/// outside, and a palette colour.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Face {
    /// Indices into [`Model::vertices`], clockwise seen from outside.
    pub vertices: &'static [usize],
    /// The face's flat palette colour.
    pub colour: u8,
}

impl Face {
    /// A face with these corners and colour; `const`, so that models can be
    /// statics.
    pub const fn new(vertices: &'static [usize], colour: u8) -> Self {
        Face { vertices, colour }
    }
}

/// The unchanging description of a solid, in object space.
#[derive(Debug)]
pub struct Model {
    /// The corners, shared by the faces that meet there.
    pub vertices: &'static [Vec3],
    /// The faces, each naming its corners in `vertices`.
    pub faces: &'static [Face],
}

/// A face that survived culling, as handed to the drawing code.
#[derive(Debug)]
pub struct VisibleFace<'a> {
    /// The model's face.
    pub face: &'a Face,
    /// The face's corners on the screen, in the face's order.
    pub polygon: &'a [Point],
    view: &'a [Vec3],
}

impl VisibleFace<'_> {
    /// The face's outward unit normal in view space, for shading.
    pub fn normal(&self) -> Vec3 {
        outward_normal(self.face.vertices.iter().map(|&v| self.view[v]))
    }

    /// The mean of the face's corners in view space: where the painter's
    /// algorithm takes a face to be.
    pub fn centre(&self) -> Vec3 {
        let sum = self
            .face
            .vertices
            .iter()
            .fold(Vec3::default(), |sum, &v| sum + self.view[v]);
        sum * (1.0 / self.face.vertices.len() as f64)
    }

    /// −1/z across the face's plane, per screen pixel, for the depth test.
    pub fn depth_plane(&self) -> Option<DepthPlane> {
        let newell = newell_normal(self.face.vertices.iter().map(|&v| self.view[v]));
        DepthPlane::new(newell, self.view[self.face.vertices[0]])
    }
}

/// How many faces one pass over the scene drew and culled (culled includes
/// the faces of an object too near to draw).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaceCounts {
    /// Faces handed to the drawing code.
    pub drawn: u32,
    /// Faces turned away from the viewer, or of an object too near to draw.
    pub culled: u32,
}

impl core::ops::AddAssign for FaceCounts {
    fn add_assign(&mut self, other: FaceCounts) {
        self.drawn += other.drawn;
        self.culled += other.culled;
    }
}

/// How many projections of any object there have been: each takes the next
/// number, so a number names one set of projected vertices (see
/// [`Object::projection`]). Zero, so that it starts in `.bss`.
static PROJECTIONS_SO_FAR: AtomicU64 = AtomicU64::new(0);

/// A model placed in the world.
#[derive(Clone, Debug)]
pub struct Object {
    model: &'static Model,
    object_to_world: Xform,
    view: [Vec3; MAX_VERTICES],
    screen: [Point; MAX_VERTICES],
    /// Every vertex lies beyond `NEAREST_DRAWN_Z`.
    in_front: bool,
    recalc: bool,
    /// The number of the projection `view` and `screen` come from (0
    /// before the first).
    projection: u64,
    #[cfg(any(test, feature = "test-support"))]
    projections: u64,
}

/// Panics if the model has more vertices, or a face more corners, than the
/// fixed-size buffers hold, or a face names a vertex that is not there.
/// (`const`, hence the index loops: an object can then be a static's.)
const fn check_model(model: &Model) {
    assert!(
        model.vertices.len() <= MAX_VERTICES,
        "model has too many vertices"
    );
    let mut f = 0;
    while f < model.faces.len() {
        let corners = model.faces[f].vertices;
        assert!(
            corners.len() <= MAX_FACE_VERTICES,
            "face has too many vertices"
        );
        let mut c = 0;
        while c < corners.len() {
            assert!(
                corners[c] < model.vertices.len(),
                "face names a missing vertex"
            );
            c += 1;
        }
        f += 1;
    }
}

impl Object {
    /// Panics if the model does not fit the fixed-size buffers (see
    /// `MAX_VERTICES`, `MAX_FACE_VERTICES`) or a face names a missing vertex.
    /// `const`, so that many objects can live in a static rather than on a
    /// stack.
    pub const fn new(model: &'static Model, object_to_world: Xform) -> Self {
        check_model(model);
        Object {
            model,
            object_to_world,
            view: [Vec3::new(0.0, 0.0, 0.0); MAX_VERTICES],
            screen: [Point::new(0, 0); MAX_VERTICES],
            in_front: false,
            recalc: true,
            projection: 0,
            #[cfg(any(test, feature = "test-support"))]
            projections: 0,
        }
    }

    /// The solid this object shows.
    pub fn model(&self) -> &'static Model {
        self.model
    }

    /// Puts another solid in this one's place, with the same transform; it is
    /// projected before the next frame. Panics as `new` does.
    pub fn set_model(&mut self, model: &'static Model) {
        check_model(model);
        self.model = model;
        self.recalc = true;
    }

    /// Where the object is and how it is turned.
    pub fn object_to_world(&self) -> &Xform {
        &self.object_to_world
    }

    /// Changes the transform; the vertices are projected again before the next
    /// frame.
    pub fn object_to_world_mut(&mut self) -> &mut Xform {
        self.recalc = true;
        &mut self.object_to_world
    }

    /// Where the object's origin is in view space.
    pub fn position(&self) -> Vec3 {
        self.object_to_world.translation_part()
    }

    /// How many times the vertices have been transformed and projected
    /// (`test-support` only: a test's way to see that an unmoved object is
    /// not projected again).
    #[cfg(any(test, feature = "test-support"))]
    pub fn projections(&self) -> u64 {
        self.projections
    }

    fn recalculate_if_moved(&mut self) {
        if !self.recalc {
            return;
        }
        let count = self.model.vertices.len();
        for (view, &vertex) in self.view.iter_mut().zip(self.model.vertices) {
            *view = self.object_to_world.transform_point(vertex);
        }
        for (screen, &view) in self.screen.iter_mut().zip(&self.view[..count]) {
            *screen = project_to_screen(view);
        }
        // Asked as `z <= limit`, so a NaN counts as too near.
        self.in_front = self.view[..count]
            .iter()
            .all(|view| view.z <= NEAREST_DRAWN_Z);
        self.recalc = false;
        self.projection = PROJECTIONS_SO_FAR.fetch_add(1, Ordering::Relaxed) + 1;
        #[cfg(any(test, feature = "test-support"))]
        {
            self.projections += 1;
        }
    }

    /// The number of the projection the object's vertices come from,
    /// projecting them first if it moved. No two projections, of this
    /// object or any other, share a number in a run of the program (a clone
    /// shares its original's until either moves), so the same number means
    /// the same model, view and screen vertices: the same faces, which a
    /// face list can keep rather than find again (`demo::faces`).
    pub fn projection(&mut self) -> u64 {
        self.recalculate_if_moved();
        self.projection
    }

    /// The screen position of each vertex (view space is world space here).
    pub fn screen_vertices(&mut self) -> &[Point] {
        self.recalculate_if_moved();
        &self.screen[..self.model.vertices.len()]
    }

    /// Calls `draw` for each face that faces the viewer, in face order, and
    /// counts the faces drawn and culled. An object reaching nearer than
    /// `NEAREST_DRAWN_Z` draws nothing.
    pub fn each_visible_face(&mut self, mut draw: impl FnMut(&VisibleFace)) -> FaceCounts {
        self.recalculate_if_moved();
        let faces = self.model.faces;
        if !self.in_front {
            return FaceCounts {
                drawn: 0,
                culled: faces.len() as u32,
            };
        }
        let mut counts = FaceCounts::default();
        let mut corners = [Point::default(); MAX_FACE_VERTICES];
        for face in faces {
            let polygon = &mut corners[..face.vertices.len()];
            for (corner, &index) in polygon.iter_mut().zip(face.vertices) {
                *corner = self.screen[index];
            }
            if is_front_facing(polygon) {
                counts.drawn += 1;
                draw(&VisibleFace {
                    face,
                    polygon,
                    view: &self.view,
                });
            } else {
                counts.culled += 1;
            }
        }
        counts
    }

    /// Calls `draw` with the screen polygon and colour of each face that faces
    /// the viewer, in face order.
    pub fn visible_faces(&mut self, mut draw: impl FnMut(&[Point], u8)) -> FaceCounts {
        self.each_visible_face(|visible| draw(visible.polygon, visible.face.colour))
    }

    /// The view-space (= world-space) position of a vertex, computed afresh;
    /// for tests and for checking models, not needed to draw.
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
    fn a_projection_number_names_one_set_of_vertices() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        let mut other = card.clone();
        let first = card.projection();
        assert_ne!(first, 0);
        assert_eq!(card.projection(), first, "unmoved, the same vertices");
        drawn_colours(&mut card);
        assert_eq!(card.projection(), first);
        // Another object's projection, even of the same model in the same
        // place, has a number of its own.
        assert_ne!(other.projection(), first);
        card.object_to_world_mut().translate(1.0, 0.0, 0.0);
        let moved = card.projection();
        assert_ne!(moved, first, "moved, new vertices");
        card.set_model(&CARD);
        assert_ne!(card.projection(), moved, "a new model, new vertices");
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
    fn counts_say_how_many_faces_were_drawn_and_culled() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        let counts = card.visible_faces(|_, _| {});
        assert_eq!(
            counts,
            FaceCounts {
                drawn: 1,
                culled: 1
            }
        );
    }

    #[test]
    fn an_object_reaching_the_eye_draws_nothing() {
        // The card's corners are at z = 0 when it sits on the eye.
        for z in [-0.5, 0.0, 30.0, f64::NAN] {
            let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, z));
            let counts = card.visible_faces(|_, _| panic!("drew a face at z = {z}"));
            assert_eq!(
                counts,
                FaceCounts {
                    drawn: 0,
                    culled: 2
                },
                "z = {z}"
            );
        }
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, NEAREST_DRAWN_Z));
        assert_eq!(card.visible_faces(|_, _| {}).drawn, 1);
    }

    #[test]
    fn a_new_model_is_projected_before_the_next_frame() {
        static TRIANGLE: Model = Model {
            vertices: &[
                Vec3::new(0.0, 10.0, 0.0),
                Vec3::new(10.0, -10.0, 0.0),
                Vec3::new(-10.0, -10.0, 0.0),
            ],
            faces: &[Face {
                vertices: &[0, 1, 2],
                colour: 3,
            }],
        };
        let mut object = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        drawn_colours(&mut object);
        object.set_model(&TRIANGLE);
        assert_eq!(drawn_colours(&mut object), [3]);
        assert_eq!(object.projections(), 2);
        assert_eq!(object.screen_vertices().len(), 3);
    }

    #[test]
    fn visible_faces_know_their_view_space_normal() {
        let mut card = Object::new(&CARD, Xform::translation(0.0, 0.0, -50.0));
        card.object_to_world_mut()
            .append_rotation_y(core::f64::consts::FRAC_PI_6);
        let mut normals = Vec::new();
        card.each_visible_face(|face| normals.push(face.normal()));
        // The front turned 30 degrees about Y: (sin 30°, 0, cos 30°).
        let expected = Vec3::new(0.5, 0.0, libm::sqrt(3.0) / 2.0);
        assert_eq!(normals.len(), 1);
        assert!((normals[0] - expected).length() < 1e-12, "{:?}", normals[0]);
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
