//! From decoded keys to commands: Abrash's keys, plus Space, R and Esc, and
//! the extras' keys (L, N, M, X, H, S, I; Home, End, Page Up, Page Down).
//! The numeric keypad rotates with NumLock on (it then types digits, like the
//! top row); with NumLock off its 4/6/8/2 are arrows and move the cube.

use crate::command::{Axis, Command, LightTurn, SceneCommand, Sense};
use pc_keyboard::{DecodedKey, KeyCode};

/// The simulator's inspector key: ignored by the demo (see the module docs).
pub const INSPECTOR_KEY: char = 'v';
const INSPECTOR_KEY_UPPER: char = 'V';

/// The command for a key press, or `None` for keys that must not count as a
/// press at all (modifiers, lock keys, and the simulator's V).
pub fn command_for(key: DecodedKey) -> Option<Command> {
    match key {
        DecodedKey::Unicode(INSPECTOR_KEY | INSPECTOR_KEY_UPPER) => None,
        DecodedKey::Unicode(character) => Some(command_for_character(character)),
        DecodedKey::RawKey(code) => command_for_raw(code),
    }
}

fn command_for_character(character: char) -> Command {
    match character {
        'a' | 'A' => Command::Scene(SceneCommand::Away),
        't' | 'T' => Command::Scene(SceneCommand::Toward),
        '4' => Command::Scene(SceneCommand::Rotate(Axis::Y, Sense::Negative)),
        '6' => Command::Scene(SceneCommand::Rotate(Axis::Y, Sense::Positive)),
        '8' => Command::Scene(SceneCommand::Rotate(Axis::X, Sense::Negative)),
        '2' => Command::Scene(SceneCommand::Rotate(Axis::X, Sense::Positive)),
        ' ' => Command::Scene(SceneCommand::ToggleSpin),
        'l' | 'L' => Command::Scene(SceneCommand::ToggleLighting),
        'n' | 'N' => Command::Scene(SceneCommand::NextSolid),
        'm' | 'M' => Command::Scene(SceneCommand::ToggleSeveral),
        'x' | 'X' => Command::Scene(SceneCommand::ToggleCrowd),
        'h' | 'H' => Command::ToggleHelp,
        's' | 'S' => Command::ToggleStats,
        'r' | 'R' => Command::Scene(SceneCommand::Reset),
        'i' | 'I' => Command::ToggleReport,
        '\u{1b}' => Command::Quit,
        _ => Command::Pause,
    }
}

fn command_for_raw(code: KeyCode) -> Option<Command> {
    Some(match code {
        KeyCode::ArrowLeft => Command::Scene(SceneCommand::MoveLeft),
        KeyCode::ArrowRight => Command::Scene(SceneCommand::MoveRight),
        KeyCode::ArrowUp => Command::Scene(SceneCommand::MoveUp),
        KeyCode::ArrowDown => Command::Scene(SceneCommand::MoveDown),
        KeyCode::F1 => Command::Scene(SceneCommand::Rotate(Axis::Z, Sense::Positive)),
        KeyCode::F2 => Command::Scene(SceneCommand::Rotate(Axis::Z, Sense::Negative)),
        KeyCode::Home => Command::Scene(SceneCommand::TurnLight(LightTurn::Left)),
        KeyCode::End => Command::Scene(SceneCommand::TurnLight(LightTurn::Right)),
        KeyCode::PageUp => Command::Scene(SceneCommand::TurnLight(LightTurn::Up)),
        KeyCode::PageDown => Command::Scene(SceneCommand::TurnLight(LightTurn::Down)),
        // Us104Key turns these into digits or arrows by NumLock; a layout or
        // decoder that hands over the keypad key itself still rotates.
        KeyCode::Numpad4 => Command::Scene(SceneCommand::Rotate(Axis::Y, Sense::Negative)),
        KeyCode::Numpad6 => Command::Scene(SceneCommand::Rotate(Axis::Y, Sense::Positive)),
        KeyCode::Numpad8 => Command::Scene(SceneCommand::Rotate(Axis::X, Sense::Negative)),
        KeyCode::Numpad2 => Command::Scene(SceneCommand::Rotate(Axis::X, Sense::Positive)),
        KeyCode::Escape => Command::Quit,
        KeyCode::LShift
        | KeyCode::RShift
        | KeyCode::LControl
        | KeyCode::RControl
        | KeyCode::RControl2
        | KeyCode::LAlt
        | KeyCode::RAltGr
        | KeyCode::RAlt2
        | KeyCode::LWin
        | KeyCode::RWin
        | KeyCode::CapsLock
        | KeyCode::NumpadLock
        | KeyCode::ScrollLock => return None,
        _ => Command::Pause,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use pc_keyboard::{layouts::Us104Key, HandleControl, PS2Keyboard as Keyboard, ScancodeSet1};
    use std::vec::Vec;

    /// Runs scancode-set-1 bytes through the same decoder the kernel uses.
    fn commands_for_bytes(bytes: &[u8]) -> Vec<Command> {
        let mut keyboard = Keyboard::new(ScancodeSet1::new(), Us104Key, HandleControl::Ignore);
        let mut commands = Vec::new();
        for &byte in bytes {
            if let Ok(Some(event)) = keyboard.add_byte(byte) {
                if let Some(command) = keyboard.process_keyevent(event).and_then(command_for) {
                    commands.push(command);
                }
            }
        }
        commands
    }

    #[test]
    fn abrashs_keys_map_to_his_commands() {
        use Command::{Pause, Quit, Scene, ToggleHelp, ToggleStats};
        use SceneCommand::*;
        let table = [
            (DecodedKey::RawKey(KeyCode::ArrowLeft), Scene(MoveLeft)),
            (DecodedKey::RawKey(KeyCode::ArrowRight), Scene(MoveRight)),
            (DecodedKey::RawKey(KeyCode::ArrowUp), Scene(MoveUp)),
            (DecodedKey::RawKey(KeyCode::ArrowDown), Scene(MoveDown)),
            (DecodedKey::Unicode('a'), Scene(Away)),
            (DecodedKey::Unicode('A'), Scene(Away)),
            (DecodedKey::Unicode('t'), Scene(Toward)),
            (DecodedKey::Unicode('T'), Scene(Toward)),
            (
                DecodedKey::RawKey(KeyCode::F1),
                Scene(Rotate(Axis::Z, Sense::Positive)),
            ),
            (
                DecodedKey::RawKey(KeyCode::F2),
                Scene(Rotate(Axis::Z, Sense::Negative)),
            ),
            (
                DecodedKey::Unicode('4'),
                Scene(Rotate(Axis::Y, Sense::Negative)),
            ),
            (
                DecodedKey::Unicode('6'),
                Scene(Rotate(Axis::Y, Sense::Positive)),
            ),
            (
                DecodedKey::Unicode('8'),
                Scene(Rotate(Axis::X, Sense::Negative)),
            ),
            (
                DecodedKey::Unicode('2'),
                Scene(Rotate(Axis::X, Sense::Positive)),
            ),
            (
                DecodedKey::RawKey(KeyCode::Numpad4),
                Scene(Rotate(Axis::Y, Sense::Negative)),
            ),
            (
                DecodedKey::RawKey(KeyCode::Numpad6),
                Scene(Rotate(Axis::Y, Sense::Positive)),
            ),
            (
                DecodedKey::RawKey(KeyCode::Numpad8),
                Scene(Rotate(Axis::X, Sense::Negative)),
            ),
            (
                DecodedKey::RawKey(KeyCode::Numpad2),
                Scene(Rotate(Axis::X, Sense::Positive)),
            ),
            (DecodedKey::RawKey(KeyCode::Escape), Quit),
            (DecodedKey::Unicode('R'), Scene(Reset)),
            (DecodedKey::Unicode(' '), Scene(ToggleSpin)),
            (DecodedKey::Unicode('l'), Scene(ToggleLighting)),
            (DecodedKey::Unicode('L'), Scene(ToggleLighting)),
            (DecodedKey::Unicode('n'), Scene(NextSolid)),
            (DecodedKey::Unicode('m'), Scene(ToggleSeveral)),
            (DecodedKey::Unicode('h'), ToggleHelp),
            (DecodedKey::Unicode('s'), ToggleStats),
            (
                DecodedKey::RawKey(KeyCode::Home),
                Scene(TurnLight(LightTurn::Left)),
            ),
            (
                DecodedKey::RawKey(KeyCode::End),
                Scene(TurnLight(LightTurn::Right)),
            ),
            (
                DecodedKey::RawKey(KeyCode::PageUp),
                Scene(TurnLight(LightTurn::Up)),
            ),
            (
                DecodedKey::RawKey(KeyCode::PageDown),
                Scene(TurnLight(LightTurn::Down)),
            ),
            (DecodedKey::Unicode('r'), Scene(Reset)),
            (DecodedKey::Unicode('\u{1b}'), Quit),
            (DecodedKey::Unicode('x'), Scene(ToggleCrowd)),
            (DecodedKey::Unicode('i'), Command::ToggleReport),
            (DecodedKey::Unicode('I'), Command::ToggleReport),
            (DecodedKey::Unicode('q'), Pause),
            (DecodedKey::Unicode('5'), Pause),
            (DecodedKey::RawKey(KeyCode::F3), Pause),
        ];
        for (key, command) in table {
            assert_eq!(command_for(key), Some(command), "{key:?}");
        }
    }

    #[test]
    fn modifiers_and_lock_keys_are_not_presses() {
        for code in [
            KeyCode::LShift,
            KeyCode::RControl,
            KeyCode::NumpadLock,
            KeyCode::CapsLock,
            KeyCode::LAlt,
        ] {
            assert_eq!(command_for(DecodedKey::RawKey(code)), None, "{code:?}");
        }
    }

    #[test]
    fn v_is_left_to_the_simulators_inspector() {
        assert_eq!(command_for(DecodedKey::Unicode('v')), None);
        assert_eq!(command_for(DecodedKey::Unicode('V')), None);
        // V pressed and released between two commands: neither pauses nor counts.
        assert_eq!(
            commands_for_bytes(&[0x2F, 0xAF, 0x1E, 0x9E, 0x2F, 0xAF]),
            [Command::Scene(SceneCommand::Away)]
        );
    }

    #[test]
    fn modifier_and_lock_scancodes_and_all_releases_give_no_command() {
        // Shifts, Ctrls, Alts, Windows keys, Caps, Num and Scroll Lock, each
        // pressed and released: Abrash's program would not have seen a key.
        let bytes = [
            0x2A, 0xAA, 0x36, 0xB6, 0x1D, 0x9D, 0xE0, 0x1D, 0xE0, 0x9D, 0x38, 0xB8, 0xE0, 0x38,
            0xE0, 0xB8, 0xE0, 0x5B, 0xE0, 0xDB, 0x3A, 0xBA, 0x45, 0xC5, 0x46, 0xC6, 0x45, 0xC5,
            0x3A, 0xBA,
        ];
        assert_eq!(commands_for_bytes(&bytes), []);
    }

    #[test]
    fn raw_scancodes_decode_to_commands() {
        use Command::{Quit, Scene};
        use SceneCommand::*;
        // Left (keypad 4 with NumLock off), extended Left, F1 and its release,
        // A, keypad 6 after NumLock on, top-row 8, Shift (nothing), Esc.
        let bytes = [
            0x4B, 0xCB, 0xE0, 0x4B, 0xE0, 0xCB, 0x3B, 0xBB, 0x1E, 0x9E, 0x45, 0xC5, 0x4D, 0xCD,
            0x09, 0x89, 0x2A, 0xAA, 0x01, 0x81,
        ];
        // pc-keyboard starts with NumLock on: the first 0x4B is keypad '4'.
        assert_eq!(
            commands_for_bytes(&bytes),
            [
                Scene(Rotate(Axis::Y, Sense::Negative)),
                Scene(MoveLeft),
                Scene(Rotate(Axis::Z, Sense::Positive)),
                Scene(Away),
                Scene(MoveRight), // NumLock toggled off: keypad 6 is Right
                Scene(Rotate(Axis::X, Sense::Negative)),
                Quit
            ]
        );
    }

    #[test]
    fn the_extras_keys_decode_from_their_scancodes() {
        use Command::{Scene, ToggleHelp, ToggleStats};
        use SceneCommand::*;
        // L, N, M, H, S, then the editing block's Home, End, Page Up and Page
        // Down (E0-prefixed, so NumLock does not touch them), each released.
        let bytes = [
            0x26, 0xA6, 0x31, 0xB1, 0x32, 0xB2, 0x23, 0xA3, 0x1F, 0x9F, 0xE0, 0x47, 0xE0, 0xC7,
            0xE0, 0x4F, 0xE0, 0xCF, 0xE0, 0x49, 0xE0, 0xC9, 0xE0, 0x51, 0xE0, 0xD1,
        ];
        assert_eq!(
            commands_for_bytes(&bytes),
            [
                Scene(ToggleLighting),
                Scene(NextSolid),
                Scene(ToggleSeveral),
                ToggleHelp,
                ToggleStats,
                Scene(TurnLight(LightTurn::Left)),
                Scene(TurnLight(LightTurn::Right)),
                Scene(TurnLight(LightTurn::Up)),
                Scene(TurnLight(LightTurn::Down)),
            ]
        );
    }
}
