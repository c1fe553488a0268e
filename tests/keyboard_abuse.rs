//! Keyboard abuse under QEMU: a flood of 2,000 PS/2 keys — random keys,
//! modifiers held down across others, Ctrl, Alt and Delete among them (with
//! near misses of the reset chord), the extended (E0) keys, Pause with its E1
//! sequence, Print Screen's modifier-dependent codes, the lock keys — and
//! every byte reaches the kernel once, every key acts once, nothing resets
//! the machine but a real Ctrl+Alt+Del, and R brings back the starting
//! picture, pixel for pixel.
//!
//! QEMU drops key events when its queues are full: its delayed-key queue
//! (behind `sendkey`) and its PS/2 keyboard's 16 bytes. A dropped Ctrl and
//! Alt release before a Delete press makes a real chord, and the kernel
//! rightly resets. So the flood is paced by what the kernel reports: with
//! the boot word `scancodes=echo` it says every byte it takes, and the test
//! sends a window of events (at most 16 bytes, by QEMU's own rules for the
//! bytes of each event) only when every byte before it has been taken. The
//! bytes taken must then be exactly the bytes sent, and the commands exactly
//! those a model of the demo, fed the same bytes, counts.

mod common;

use boot::{line, BootRequest, Qemu, QemuOptions};
use common::flood::{
    assert_flood_presses_the_chord_keys_yet_never_makes_it, assert_flood_taken_once,
    assert_reset_once, table_bytes, track_modifier, Flood, KeyBytes, Pacer, Target,
};
use common::{assert_same_picture, model_picture, soft_vga_in_mode_x, BOOT_TIMEOUT};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use modex::ModeX;
use std::time::{Duration, Instant};

/// QEMU key names the flood taps; Esc is left out (it ends the demo, as it
/// should).
const KEYS: &[&str] = &[
    "a",
    "b",
    "c",
    "d",
    "e",
    "f",
    "g",
    "h",
    "i",
    "j",
    "k",
    "l",
    "m",
    "n",
    "o",
    "p",
    "q",
    "r",
    "s",
    "t",
    "u",
    "v",
    "w",
    "x",
    "y",
    "z",
    "0",
    "1",
    "2",
    "3",
    "4",
    "5",
    "6",
    "7",
    "8",
    "9",
    "kp_0",
    "kp_1",
    "kp_2",
    "kp_3",
    "kp_4",
    "kp_5",
    "kp_6",
    "kp_7",
    "kp_8",
    "kp_9",
    "kp_add",
    "kp_subtract",
    "kp_multiply",
    "kp_divide",
    "kp_enter",
    "kp_decimal",
    "f1",
    "f2",
    "f3",
    "f4",
    "f5",
    "f6",
    "f7",
    "f8",
    "f9",
    "f10",
    "f11",
    "f12",
    "left",
    "right",
    "up",
    "down",
    "home",
    "end",
    "pgup",
    "pgdn",
    "insert",
    "delete",
    "spc",
    "ret",
    "tab",
    "backspace",
    "minus",
    "equal",
    "comma",
    "dot",
    "slash",
    "semicolon",
    "apostrophe",
    "bracket_left",
    "bracket_right",
    "backslash",
    "grave_accent",
    "shift",
    "shift_r",
    "ctrl",
    "ctrl_r",
    "alt",
    "alt_r",
    "caps_lock",
    "num_lock",
    "scroll_lock",
    "pause",
    "print",
    "compose",
];
/// Keys in the flood (taps, holds, releases and near misses).
const FLOOD_KEYS: usize = 2000;
/// A boot on a machine shared with busy loops and other emulators can take
/// minutes; this only bounds a failure.
const FLOOD_BOOT_TIMEOUT: Duration = Duration::from_secs(300);
/// QEMU's PS/2 keyboard, as far as the bytes of an event go: it remembers
/// which modifiers are down, and Pause and Print Screen send different
/// codes with them (`ps2_keyboard_event`, translated to set 1 by the 8042
/// as the kernel leaves it).
#[derive(Clone, Default)]
struct QemuPs2 {
    held: Vec<&'static str>,
}

impl QemuPs2 {
    fn holds(&self, key: &str) -> bool {
        self.held.contains(&key)
    }
}

impl KeyBytes for QemuPs2 {
    fn held(&self) -> &[&'static str] {
        &self.held
    }

    fn bytes(&mut self, key: &'static str, down: bool) -> Vec<u8> {
        track_modifier(&mut self.held, key, down);
        let ctrl = self.holds("ctrl") || self.holds("ctrl_r");
        let shift = self.holds("shift") || self.holds("shift_r");
        match (key, down) {
            ("pause", true) if ctrl => vec![0xE0, 0x46, 0xE0, 0xC6],
            ("pause", true) => vec![0xE1, 0x1D, 0x45, 0xE1, 0x9D, 0xC5],
            ("pause", false) => vec![],
            ("print", true) if self.holds("alt") => vec![0xB8, 0x38, 0x54],
            ("print", false) if self.holds("alt") => vec![0xD4, 0xB8, 0x38],
            ("print", true) if self.holds("alt_r") => vec![0xE0, 0xB8, 0xE0, 0x38, 0x54],
            ("print", false) if self.holds("alt_r") => vec![0xD4, 0xE0, 0xB8, 0xE0, 0x38],
            ("print", true) if shift || ctrl => vec![0xE0, 0x37],
            ("print", false) if shift || ctrl => vec![0xE0, 0xB7],
            ("print", true) => vec![0xE0, 0x2A, 0xE0, 0x37],
            ("print", false) => vec![0xE0, 0xB7, 0xE0, 0xAA],
            _ => {
                // QEMU's "compose" is the Menu (Application) key, E0 5D; its
                // "menu" sends nothing on PS/2.
                table_bytes(if key == "compose" { "menu" } else { key }, down)
            }
        }
    }
}

fn boot_echoing() -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.boot = BootRequest {
        echo_scancodes: true,
        ..BootRequest::default()
    };
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    qemu.wait_for_serial(boot::READY_LINE, FLOOD_BOOT_TIMEOUT)
        .unwrap();
    qemu
}

#[test]
fn a_paced_flood_of_two_thousand_keys_acts_once_each_and_only_the_real_chord_resets() {
    let mut qemu = boot_echoing();
    let started = Instant::now();
    let mut flood = Flood::new(QemuPs2::default(), KEYS, false);
    let mut model = App::new();
    let mut pacer = Pacer::new(Target::Ps2);
    for index in 0..FLOOD_KEYS {
        for (event, bytes) in flood.action(index) {
            for &byte in &bytes {
                model.feed_scancode(byte);
            }
            pacer.push(&mut qemu, event, &bytes);
        }
        assert!(!model.quit_requested(), "the flood asked to quit");
    }
    // Whatever is still held goes up.
    for (event, bytes) in flood.release_held() {
        for &byte in &bytes {
            model.feed_scancode(byte);
        }
        pacer.push(&mut qemu, event, &bytes);
    }
    pacer.flush(&mut qemu);
    if model.commands() > 0 {
        qemu.wait_for_serial(
            &line::CommandDone(model.commands()).to_string(),
            BOOT_TIMEOUT,
        )
        .unwrap();
    }
    let console = qemu.serial();
    println!(
        "{FLOOD_KEYS} actions, {} bytes in {} windows, {} commands, in {:.1?}",
        pacer.sent.len(),
        pacer.windows,
        model.commands(),
        started.elapsed()
    );
    assert_flood_taken_once(&console, &pacer.sent, model.commands());

    // R resumes if the flood left the demo paused, then R resets.
    for _ in 0..2 {
        let bytes = flood.keyboard.bytes("r", true);
        let release = flood.keyboard.bytes("r", false);
        for &byte in bytes.iter().chain(&release) {
            model.feed_scancode(byte);
        }
        pacer.push(&mut qemu, ("r", true), &bytes);
        pacer.push(&mut qemu, ("r", false), &release);
        pacer.flush(&mut qemu);
        qemu.wait_for_serial(
            &line::CommandDone(model.commands()).to_string(),
            BOOT_TIMEOUT,
        )
        .unwrap();
    }
    assert!(!model.paused());
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &model_picture(&soft),
        "after the flood and R",
    );

    // And a real Ctrl+Alt+Del resets the machine (QEMU, told not to
    // reboot, ends).
    let (chord, resets) = flood.chord_press();
    assert!(resets, "the model sees the chord");
    for (event, bytes) in &chord {
        pacer.push(&mut qemu, *event, bytes);
    }
    pacer.send_last(&mut qemu);
    let status = assert_reset_once(&mut qemu, &pacer.sent);
    println!("QEMU ended with {status} after the chord");
}

/// The flood itself, on the host: Ctrl, Alt and Delete are pressed often,
/// modifiers are held across other keys, no event's bytes overflow QEMU's
/// queue on their own, and the byte stream, fed to the kernel's chord
/// watch, never resets.
#[test]
fn the_flood_presses_ctrl_alt_and_delete_yet_never_makes_the_chord() {
    assert_flood_presses_the_chord_keys_yet_never_makes_it(
        Flood::new(QemuPs2::default(), KEYS, false),
        FLOOD_KEYS,
    );
}
