//! Hidden surfaces in QEMU: the letter L, the three beams, solids passing
//! through each other and the crowd of many solids. After each key, QEMU's
//! screendump of its own VGA emulation must equal the software VGA's picture
//! of the same commands, pixel for pixel.

mod common;

use common::assert_same_picture;
use demo::scene::{Axis, Command};

fn after_each_key(keys: &[(&str, Command)]) {
    common::after_each_key(keys, |qemu, model, _, what| {
        assert_same_picture(qemu, model, what)
    });
}

#[test]
fn the_letter_l_and_the_beams() {
    let mut keys = vec![("r", Command::Reset)];
    keys.extend([("n", Command::NextSolid); 5]); // the letter L
    keys.extend([
        ("6", Command::Rotate(Axis::Y, true)),
        ("6", Command::Rotate(Axis::Y, true)),
        ("8", Command::Rotate(Axis::X, false)),
        ("n", Command::NextSolid), // the three beams
        ("4", Command::Rotate(Axis::Y, false)),
        ("l", Command::ToggleLighting),
    ]);
    after_each_key(&keys);
}

#[test]
fn solids_passing_through_each_other() {
    let mut keys = vec![("r", Command::Reset), ("m", Command::ToggleSeveral)];
    // Into the octahedron's orbit, where it waits at the start.
    keys.extend([("right", Command::MoveRight); 7]);
    keys.extend([("up", Command::MoveUp); 3]);
    keys.push(("6", Command::Rotate(Axis::Y, true)));
    after_each_key(&keys);
}

#[test]
fn the_crowd() {
    after_each_key(&[
        ("r", Command::Reset),
        ("x", Command::ToggleCrowd),
        ("6", Command::Rotate(Axis::Y, true)),
        ("l", Command::ToggleLighting),
        ("x", Command::ToggleCrowd),
    ]);
}
