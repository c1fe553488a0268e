//! Keys as a PC keyboard sends them: PS/2 scan-code set 1, a make code on
//! press and the same code with bit 7 set on release, E0-prefixed for the
//! keys the 84-key keyboard did not have (the arrows and the editing block).
//!
//! Each key has the name the runner's `--keys` (QEMU's `sendkey`) uses, so a
//! key sequence means the same to the runner and to the simulator.

use minifb::Key;

/// The prefix of the extended keys.
const EXTENDED_PREFIX: u8 = 0xE0;
/// Set on a make code, it makes the break code.
const BREAK_BIT: u8 = 0x80;

/// One key's scan code in set 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Scancode {
    /// Sent after an E0 prefix.
    pub extended: bool,
    /// The make code (bit 7 clear).
    pub code: u8,
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
    pub fn make(self) -> Vec<u8> {
        self.bytes(self.code)
    }

    /// The bytes the keyboard sends when the key comes up.
    pub fn release(self) -> Vec<u8> {
        self.bytes(self.code | BREAK_BIT)
    }

    /// A press and release, as a tap on the key sends them.
    pub fn tap(self) -> Vec<u8> {
        let mut bytes = self.make();
        bytes.extend(self.release());
        bytes
    }

    fn bytes(self, code: u8) -> Vec<u8> {
        if self.extended {
            vec![EXTENDED_PREFIX, code]
        } else {
            vec![code]
        }
    }
}

/// Every key the simulator passes on: its runner (QEMU) name, the host key
/// and its scan code.
const KEYS: &[(&str, Key, Scancode)] = &[
    ("esc", Key::Escape, Scancode::plain(0x01)),
    ("1", Key::Key1, Scancode::plain(0x02)),
    ("2", Key::Key2, Scancode::plain(0x03)),
    ("3", Key::Key3, Scancode::plain(0x04)),
    ("4", Key::Key4, Scancode::plain(0x05)),
    ("5", Key::Key5, Scancode::plain(0x06)),
    ("6", Key::Key6, Scancode::plain(0x07)),
    ("7", Key::Key7, Scancode::plain(0x08)),
    ("8", Key::Key8, Scancode::plain(0x09)),
    ("9", Key::Key9, Scancode::plain(0x0A)),
    ("0", Key::Key0, Scancode::plain(0x0B)),
    ("minus", Key::Minus, Scancode::plain(0x0C)),
    ("equal", Key::Equal, Scancode::plain(0x0D)),
    ("backspace", Key::Backspace, Scancode::plain(0x0E)),
    ("tab", Key::Tab, Scancode::plain(0x0F)),
    ("q", Key::Q, Scancode::plain(0x10)),
    ("w", Key::W, Scancode::plain(0x11)),
    ("e", Key::E, Scancode::plain(0x12)),
    ("r", Key::R, Scancode::plain(0x13)),
    ("t", Key::T, Scancode::plain(0x14)),
    ("y", Key::Y, Scancode::plain(0x15)),
    ("u", Key::U, Scancode::plain(0x16)),
    ("i", Key::I, Scancode::plain(0x17)),
    ("o", Key::O, Scancode::plain(0x18)),
    ("p", Key::P, Scancode::plain(0x19)),
    ("bracket_left", Key::LeftBracket, Scancode::plain(0x1A)),
    ("bracket_right", Key::RightBracket, Scancode::plain(0x1B)),
    ("ret", Key::Enter, Scancode::plain(0x1C)),
    ("ctrl", Key::LeftCtrl, Scancode::plain(0x1D)),
    ("a", Key::A, Scancode::plain(0x1E)),
    ("s", Key::S, Scancode::plain(0x1F)),
    ("d", Key::D, Scancode::plain(0x20)),
    ("f", Key::F, Scancode::plain(0x21)),
    ("g", Key::G, Scancode::plain(0x22)),
    ("h", Key::H, Scancode::plain(0x23)),
    ("j", Key::J, Scancode::plain(0x24)),
    ("k", Key::K, Scancode::plain(0x25)),
    ("l", Key::L, Scancode::plain(0x26)),
    ("semicolon", Key::Semicolon, Scancode::plain(0x27)),
    ("apostrophe", Key::Apostrophe, Scancode::plain(0x28)),
    ("grave_accent", Key::Backquote, Scancode::plain(0x29)),
    ("shift", Key::LeftShift, Scancode::plain(0x2A)),
    ("backslash", Key::Backslash, Scancode::plain(0x2B)),
    ("z", Key::Z, Scancode::plain(0x2C)),
    ("x", Key::X, Scancode::plain(0x2D)),
    ("c", Key::C, Scancode::plain(0x2E)),
    ("v", Key::V, Scancode::plain(0x2F)),
    ("b", Key::B, Scancode::plain(0x30)),
    ("n", Key::N, Scancode::plain(0x31)),
    ("m", Key::M, Scancode::plain(0x32)),
    ("comma", Key::Comma, Scancode::plain(0x33)),
    ("dot", Key::Period, Scancode::plain(0x34)),
    ("slash", Key::Slash, Scancode::plain(0x35)),
    ("shift_r", Key::RightShift, Scancode::plain(0x36)),
    ("kp_multiply", Key::NumPadAsterisk, Scancode::plain(0x37)),
    ("alt", Key::LeftAlt, Scancode::plain(0x38)),
    ("spc", Key::Space, Scancode::plain(0x39)),
    ("caps_lock", Key::CapsLock, Scancode::plain(0x3A)),
    ("f1", Key::F1, Scancode::plain(0x3B)),
    ("f2", Key::F2, Scancode::plain(0x3C)),
    ("f3", Key::F3, Scancode::plain(0x3D)),
    ("f4", Key::F4, Scancode::plain(0x3E)),
    ("f5", Key::F5, Scancode::plain(0x3F)),
    ("f6", Key::F6, Scancode::plain(0x40)),
    ("f7", Key::F7, Scancode::plain(0x41)),
    ("f8", Key::F8, Scancode::plain(0x42)),
    ("f9", Key::F9, Scancode::plain(0x43)),
    ("f10", Key::F10, Scancode::plain(0x44)),
    ("num_lock", Key::NumLock, Scancode::plain(0x45)),
    ("scroll_lock", Key::ScrollLock, Scancode::plain(0x46)),
    ("kp_7", Key::NumPad7, Scancode::plain(0x47)),
    ("kp_8", Key::NumPad8, Scancode::plain(0x48)),
    ("kp_9", Key::NumPad9, Scancode::plain(0x49)),
    ("kp_subtract", Key::NumPadMinus, Scancode::plain(0x4A)),
    ("kp_4", Key::NumPad4, Scancode::plain(0x4B)),
    ("kp_5", Key::NumPad5, Scancode::plain(0x4C)),
    ("kp_6", Key::NumPad6, Scancode::plain(0x4D)),
    ("kp_add", Key::NumPadPlus, Scancode::plain(0x4E)),
    ("kp_1", Key::NumPad1, Scancode::plain(0x4F)),
    ("kp_2", Key::NumPad2, Scancode::plain(0x50)),
    ("kp_3", Key::NumPad3, Scancode::plain(0x51)),
    ("kp_0", Key::NumPad0, Scancode::plain(0x52)),
    ("kp_decimal", Key::NumPadDot, Scancode::plain(0x53)),
    ("f11", Key::F11, Scancode::plain(0x57)),
    ("f12", Key::F12, Scancode::plain(0x58)),
    ("kp_enter", Key::NumPadEnter, Scancode::extended(0x1C)),
    ("ctrl_r", Key::RightCtrl, Scancode::extended(0x1D)),
    ("kp_divide", Key::NumPadSlash, Scancode::extended(0x35)),
    ("alt_r", Key::RightAlt, Scancode::extended(0x38)),
    ("home", Key::Home, Scancode::extended(0x47)),
    ("up", Key::Up, Scancode::extended(0x48)),
    ("pgup", Key::PageUp, Scancode::extended(0x49)),
    ("left", Key::Left, Scancode::extended(0x4B)),
    ("right", Key::Right, Scancode::extended(0x4D)),
    ("end", Key::End, Scancode::extended(0x4F)),
    ("down", Key::Down, Scancode::extended(0x50)),
    ("pgdn", Key::PageDown, Scancode::extended(0x51)),
    ("insert", Key::Insert, Scancode::extended(0x52)),
    ("delete", Key::Delete, Scancode::extended(0x53)),
    ("meta_l", Key::LeftSuper, Scancode::extended(0x5B)),
    ("meta_r", Key::RightSuper, Scancode::extended(0x5C)),
    ("menu", Key::Menu, Scancode::extended(0x5D)),
];

/// The scan code of a host key; `None` for keys a PC keyboard has no plain
/// scan code for (F13 and up, Pause's E1 sequence).
pub fn scancode_for_key(key: Key) -> Option<Scancode> {
    KEYS.iter()
        .find(|(_, host, _)| *host == key)
        .map(|&(_, _, scancode)| scancode)
}

/// The scan code of a key named as the runner's `--keys` names it.
pub fn scancode_for_name(name: &str) -> Option<Scancode> {
    KEYS.iter()
        .find(|(known, _, _)| known.eq_ignore_ascii_case(name))
        .map(|&(_, _, scancode)| scancode)
}

/// A `--keys` argument ("r 4 4 f1 left spc"), as scan codes; an unknown name
/// is refused with the list of names.
pub fn parse_keys(text: &str) -> Result<Vec<Scancode>, String> {
    text.split_whitespace()
        .map(|name| {
            scancode_for_name(name).ok_or_else(|| {
                let names: Vec<&str> = KEYS.iter().map(|(name, _, _)| *name).collect();
                format!("unknown key {name:?}; key names: {}", names.join(" "))
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrows_and_the_editing_block_are_extended() {
        for name in ["left", "right", "up", "down", "home", "end", "pgup", "pgdn"] {
            let scancode = scancode_for_name(name).unwrap();
            assert!(scancode.extended, "{name}");
            assert_eq!(scancode.make(), [0xE0, scancode.code]);
            assert_eq!(scancode.release(), [0xE0, scancode.code | 0x80]);
        }
        assert_eq!(scancode_for_key(Key::Left), scancode_for_name("left"));
    }

    #[test]
    fn the_keypad_and_the_top_row_differ() {
        assert_eq!(scancode_for_name("kp_4").unwrap().tap(), [0x4B, 0xCB]);
        assert_eq!(scancode_for_name("4").unwrap().tap(), [0x05, 0x85]);
        assert_eq!(scancode_for_name("esc").unwrap().tap(), [0x01, 0x81]);
    }

    #[test]
    fn names_and_host_keys_are_each_listed_once() {
        for (index, (name, key, _)) in KEYS.iter().enumerate() {
            assert!(!KEYS[..index].iter().any(|(other, _, _)| other == name));
            assert!(!KEYS[..index].iter().any(|(_, other, _)| other == key));
        }
    }

    #[test]
    fn unknown_names_are_refused_with_the_list() {
        let error = parse_keys("r bogus").unwrap_err();
        assert!(
            error.contains("\"bogus\"") && error.contains("pgdn"),
            "{error}"
        );
        assert_eq!(parse_keys(" R  f1 ").unwrap().len(), 2);
    }
}
