//! The scene: Abrash's cube floating in front of the viewer, moved and
//! turned by commands, optionally spinning by itself; and, switched on by
//! keys, flat shading by a light, other solids in the cube's place, two
//! more solids circling on their own, and a crowd of small ones.
//!
//! The scene owns its objects, their motion and their colours. Each frame
//! it hands its faces out, one way, as plain data ([`Scene::faces`] fills a
//! [`SceneFaces`] list: projected, culled, coloured, with each object's
//! screen rectangle and the far-to-near order); how they are drawn, and
//! which surfaces hide which, is `crate::depth`'s business, which this
//! module neither calls nor knows.

mod command;
mod crowd;
mod orbit;

use crate::faces::{FaceList, Faces};
use crate::shading::{default_light, shaded_colour};
use crate::solids::{Solid, SHAPES};
use core::f64::consts::PI;
use crowd::Member;
pub use crowd::CROWD;
use engine::{FaceCounts, Light, Model, Object, Point, VisibleFace, Xform};
use orbit::{Satellite, ORBITS};

pub use command::{Axis, LightTurn, SceneCommand, Sense};

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
/// The automatic spin's turn about X per frame.
pub const SPIN_X_PER_FRAME: f64 = PI / 360.0;
/// Rotations between re-orthonormalisations: often enough that the drift
/// stays far below what a pixel can show.
const ROTATIONS_PER_REORTHONORMALIZATION: u32 = 64;
/// The two satellites of the three-object scene.
pub const SATELLITES: usize = 2;
/// The cube (or the solid in its place), two satellites, and the crowd.
pub const MAX_OBJECTS: usize = 1 + SATELLITES + CROWD;
/// The most faces the objects can have between them: the most of any shape
/// for the solid in the cube's place, then each satellite's and each crowd
/// member's own. (Loops, not iterators: this is worked out when compiling.)
pub const MAX_FACES: usize = {
    let mut most = 0;
    let mut shape = 0;
    while shape < SHAPES.len() {
        if SHAPES[shape].model.faces.len() > most {
            most = SHAPES[shape].model.faces.len();
        }
        shape += 1;
    }
    let mut total = most;
    let mut satellite = 0;
    while satellite < SATELLITES {
        total += ORBITS[satellite].model.faces.len();
        satellite += 1;
    }
    let mut member = 0;
    while member < CROWD {
        total += Member::model(member).faces.len();
        member += 1;
    }
    total
};

/// Room for the scene's faces and their rows, this frame's and the last's
/// (267 KiB), for [`Scene::faces`].
pub type SceneFaces = FaceList<MAX_OBJECTS, MAX_FACES>;

/// What is drawn: the objects, the light, and the switches the keys flip.
///
/// # Example
///
/// ```
/// use demo::scene::{Scene, SceneCommand};
///
/// let mut scene = Scene::initial(); // Abrash's cube, still
/// let mut faces = 0;
/// let counts = scene.visible_faces(|_polygon, _colour| faces += 1);
/// assert_eq!((faces, counts.drawn), (1, 1)); // seen face on: one face
/// scene.apply(SceneCommand::ToggleSeveral);
/// assert_eq!(scene.objects().len(), 3); // with its two satellites
/// ```
#[derive(Clone, Debug)]
pub struct Scene {
    /// The object the keys move (index 0), the satellites, then the crowd:
    /// the objects shown are always a prefix.
    objects: [Object; MAX_OBJECTS],
    satellites: [Satellite; SATELLITES],
    members: [Member; CROWD],
    several: bool,
    crowd: bool,
    /// Frames ticked with the crowd on: when each member moves.
    crowd_frames: u32,
    solid: usize,
    lighting: bool,
    light: Light,
    /// Another number each time `lighting` or `light` changes: the face
    /// list keeps an unmoved object's faces, colours and all, only while
    /// it stays the same.
    colouring: u64,
    spinning: bool,
    rotations: u32,
    /// The last drawing order and how many objects it held: the next
    /// frame's sort starts from it, as objects move little between frames.
    last_order: ([usize; MAX_OBJECTS], usize),
}

impl Default for Scene {
    fn default() -> Self {
        Self::new()
    }
}

impl Scene {
    /// The scene at boot: Abrash's initial cube, spinning.
    pub fn new() -> Self {
        let mut scene = Self::initial();
        scene.spinning = true;
        scene
    }

    /// The starting scene, still: what Reset returns to. The satellites
    /// wait at the start of their orbits until several objects are switched on.
    pub fn initial() -> Self {
        let satellites = ORBITS.map(|orbit| Satellite::start(&orbit));
        let members: [Member; CROWD] = core::array::from_fn(Member::start);
        let objects = core::array::from_fn(|index| match index {
            0 => Object::new(SHAPES[0].model, Xform::translation(0.0, 0.0, INITIAL_Z)),
            1..=SATELLITES => {
                let orbit = &ORBITS[index - 1];
                Object::new(orbit.model, satellites[index - 1].object_to_world(orbit))
            }
            _ => {
                let member = &members[index - 1 - SATELLITES];
                Object::new(
                    Member::model(index - 1 - SATELLITES),
                    member.object_to_world(),
                )
            }
        });
        Scene {
            objects,
            satellites,
            members,
            several: false,
            crowd: false,
            crowd_frames: 0,
            solid: 0,
            lighting: false,
            light: default_light(),
            colouring: 0,
            spinning: false,
            rotations: 0,
            last_order: ([0; MAX_OBJECTS], 0),
        }
    }

    /// The automatic spin is on.
    pub fn spinning(&self) -> bool {
        self.spinning
    }

    /// Faces are shaded by the light.
    pub fn lighting(&self) -> bool {
        self.lighting
    }

    /// The light the shading uses.
    pub fn light(&self) -> &Light {
        &self.light
    }

    /// The two satellites are shown.
    pub fn several(&self) -> bool {
        self.several
    }

    /// The crowd is shown.
    pub fn crowd(&self) -> bool {
        self.crowd
    }

    /// The solid the keys move.
    pub fn solid(&self) -> &'static Solid {
        &SHAPES[self.solid]
    }

    /// The object the keys move: Abrash's cube unless N put another solid
    /// in its place.
    pub fn primary(&self) -> &Object {
        &self.objects[0]
    }

    /// The object the keys move, to change.
    pub fn primary_mut(&mut self) -> &mut Object {
        &mut self.objects[0]
    }

    /// The objects in the scene: the primary alone, or with the satellites,
    /// or with the satellites and the crowd.
    pub fn objects(&self) -> &[Object] {
        &self.objects[..self.object_count()]
    }

    /// The objects in the scene, to change (their projections are cached).
    pub fn objects_mut(&mut self) -> &mut [Object] {
        let count = self.object_count();
        &mut self.objects[..count]
    }

    fn object_count(&self) -> usize {
        if self.crowd {
            MAX_OBJECTS
        } else if self.several {
            1 + SATELLITES
        } else {
            1
        }
    }

    /// Applies one command.
    pub fn apply(&mut self, command: SceneCommand) {
        match command {
            SceneCommand::MoveLeft => self.translate(-MOVE_STEP, 0.0, 0.0),
            SceneCommand::MoveRight => self.translate(MOVE_STEP, 0.0, 0.0),
            SceneCommand::MoveUp => self.translate(0.0, MOVE_STEP, 0.0),
            SceneCommand::MoveDown => self.translate(0.0, -MOVE_STEP, 0.0),
            SceneCommand::Away => self.translate(0.0, 0.0, -MOVE_STEP),
            SceneCommand::Toward => {
                if self.primary().position().z < NEAREST_Z {
                    self.translate(0.0, 0.0, MOVE_STEP);
                }
            }
            SceneCommand::Rotate(axis, sense) => self.rotate(axis, sense.signed(ROTATION_STEP)),
            SceneCommand::ToggleSpin => self.spinning = !self.spinning,
            SceneCommand::ToggleLighting => {
                self.lighting = !self.lighting;
                self.colouring += 1;
            }
            SceneCommand::TurnLight(turn) => {
                let (yaw, pitch) = match turn {
                    LightTurn::Left => (-LIGHT_STEP, 0.0),
                    LightTurn::Right => (LIGHT_STEP, 0.0),
                    LightTurn::Up => (0.0, LIGHT_STEP),
                    LightTurn::Down => (0.0, -LIGHT_STEP),
                };
                self.light.turn(yaw, pitch);
                self.colouring += 1;
            }
            SceneCommand::NextSolid => {
                self.solid = (self.solid + 1) % SHAPES.len();
                self.objects[0].set_model(SHAPES[self.solid].model);
            }
            SceneCommand::ToggleSeveral => self.several = !self.several,
            SceneCommand::ToggleCrowd => self.crowd = !self.crowd,
            SceneCommand::Reset => *self = Self::initial(),
        }
    }

    /// One frame of motion, if the spin is on: the primary spins as in
    /// Abrash's original program, and the satellites, when shown, move along their orbits.
    pub fn tick(&mut self) {
        if !self.spinning {
            return;
        }
        self.rotate(Axis::Y, SPIN_Y_PER_FRAME);
        self.rotate(Axis::X, SPIN_X_PER_FRAME);
        if self.several || self.crowd {
            for (index, orbit) in ORBITS.iter().enumerate() {
                let satellite = &mut self.satellites[index];
                satellite.advance(orbit);
                *self.objects[index + 1].object_to_world_mut() = satellite.object_to_world(orbit);
            }
        }
        if self.crowd {
            self.crowd_frames = self.crowd_frames.wrapping_add(1);
            let objects = &mut self.objects[1 + SATELLITES..];
            for (member, object) in self.members.iter_mut().zip(objects) {
                // Only a member that moves is touched, so only it is
                // transformed and projected again.
                if member.moves_on(self.crowd_frames) {
                    member.advance();
                    *object.object_to_world_mut() = member.object_to_world();
                }
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
        // The objects shown are always a prefix, so the last order holds
        // the same objects when it holds as many.
        let (mut order, last_count) = self.last_order;
        if last_count != count {
            // A loop over the objects shown, not an array built whole,
            // which was 59 stores' worth of code.
            for (index, slot) in order[..count].iter_mut().enumerate() {
                *slot = index;
            }
        }
        let objects = &self.objects[..count];
        sort_far_to_near(&mut order[..count], |index| {
            objects[index].position().length()
        });
        (order, count)
    }

    /// `drawing_order`, kept as where the next frame's sort starts. Out of
    /// line: one copy in the kernel file for both its callers.
    #[inline(never)]
    fn next_drawing_order(&mut self) -> ([usize; MAX_OBJECTS], usize) {
        self.last_order = self.drawing_order();
        self.last_order
    }

    /// The faces to draw this frame, far to near, as screen polygons with
    /// their colours: Abrash's flat colours, or with lighting on the level of
    /// the colour's ramp that the face's brightness gives.
    pub fn visible_faces(&mut self, mut draw: impl FnMut(&[Point], u8)) -> FaceCounts {
        let (order, count) = self.next_drawing_order();
        let (lighting, light) = (self.lighting, self.light);
        let mut counts = FaceCounts::default();
        for &index in &order[..count] {
            counts += self.objects[index].each_visible_face(|visible| {
                draw(visible.polygon, face_colour(visible, lighting, &light));
            });
        }
        counts
    }

    /// Every face that survives backface removal, object by object in no
    /// particular depth order, with its colour as `visible_faces` gives it:
    /// for drawing with a depth test, where order does not matter.
    pub fn each_visible_face(&mut self, mut draw: impl FnMut(&VisibleFace, u8)) -> FaceCounts {
        let (lighting, light) = (self.lighting, self.light);
        let mut counts = FaceCounts::default();
        for object in self.objects_mut() {
            counts += object.each_visible_face(|visible| {
                draw(visible, face_colour(visible, lighting, &light));
            });
        }
        counts
    }

    /// This frame's faces, handed out as plain data into `list`: each
    /// object's faces that survive backface removal (in the order of
    /// `each_visible_face`), projected and coloured as `visible_faces`
    /// colours them, with its screen rectangle and whether it is convex; the
    /// objects' far-to-near order (`drawing_order`); and whether the crowd's
    /// small solids are shown. The scene does not draw them, nor know how
    /// they will be drawn.
    pub fn faces<'list>(&mut self, list: &'list mut SceneFaces) -> Faces<'list> {
        list.begin_frame(self.crowd);
        let (lighting, light, colouring) = (self.lighting, self.light, self.colouring);
        for object in self.objects_mut() {
            let convex = convex(object.model());
            list.push_object(object, convex, colouring, |visible| {
                face_colour(visible, lighting, &light)
            });
        }
        let (order, count) = self.next_drawing_order();
        list.set_far_to_near(&order[..count]);
        list.faces()
    }
}

/// Sorts `order` (indices, each at `distance(index)`) farthest first,
/// and by index among equals, so that the result is the one order those
/// two rules give, whatever order it starts in. An insertion sort: the scene holds at
/// most MAX_OBJECTS objects (59), the library's sort was 17 KB of the
/// kernel file for them, and started from the last frame's order, which
/// objects moving a little a frame seldom change, it makes one compare an
/// object rather than one for every pair (`drawing_order`).
fn sort_far_to_near(order: &mut [usize], distance: impl Fn(usize) -> f64) {
    let after = |a: usize, b: usize| match distance(a).total_cmp(&distance(b)) {
        core::cmp::Ordering::Less => true,
        core::cmp::Ordering::Equal => a > b,
        core::cmp::Ordering::Greater => false,
    };
    for sorted in 1..order.len() {
        let mut at = sorted;
        while at > 0 && after(order[at - 1], order[at]) {
            order.swap(at - 1, at);
            at -= 1;
        }
    }
}

/// Whether the shape with this model is convex; a model that is none of the
/// shapes counts as not convex, so that the depth test covers it.
fn convex(model: &Model) -> bool {
    SHAPES
        .iter()
        .find(|solid| core::ptr::eq(solid.model, model))
        .is_some_and(|solid| solid.convex)
}

/// Abrash's flat colour, or with lighting on the level of the colour's ramp
/// that the face's brightness gives.
fn face_colour(visible: &VisibleFace, lighting: bool, light: &Light) -> u8 {
    if lighting {
        shaded_colour(visible.face.colour, light.intensity(visible.normal()))
    } else {
        visible.face.colour
    }
}

#[cfg(test)]
mod tests;
