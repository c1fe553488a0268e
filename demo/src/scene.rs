//! The seed's scene: one cube floating in front of the viewer, moved and
//! turned by commands, optionally spinning by itself.

use core::f64::consts::PI;
use engine::{Face, Model, Object, Point, Vec3, Xform};

/// The seed's cube: eight shared vertices, in the seed's order (vertex 6 is
/// (-15, -15, 15); the OCR of the seed lost a digit there).
static CUBE_VERTICES: [Vec3; 8] = [
    Vec3::new(15.0, 15.0, 15.0),
    Vec3::new(15.0, 15.0, -15.0),
    Vec3::new(15.0, -15.0, 15.0),
    Vec3::new(15.0, -15.0, -15.0),
    Vec3::new(-15.0, 15.0, 15.0),
    Vec3::new(-15.0, 15.0, -15.0),
    Vec3::new(-15.0, -15.0, 15.0),
    Vec3::new(-15.0, -15.0, -15.0),
];

/// Six faces, clockwise seen from outside, with the seed's colours (white,
/// yellow, bright red, bright cyan, bright green, bright blue).
static CUBE_FACES: [Face; 6] = [
    Face {
        vertices: &[1, 3, 2, 0],
        colour: 15,
    },
    Face {
        vertices: &[5, 7, 3, 1],
        colour: 14,
    },
    Face {
        vertices: &[4, 5, 1, 0],
        colour: 12,
    },
    Face {
        vertices: &[3, 7, 6, 2],
        colour: 11,
    },
    Face {
        vertices: &[5, 4, 6, 7],
        colour: 10,
    },
    Face {
        vertices: &[0, 2, 6, 4],
        colour: 9,
    },
];

pub static CUBE: Model = Model {
    vertices: &CUBE_VERTICES,
    faces: &CUBE_FACES,
};

/// Where the cube starts: no rotation, 100 units in front of the viewer.
pub const INITIAL_Z: f64 = -100.0;
/// One keypress moves the cube this far.
pub const MOVE_STEP: f64 = 3.0;
/// Toward the viewer stops here, so no near-plane clipping is needed.
pub const NEAREST_Z: f64 = -40.0;
/// One keypress turns the cube 6 degrees.
pub const ROTATION_STEP: f64 = PI / 30.0;
/// The automatic spin per frame: about Y and, more slowly, about X.
pub const SPIN_Y_PER_FRAME: f64 = PI / 180.0;
pub const SPIN_X_PER_FRAME: f64 = PI / 360.0;
/// Rotations between re-orthonormalisations: often enough that the drift
/// stays far below what a pixel can show.
const ROTATIONS_PER_REORTHONORMALIZATION: u32 = 64;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X,
    Y,
    Z,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Command {
    MoveLeft,
    MoveRight,
    MoveUp,
    MoveDown,
    Away,
    Toward,
    /// Rotate by +6 (true) or -6 (false) degrees about the axis.
    Rotate(Axis, bool),
    ToggleSpin,
    Reset,
    /// Any key that is not a command: wait for the next key.
    Pause,
    Quit,
}

pub struct Scene {
    cube: Object,
    spinning: bool,
    rotations: u32,
}

impl Default for Scene {
    fn default() -> Self {
        Self::new()
    }
}

impl Scene {
    /// The scene at boot: the seed's initial cube, spinning.
    pub fn new() -> Self {
        let mut scene = Self::initial();
        scene.spinning = true;
        scene
    }

    /// The seed's initial state, still: what Reset returns to.
    pub fn initial() -> Self {
        Scene {
            cube: Object::new(&CUBE, Xform::translation(0.0, 0.0, INITIAL_Z)),
            spinning: false,
            rotations: 0,
        }
    }

    pub fn spinning(&self) -> bool {
        self.spinning
    }

    pub fn cube(&self) -> &Object {
        &self.cube
    }

    pub fn cube_mut(&mut self) -> &mut Object {
        &mut self.cube
    }

    /// Applies one command (Pause and Quit are the caller's business and leave
    /// the scene as it is).
    pub fn apply(&mut self, command: Command) {
        match command {
            Command::MoveLeft => self.translate(-MOVE_STEP, 0.0, 0.0),
            Command::MoveRight => self.translate(MOVE_STEP, 0.0, 0.0),
            Command::MoveUp => self.translate(0.0, MOVE_STEP, 0.0),
            Command::MoveDown => self.translate(0.0, -MOVE_STEP, 0.0),
            Command::Away => self.translate(0.0, 0.0, -MOVE_STEP),
            Command::Toward => {
                if self.cube.object_to_world().translation_part().z < NEAREST_Z {
                    self.translate(0.0, 0.0, MOVE_STEP);
                }
            }
            Command::Rotate(axis, positive) => self.rotate(
                axis,
                if positive {
                    ROTATION_STEP
                } else {
                    -ROTATION_STEP
                },
            ),
            Command::ToggleSpin => self.spinning = !self.spinning,
            Command::Reset => *self = Self::initial(),
            Command::Pause | Command::Quit => {}
        }
    }

    /// One frame of the automatic spin, if it is on.
    pub fn tick(&mut self) {
        if self.spinning {
            self.rotate(Axis::Y, SPIN_Y_PER_FRAME);
            self.rotate(Axis::X, SPIN_X_PER_FRAME);
        }
    }

    fn translate(&mut self, dx: f64, dy: f64, dz: f64) {
        self.cube.object_to_world_mut().translate(dx, dy, dz);
    }

    fn rotate(&mut self, axis: Axis, angle: f64) {
        let xform = self.cube.object_to_world_mut();
        match axis {
            Axis::X => xform.append_rotation_x(angle),
            Axis::Y => xform.append_rotation_y(angle),
            Axis::Z => xform.append_rotation_z(angle),
        }
        self.rotations += 1;
        if self
            .rotations
            .is_multiple_of(ROTATIONS_PER_REORTHONORMALIZATION)
        {
            xform.reorthonormalize();
        }
    }

    /// The faces to draw this frame, as screen polygons with their colours.
    pub fn visible_faces(&mut self, draw: impl FnMut(&[Point], u8)) {
        self.cube.visible_faces(draw);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn face_normal_and_centre(object: &Object, face: &Face) -> (Vec3, Vec3) {
        let v: [Vec3; 3] = core::array::from_fn(|i| object.view_vertex(face.vertices[i]));
        // Clockwise seen from outside, right-handed: (v0 - v1) x (v2 - v1) points out.
        let normal = (v[0] - v[1]).cross(v[2] - v[1]);
        let count = face.vertices.len() as f64;
        let centre = face
            .vertices
            .iter()
            .fold(Vec3::default(), |sum, &i| sum + object.view_vertex(i))
            * (1.0 / count);
        (normal, centre)
    }

    #[test]
    fn every_cube_face_is_clockwise_seen_from_outside() {
        let cube = Object::new(&CUBE, Xform::identity());
        for face in CUBE.faces {
            let (normal, centre) = face_normal_and_centre(&cube, face);
            // The normal points away from the cube's centre (the origin).
            assert!(
                normal.dot(centre) > 0.0,
                "face {face:?} is wound the wrong way"
            );
            assert_eq!(face.vertices.len(), 4);
        }
    }

    #[test]
    fn the_initial_cube_projects_to_hand_computed_points() {
        let mut scene = Scene::initial();
        // Front face z = -85: 15/85·320 = 56.47 -> ±56; back face z = -115:
        // 15/115·320 = 41.74 -> ±42.
        let expected = [
            Point::new(216, 64),
            Point::new(202, 78),
            Point::new(216, 176),
            Point::new(202, 162),
            Point::new(104, 64),
            Point::new(118, 78),
            Point::new(104, 176),
            Point::new(118, 162),
        ];
        assert_eq!(scene.cube_mut().screen_vertices(), &expected);
        // Only the front face (vertices 0, 2, 6, 4; colour 9) faces the viewer.
        let mut drawn = std::vec::Vec::new();
        scene.visible_faces(|polygon, colour| drawn.push((polygon.to_vec(), colour)));
        assert_eq!(drawn.len(), 1);
        assert_eq!(drawn[0].1, 9);
    }

    #[test]
    fn screen_culling_agrees_with_the_view_space_dot_product_test() {
        // Rost's test: a face is visible when its outward normal points toward
        // the eye, normal · (eye − point on face) > 0, with the eye at the origin.
        let mut seed = 0x1234_5678_9abc_def1u64;
        let mut random = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 10_000) as f64 / 10_000.0
        };
        let (mut checked, mut skipped) = (0, 0);
        for _ in 0..2000 {
            let mut xform = Xform::translation(
                random() * 60.0 - 30.0,
                random() * 60.0 - 30.0,
                -60.0 - random() * 150.0,
            );
            xform.append_rotation_x(random() * 2.0 * PI);
            xform.append_rotation_y(random() * 2.0 * PI);
            xform.append_rotation_z(random() * 2.0 * PI);
            let mut cube = Object::new(&CUBE, xform);
            let mut drawn = [false; 6];
            let mut index = 0;
            let screen: std::vec::Vec<Point> = cube.screen_vertices().to_vec();
            for (i, face) in CUBE.faces.iter().enumerate() {
                let polygon: std::vec::Vec<Point> =
                    face.vertices.iter().map(|&v| screen[v]).collect();
                drawn[i] = engine::is_front_facing(&polygon);
            }
            cube.visible_faces(|_, _| index += 1);
            assert_eq!(index, drawn.iter().filter(|&&d| d).count());
            for (i, face) in CUBE.faces.iter().enumerate() {
                let (normal, centre) = face_normal_and_centre(&cube, face);
                let facing = normal.dot(-centre) / (normal.length() * centre.length());
                // Nearly edge-on faces project to slivers a pixel or two wide,
                // where integer rounding may legitimately decide either way.
                if facing.abs() < 0.02 {
                    skipped += 1;
                    continue;
                }
                checked += 1;
                assert_eq!(drawn[i], facing > 0.0, "face {i} at cos {facing}");
            }
        }
        assert!(checked > 11_000, "checked {checked}, skipped {skipped}");
    }

    #[test]
    fn commands_move_and_turn_like_the_seed() {
        let mut scene = Scene::initial();
        for (command, expected) in [
            (Command::MoveLeft, Vec3::new(-3.0, 0.0, -100.0)),
            (Command::MoveUp, Vec3::new(-3.0, 3.0, -100.0)),
            (Command::MoveRight, Vec3::new(0.0, 3.0, -100.0)),
            (Command::MoveDown, Vec3::new(0.0, 0.0, -100.0)),
            (Command::Away, Vec3::new(0.0, 0.0, -103.0)),
            (Command::Toward, Vec3::new(0.0, 0.0, -100.0)),
        ] {
            scene.apply(command);
            assert_eq!(
                scene.cube().object_to_world().translation_part(),
                expected,
                "{command:?}"
            );
        }
        scene.apply(Command::Rotate(Axis::Y, true));
        let mut expected = Xform::translation(0.0, 0.0, -100.0);
        expected.append_rotation_y(ROTATION_STEP);
        assert_eq!(scene.cube().object_to_world(), &expected);
    }

    #[test]
    fn toward_stops_at_the_near_limit() {
        let mut scene = Scene::initial();
        for _ in 0..100 {
            scene.apply(Command::Toward);
        }
        let z = scene.cube().object_to_world().translation_part().z;
        assert!((NEAREST_Z..NEAREST_Z + MOVE_STEP).contains(&z), "z = {z}");
    }

    #[test]
    fn vertices_are_projected_only_when_something_moved() {
        let mut scene = Scene::initial();
        scene.visible_faces(|_, _| {});
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.cube().projections(), 1);
        scene.tick(); // not spinning: nothing moves
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.cube().projections(), 1);
        scene.apply(Command::MoveLeft);
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.cube().projections(), 2);
    }

    #[test]
    fn spin_is_on_at_boot_and_reset_restores_the_initial_state() {
        let mut scene = Scene::new();
        assert!(scene.spinning());
        for _ in 0..500 {
            scene.tick();
        }
        scene.apply(Command::MoveLeft);
        scene.apply(Command::Reset);
        assert!(!scene.spinning());
        assert_eq!(
            scene.cube().object_to_world(),
            Scene::initial().cube().object_to_world()
        );
    }
}
