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
use common::{assert_same_picture, model_picture, soft_vga_in_mode_x, BOOT_TIMEOUT};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use keyboard::reset_keys::ResetChord;
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
/// The modifiers the flood holds down across other keys.
const MODIFIERS: &[&str] = &["shift", "shift_r", "ctrl", "ctrl_r", "alt", "alt_r"];
/// Keys in the flood (taps, holds, releases and near misses).
const FLOOD_KEYS: usize = 2000;
/// A boot on a machine shared with busy loops and other emulators can take
/// minutes; this only bounds a failure.
const FLOOD_BOOT_TIMEOUT: Duration = Duration::from_secs(300);
/// QEMU's PS/2 keyboard queues 16 bytes and drops an event that does not
/// fit (`hw/input/ps2.c`, `PS2_QUEUE_SIZE`).
const PS2_QUEUE_BYTES: usize = 16;

/// QEMU's PS/2 keyboard, as far as the bytes of an event go: it remembers
/// which modifiers are down, and Pause and Print Screen send different
/// codes with them (`ps2_keyboard_event`, translated to set 1 by the 8042
/// as the kernel leaves it).
#[derive(Default)]
struct QemuPs2 {
    held: Vec<&'static str>,
}

impl QemuPs2 {
    fn holds(&self, key: &str) -> bool {
        self.held.contains(&key)
    }

    fn bytes(&mut self, key: &'static str, down: bool) -> Vec<u8> {
        if MODIFIERS.contains(&key) {
            self.held.retain(|&held| held != key);
            if down {
                self.held.push(key);
            }
        }
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
                let name = if key == "compose" { "menu" } else { key };
                let scancode = keyboard::keys::scancode_for_name(name)
                    .unwrap_or_else(|| panic!("{key:?} is not in the key table"));
                if down {
                    scancode.make().to_vec()
                } else {
                    scancode.release().to_vec()
                }
            }
        }
    }
}

/// The flood, generated with what it will do: the bytes QEMU makes of each
/// event, the reset chord watched as the kernel watches it.
struct Flood {
    keyboard: QemuPs2,
    chord: ResetChord,
    state: u64,
}

impl Flood {
    fn random(&mut self, below: usize) -> usize {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        (self.state % below as u64) as usize
    }

    /// The `index`th action's events.
    fn propose(&mut self, index: usize) -> Vec<(&'static str, bool)> {
        match index % 100 {
            // Near misses of the reset chord: Ctrl and Alt released before
            // Delete; Ctrl+Delete; Alt+keypad Delete.
            37 => vec![
                ("ctrl", true),
                ("alt", true),
                ("ctrl", false),
                ("alt", false),
                ("delete", true),
                ("delete", false),
            ],
            61 => vec![
                ("ctrl_r", true),
                ("delete", true),
                ("delete", false),
                ("ctrl_r", false),
            ],
            83 => vec![
                ("alt_r", true),
                ("kp_decimal", true),
                ("kp_decimal", false),
                ("alt_r", false),
            ],
            // A modifier goes down and stays down across the keys after it...
            11 | 45 | 70 | 80 => {
                let modifier = MODIFIERS[self.random(MODIFIERS.len())];
                vec![(modifier, true)]
            }
            // ...until one is released.
            29 | 55 | 91 => match self.keyboard.held.clone().as_slice() {
                [] => vec![],
                held => vec![(held[self.random(held.len())], false)],
            },
            _ => {
                let key = KEYS[self.random(KEYS.len())];
                vec![(key, true), (key, false)]
            }
        }
    }

    /// The `index`th action, as events and each event's bytes; an action
    /// that would complete Ctrl+Alt+Del is not taken (a tap of a random key
    /// is drawn instead, until one does not), so that the only chord is the
    /// one at the end.
    fn action(&mut self, index: usize) -> Vec<((&'static str, bool), Vec<u8>)> {
        let mut events = self.propose(index);
        loop {
            let (mut keyboard, mut chord) = (
                QemuPs2 {
                    held: self.keyboard.held.clone(),
                },
                self.chord,
            );
            let mut resets = false;
            let with_bytes: Vec<_> = events
                .iter()
                .map(|&(key, down)| {
                    let bytes = keyboard.bytes(key, down);
                    for &byte in &bytes {
                        resets |= chord.feed(byte);
                    }
                    ((key, down), bytes)
                })
                .collect();
            if !resets {
                self.keyboard = keyboard;
                self.chord = chord;
                return with_bytes;
            }
            let key = KEYS[self.random(KEYS.len())];
            events = vec![(key, true), (key, false)];
        }
    }
}

/// Sends events in windows QEMU's PS/2 queue holds, each only when the
/// kernel has taken every byte before it; keeps the bytes sent in order.
struct Pacer {
    window: Vec<(&'static str, bool)>,
    window_bytes: usize,
    sent: Vec<u8>,
    windows: usize,
}

impl Pacer {
    fn new() -> Pacer {
        Pacer {
            window: Vec::new(),
            window_bytes: 0,
            sent: Vec::new(),
            windows: 0,
        }
    }

    fn push(&mut self, qemu: &mut Qemu, event: (&'static str, bool), bytes: &[u8]) {
        if self.window_bytes + bytes.len() > PS2_QUEUE_BYTES {
            self.flush(qemu);
        }
        self.window.push(event);
        self.window_bytes += bytes.len();
        self.sent.extend_from_slice(bytes);
    }

    /// Sends the window and waits until the kernel has taken all its bytes.
    fn flush(&mut self, qemu: &mut Qemu) {
        if self.window.is_empty() {
            return;
        }
        qemu.key_events(&self.window).unwrap();
        self.windows += 1;
        if self.window_bytes > 0 {
            let needle = format!(", {} in all\n", self.sent.len());
            if let Err(e) = qemu.wait_for_serial(&needle, BOOT_TIMEOUT) {
                panic!(
                    "the kernel never took byte {} (window {:?}, bytes {:x?}): {e}",
                    self.sent.len(),
                    self.window,
                    &self.sent[self.sent.len() - self.window_bytes..]
                );
            }
        }
        self.window.clear();
        self.window_bytes = 0;
    }
}

/// Every byte the kernel said it took, in order; the totals must agree.
fn bytes_taken(console: &str) -> Vec<u8> {
    let mut taken = Vec::new();
    let mut line_bytes = [0u8; 64];
    for text in console.lines() {
        if let Some((count, total)) = line::ScancodesTaken::parse(text, &mut line_bytes) {
            taken.extend_from_slice(&line_bytes[..count]);
            assert_eq!(total, taken.len() as u64, "{text}");
        }
    }
    taken
}

/// The count in the kernel's last "demo: command N done" line.
fn commands_done(console: &str) -> u64 {
    console
        .lines()
        .rev()
        .find_map(line::CommandDone::parse)
        .unwrap_or(0)
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
    let mut flood = Flood {
        keyboard: QemuPs2::default(),
        chord: ResetChord::new(),
        state: 0x2545_f491_4f6c_dd1d,
    };
    let mut model = App::new();
    let mut pacer = Pacer::new();
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
    for modifier in flood.keyboard.held.clone() {
        let bytes = flood.keyboard.bytes(modifier, false);
        for &byte in &bytes {
            assert!(!flood.chord.feed(byte));
            model.feed_scancode(byte);
        }
        pacer.push(&mut qemu, (modifier, false), &bytes);
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
    let taken = bytes_taken(&console);
    assert!(
        taken == pacer.sent,
        "the bytes taken are not the bytes sent: {} taken, {} sent, first difference at {:?}",
        taken.len(),
        pacer.sent.len(),
        taken.iter().zip(&pacer.sent).position(|(a, b)| a != b)
    );
    assert_eq!(
        commands_done(&console),
        model.commands(),
        "a key acted twice"
    );
    assert!(
        !console.contains("power: Ctrl+Alt+Del") && !console.contains("EXCEPTION"),
        "{console}"
    );
    let last_command = console
        .lines()
        .rev()
        .find(|l| line::CommandDone::parse(l).is_some())
        .unwrap_or_default();
    assert!(
        last_command.ends_with("scancodes dropped=0"),
        "{last_command}"
    );

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
    let chord = [("ctrl", true), ("alt", true), ("delete", true)];
    let mut resets = false;
    for event in chord {
        let bytes = flood.keyboard.bytes(event.0, event.1);
        for &byte in &bytes {
            resets |= flood.chord.feed(byte);
        }
        pacer.push(&mut qemu, event, &bytes);
    }
    assert!(resets, "the model sees the chord");
    qemu.key_events(&pacer.window).unwrap();
    let status = qemu
        .wait_exit(BOOT_TIMEOUT)
        .unwrap()
        .expect("QEMU ended on the reset");
    let console = qemu.serial();
    assert_eq!(
        console.matches("power: Ctrl+Alt+Del: resetting").count(),
        1,
        "{console}"
    );
    assert_eq!(bytes_taken(&console), pacer.sent);
    println!("QEMU ended with {status} after the chord");
}

/// The flood itself, on the host: Ctrl, Alt and Delete are pressed often,
/// modifiers are held across other keys, no event's bytes overflow QEMU's
/// queue on their own, and the byte stream, fed to the kernel's chord
/// watch, never resets.
#[test]
fn the_flood_presses_ctrl_alt_and_delete_yet_never_makes_the_chord() {
    let mut flood = Flood {
        keyboard: QemuPs2::default(),
        chord: ResetChord::new(),
        state: 0x2545_f491_4f6c_dd1d,
    };
    let mut watch = ResetChord::new();
    let mut presses = std::collections::HashMap::new();
    let mut most_held = 0;
    for index in 0..FLOOD_KEYS {
        for ((key, down), bytes) in flood.action(index) {
            assert!(bytes.len() <= PS2_QUEUE_BYTES);
            for byte in bytes {
                assert!(!watch.feed(byte), "a chord at action {index}");
            }
            if down {
                *presses.entry(key).or_insert(0) += 1;
            }
            most_held = most_held.max(flood.keyboard.held.len());
        }
    }
    for key in ["ctrl", "ctrl_r", "alt", "alt_r", "delete", "kp_decimal"] {
        assert!(
            presses.get(key).copied().unwrap_or(0) >= 20,
            "{key}: {presses:?}"
        );
    }
    assert!(most_held >= 2, "modifiers held together: {most_held}");
}
