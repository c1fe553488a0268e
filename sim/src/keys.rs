//! Host keys as a PC keyboard would send them: each host key has the runner's
//! name for it, and `keyboard::keys` has the one table of names and PS/2 scan
//! codes, so a key sequence means the same to the runner and to the simulator.
//! The host keys of the window are the `desktop` feature's; the names, the
//! key lists and taps are everyone's (the web page's too).

#[cfg(feature = "desktop")]
use minifb::Key;

pub use keyboard::keys::{scancode_for_name, Scancode};

/// Every host key the simulator passes on, with its name in `keyboard::keys`.
#[cfg(feature = "desktop")]
const HOST_KEYS: &[(Key, &str)] = &[
    (Key::Escape, "esc"),
    (Key::Key1, "1"),
    (Key::Key2, "2"),
    (Key::Key3, "3"),
    (Key::Key4, "4"),
    (Key::Key5, "5"),
    (Key::Key6, "6"),
    (Key::Key7, "7"),
    (Key::Key8, "8"),
    (Key::Key9, "9"),
    (Key::Key0, "0"),
    (Key::Minus, "minus"),
    (Key::Equal, "equal"),
    (Key::Backspace, "backspace"),
    (Key::Tab, "tab"),
    (Key::Q, "q"),
    (Key::W, "w"),
    (Key::E, "e"),
    (Key::R, "r"),
    (Key::T, "t"),
    (Key::Y, "y"),
    (Key::U, "u"),
    (Key::I, "i"),
    (Key::O, "o"),
    (Key::P, "p"),
    (Key::LeftBracket, "bracket_left"),
    (Key::RightBracket, "bracket_right"),
    (Key::Enter, "ret"),
    (Key::LeftCtrl, "ctrl"),
    (Key::A, "a"),
    (Key::S, "s"),
    (Key::D, "d"),
    (Key::F, "f"),
    (Key::G, "g"),
    (Key::H, "h"),
    (Key::J, "j"),
    (Key::K, "k"),
    (Key::L, "l"),
    (Key::Semicolon, "semicolon"),
    (Key::Apostrophe, "apostrophe"),
    (Key::Backquote, "grave_accent"),
    (Key::LeftShift, "shift"),
    (Key::Backslash, "backslash"),
    (Key::Z, "z"),
    (Key::X, "x"),
    (Key::C, "c"),
    (Key::V, "v"),
    (Key::B, "b"),
    (Key::N, "n"),
    (Key::M, "m"),
    (Key::Comma, "comma"),
    (Key::Period, "dot"),
    (Key::Slash, "slash"),
    (Key::RightShift, "shift_r"),
    (Key::NumPadAsterisk, "kp_multiply"),
    (Key::LeftAlt, "alt"),
    (Key::Space, "spc"),
    (Key::CapsLock, "caps_lock"),
    (Key::F1, "f1"),
    (Key::F2, "f2"),
    (Key::F3, "f3"),
    (Key::F4, "f4"),
    (Key::F5, "f5"),
    (Key::F6, "f6"),
    (Key::F7, "f7"),
    (Key::F8, "f8"),
    (Key::F9, "f9"),
    (Key::F10, "f10"),
    (Key::NumLock, "num_lock"),
    (Key::ScrollLock, "scroll_lock"),
    (Key::NumPad7, "kp_7"),
    (Key::NumPad8, "kp_8"),
    (Key::NumPad9, "kp_9"),
    (Key::NumPadMinus, "kp_subtract"),
    (Key::NumPad4, "kp_4"),
    (Key::NumPad5, "kp_5"),
    (Key::NumPad6, "kp_6"),
    (Key::NumPadPlus, "kp_add"),
    (Key::NumPad1, "kp_1"),
    (Key::NumPad2, "kp_2"),
    (Key::NumPad3, "kp_3"),
    (Key::NumPad0, "kp_0"),
    (Key::NumPadDot, "kp_decimal"),
    (Key::F11, "f11"),
    (Key::F12, "f12"),
    (Key::NumPadEnter, "kp_enter"),
    (Key::RightCtrl, "ctrl_r"),
    (Key::NumPadSlash, "kp_divide"),
    (Key::RightAlt, "alt_r"),
    (Key::Home, "home"),
    (Key::Up, "up"),
    (Key::PageUp, "pgup"),
    (Key::Left, "left"),
    (Key::Right, "right"),
    (Key::End, "end"),
    (Key::Down, "down"),
    (Key::PageDown, "pgdn"),
    (Key::Insert, "insert"),
    (Key::Delete, "delete"),
    (Key::LeftSuper, "meta_l"),
    (Key::RightSuper, "meta_r"),
    (Key::Menu, "menu"),
];

/// The scan code of a host key; `None` for keys a PC keyboard has no plain
/// scan code for (F13 and up, Pause's E1 sequence).
#[cfg(feature = "desktop")]
pub fn scancode_for_key(key: Key) -> Option<Scancode> {
    HOST_KEYS
        .iter()
        .find(|(host, _)| *host == key)
        .and_then(|&(_, name)| scancode_for_name(name))
}

/// A key name that `--keys` does not know; its message lists the names.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown key {name:?}; key names: {}", known_names())]
pub struct UnknownKey {
    /// The name as given.
    pub name: String,
}

fn known_names() -> String {
    keyboard::keys::names().collect::<Vec<_>>().join(" ")
}

/// A `--keys` argument ("r 4 4 f1 left spc"), as scan codes; an unknown name
/// is refused with the list of names.
pub fn parse_keys(text: &str) -> Result<Vec<Scancode>, UnknownKey> {
    text.split_whitespace()
        .map(|name| {
            scancode_for_name(name).ok_or_else(|| UnknownKey {
                name: name.to_string(),
            })
        })
        .collect()
}

/// The bytes of a press and release, as a tap on the key sends them.
pub fn tap(scancode: Scancode) -> Vec<u8> {
    let mut bytes = scancode.make().to_vec();
    bytes.extend_from_slice(&scancode.release());
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(feature = "desktop")]
    #[test]
    fn every_host_key_has_a_known_name_and_each_is_listed_once() {
        for (index, (key, name)) in HOST_KEYS.iter().enumerate() {
            assert!(scancode_for_name(name).is_some(), "{name}");
            assert!(!HOST_KEYS[..index].iter().any(|(other, _)| other == key));
            assert!(!HOST_KEYS[..index].iter().any(|(_, other)| other == name));
        }
        assert_eq!(scancode_for_key(Key::Left), scancode_for_name("left"));
    }

    #[test]
    fn unknown_names_are_refused_with_the_list() {
        let error = parse_keys("r bogus").unwrap_err();
        assert_eq!(error.name, "bogus");
        let error = error.to_string();
        assert!(
            error.contains("\"bogus\"") && error.contains("pgdn"),
            "{error}"
        );
        assert_eq!(parse_keys(" R  f1 ").unwrap().len(), 2);
        assert_eq!(tap(scancode_for_name("esc").unwrap()), [0x01, 0x81]);
    }
}
