//! The extras in QEMU: lighting, the other solids, several objects, help and
//! statistics. After each key, QEMU's screendump of its own VGA emulation must
//! equal the software VGA's picture of the same commands, pixel for pixel —
//! except the top statistics line, whose figures are timings.

mod common;

use boot::RgbImage;
use common::{assert_pictures_equal, assert_same_picture, TURNED};
use demo::command::{Axis, Command, LightTurn, SceneCommand, Sense};
use demo::osd::BAR_ROWS;

/// After each key, exactly the model's picture (with statistics on, all but
/// their timings).
fn after_each_key(keys: &[(&str, Command)]) {
    common::after_each_key(keys, |qemu, model, app, what| {
        if app.overlay().stats {
            exactly_but_the_timings(qemu, model, what);
        } else {
            assert_same_picture(qemu, model, what);
        }
    });
}

fn turned_then(more: &[(&'static str, Command)]) -> Vec<(&'static str, Command)> {
    TURNED.iter().chain(more).copied().collect()
}

#[test]
fn lighting_and_turning_the_light() {
    after_each_key(&turned_then(&[
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
        (
            "end",
            Command::Scene(SceneCommand::TurnLight(LightTurn::Right)),
        ),
        (
            "end",
            Command::Scene(SceneCommand::TurnLight(LightTurn::Right)),
        ),
        (
            "pgdn",
            Command::Scene(SceneCommand::TurnLight(LightTurn::Down)),
        ),
        (
            "home",
            Command::Scene(SceneCommand::TurnLight(LightTurn::Left)),
        ),
        (
            "pgup",
            Command::Scene(SceneCommand::TurnLight(LightTurn::Up)),
        ),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
    ]));
}

#[test]
fn every_solid_in_turn() {
    after_each_key(&turned_then(&[
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("f1", common::turn(Axis::Z, Sense::Positive)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
    ]));
}

#[test]
fn several_objects_then_reset() {
    after_each_key(&turned_then(&[
        ("m", Command::Scene(SceneCommand::ToggleSeveral)),
        ("right", Command::Scene(SceneCommand::MoveRight)),
        ("right", Command::Scene(SceneCommand::MoveRight)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("r", Command::Scene(SceneCommand::Reset)),
    ]));
}

#[test]
fn help_opens_over_the_scene_and_closes() {
    after_each_key(&turned_then(&[
        ("h", Command::ToggleHelp),
        ("left", Command::Scene(SceneCommand::MoveLeft)),
        ("h", Command::ToggleHelp),
    ]));
}

const WHITE: [u8; 3] = [255, 255, 255];
const BLACK: [u8; 3] = [0, 0, 0];

/// Rows `from..to` of a picture.
fn rows(picture: &RgbImage, from: usize, to: usize) -> RgbImage {
    let pixels = picture.pixels[from * picture.width..to * picture.width].to_vec();
    RgbImage::new(picture.width, to - from, pixels)
}

/// Exact below the top bar; the top bar (frame rate and frame time, which
/// differ between QEMU and the model) must be white text on black.
fn exactly_but_the_timings(qemu: &RgbImage, model: &RgbImage, what: &str) {
    let qemu = qemu.halve().unwrap_or_else(|e| panic!("{what}: {e}"));
    let bar = BAR_ROWS as usize;
    assert_pictures_equal(
        &rows(&qemu, bar, qemu.height),
        &rows(model, bar, model.height),
        what,
    );
    let top = rows(&qemu, 0, bar);
    assert!(
        top.pixels.iter().all(|&p| p == WHITE || p == BLACK),
        "{what}: the top bar is not white on black"
    );
    let text = top.pixels.iter().filter(|&&p| p == WHITE).count();
    assert!(text > 100, "{what}: only {text} text pixels in the top bar");
}

#[test]
fn statistics_in_the_top_and_bottom_rows() {
    after_each_key(&turned_then(&[
        ("s", Command::ToggleStats),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("m", Command::Scene(SceneCommand::ToggleSeveral)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
    ]));
}
