//! What a real keyboard event carries besides its `code`: the Windows
//! virtual-key code Chromium's input pipeline wants (`keyCode` in the page)
//! and the key's place on the keyboard, for the keys of a PC keyboard.

/// The protocol's `location` of the left one of a pair (Shift, Ctrl, Alt);
/// the page sees it as `KeyboardEvent.location` 1.
pub const LOCATION_LEFT: u32 = 1;
/// The protocol's `location` of the right one of a pair.
pub const LOCATION_RIGHT: u32 = 2;

/// The Windows virtual-key code of the key whose `KeyboardEvent.code` is
/// `code`, or `None` for a code this table does not know.
pub fn virtual_key_code(code: &str) -> Option<u32> {
    // Letters and digits: their ASCII capitals.
    if let Some(letter) = code.strip_prefix("Key") {
        return single_char(letter)
            .filter(char::is_ascii_uppercase)
            .map(u32::from);
    }
    if let Some(digit) = code.strip_prefix("Digit") {
        return single_char(digit)
            .filter(char::is_ascii_digit)
            .map(u32::from);
    }
    if let Some(digit) = code.strip_prefix("Numpad").and_then(single_char) {
        return digit.to_digit(10).map(|d| 0x60 + d);
    }
    if let Some(number) = code.strip_prefix('F').and_then(|n| n.parse::<u32>().ok()) {
        return (1..=24).contains(&number).then_some(0x6F + number);
    }
    let vk = match code {
        "Backspace" => 0x08,
        "Tab" => 0x09,
        "Enter" | "NumpadEnter" => 0x0D,
        "ShiftLeft" | "ShiftRight" => 0x10,
        "ControlLeft" | "ControlRight" => 0x11,
        "AltLeft" | "AltRight" => 0x12,
        "Pause" => 0x13,
        "CapsLock" => 0x14,
        "Escape" => 0x1B,
        "Space" => 0x20,
        "PageUp" => 0x21,
        "PageDown" => 0x22,
        "End" => 0x23,
        "Home" => 0x24,
        "ArrowLeft" => 0x25,
        "ArrowUp" => 0x26,
        "ArrowRight" => 0x27,
        "ArrowDown" => 0x28,
        "PrintScreen" => 0x2C,
        "Insert" => 0x2D,
        "Delete" => 0x2E,
        "MetaLeft" => 0x5B,
        "MetaRight" => 0x5C,
        "ContextMenu" => 0x5D,
        "NumpadMultiply" => 0x6A,
        "NumpadAdd" => 0x6B,
        "NumpadSubtract" => 0x6D,
        "NumpadDecimal" => 0x6E,
        "NumpadDivide" => 0x6F,
        "NumLock" => 0x90,
        "ScrollLock" => 0x91,
        "Semicolon" => 0xBA,
        "Equal" => 0xBB,
        "Comma" => 0xBC,
        "Minus" => 0xBD,
        "Period" => 0xBE,
        "Slash" => 0xBF,
        "Backquote" => 0xC0,
        "BracketLeft" => 0xDB,
        "Backslash" => 0xDC,
        "BracketRight" => 0xDD,
        "Quote" => 0xDE,
        "IntlBackslash" => 0xE2,
        _ => return None,
    };
    Some(vk)
}

/// Whether the key is on the numeric keypad: the protocol says so with
/// `isKeypad`, and the page sees `KeyboardEvent.location` 3.
pub fn is_keypad(code: &str) -> bool {
    code.starts_with("Numpad")
}

/// The protocol's `location` of the key whose code is `code`: left or
/// right of a pair, else 0.
pub fn location(code: &str) -> u32 {
    if code.ends_with("Left") && !code.starts_with("Arrow") && !code.starts_with("Bracket") {
        LOCATION_LEFT
    } else if code.ends_with("Right") && !code.starts_with("Arrow") && !code.starts_with("Bracket")
    {
        LOCATION_RIGHT
    } else {
        0
    }
}

fn single_char(text: &str) -> Option<char> {
    let mut chars = text.chars();
    let first = chars.next()?;
    chars.next().is_none().then_some(first)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letters_digits_and_function_keys_follow_their_ranges() {
        assert_eq!(virtual_key_code("KeyA"), Some(0x41));
        assert_eq!(virtual_key_code("KeyZ"), Some(0x5A));
        assert_eq!(virtual_key_code("Digit0"), Some(0x30));
        assert_eq!(virtual_key_code("Digit9"), Some(0x39));
        assert_eq!(virtual_key_code("Numpad4"), Some(0x64));
        assert_eq!(virtual_key_code("F1"), Some(0x70));
        assert_eq!(virtual_key_code("F12"), Some(0x7B));
    }

    #[test]
    fn codes_outside_the_table_have_none() {
        for code in [
            "Keya", "KeyAB", "Key", "Digit", "DigitX", "F0", "F25", "Fn", "Nope",
        ] {
            assert_eq!(virtual_key_code(code), None, "{code}");
        }
    }

    #[test]
    fn the_keypad_and_paired_modifiers_say_where_they_are() {
        assert!(is_keypad("Numpad8") && is_keypad("NumpadEnter"));
        assert!(!is_keypad("Digit8") && !is_keypad("NumLock"));
        assert_eq!(location("Numpad8"), 0);
        assert_eq!(location("ShiftLeft"), LOCATION_LEFT);
        assert_eq!(location("ControlRight"), LOCATION_RIGHT);
        assert_eq!(location("ArrowLeft"), 0);
        assert_eq!(location("BracketRight"), 0);
        assert_eq!(location("KeyL"), 0);
    }
}
