//! A USB boot keyboard's reports become PS/2 scancode set 1, as the 8042
//! delivers it after translation: each report is compared with the last,
//! and every key that went down gives its make code and every key that came
//! up its break code (the make code with bit 7 set, after the same E0
//! prefix). A USB keyboard does not repeat by itself, so the last key pressed
//! repeats here at the PS/2 defaults (500 ms, then about 10.9 a second),
//! driven by the caller's clock.

use crate::hid::KeySet;
use keyboard::scancode::{BREAK_BIT as BREAK, EXTENDED_PREFIX as PREFIX_E0};

/// The eight bytes of a boot-protocol keyboard report: modifier bits, a
/// reserved byte, and up to six usages of keys held down.
pub const REPORT_BYTES: usize = 8;
/// PS/2's default typematic delay: a key held this long starts repeating.
pub const REPEAT_DELAY_MICROS: u64 = 500_000;
/// PS/2's default typematic rate, 10.9 characters a second, as a period.
pub const REPEAT_PERIOD_MICROS: u64 = 91_743;
/// Usages 1-3 in every key slot say "too many keys" (ErrorRollOver,
/// POSTFail, ErrorUndefined), not which keys are down.
const FIRST_REAL_USAGE: u8 = 0x04;

/// A set-1 key: its code and whether PS/2 sends an E0 before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Set1Key {
    /// The make code (without the break bit).
    pub code: u8,
    /// PS/2 sends E0 first (the keys the original 84-key keyboard lacked).
    pub extended: bool,
}

const fn plain(code: u8) -> Option<Set1Key> {
    Some(Set1Key {
        code,
        extended: false,
    })
}

const fn extended(code: u8) -> Option<Set1Key> {
    Some(Set1Key {
        code,
        extended: true,
    })
}

/// The modifier byte's bits, from bit 0: left Ctrl, Shift, Alt, GUI, then
/// the right-hand ones.
const MODIFIERS: [Set1Key; 8] = [
    Set1Key {
        code: 0x1D,
        extended: false,
    },
    Set1Key {
        code: 0x2A,
        extended: false,
    },
    Set1Key {
        code: 0x38,
        extended: false,
    },
    Set1Key {
        code: 0x5B,
        extended: true,
    },
    Set1Key {
        code: 0x1D,
        extended: true,
    },
    Set1Key {
        code: 0x36,
        extended: false,
    },
    Set1Key {
        code: 0x38,
        extended: true,
    },
    Set1Key {
        code: 0x5C,
        extended: true,
    },
];

/// The set-1 key for a HID keyboard usage (page 7), if PS/2 has one.
pub fn set1_key(usage: u8) -> Option<Set1Key> {
    // Letters a-z in usage order.
    const LETTERS: [u8; 26] = [
        0x1E, 0x30, 0x2E, 0x20, 0x12, 0x21, 0x22, 0x23, 0x17, 0x24, 0x25, 0x26, 0x32, 0x31, 0x18,
        0x19, 0x10, 0x13, 0x1F, 0x14, 0x16, 0x2F, 0x11, 0x2D, 0x15, 0x2C,
    ];
    match usage {
        0x04..=0x1D => plain(LETTERS[usize::from(usage - 0x04)]),
        // 1-9 then 0, as on the keyboard's top row.
        0x1E..=0x27 => plain(usage - 0x1E + 0x02),
        0x28 => plain(0x1C),                       // Enter
        0x29 => plain(0x01),                       // Esc
        0x2A => plain(0x0E),                       // Backspace
        0x2B => plain(0x0F),                       // Tab
        0x2C => plain(0x39),                       // Space
        0x2D => plain(0x0C),                       // -
        0x2E => plain(0x0D),                       // =
        0x2F => plain(0x1A),                       // [
        0x30 => plain(0x1B),                       // ]
        0x31 | 0x32 => plain(0x2B),                // \ and the non-US # (same key position)
        0x33 => plain(0x27),                       // ;
        0x34 => plain(0x28),                       // '
        0x35 => plain(0x29),                       // `
        0x36 => plain(0x33),                       // ,
        0x37 => plain(0x34),                       // .
        0x38 => plain(0x35),                       // /
        0x39 => plain(0x3A),                       // Caps Lock
        0x3A..=0x43 => plain(usage - 0x3A + 0x3B), // F1-F10
        0x44 => plain(0x57),                       // F11
        0x45 => plain(0x58),                       // F12
        0x46 => extended(0x37),                    // Print Screen (its E0 2A prefix left out)
        0x47 => plain(0x46),                       // Scroll Lock
        0x49 => extended(0x52),                    // Insert
        0x4A => extended(0x47),                    // Home
        0x4B => extended(0x49),                    // Page Up
        0x4C => extended(0x53),                    // Delete
        0x4D => extended(0x4F),                    // End
        0x4E => extended(0x51),                    // Page Down
        0x4F => extended(0x4D),                    // Right
        0x50 => extended(0x4B),                    // Left
        0x51 => extended(0x50),                    // Down
        0x52 => extended(0x48),                    // Up
        0x53 => plain(0x45),                       // Num Lock
        0x54 => extended(0x35),                    // keypad /
        0x55 => plain(0x37),                       // keypad *
        0x56 => plain(0x4A),                       // keypad -
        0x57 => plain(0x4E),                       // keypad +
        0x58 => extended(0x1C),                    // keypad Enter
        0x59 => plain(0x4F),                       // keypad 1
        0x5A => plain(0x50),                       // keypad 2
        0x5B => plain(0x51),                       // keypad 3
        0x5C => plain(0x4B),                       // keypad 4
        0x5D => plain(0x4C),                       // keypad 5
        0x5E => plain(0x4D),                       // keypad 6
        0x5F => plain(0x47),                       // keypad 7
        0x60 => plain(0x48),                       // keypad 8
        0x61 => plain(0x49),                       // keypad 9
        0x62 => plain(0x52),                       // keypad 0
        0x63 => plain(0x53),                       // keypad .
        0x64 => plain(0x56),                       // the non-US \ left of Z
        0x65 => extended(0x5D),                    // Menu (Application)
        _ => None,
    }
}

/// Pause has no break code and a six-byte make: E1 1D 45 E1 9D C5.
const PAUSE_USAGE: u8 = 0x48;
const PAUSE_BYTES: [u8; 6] = [0xE1, 0x1D, 0x45, 0xE1, 0x9D, 0xC5];

/// The first modifier usage (left Ctrl); the eight run to right GUI, in
/// the boot report's modifier bit order.
const FIRST_MODIFIER_USAGE: u8 = 0xE0;

/// What is held down and repeating; fed reports, gives scancode bytes.
#[derive(Clone, Debug, Default)]
pub struct BootKeyboard {
    /// The usages held down (modifiers as 0xE0-0xE7).
    held: KeySet,
    /// The key that repeats (the last pressed, while it is held) and when it
    /// next does.
    repeating: Option<(Set1Key, u64)>,
}

fn emit(key: Set1Key, released: bool, out: &mut impl FnMut(u8)) {
    if key.extended {
        out(PREFIX_E0);
    }
    out(if released { key.code | BREAK } else { key.code });
}

/// The set-1 key of a usage, modifiers included.
fn key_of(usage: u8) -> Option<Set1Key> {
    match usage.checked_sub(FIRST_MODIFIER_USAGE) {
        Some(bit) if bit < 8 => Some(MODIFIERS[usize::from(bit)]),
        _ => set1_key(usage),
    }
}

/// Usages in the order their codes go out: modifiers first (so that Shift
/// or Ctrl is down before the key it changes), then the rest by usage.
fn usages_in_order() -> impl Iterator<Item = u8> {
    (FIRST_MODIFIER_USAGE..=FIRST_MODIFIER_USAGE + 7).chain(0..FIRST_MODIFIER_USAGE)
}

/// A boot report's keys as a key set, or None for a short or
/// rollover-error report (whose keys are unknown).
pub fn boot_report_keys(bytes: &[u8]) -> Option<KeySet> {
    let report = bytes.get(..REPORT_BYTES)?;
    let mut keys = KeySet::default();
    for bit in 0..8 {
        if report[0] & (1 << bit) != 0 {
            keys.insert(FIRST_MODIFIER_USAGE + bit);
        }
    }
    for &usage in &report[2..] {
        match usage {
            0 => {}
            1..FIRST_REAL_USAGE => return None,
            _ => keys.insert(usage),
        }
    }
    Some(keys)
}

impl BootKeyboard {
    /// A keyboard with nothing held.
    pub fn new() -> Self {
        Self::default()
    }

    /// Takes one boot report (`bytes`, as many as the device sent) received
    /// at `now_micros`, giving the scancode bytes for what changed. Short
    /// reports and rollover-error reports change nothing.
    pub fn report(&mut self, bytes: &[u8], now_micros: u64, out: &mut impl FnMut(u8)) {
        if let Some(keys) = boot_report_keys(bytes) {
            self.keys(&keys, now_micros, out);
        }
    }

    /// Takes the set of keys now down (however the report said it), giving
    /// the scancode bytes for what changed since the last set.
    pub fn keys(&mut self, keys: &KeySet, now_micros: u64, out: &mut impl FnMut(u8)) {
        // Breaks first, so that a key moving between slots never looks released.
        for usage in usages_in_order() {
            if self.held.contains(usage) && !keys.contains(usage) && usage != PAUSE_USAGE {
                if let Some(key) = key_of(usage) {
                    self.released(key, out);
                }
            }
        }
        for usage in usages_in_order() {
            if !keys.contains(usage) || self.held.contains(usage) {
                continue;
            }
            if usage == PAUSE_USAGE {
                PAUSE_BYTES.iter().for_each(|&b| out(b));
                // Pause does not repeat, and stops whatever did (as on PS/2).
                self.repeating = None;
            } else if let Some(key) = key_of(usage) {
                self.pressed(key, now_micros, out);
            }
        }
        self.held = *keys;
    }

    fn pressed(&mut self, key: Set1Key, now_micros: u64, out: &mut impl FnMut(u8)) {
        emit(key, false, out);
        self.repeating = Some((key, now_micros.saturating_add(REPEAT_DELAY_MICROS)));
    }

    fn released(&mut self, key: Set1Key, out: &mut impl FnMut(u8)) {
        emit(key, true, out);
        if self
            .repeating
            .is_some_and(|(repeating, _)| repeating == key)
        {
            self.repeating = None;
        }
    }

    /// Repeats the held key's make code for every repeat due by `now_micros`
    /// (at most a few, so a long stall gives a short burst, not a flood).
    pub fn tick(&mut self, now_micros: u64, out: &mut impl FnMut(u8)) {
        const MOST_REPEATS_AT_ONCE: u32 = 4;
        let Some((key, mut due)) = self.repeating else {
            return;
        };
        let mut repeats = 0;
        while now_micros >= due {
            if repeats < MOST_REPEATS_AT_ONCE {
                emit(key, false, out);
                repeats += 1;
            }
            due = due.saturating_add(REPEAT_PERIOD_MICROS);
        }
        self.repeating = Some((key, due));
    }

    /// Forgets every key (the device went away): gives break codes for what
    /// was held, so nothing stays pressed.
    pub fn release_all(&mut self, out: &mut impl FnMut(u8)) {
        self.keys(&KeySet::default(), 0, out);
        self.repeating = None;
    }
}

#[cfg(test)]
mod tests;
