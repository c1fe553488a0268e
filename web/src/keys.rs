//! The browser's keys as a PC keyboard sends them: each `KeyboardEvent.code`
//! the page passes on has the runner's name for the key, and `keyboard::keys`
//! has the one table of names and set-1 scan codes, so a key in the browser
//! means what it means to the runner, the simulator and the kernel.

use keyboard::keys::{scancode_for_name, Scancode};

/// Every `KeyboardEvent.code` the page passes on, with the key's name in
/// `keyboard::keys`. The letters, digits and function keys follow a pattern
/// and are in [`name_for_code`]; these are the rest.
const CODES: &[(&str, &str)] = &[
    ("Escape", "esc"),
    ("Minus", "minus"),
    ("Equal", "equal"),
    ("Backspace", "backspace"),
    ("Tab", "tab"),
    ("BracketLeft", "bracket_left"),
    ("BracketRight", "bracket_right"),
    ("Enter", "ret"),
    ("ControlLeft", "ctrl"),
    ("Semicolon", "semicolon"),
    ("Quote", "apostrophe"),
    ("Backquote", "grave_accent"),
    ("ShiftLeft", "shift"),
    ("Backslash", "backslash"),
    ("Comma", "comma"),
    ("Period", "dot"),
    ("Slash", "slash"),
    ("ShiftRight", "shift_r"),
    ("NumpadMultiply", "kp_multiply"),
    ("AltLeft", "alt"),
    ("Space", "spc"),
    ("CapsLock", "caps_lock"),
    ("NumLock", "num_lock"),
    ("ScrollLock", "scroll_lock"),
    ("NumpadSubtract", "kp_subtract"),
    ("NumpadAdd", "kp_add"),
    ("NumpadDecimal", "kp_decimal"),
    ("NumpadEnter", "kp_enter"),
    ("ControlRight", "ctrl_r"),
    ("NumpadDivide", "kp_divide"),
    ("AltRight", "alt_r"),
    ("Home", "home"),
    ("ArrowUp", "up"),
    ("PageUp", "pgup"),
    ("ArrowLeft", "left"),
    ("ArrowRight", "right"),
    ("End", "end"),
    ("ArrowDown", "down"),
    ("PageDown", "pgdn"),
    ("Insert", "insert"),
    ("Delete", "delete"),
    ("MetaLeft", "meta_l"),
    ("MetaRight", "meta_r"),
    ("ContextMenu", "menu"),
];

/// Keys the browser is left to handle even while the picture has focus:
/// Tab moves the focus on, so the keyboard never traps a reader.
const BROWSER_KEEPS: &[&str] = &["Tab"];

/// The runner's name for the key with `KeyboardEvent.code` `code`; `None`
/// for keys a PC keyboard has no plain scan code for (F13 and up, media
/// keys, the international keys).
pub fn name_for_code(code: &str) -> Option<&'static str> {
    if let Some(&(_, name)) = CODES.iter().find(|(known, _)| *known == code) {
        return Some(name);
    }
    let single = |rest: &str, first: u8, last: u8| -> Option<u8> {
        let &[byte] = rest.as_bytes() else {
            return None;
        };
        (first..=last).contains(&byte).then_some(byte)
    };
    // "KeyA" to "KeyZ", "Digit0" to "Digit9", "Numpad0" to "Numpad9".
    if let Some(letter) = code.strip_prefix("Key").and_then(|l| single(l, b'A', b'Z')) {
        return known(&[letter.to_ascii_lowercase()]);
    }
    if let Some(digit) = code
        .strip_prefix("Digit")
        .and_then(|d| single(d, b'0', b'9'))
    {
        return known(&[digit]);
    }
    if let Some(digit) = code
        .strip_prefix("Numpad")
        .and_then(|d| single(d, b'0', b'9'))
    {
        return known(&[b'k', b'p', b'_', digit]);
    }
    // "F1" to "F12".
    let number: u8 = code.strip_prefix('F')?.parse().ok()?;
    if (1..=12).contains(&number) {
        return keyboard::keys::names().find(|name| *name == format!("f{number}"));
    }
    None
}

/// The name in `keyboard::keys` spelled by `bytes`, as the table's own
/// `&'static str`.
fn known(bytes: &[u8]) -> Option<&'static str> {
    let spelled = core::str::from_utf8(bytes).ok()?;
    keyboard::keys::names().find(|name| *name == spelled)
}

/// What a key event does on the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyAction {
    /// The key's scan code.
    pub scancode: Scancode,
    /// The browser must not act on it too (scroll on the arrows and Space,
    /// open a menu on F10 or Alt, search on '/', go back on Backspace).
    pub prevent_default: bool,
}

/// The page's action for the key with `KeyboardEvent.code` `code`; `None`
/// for a key the page does not use, which the browser keeps.
pub fn action_for_code(code: &str) -> Option<KeyAction> {
    let scancode = scancode_for_name(name_for_code(code)?)?;
    Some(KeyAction {
        scancode,
        prevent_default: !BROWSER_KEEPS.contains(&code),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_readme_keys_map_to_their_runner_names() {
        let table = [
            ("ArrowLeft", "left"),
            ("ArrowRight", "right"),
            ("ArrowUp", "up"),
            ("ArrowDown", "down"),
            ("Space", "spc"),
            ("Escape", "esc"),
            ("KeyL", "l"),
            ("KeyM", "m"),
            ("KeyX", "x"),
            ("KeyH", "h"),
            ("KeyV", "v"),
            ("Digit4", "4"),
            ("Numpad4", "kp_4"),
            ("F1", "f1"),
            ("F12", "f12"),
            ("PageUp", "pgup"),
            ("Home", "home"),
            ("Enter", "ret"),
        ];
        for (code, name) in table {
            assert_eq!(name_for_code(code), Some(name), "{code}");
            assert_eq!(
                action_for_code(code).map(|a| a.scancode),
                scancode_for_name(name),
                "{code}"
            );
        }
    }

    #[test]
    fn every_runner_key_has_exactly_one_browser_code() {
        let mut codes: Vec<String> = CODES.iter().map(|(c, _)| c.to_string()).collect();
        codes.extend((b'A'..=b'Z').map(|l| format!("Key{}", l as char)));
        codes.extend((0..10).map(|d| format!("Digit{d}")));
        codes.extend((0..10).map(|d| format!("Numpad{d}")));
        codes.extend((1..=12).map(|f| format!("F{f}")));
        let mut named: Vec<&str> = codes
            .iter()
            .map(|code| name_for_code(code).unwrap_or_else(|| panic!("{code}")))
            .collect();
        named.sort_unstable();
        let before = named.len();
        named.dedup();
        assert_eq!(named.len(), before, "two codes give one name");
        let mut names: Vec<&str> = keyboard::keys::names().collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(named, names);
    }

    #[test]
    fn keys_a_pc_keyboard_lacks_are_left_to_the_browser() {
        for code in [
            "F13",
            "F0",
            "F",
            "Key",
            "KeyAB",
            "Keya",
            "Digit10",
            "IntlBackslash",
            "",
            "Fn",
        ] {
            assert_eq!(action_for_code(code), None, "{code}");
        }
        assert!(action_for_code("ArrowDown").unwrap().prevent_default);
        assert!(action_for_code("F10").unwrap().prevent_default);
        assert!(!action_for_code("Tab").unwrap().prevent_default);
    }
}
