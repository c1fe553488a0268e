//! Hidden surfaces in QEMU: the letter L, the three beams, solids passing
//! through each other and the crowd of many solids. After each key, QEMU's
//! screendump of its own VGA emulation must equal the software VGA's picture
//! of the same commands, pixel for pixel.

mod common;

use common::assert_same_picture;
use demo::command::{Axis, Command, SceneCommand, Sense};

fn after_each_key(keys: &[(&str, Command)]) {
    common::after_each_key(keys, |qemu, model, _, what| {
        assert_same_picture(qemu, model, what)
    });
}

#[test]
fn the_letter_l_and_the_beams() {
    let mut keys = vec![("r", Command::Scene(SceneCommand::Reset))];
    keys.extend([("n", Command::Scene(SceneCommand::NextSolid)); 5]); // the letter L
    keys.extend([
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("8", common::turn(Axis::X, Sense::Negative)),
        ("n", Command::Scene(SceneCommand::NextSolid)), // the three beams
        ("4", common::turn(Axis::Y, Sense::Negative)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
    ]);
    after_each_key(&keys);
}

#[test]
fn solids_passing_through_each_other() {
    let mut keys = vec![
        ("r", Command::Scene(SceneCommand::Reset)),
        ("m", Command::Scene(SceneCommand::ToggleSeveral)),
    ];
    // Into the octahedron's orbit, where it waits at the start.
    keys.extend([("right", Command::Scene(SceneCommand::MoveRight)); 7]);
    keys.extend([("up", Command::Scene(SceneCommand::MoveUp)); 3]);
    keys.push(("6", common::turn(Axis::Y, Sense::Positive)));
    after_each_key(&keys);
}

#[test]
fn the_crowd() {
    after_each_key(&[
        ("r", Command::Scene(SceneCommand::Reset)),
        ("x", Command::Scene(SceneCommand::ToggleCrowd)),
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
        ("x", Command::Scene(SceneCommand::ToggleCrowd)),
    ]);
}
