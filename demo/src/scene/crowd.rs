//! The many-object scene (key X): a crowd of small solids in a loose grid
//! far behind the cube, each circling its own spot and turning about its own
//! axis at its own pace. Each moves only on some frames (every first, second,
//! third or fourth), so on any frame only some of them need transforming
//! again; the others keep last frame's projection (the recalculation flag).
//! Neighbours' circles overlap now and then, so solids pass through each
//! other: only the depth test draws that right.

use super::ROTATIONS_PER_REORTHONORMALIZATION;
use crate::solids::SHAPES;
use core::f64::consts::PI;
use engine::{Model, Xform};

pub const COLUMNS: usize = 8;
pub const ROWS: usize = 7;
/// How many solids the crowd has.
pub const CROWD: usize = COLUMNS * ROWS;
/// Their size relative to the models (about 10 units from centre to vertex).
const SCALE: f64 = 0.4;
/// Grid spacing, and the radius of each solid's circle: neighbours' circles
/// overlap, so now and then two solids meet.
const SPACING_X: f64 = 36.0;
const SPACING_Y: f64 = 30.0;
const CIRCLE: f64 = 14.0;
const DEPTH: f64 = -300.0;

/// Where one member of the crowd is and how it moves.
#[derive(Clone, Debug)]
pub(super) struct Member {
    index: usize,
    phase: f64,
    orientation: Xform,
    rotations: u32,
}

impl Member {
    pub fn start(index: usize) -> Self {
        Member {
            index,
            phase: index as f64 * 0.7,
            orientation: Xform::identity(),
            rotations: 0,
        }
    }

    /// The shape it shows: every shape in turn along the grid.
    pub const fn model(index: usize) -> &'static Model {
        SHAPES[index % SHAPES.len()].model
    }

    /// Whether it moves on frame `frame`: every `index % 4 + 1`-th frame.
    pub fn moves_on(&self, frame: u32) -> bool {
        frame.is_multiple_of(self.index as u32 % 4 + 1)
    }

    /// One step along its circle and one step of its turn; bigger steps for
    /// the ones that move less often, so all go round at a similar pace.
    pub fn advance(&mut self) {
        let step = (self.index % 4 + 1) as f64;
        let direction = if self.index.is_multiple_of(2) {
            1.0
        } else {
            -1.0
        };
        self.phase = (self.phase + direction * step * PI / 200.0) % (2.0 * PI);
        let spin = step * PI / (60.0 + (self.index % 7) as f64 * 10.0);
        if self.index.is_multiple_of(3) {
            self.orientation.append_rotation_x(spin);
        } else {
            self.orientation.append_rotation_y(spin);
        }
        self.rotations += 1;
        if self
            .rotations
            .is_multiple_of(ROTATIONS_PER_REORTHONORMALIZATION)
        {
            self.orientation.reorthonormalize();
        }
    }

    pub fn object_to_world(&self) -> Xform {
        let (column, row) = (self.index % COLUMNS, self.index / COLUMNS);
        let x = (column as f64 - (COLUMNS as f64 - 1.0) / 2.0) * SPACING_X;
        let y = (row as f64 - (ROWS as f64 - 1.0) / 2.0) * SPACING_Y;
        let (sin, cos) = (libm::sin(self.phase), libm::cos(self.phase));
        let placed = Xform::concat(
            &Xform::translation(x + CIRCLE * cos, y, DEPTH + CIRCLE * sin),
            &self.orientation,
        );
        Xform::concat(&placed, &Xform::scaling(SCALE))
    }
}
