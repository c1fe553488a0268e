//! Keys by name, as the runner's `--keys` and QEMU's `sendkey` name them, and
//! the PS/2 scan-code set 1 bytes a PC keyboard sends for each: a make code on
//! press and the same code with bit 7 set on release, E0-prefixed for the
//! keys the 84-key keyboard did not have (the arrows and the editing block).
//!
//! One table serves the runner (which checks names before QEMU sees them),
//! the simulator (which turns names and host keys into scan codes) and the
//! list of names in `docs/runner.md` (which `tests/docs.rs` compares with it).

use crate::scancode::{BREAK_BIT, EXTENDED_PREFIX};

/// One key's scan code in set 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scancode {
    /// Sent after an E0 prefix.
    pub extended: bool,
    /// The make code (bit 7 clear).
    pub code: u8,
}

/// The one or two bytes of a make or break code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScancodeBytes {
    bytes: [u8; 2],
    len: usize,
}

impl core::ops::Deref for ScancodeBytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.bytes[..self.len]
    }
}

impl Scancode {
    const fn plain(code: u8) -> Self {
        Self {
            extended: false,
            code,
        }
    }

    const fn extended(code: u8) -> Self {
        Self {
            extended: true,
            code,
        }
    }

    /// The bytes the keyboard sends when the key goes down (or repeats).
    pub fn make(self) -> ScancodeBytes {
        self.bytes(self.code)
    }

    /// The bytes the keyboard sends when the key comes up.
    pub fn release(self) -> ScancodeBytes {
        self.bytes(self.code | BREAK_BIT)
    }

    fn bytes(self, code: u8) -> ScancodeBytes {
        if self.extended {
            ScancodeBytes {
                bytes: [EXTENDED_PREFIX, code],
                len: 2,
            }
        } else {
            ScancodeBytes {
                bytes: [code, 0],
                len: 1,
            }
        }
    }
}

/// Every key by its name, in scan-code order.
pub const KEYS: &[(&str, Scancode)] = &[
    ("esc", Scancode::plain(0x01)),
    ("1", Scancode::plain(0x02)),
    ("2", Scancode::plain(0x03)),
    ("3", Scancode::plain(0x04)),
    ("4", Scancode::plain(0x05)),
    ("5", Scancode::plain(0x06)),
    ("6", Scancode::plain(0x07)),
    ("7", Scancode::plain(0x08)),
    ("8", Scancode::plain(0x09)),
    ("9", Scancode::plain(0x0A)),
    ("0", Scancode::plain(0x0B)),
    ("minus", Scancode::plain(0x0C)),
    ("equal", Scancode::plain(0x0D)),
    ("backspace", Scancode::plain(0x0E)),
    ("tab", Scancode::plain(0x0F)),
    ("q", Scancode::plain(0x10)),
    ("w", Scancode::plain(0x11)),
    ("e", Scancode::plain(0x12)),
    ("r", Scancode::plain(0x13)),
    ("t", Scancode::plain(0x14)),
    ("y", Scancode::plain(0x15)),
    ("u", Scancode::plain(0x16)),
    ("i", Scancode::plain(0x17)),
    ("o", Scancode::plain(0x18)),
    ("p", Scancode::plain(0x19)),
    ("bracket_left", Scancode::plain(0x1A)),
    ("bracket_right", Scancode::plain(0x1B)),
    ("ret", Scancode::plain(0x1C)),
    ("ctrl", Scancode::plain(0x1D)),
    ("a", Scancode::plain(0x1E)),
    ("s", Scancode::plain(0x1F)),
    ("d", Scancode::plain(0x20)),
    ("f", Scancode::plain(0x21)),
    ("g", Scancode::plain(0x22)),
    ("h", Scancode::plain(0x23)),
    ("j", Scancode::plain(0x24)),
    ("k", Scancode::plain(0x25)),
    ("l", Scancode::plain(0x26)),
    ("semicolon", Scancode::plain(0x27)),
    ("apostrophe", Scancode::plain(0x28)),
    ("grave_accent", Scancode::plain(0x29)),
    ("shift", Scancode::plain(0x2A)),
    ("backslash", Scancode::plain(0x2B)),
    ("z", Scancode::plain(0x2C)),
    ("x", Scancode::plain(0x2D)),
    ("c", Scancode::plain(0x2E)),
    ("v", Scancode::plain(0x2F)),
    ("b", Scancode::plain(0x30)),
    ("n", Scancode::plain(0x31)),
    ("m", Scancode::plain(0x32)),
    ("comma", Scancode::plain(0x33)),
    ("dot", Scancode::plain(0x34)),
    ("slash", Scancode::plain(0x35)),
    ("shift_r", Scancode::plain(0x36)),
    ("kp_multiply", Scancode::plain(0x37)),
    ("alt", Scancode::plain(0x38)),
    ("spc", Scancode::plain(0x39)),
    ("caps_lock", Scancode::plain(0x3A)),
    ("f1", Scancode::plain(0x3B)),
    ("f2", Scancode::plain(0x3C)),
    ("f3", Scancode::plain(0x3D)),
    ("f4", Scancode::plain(0x3E)),
    ("f5", Scancode::plain(0x3F)),
    ("f6", Scancode::plain(0x40)),
    ("f7", Scancode::plain(0x41)),
    ("f8", Scancode::plain(0x42)),
    ("f9", Scancode::plain(0x43)),
    ("f10", Scancode::plain(0x44)),
    ("num_lock", Scancode::plain(0x45)),
    ("scroll_lock", Scancode::plain(0x46)),
    ("kp_7", Scancode::plain(0x47)),
    ("kp_8", Scancode::plain(0x48)),
    ("kp_9", Scancode::plain(0x49)),
    ("kp_subtract", Scancode::plain(0x4A)),
    ("kp_4", Scancode::plain(0x4B)),
    ("kp_5", Scancode::plain(0x4C)),
    ("kp_6", Scancode::plain(0x4D)),
    ("kp_add", Scancode::plain(0x4E)),
    ("kp_1", Scancode::plain(0x4F)),
    ("kp_2", Scancode::plain(0x50)),
    ("kp_3", Scancode::plain(0x51)),
    ("kp_0", Scancode::plain(0x52)),
    ("kp_decimal", Scancode::plain(0x53)),
    ("f11", Scancode::plain(0x57)),
    ("f12", Scancode::plain(0x58)),
    ("kp_enter", Scancode::extended(0x1C)),
    ("ctrl_r", Scancode::extended(0x1D)),
    ("kp_divide", Scancode::extended(0x35)),
    ("alt_r", Scancode::extended(0x38)),
    ("home", Scancode::extended(0x47)),
    ("up", Scancode::extended(0x48)),
    ("pgup", Scancode::extended(0x49)),
    ("left", Scancode::extended(0x4B)),
    ("right", Scancode::extended(0x4D)),
    ("end", Scancode::extended(0x4F)),
    ("down", Scancode::extended(0x50)),
    ("pgdn", Scancode::extended(0x51)),
    ("insert", Scancode::extended(0x52)),
    ("delete", Scancode::extended(0x53)),
    ("meta_l", Scancode::extended(0x5B)),
    ("meta_r", Scancode::extended(0x5C)),
    ("menu", Scancode::extended(0x5D)),
];

/// The scan code of the key with this name (any case).
pub fn scancode_for_name(name: &str) -> Option<Scancode> {
    KEYS.iter()
        .find(|(known, _)| known.eq_ignore_ascii_case(name))
        .map(|&(_, scancode)| scancode)
}

/// The names, in the order error messages and `docs/runner.md` list them.
pub fn names() -> impl Iterator<Item = &'static str> {
    KEYS.iter().map(|&(name, _)| name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrows_and_the_editing_block_are_extended() {
        for name in ["left", "right", "up", "down", "home", "end", "pgup", "pgdn"] {
            let scancode = scancode_for_name(name).unwrap();
            assert!(scancode.extended, "{name}");
            assert_eq!(*scancode.make(), [0xE0, scancode.code]);
            assert_eq!(*scancode.release(), [0xE0, scancode.code | 0x80]);
        }
    }

    #[test]
    fn the_keypad_and_the_top_row_differ() {
        assert_eq!(*scancode_for_name("kp_4").unwrap().make(), [0x4B]);
        assert_eq!(*scancode_for_name("4").unwrap().make(), [0x05]);
        assert_eq!(*scancode_for_name("ESC").unwrap().release(), [0x81]);
    }

    #[test]
    fn names_and_scan_codes_are_each_listed_once() {
        for (index, (name, scancode)) in KEYS.iter().enumerate() {
            assert!(
                !KEYS[..index].iter().any(|(other, _)| other == name),
                "{name}"
            );
            assert!(
                !KEYS[..index].iter().any(|(_, other)| other == scancode),
                "{name}"
            );
        }
    }
}
