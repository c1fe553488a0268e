//! The frame sets the cost benches replay: one entry a frame, a command first
//! or none (the spin alone). Shared, so the bus and the present benches
//! measure the same frames.

use demo::scene::{Axis, SceneCommand, Sense};

/// The cube: a 360-frame spin, then moved, zoomed and partly off-screen.
pub fn cube_set() -> Vec<Option<SceneCommand>> {
    let mut frames: Vec<Option<SceneCommand>> = vec![None; 360];
    let mut repeat = |command: SceneCommand, times: usize| {
        frames.extend(std::iter::repeat_n(Some(command), times))
    };
    repeat(SceneCommand::ToggleSpin, 1);
    repeat(SceneCommand::Rotate(Axis::X, Sense::Positive), 4);
    repeat(SceneCommand::MoveLeft, 45); // past the left edge
    repeat(SceneCommand::MoveUp, 30); // and the top
    repeat(SceneCommand::MoveRight, 90); // across to the right edge
    repeat(SceneCommand::MoveDown, 60);
    repeat(SceneCommand::Toward, 22); // as close as it goes
    repeat(SceneCommand::Away, 60); // and far away
    repeat(SceneCommand::Rotate(Axis::Z, Sense::Positive), 30);
    frames
}

/// The extras: three objects, lit, spinning and circling for a full orbit of
/// the nearer satellite, then the other solids in the cube's place.
pub fn extras_set() -> Vec<Option<SceneCommand>> {
    let mut frames = vec![
        Some(SceneCommand::ToggleSeveral),
        Some(SceneCommand::ToggleLighting),
    ];
    frames.extend(vec![None; 360]);
    for _ in 0..4 {
        frames.push(Some(SceneCommand::NextSolid));
        frames.extend(vec![None; 60]);
    }
    frames
}
