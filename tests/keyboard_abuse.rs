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

use boot::{BootRequest, Qemu, QemuOptions};
use common::assert_same_picture;
use common::flood::{
    assert_flood_presses_the_chord_keys_yet_never_makes_it, flood_then_r_then_the_chord,
    table_bytes, track_modifier, Flood, KeyBytes, Pacer, Target, TABLE_KEYS,
};
use demo::app::App;
use std::time::Duration;

/// QEMU key names the flood taps: the keys both keyboards send as the key
/// table says, and Pause, Print Screen and Menu (QEMU's "compose"), whose
/// PS/2 codes QEMU makes by its own rules.
fn keys() -> Vec<&'static str> {
    let mut keys = TABLE_KEYS.to_vec();
    keys.extend(["pause", "print", "compose"]);
    keys
}
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
    flood_then_r_then_the_chord(
        &mut qemu,
        Flood::new(QemuPs2::default(), keys(), false),
        App::new(),
        Pacer::new(Target::Ps2),
        FLOOD_KEYS,
        assert_same_picture,
    );
}

/// The flood itself, on the host: Ctrl, Alt and Delete are pressed often,
/// modifiers are held across other keys, no event's bytes overflow QEMU's
/// queue on their own, and the byte stream, fed to the kernel's chord
/// watch, never resets.
#[test]
fn the_flood_presses_ctrl_alt_and_delete_yet_never_makes_the_chord() {
    assert_flood_presses_the_chord_keys_yet_never_makes_it(
        Flood::new(QemuPs2::default(), keys(), false),
        FLOOD_KEYS,
    );
}
