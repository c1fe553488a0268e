//! PS/2 scan code set 1's two marks, defined once for everyone who reads or
//! makes set-1 bytes: the key table ([`crate::keys`]), the USB keyboard's
//! report conversion, and the kernel's Ctrl+Alt+Del watch.

/// The prefix of the keys the 84-key keyboard did not have (the arrows, the
/// editing block, right Ctrl and Alt).
pub const EXTENDED_PREFIX: u8 = 0xE0;
/// Set in a make code, it makes the key's break (release) code.
pub const BREAK_BIT: u8 = 0x80;
