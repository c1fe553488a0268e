//! Ctrl+Alt+Del, seen in the raw PS/2 set-1 bytes: the demo's decoder treats
//! Ctrl and Alt as nothing, and after a fault there is no decoder at all, so
//! the kernel watches the bytes itself and resets the machine on the chord.

use crate::scancode::{BREAK_BIT as BREAK, EXTENDED_PREFIX as EXTENDED};

const CTRL: u8 = 0x1D;
const ALT: u8 = 0x38;
/// Delete: E0 53 in the editing block, 53 on the keypad (NumLock off).
const DELETE: u8 = 0x53;

/// Which of Ctrl and Alt are held (either side), fed one byte at a time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ResetChord {
    extended: bool,
    /// Held, by side: [left, right].
    ctrl: [bool; 2],
    alt: [bool; 2],
}

impl ResetChord {
    /// Nothing held.
    pub const fn new() -> Self {
        ResetChord {
            extended: false,
            ctrl: [false; 2],
            alt: [false; 2],
        }
    }

    /// Takes the next byte; true when it completes Ctrl+Alt+Del (Delete
    /// pressed while a Ctrl and an Alt are held).
    pub fn feed(&mut self, byte: u8) -> bool {
        if byte == EXTENDED {
            self.extended = true;
            return false;
        }
        let side = usize::from(self.extended);
        self.extended = false;
        let pressed = byte & BREAK == 0;
        match byte & !BREAK {
            CTRL => self.ctrl[side] = pressed,
            ALT => self.alt[side] = pressed,
            DELETE => {
                return pressed && self.ctrl.contains(&true) && self.alt.contains(&true);
            }
            _ => {}
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn feed_all(chord: &mut ResetChord, bytes: &[u8]) -> bool {
        bytes.iter().fold(false, |seen, &b| chord.feed(b) | seen)
    }

    #[test]
    fn ctrl_alt_del_on_either_side_and_either_delete() {
        for bytes in [
            &[0x1D, 0x38, 0xE0, 0x53][..], // left Ctrl, left Alt, Delete
            &[0xE0, 0x1D, 0xE0, 0x38, 0xE0, 0x53][..], // right Ctrl, right Alt (AltGr)
            &[0x38, 0x1D, 0x53][..],       // keypad Delete, Alt first
        ] {
            assert!(feed_all(&mut ResetChord::new(), bytes), "{bytes:x?}");
        }
    }

    #[test]
    fn delete_alone_or_after_a_release_does_not_reset() {
        assert!(!feed_all(&mut ResetChord::new(), &[0xE0, 0x53]));
        assert!(!feed_all(&mut ResetChord::new(), &[0x1D, 0xE0, 0x53]));
        // Ctrl and Alt pressed, Alt released, then Delete.
        assert!(!feed_all(
            &mut ResetChord::new(),
            &[0x1D, 0x38, 0xB8, 0xE0, 0x53]
        ));
        // Releasing the right Ctrl does not release the left one.
        let mut chord = ResetChord::new();
        assert!(!feed_all(&mut chord, &[0x1D, 0xE0, 0x1D, 0xE0, 0x9D, 0x38]));
        assert!(chord.feed(0x53));
        // Delete's own release is not a press.
        assert!(!feed_all(&mut ResetChord::new(), &[0x1D, 0x38, 0xE0, 0xD3]));
    }
}
