//! The scene: the seed's cube floating in front of the viewer, moved and
//! turned by commands, optionally spinning by itself; and, switched on by
//! keys, flat shading by a light, other solids in the cube's place, and two
//! more solids circling on their own, drawn far to near.

use crate::shading::{default_light, shaded_colour};
use crate::solids::{Solid, OCTAHEDRON, SOLIDS, TETRAHEDRON};
use core::f64::consts::PI;
use engine::{FaceCounts, Light, Model, Object, Point, Vec3, Xform};

/// Where the cube starts: no rotation, 100 units in front of the viewer.
pub const INITIAL_Z: f64 = -100.0;
/// One keypress moves the cube this far.
pub const MOVE_STEP: f64 = 3.0;
/// Toward the viewer stops here, so no near-plane clipping is needed.
pub const NEAREST_Z: f64 = -40.0;
/// One keypress turns the cube 6 degrees.
pub const ROTATION_STEP: f64 = PI / 30.0;
/// One keypress turns the light 15 degrees.
pub const LIGHT_STEP: f64 = PI / 12.0;
/// The automatic spin per frame: about Y and, more slowly, about X.
pub const SPIN_Y_PER_FRAME: f64 = PI / 180.0;
pub const SPIN_X_PER_FRAME: f64 = PI / 360.0;
/// Rotations between re-orthonormalisations: often enough that the drift
/// stays far below what a pixel can show.
const ROTATIONS_PER_REORTHONORMALIZATION: u32 = 64;
/// The cube (or the solid in its place) plus two satellites.
pub const MAX_OBJECTS: usize = 3;

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
    /// Flat shading by the light, or the seed's flat colours.
    ToggleLighting,
    /// Turn the light 15 degrees: about Y to the right (true) or left, about
    /// X up (true) or down.
    TurnLight(Axis, bool),
    /// Put the next solid in the cube's place.
    NextSolid,
    /// One object, or three moving independently.
    ToggleSeveral,
    /// The on-screen help and statistics belong to the app, not the scene.
    ToggleHelp,
    ToggleStats,
    Reset,
    /// Any key that is not a command: wait for the next key.
    Pause,
    Quit,
}

/// A solid that circles on its own in the several-objects scene: its centre
/// runs round an ellipse, `centre + major·cos(phase) + minor·sin(phase)`, and
/// it spins about its own Y axis as it goes.
struct Orbit {
    model: &'static Model,
    /// Its size relative to the model.
    scale: f64,
    centre: Vec3,
    major: Vec3,
    minor: Vec3,
    start_phase: f64,
    phase_per_frame: f64,
    spin_per_frame: f64,
}

/// An octahedron circling through the space in front of and behind the
/// cube's starting place (never nearer than 58 units minus its own 13), and
/// a tetrahedron wheeling round far behind it. The orbits keep 40 units away
/// from the cube's starting place and from each other, so unless the cube is
/// moved into them no two solids interpenetrate, and painting whole objects
/// far to near is exact.
const ORBITS: [Orbit; MAX_OBJECTS - 1] = [
    Orbit {
        model: &OCTAHEDRON,
        scale: 0.5,
        centre: Vec3::new(0.0, 0.0, INITIAL_Z),
        major: Vec3::new(42.0, 0.0, 0.0),
        minor: Vec3::new(0.0, 0.0, 42.0),
        start_phase: PI / 3.0,
        phase_per_frame: PI / 180.0,
        spin_per_frame: PI / 90.0,
    },
    Orbit {
        model: &TETRAHEDRON,
        scale: 0.5,
        centre: Vec3::new(0.0, 0.0, -180.0),
        major: Vec3::new(60.0, 0.0, 0.0),
        minor: Vec3::new(0.0, 40.0, 0.0),
        start_phase: 3.0 * PI / 4.0,
        phase_per_frame: -PI / 240.0,
        spin_per_frame: -PI / 120.0,
    },
];

/// Where a satellite is along its orbit and how it is turned.
#[derive(Clone)]
struct Satellite {
    phase: f64,
    /// Rotation only, so it can be re-orthonormalized; position and scale are
    /// applied on top.
    orientation: Xform,
    rotations: u32,
}

impl Satellite {
    fn object_to_world(&self, orbit: &Orbit) -> Xform {
        let (sin, cos) = (libm::sin(self.phase), libm::cos(self.phase));
        let position = orbit.centre + orbit.major * cos + orbit.minor * sin;
        let placed = Xform::concat(
            &Xform::translation(position.x, position.y, position.z),
            &self.orientation,
        );
        Xform::concat(&placed, &Xform::scaling(orbit.scale))
    }
}

#[derive(Clone)]
pub struct Scene {
    /// The object the keys move (index 0) and the satellites.
    objects: [Object; MAX_OBJECTS],
    satellites: [Satellite; MAX_OBJECTS - 1],
    several: bool,
    solid: usize,
    lighting: bool,
    light: Light,
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

    /// The seed's initial state, still: what Reset returns to. The satellites
    /// wait at the start of their orbits until several objects are switched on.
    pub fn initial() -> Self {
        let satellites = ORBITS.map(|orbit| Satellite {
            phase: orbit.start_phase,
            orientation: Xform::identity(),
            rotations: 0,
        });
        let objects = [
            Object::new(SOLIDS[0].model, Xform::translation(0.0, 0.0, INITIAL_Z)),
            Object::new(ORBITS[0].model, satellites[0].object_to_world(&ORBITS[0])),
            Object::new(ORBITS[1].model, satellites[1].object_to_world(&ORBITS[1])),
        ];
        Scene {
            objects,
            satellites,
            several: false,
            solid: 0,
            lighting: false,
            light: default_light(),
            spinning: false,
            rotations: 0,
        }
    }

    pub fn spinning(&self) -> bool {
        self.spinning
    }

    pub fn lighting(&self) -> bool {
        self.lighting
    }

    pub fn light(&self) -> &Light {
        &self.light
    }

    pub fn several(&self) -> bool {
        self.several
    }

    /// The solid the keys move.
    pub fn solid(&self) -> &'static Solid {
        &SOLIDS[self.solid]
    }

    /// The object the keys move: the seed's cube unless N put another solid
    /// in its place.
    pub fn primary(&self) -> &Object {
        &self.objects[0]
    }

    pub fn primary_mut(&mut self) -> &mut Object {
        &mut self.objects[0]
    }

    /// The objects in the scene: the primary alone, or with the satellites.
    pub fn objects(&self) -> &[Object] {
        &self.objects[..self.object_count()]
    }

    fn object_count(&self) -> usize {
        if self.several {
            MAX_OBJECTS
        } else {
            1
        }
    }

    /// Applies one command (Pause, Quit and the display toggles are the
    /// caller's business and leave the scene as it is).
    pub fn apply(&mut self, command: Command) {
        match command {
            Command::MoveLeft => self.translate(-MOVE_STEP, 0.0, 0.0),
            Command::MoveRight => self.translate(MOVE_STEP, 0.0, 0.0),
            Command::MoveUp => self.translate(0.0, MOVE_STEP, 0.0),
            Command::MoveDown => self.translate(0.0, -MOVE_STEP, 0.0),
            Command::Away => self.translate(0.0, 0.0, -MOVE_STEP),
            Command::Toward => {
                if self.primary().position().z < NEAREST_Z {
                    self.translate(0.0, 0.0, MOVE_STEP);
                }
            }
            Command::Rotate(axis, positive) => self.rotate(axis, signed(ROTATION_STEP, positive)),
            Command::ToggleSpin => self.spinning = !self.spinning,
            Command::ToggleLighting => self.lighting = !self.lighting,
            Command::TurnLight(Axis::Y, right) => self.light.turn(signed(LIGHT_STEP, right), 0.0),
            Command::TurnLight(_, up) => self.light.turn(0.0, signed(LIGHT_STEP, up)),
            Command::NextSolid => {
                self.solid = (self.solid + 1) % SOLIDS.len();
                self.objects[0].set_model(SOLIDS[self.solid].model);
            }
            Command::ToggleSeveral => self.several = !self.several,
            Command::Reset => *self = Self::initial(),
            Command::ToggleHelp | Command::ToggleStats | Command::Pause | Command::Quit => {}
        }
    }

    /// One frame of motion, if the spin is on: the primary spins as in the
    /// seed, and the satellites, when shown, move along their orbits.
    pub fn tick(&mut self) {
        if !self.spinning {
            return;
        }
        self.rotate(Axis::Y, SPIN_Y_PER_FRAME);
        self.rotate(Axis::X, SPIN_X_PER_FRAME);
        if self.several {
            for (index, orbit) in ORBITS.iter().enumerate() {
                let satellite = &mut self.satellites[index];
                satellite.phase = (satellite.phase + orbit.phase_per_frame) % (2.0 * PI);
                satellite
                    .orientation
                    .append_rotation_y(orbit.spin_per_frame);
                satellite.rotations += 1;
                if satellite
                    .rotations
                    .is_multiple_of(ROTATIONS_PER_REORTHONORMALIZATION)
                {
                    satellite.orientation.reorthonormalize();
                }
                *self.objects[index + 1].object_to_world_mut() = satellite.object_to_world(orbit);
            }
        }
    }

    fn translate(&mut self, dx: f64, dy: f64, dz: f64) {
        self.objects[0].object_to_world_mut().translate(dx, dy, dz);
    }

    fn rotate(&mut self, axis: Axis, angle: f64) {
        let xform = self.objects[0].object_to_world_mut();
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

    /// The objects to draw, farthest first (the painter's algorithm, whole
    /// objects at a time: each is convex, so within one object backface
    /// removal alone hides what it must). Distance is measured from the eye
    /// to each object's centre.
    pub fn drawing_order(&self) -> ([usize; MAX_OBJECTS], usize) {
        let count = self.object_count();
        let mut order = [0, 1, 2];
        let distance = |index: &usize| self.objects[*index].position().length();
        order[..count].sort_unstable_by(|a, b| distance(b).total_cmp(&distance(a)));
        (order, count)
    }

    /// The faces to draw this frame, far to near, as screen polygons with
    /// their colours: the seed's flat colours, or with lighting on the level of
    /// the colour's ramp that the face's brightness gives.
    pub fn visible_faces(&mut self, mut draw: impl FnMut(&[Point], u8)) -> FaceCounts {
        let (order, count) = self.drawing_order();
        let (lighting, light) = (self.lighting, self.light);
        let mut counts = FaceCounts::default();
        for &index in &order[..count] {
            counts += self.objects[index].each_visible_face(|visible| {
                let colour = if lighting {
                    shaded_colour(visible.face.colour, light.intensity(visible.normal()))
                } else {
                    visible.face.colour
                };
                draw(visible.polygon, colour);
            });
        }
        counts
    }
}

fn signed(step: f64, positive: bool) -> f64 {
    if positive {
        step
    } else {
        -step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solids::CUBE;
    use engine::Face;

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
        assert_eq!(scene.primary_mut().screen_vertices(), &expected);
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
                scene.primary().object_to_world().translation_part(),
                expected,
                "{command:?}"
            );
        }
        scene.apply(Command::Rotate(Axis::Y, true));
        let mut expected = Xform::translation(0.0, 0.0, -100.0);
        expected.append_rotation_y(ROTATION_STEP);
        assert_eq!(scene.primary().object_to_world(), &expected);
    }

    #[test]
    fn toward_stops_at_the_near_limit() {
        let mut scene = Scene::initial();
        for _ in 0..100 {
            scene.apply(Command::Toward);
        }
        let z = scene.primary().object_to_world().translation_part().z;
        assert!((NEAREST_Z..NEAREST_Z + MOVE_STEP).contains(&z), "z = {z}");
    }

    #[test]
    fn vertices_are_projected_only_when_something_moved() {
        let mut scene = Scene::initial();
        scene.visible_faces(|_, _| {});
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.primary().projections(), 1);
        scene.tick(); // not spinning: nothing moves
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.primary().projections(), 1);
        scene.apply(Command::MoveLeft);
        scene.visible_faces(|_, _| {});
        assert_eq!(scene.primary().projections(), 2);
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
            scene.primary().object_to_world(),
            Scene::initial().primary().object_to_world()
        );
    }

    fn colours_drawn(scene: &mut Scene) -> std::vec::Vec<u8> {
        let mut colours = std::vec::Vec::new();
        scene.visible_faces(|_, colour| colours.push(colour));
        colours
    }

    #[test]
    fn lighting_shades_each_face_by_the_angle_to_the_light() {
        let mut scene = Scene::initial();
        scene.apply(Command::ToggleLighting);
        // Only the front face (bright blue, ramp 0) shows; its normal is
        // (0, 0, 1) and the light comes from (-1, 1, 1)/√3: intensity
        // 0.25 + 0.75/√3 = 0.683, level round(0.683 · 31) = 21.
        assert_eq!(colours_drawn(&mut scene), [16 + 21]);
        // Three steps right put the light straight above the line of sight:
        // 0.25 + 0.75 · cos 35.26° = 0.862, level 27.
        for _ in 0..3 {
            scene.apply(Command::TurnLight(Axis::Y, true));
        }
        assert_eq!(colours_drawn(&mut scene), [16 + 27]);
        // Turned away behind the cube, only the ambient share is left: 0.25,
        // level 8 (7.75 rounded).
        for _ in 0..12 {
            scene.apply(Command::TurnLight(Axis::Y, true));
        }
        for _ in 0..3 {
            scene.apply(Command::TurnLight(Axis::X, false));
        }
        assert_eq!(colours_drawn(&mut scene), [16 + 8]);
        scene.apply(Command::ToggleLighting);
        assert_eq!(colours_drawn(&mut scene), [9], "flat colours again");
    }

    #[test]
    fn n_puts_each_solid_in_the_cubes_place_in_turn() {
        let mut scene = Scene::initial();
        scene.apply(Command::MoveLeft);
        let place = *scene.primary().object_to_world();
        let mut seen = std::vec::Vec::new();
        for _ in 0..SOLIDS.len() {
            scene.apply(Command::NextSolid);
            seen.push(scene.solid().name);
            assert!(core::ptr::eq(scene.primary().model(), scene.solid().model));
            assert_eq!(scene.primary().object_to_world(), &place);
            assert!(!colours_drawn(&mut scene).is_empty());
        }
        assert_eq!(
            seen,
            [
                "tetrahedron",
                "octahedron",
                "dodecahedron",
                "icosahedron",
                "cube"
            ]
        );
    }

    #[test]
    fn reset_returns_to_the_seeds_scene_from_every_extra() {
        let mut scene = Scene::new();
        for command in [
            Command::ToggleLighting,
            Command::TurnLight(Axis::X, true),
            Command::NextSolid,
            Command::ToggleSeveral,
        ] {
            scene.apply(command);
        }
        scene.tick();
        scene.apply(Command::Reset);
        assert!(!scene.lighting() && !scene.several() && !scene.spinning());
        assert_eq!(scene.solid().name, "cube");
        assert_eq!(scene.light(), &default_light());
        assert_eq!(scene.objects().len(), 1);
        assert_eq!(colours_drawn(&mut scene), [9]);
    }

    #[test]
    fn several_objects_are_drawn_far_to_near() {
        let mut scene = Scene::initial();
        scene.apply(Command::ToggleSeveral);
        // The tetrahedron circles 180 units away, the octahedron starts in
        // front of the cube's right side (about 67 units away).
        assert_eq!(scene.drawing_order(), ([2, 0, 1], 3));
        for _ in 0..100 {
            scene.apply(Command::Away);
        }
        assert_eq!(scene.drawing_order(), ([0, 2, 1], 3));
        scene.apply(Command::ToggleSeveral);
        assert_eq!(scene.drawing_order().1, 1);
    }

    /// Each object alone, as colour indices (0 where it does not cover).
    fn picture_of(object: &Object) -> std::vec::Vec<u8> {
        let mut object = object.clone();
        let mut picture = std::vec![0u8; 320 * 240];
        let clip = engine::ClipRect {
            x0: 0,
            y0: 0,
            x1: 320,
            y1: 240,
        };
        object.visible_faces(|polygon, colour| {
            engine::fill_convex_polygon(polygon, clip, |y, x0, x1| {
                let row = y as usize * 320;
                picture[row + x0 as usize..row + x1 as usize].fill(colour);
            });
        });
        picture
    }

    #[test]
    fn where_objects_overlap_the_nearer_one_shows() {
        let mut scene = Scene::new();
        scene.apply(Command::ToggleSeveral);
        let mut overlapping_pixels = 0;
        for frame in 0..720 {
            scene.tick();
            if frame % 8 != 0 {
                continue;
            }
            let mut frame_picture = std::vec![0u8; 320 * 240];
            let clip = crate::frame::SCREEN_CLIP;
            scene.visible_faces(|polygon, colour| {
                engine::fill_convex_polygon(polygon, clip, |y, x0, x1| {
                    let row = y as usize * 320;
                    frame_picture[row + x0 as usize..row + x1 as usize].fill(colour);
                });
            });
            // Nearest first.
            let mut alone: std::vec::Vec<(f64, std::vec::Vec<u8>)> = scene
                .objects()
                .iter()
                .map(|object| (object.position().length(), picture_of(object)))
                .collect();
            alone.sort_by(|a, b| a.0.total_cmp(&b.0));
            for pixel in 0..320 * 240 {
                let covering: std::vec::Vec<u8> = alone
                    .iter()
                    .map(|(_, picture)| picture[pixel])
                    .filter(|&colour| colour != 0)
                    .collect();
                overlapping_pixels += usize::from(covering.len() > 1);
                let expected = covering.first().copied().unwrap_or(0);
                assert_eq!(
                    frame_picture[pixel], expected,
                    "frame {frame}, pixel {pixel}"
                );
            }
        }
        assert!(
            overlapping_pixels > 10_000,
            "only {overlapping_pixels} overlaps"
        );
    }

    #[test]
    fn only_the_objects_that_moved_are_projected_again() {
        let mut scene = Scene::initial();
        scene.apply(Command::ToggleSeveral);
        let projections = |scene: &Scene| -> std::vec::Vec<u64> {
            scene.objects().iter().map(Object::projections).collect()
        };
        scene.visible_faces(|_, _| {});
        assert_eq!(projections(&scene), [1, 1, 1]);
        scene.visible_faces(|_, _| {});
        scene.tick(); // spin is off: nothing moves
        scene.visible_faces(|_, _| {});
        assert_eq!(projections(&scene), [1, 1, 1]);
        scene.apply(Command::MoveLeft);
        scene.visible_faces(|_, _| {});
        assert_eq!(projections(&scene), [2, 1, 1], "only the cube moved");
        scene.apply(Command::ToggleSpin);
        scene.tick();
        scene.visible_faces(|_, _| {});
        assert_eq!(projections(&scene), [3, 2, 2], "everything moves");
        scene.apply(Command::ToggleSeveral);
        scene.tick();
        scene.visible_faces(|_, _| {});
        scene.apply(Command::ToggleSeveral);
        scene.visible_faces(|_, _| {});
        assert_eq!(
            projections(&scene),
            [4, 2, 2],
            "hidden satellites neither move nor get projected"
        );
    }

    #[test]
    fn the_satellites_never_come_near_the_viewer_and_keep_apart() {
        let mut scene = Scene::new();
        scene.apply(Command::ToggleSeveral);
        let initial_cube = Scene::initial().primary().position();
        for _ in 0..2000 {
            scene.tick();
            let objects = scene.objects();
            let (a, b) = (objects[1].position(), objects[2].position());
            for position in [a, b] {
                assert!(position.z + 13.0 < NEAREST_Z, "{position:?}");
                assert!((position - initial_cube).length() > 26.0 + 13.0);
            }
            assert!((a - b).length() > 26.0, "{a:?} {b:?}");
        }
    }
}
