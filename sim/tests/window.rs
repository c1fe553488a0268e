//! The window under a virtual X server: the test starts `Xvfb` itself, runs
//! the built simulator in it, types keys with `xdotool` and captures the
//! window with `xwd`. After every key the window must show exactly the
//! software VGA's scan-out of the same keys, doubled; V must open the
//! inspector beside it and Esc must close the window.
//!
//! Nothing here waits on host timing: the simulator prints a line once each
//! command has reached the screen, and the test waits for those lines.

mod x11;

use sim::keys::scancode_for_name;
use sim::machine::Machine;
use sim::screen::compose;
use std::time::Duration;
use x11::{Simulator, VirtualDisplay};

/// Long enough for a busy two-core machine; reached only when something is broken.
const TIMEOUT: Duration = Duration::from_secs(120);
const SCALE: usize = 2;

/// (the runner's key name, the X keysym xdotool types for it). R first: it
/// stops the spin, so each picture after it stays still until the next key.
const KEYS: &[(&str, &str)] = &[
    ("r", "r"),
    ("left", "Left"),
    ("up", "Up"),
    ("4", "4"),
    ("f1", "F1"),
    ("l", "l"),
    ("pgup", "Prior"),
    ("home", "Home"),
    ("n", "n"),
    ("m", "m"),
    ("a", "a"),
];

#[test]
fn the_window_shows_the_software_vgas_picture_after_each_key() {
    let display = VirtualDisplay::start(TIMEOUT);
    let mut simulator = Simulator::start(&display, &[]);
    let window = simulator.wait_for_window(TIMEOUT);
    assert_eq!((window.width, window.height), (640, 480));

    let mut model = Machine::new();
    for (n, &(name, keysym)) in KEYS.iter().enumerate() {
        display.type_key(window.id, keysym);
        simulator.wait_for_command(n as u64 + 1, TIMEOUT);
        model.tap(scancode_for_name(name).unwrap());
        model.frame();
        let expected = compose(&model.scanout_rgb(), SCALE, None);
        let shown = display.capture(window.id);
        shown.assert_equals(
            &expected,
            640,
            480,
            &format!("after key {} ({name})", n + 1),
        );
    }

    display.type_key(window.id, "v");
    simulator.wait_for_line("sim: inspector shown", TIMEOUT);
    let window = simulator.last_window();
    let shown = display.capture(window.id);
    assert_eq!(
        (shown.width, shown.height),
        (640 + 400, 480),
        "the inspector's window"
    );
    let picture = compose(&model.scanout_rgb(), SCALE, None);
    shown
        .left(640)
        .assert_equals(&picture, 640, 480, "the picture beside the inspector");
    let saved = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("inspector.png");
    shown.write_png(&saved);
    println!("the inspector's window: {}", saved.display());

    display.type_key(window.id, "Escape");
    simulator.wait_for_line("sim: Esc: goodbye", TIMEOUT);
    assert!(
        simulator.wait_exit(TIMEOUT).success(),
        "Esc: the simulator did not exit cleanly"
    );
}

#[test]
fn the_scripted_keys_and_the_inspector_flag_work_in_the_window() {
    let display = VirtualDisplay::start(TIMEOUT);
    let args = ["--inspect", "--keys", "r m l 6", "--key-every", "3"];
    let mut simulator = Simulator::start(&display, &args);
    let window = simulator.wait_for_window(TIMEOUT);
    assert_eq!((window.width, window.height), (1040, 480));
    simulator.wait_for_command(4, TIMEOUT);
    let mut model = Machine::new();
    for name in ["r", "m", "l", "6"] {
        model.tap(scancode_for_name(name).unwrap());
        model.frame();
    }
    let shown = display.capture(window.id);
    let picture = compose(&model.scanout_rgb(), SCALE, None);
    shown
        .left(640)
        .assert_equals(&picture, 640, 480, "after the scripted keys");
}
