//! What the scene can be asked to do. Each variant says everything it means:
//! a rotation names its axis and its sense, a light turn its direction, so no
//! combination is left for `apply` to guess at.

/// A coordinate axis of the object being turned.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    /// Left to right across the screen.
    X,
    /// Bottom to top.
    Y,
    /// Out of the screen, toward the viewer.
    Z,
}

/// Which way a rotation goes: positive is counterclockwise seen from the
/// positive end of the axis (the right-hand rule).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sense {
    /// By +6 degrees.
    Positive,
    /// By -6 degrees.
    Negative,
}

impl Sense {
    /// `step` with this sense's sign.
    pub fn signed(self, step: f64) -> f64 {
        match self {
            Sense::Positive => step,
            Sense::Negative => -step,
        }
    }
}

/// Which way one key turns the light, 15 degrees at a time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightTurn {
    /// About the vertical axis, toward the left.
    Left,
    /// About the vertical axis, toward the right.
    Right,
    /// About the horizontal axis, upward.
    Up,
    /// About the horizontal axis, downward.
    Down,
}

/// A change to the scene: the moves and turns of Abrash's original program,
/// and the extras' switches.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneCommand {
    /// Move the object 3 units left.
    MoveLeft,
    /// Move the object 3 units right.
    MoveRight,
    /// Move the object 3 units up.
    MoveUp,
    /// Move the object 3 units down.
    MoveDown,
    /// Move the object 3 units away from the viewer.
    Away,
    /// Move the object 3 units toward the viewer, stopping at the nearest
    /// distance the renderer handles without clipping.
    Toward,
    /// Turn the object 6 degrees about one of its axes.
    Rotate(Axis, Sense),
    /// Start or stop the automatic spin.
    ToggleSpin,
    /// Flat shading by the light, or the flat colours of Abrash's original
    /// program.
    ToggleLighting,
    /// Turn the light.
    TurnLight(LightTurn),
    /// Put the next solid in the cube's place.
    NextSolid,
    /// One object, or three moving independently.
    ToggleSeveral,
    /// The crowd of many solids on (with the three objects) or off.
    ToggleCrowd,
    /// Back to the starting scene: the cube still, unlit, alone.
    Reset,
}
