//! The two satellites of the several-objects scene: where their orbits run,
//! and how each moves along its orbit a frame at a time.

use super::{INITIAL_Z, ROTATIONS_PER_REORTHONORMALIZATION, SATELLITES};
use crate::solids::{OCTAHEDRON, TETRAHEDRON};
use core::f64::consts::PI;
use engine::{Model, Vec3, Xform};

/// A solid that circles on its own in the several-objects scene: its centre
/// runs round an ellipse, `centre + major·cos(phase) + minor·sin(phase)`, and
/// it spins about its own Y axis as it goes.
pub(super) struct Orbit {
    pub model: &'static Model,
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
pub(super) const ORBITS: [Orbit; SATELLITES] = [
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
#[derive(Clone, Debug)]
pub(super) struct Satellite {
    phase: f64,
    /// Rotation only, so it can be re-orthonormalized; position and scale are
    /// applied on top.
    orientation: Xform,
    rotations: u32,
}

impl Satellite {
    /// At the start of its orbit, unturned.
    pub fn start(orbit: &Orbit) -> Self {
        Satellite {
            phase: orbit.start_phase,
            orientation: Xform::identity(),
            rotations: 0,
        }
    }

    /// One frame along the orbit, and one frame's turn.
    pub fn advance(&mut self, orbit: &Orbit) {
        self.phase = (self.phase + orbit.phase_per_frame) % (2.0 * PI);
        self.orientation.append_rotation_y(orbit.spin_per_frame);
        self.rotations += 1;
        if self
            .rotations
            .is_multiple_of(ROTATIONS_PER_REORTHONORMALIZATION)
        {
            self.orientation.reorthonormalize();
        }
    }

    /// Where the satellite is now: on its orbit, turned, at its size.
    pub fn object_to_world(&self, orbit: &Orbit) -> Xform {
        let (sin, cos) = (libm::sin(self.phase), libm::cos(self.phase));
        let position = orbit.centre + orbit.major * cos + orbit.minor * sin;
        let placed = Xform::concat(
            &Xform::translation(position.x, position.y, position.z),
            &self.orientation,
        );
        Xform::concat(&placed, &Xform::scaling(orbit.scale))
    }
}
