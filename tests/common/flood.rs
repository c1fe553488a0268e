//! The key floods' shared model: actions drawn from a key list (taps,
//! modifiers held across other keys, near misses of Ctrl+Alt+Del) with the
//! scancode bytes the kernel will take for each event, the reset chord
//! watched as the kernel watches it so that no action makes it; and the
//! pacer that sends them in windows QEMU's keyboard queue holds, each only
//! when the kernel's echo (`scancodes=echo`) shows every earlier byte taken.
//! The PS/2 flood (`tests/keyboard_abuse.rs`) and the USB flood
//! (`tests/usb.rs`) differ only in the keyboard that turns events into bytes
//! and the device the events are sent to.

use boot::{line, Qemu, RgbImage};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use keyboard::reset_keys::ResetChord;
use modex::ModeX;
use std::time::Instant;

use super::{model_picture, soft_vga_in_mode_x, BOOT_TIMEOUT};

/// The modifiers the floods hold down across other keys.
pub const MODIFIERS: &[&str] = &["shift", "shift_r", "ctrl", "ctrl_r", "alt", "alt_r"];
/// QEMU key names of the keys a PC keyboard sends as the key table says,
/// on PS/2 and on USB (QEMU's usb-kbd queues the same scancodes for them as
/// the kernel gives from its reports). Esc is left out: it ends the demo,
/// as it should.
pub const TABLE_KEYS: &[&str] = &[
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
];
/// QEMU's PS/2 keyboard queues 16 bytes (`hw/input/ps2.c`, `PS2_QUEUE_SIZE`)
/// and its usb-hid 16 scancodes (`hw/input/hid.c`, `QUEUE_LENGTH`); each
/// drops an event that does not fit. For the keys the floods press, an
/// event's bytes are as many as it takes in either queue.
pub const QEMU_KEY_QUEUE: usize = 16;

/// A keyboard as far as the bytes of an event go, as the kernel takes them.
pub trait KeyBytes: Clone {
    /// The bytes of `key` going down or up; remembers held modifiers.
    fn bytes(&mut self, key: &'static str, down: bool) -> Vec<u8>;
    /// The modifiers held down, oldest first.
    fn held(&self) -> &[&'static str];
}

/// Keeps `held` up to date with a modifier's event.
pub fn track_modifier(held: &mut Vec<&'static str>, key: &'static str, down: bool) {
    if MODIFIERS.contains(&key) {
        held.retain(|&h| h != key);
        if down {
            held.push(key);
        }
    }
}

/// A key's set-1 bytes from the project's one key table.
pub fn table_bytes(name: &str, down: bool) -> Vec<u8> {
    let scancode = keyboard::keys::scancode_for_name(name)
        .unwrap_or_else(|| panic!("{name:?} is not in the key table"));
    if down {
        scancode.make().to_vec()
    } else {
        scancode.release().to_vec()
    }
}

/// One action: its events, each with the bytes the kernel takes for it.
pub type Action = Vec<((&'static str, bool), Vec<u8>)>;

/// The flood, generated with what it will do.
pub struct Flood<K: KeyBytes> {
    pub keyboard: K,
    pub chord: ResetChord,
    state: u64,
    keys: Vec<&'static str>,
    /// The flood is for a USB keyboard, whose last key pressed repeats while
    /// held (the kernel's own typematic, timed by the guest's clock): a
    /// modifier's hold is followed in the same action by a tap, and a tap
    /// never presses a held modifier (a USB keyboard sends nothing for it,
    /// so the modifier before it would go on repeating), so that no action
    /// ends with a key that repeats while the test waits.
    usb: bool,
}

impl<K: KeyBytes> Flood<K> {
    /// A flood of taps of `keys` and the holds and near misses below,
    /// always the same for one keyboard and key list.
    pub fn new(keyboard: K, keys: Vec<&'static str>, usb: bool) -> Self {
        Flood {
            keyboard,
            chord: ResetChord::new(),
            state: 0x2545_f491_4f6c_dd1d,
            keys,
            usb,
        }
    }

    fn random(&mut self, below: usize) -> usize {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        (self.state % below as u64) as usize
    }

    fn tap(&mut self) -> Vec<(&'static str, bool)> {
        loop {
            let drawn = self.random(self.keys.len());
            let key = self.keys[drawn];
            if !(self.usb && self.keyboard.held().contains(&key)) {
                return vec![(key, true), (key, false)];
            }
        }
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
                let mut events = vec![(modifier, true)];
                if self.usb {
                    // The tap's key is drawn as if the modifier were held.
                    let mut tap = self.tap();
                    while tap[0].0 == modifier {
                        tap = self.tap();
                    }
                    events.extend(tap);
                }
                events
            }
            // ...until one is released.
            29 | 55 | 91 => match self.keyboard.held().to_vec().as_slice() {
                [] => vec![],
                held => vec![(held[self.random(held.len())], false)],
            },
            _ => self.tap(),
        }
    }

    /// The `index`th action, as events and each event's bytes; an action
    /// that would complete Ctrl+Alt+Del is not taken (a tap of a random key
    /// is drawn instead, until one does not), so that the only chord is the
    /// one at the end.
    pub fn action(&mut self, index: usize) -> Action {
        let mut events = self.propose(index);
        loop {
            let (mut keyboard, mut chord) = (self.keyboard.clone(), self.chord);
            let mut resets = false;
            let with_bytes: Action = events
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
            events = self.tap();
        }
    }

    /// The events that release whatever is still held, with their bytes;
    /// none of them may make the chord.
    pub fn release_held(&mut self) -> Action {
        self.keyboard
            .held()
            .to_vec()
            .into_iter()
            .map(|modifier| {
                let bytes = self.keyboard.bytes(modifier, false);
                for &byte in &bytes {
                    assert!(!self.chord.feed(byte), "releasing {modifier} resets");
                }
                ((modifier, false), bytes)
            })
            .collect()
    }

    /// Ctrl+Alt+Del pressed: its events and bytes, and whether the
    /// kernel's chord watch, fed them after the flood, resets.
    pub fn chord_press(&mut self) -> (Action, bool) {
        let mut resets = false;
        let action = [("ctrl", true), ("alt", true), ("delete", true)]
            .into_iter()
            .map(|(key, down)| {
                let bytes = self.keyboard.bytes(key, down);
                for &byte in &bytes {
                    resets |= self.chord.feed(byte);
                }
                ((key, down), bytes)
            })
            .collect();
        (action, resets)
    }
}

/// Where the pacer's events go: the PS/2 keyboard, or the USB keyboard
/// bound to a display.
#[derive(Clone, Copy)]
pub enum Target {
    Ps2,
    BoundTo(&'static str),
}

/// Sends events in windows QEMU's queue holds, each only when the kernel has
/// taken every byte before it; keeps the bytes sent in order.
pub struct Pacer {
    target: Target,
    pub window: Vec<(&'static str, bool)>,
    /// What the window takes in QEMU's queue.
    window_cost: usize,
    /// The bytes the kernel takes for the window.
    window_bytes: usize,
    pub sent: Vec<u8>,
    pub windows: usize,
}

impl Pacer {
    pub fn new(target: Target) -> Pacer {
        Pacer {
            target,
            window: Vec::new(),
            window_cost: 0,
            window_bytes: 0,
            sent: Vec::new(),
            windows: 0,
        }
    }

    fn send(&self, qemu: &mut Qemu, events: &[(&str, bool)]) {
        match self.target {
            Target::Ps2 => qemu.key_events(events).unwrap(),
            Target::BoundTo(display) => qemu.key_events_on(display, events).unwrap(),
        }
    }

    /// What an event takes in QEMU's queue: its bytes on PS/2 (QEMU queues
    /// them translated to set 1, as the kernel takes them); on USB its
    /// scancodes by the key table, even when the kernel takes none (a held
    /// modifier pressed again changes no report).
    fn queue_cost(&self, (key, down): (&'static str, bool), bytes: &[u8]) -> usize {
        match self.target {
            Target::Ps2 => bytes.len(),
            Target::BoundTo(_) => table_bytes(key, down).len(),
        }
    }

    /// Adds an event to the window, sending the window first if the event
    /// does not fit in it.
    pub fn push(&mut self, qemu: &mut Qemu, event: (&'static str, bool), bytes: &[u8]) {
        let cost = self.queue_cost(event, bytes);
        if self.window_cost + cost > QEMU_KEY_QUEUE {
            self.flush(qemu);
        }
        self.window.push(event);
        self.window_cost += cost;
        self.window_bytes += bytes.len();
        self.sent.extend_from_slice(bytes);
    }

    /// Adds a whole action to one window, sending the window first if the
    /// action does not fit in it: no window ends inside an action.
    pub fn push_action(&mut self, qemu: &mut Qemu, action: &Action) {
        let cost: usize = action
            .iter()
            .map(|(event, bytes)| self.queue_cost(*event, bytes))
            .sum();
        assert!(
            cost <= QEMU_KEY_QUEUE,
            "too big for QEMU's queue: {action:?}"
        );
        if self.window_cost + cost > QEMU_KEY_QUEUE {
            self.flush(qemu);
        }
        for (event, bytes) in action {
            self.push(qemu, *event, bytes);
        }
    }

    /// Sends the window and waits until the kernel has taken all its bytes.
    pub fn flush(&mut self, qemu: &mut Qemu) {
        if self.window.is_empty() {
            return;
        }
        self.send(qemu, &self.window);
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
        self.window_cost = 0;
        self.window_bytes = 0;
    }

    /// Sends the window without waiting (its last event ends the machine).
    pub fn send_last(&mut self, qemu: &mut Qemu) {
        self.send(qemu, &self.window);
        self.windows += 1;
    }
}

/// Every byte the kernel said it took, in order; the totals must agree.
pub fn bytes_taken(console: &str) -> Vec<u8> {
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
pub fn commands_done(console: &str) -> u64 {
    console
        .lines()
        .rev()
        .find_map(line::CommandDone::parse)
        .unwrap_or(0)
}

/// The kernel's log after a flood: the bytes taken are the bytes sent, the
/// commands done are the model's, nothing reset or faulted, and the last
/// command line says no scancode was dropped.
pub fn assert_flood_taken_once(console: &str, sent: &[u8], model_commands: u64) {
    let taken = bytes_taken(console);
    assert!(
        taken == sent,
        "the bytes taken are not the bytes sent: {} taken, {} sent, first difference at {:?}",
        taken.len(),
        sent.len(),
        taken.iter().zip(sent).position(|(a, b)| a != b)
    );
    assert_eq!(commands_done(console), model_commands, "a key acted twice");
    assert!(
        !console.contains("power: Ctrl+Alt+Del")
            && !console.contains("EXCEPTION")
            && !console.contains("PANIC"),
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
}

/// After the chord: QEMU (told not to reboot) has ended, the kernel said it
/// was resetting exactly once, and took exactly the bytes sent.
pub fn assert_reset_once(qemu: &mut Qemu, sent: &[u8]) -> std::process::ExitStatus {
    let status = qemu
        .wait_exit(BOOT_TIMEOUT)
        .unwrap()
        .unwrap_or_else(|| panic!("QEMU still runs after the chord:\n{}", qemu.serial()));
    let console = qemu.serial();
    assert_eq!(
        console.matches("power: Ctrl+Alt+Del: resetting").count(),
        1,
        "{console}"
    );
    assert_eq!(bytes_taken(&console), sent);
    status
}

/// The flood itself, on the host: Ctrl, Alt and Delete (and right Ctrl,
/// right Alt, keypad Delete) are pressed often, modifiers are held across
/// other keys, no action's bytes overflow QEMU's queue on their own, and the
/// byte stream, fed to the kernel's chord watch, never resets.
pub fn assert_flood_presses_the_chord_keys_yet_never_makes_it<K: KeyBytes>(
    mut flood: Flood<K>,
    actions: usize,
) {
    let mut watch = ResetChord::new();
    let mut presses = std::collections::HashMap::new();
    let mut most_held = 0;
    for index in 0..actions {
        let action = flood.action(index);
        let action_bytes: usize = action.iter().map(|(_, bytes)| bytes.len()).sum();
        assert!(action_bytes <= QEMU_KEY_QUEUE, "action {index}: {action:?}");
        for ((key, down), bytes) in action {
            for byte in bytes {
                assert!(!watch.feed(byte), "a chord at action {index}");
            }
            if down {
                *presses.entry(key).or_insert(0) += 1;
            }
            most_held = most_held.max(flood.keyboard.held().len());
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

/// Feeds an action's bytes to a model app, as the kernel will take them.
pub fn feed(model: &mut App, action: &Action) {
    for (_, bytes) in action {
        for &byte in bytes {
            model.feed_scancode(byte);
        }
    }
}

/// The flood on a QEMU at the ready line whose kernel echoes what it takes,
/// `model` standing where the kernel's app stands and `pacer.sent` holding
/// every byte taken so far: `actions` actions, then whatever is still held
/// released; the bytes taken must be the bytes sent and the commands the
/// model's. Then R twice (the first resumes if the flood left the demo
/// paused), and `compare` gets the screen and the software VGA's starting
/// scene (as the model shows it, 320x240). Last, a real Ctrl+Alt+Del must
/// reset the machine exactly once. A USB flood is sent a whole action to a
/// window (see [`Flood::usb`]); a PS/2 one fills each window to the last byte.
pub fn flood_then_r_then_the_chord<K: KeyBytes>(
    qemu: &mut Qemu,
    mut flood: Flood<K>,
    mut model: App,
    mut pacer: Pacer,
    actions: usize,
    compare: impl Fn(&RgbImage, &RgbImage, &str),
) {
    let started = Instant::now();
    let bytes_before = pacer.sent.len();
    for index in 0..actions {
        let action = flood.action(index);
        feed(&mut model, &action);
        assert!(!model.quit_requested(), "the flood asked to quit");
        if flood.usb {
            pacer.push_action(qemu, &action);
        } else {
            for (event, bytes) in &action {
                pacer.push(qemu, *event, bytes);
            }
        }
    }
    let release = flood.release_held();
    feed(&mut model, &release);
    pacer.push_action(qemu, &release);
    pacer.flush(qemu);
    let done = line::CommandDone(model.commands()).to_string();
    qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    println!(
        "{actions} actions, {} bytes in {} windows, {} commands done, in {:.1?}",
        pacer.sent.len() - bytes_before,
        pacer.windows,
        model.commands(),
        started.elapsed()
    );
    assert_flood_taken_once(&qemu.serial(), &pacer.sent, model.commands());

    for _ in 0..2 {
        let tap = [("r", true), ("r", false)]
            .map(|(key, down)| ((key, down), flood.keyboard.bytes(key, down)))
            .to_vec();
        feed(&mut model, &tap);
        pacer.push_action(qemu, &tap);
        pacer.flush(qemu);
        let done = line::CommandDone(model.commands()).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    }
    assert!(!model.paused());
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    compare(
        &qemu.screendump().unwrap(),
        &model_picture(&soft),
        "after the flood and R",
    );

    // QEMU, told not to reboot, ends on the reset.
    let (chord, resets) = flood.chord_press();
    assert!(resets, "the model sees the chord");
    for (event, bytes) in &chord {
        pacer.push(qemu, *event, bytes);
    }
    pacer.send_last(qemu);
    let status = assert_reset_once(qemu, &pacer.sent);
    println!("QEMU ended with {status} after the chord");
}
