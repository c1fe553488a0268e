//! What every keyboard path shares, whatever the hardware: PS/2 scan code
//! set 1 is the kernel's one keyboard language. The PS/2 keyboard sends it,
//! and the USB driver (the `usb` crate) translates its reports
//! into it.
//!
//! - [`scancode`]: the set-1 byte values every part agrees on;
//! - [`keys`]: set-1 codes by key name, shared with the runner and the
//!   simulator;
//! - [`scancode_queue`]: the lock-free queue that carries bytes from the
//!   keyboard interrupt (or a poll) to the frame loop;
//! - [`reset_keys`]: Ctrl+Alt+Del, recognised from the byte stream;
//! - [`i8042`]: the PS/2 controller's set-up and byte taking, behind a port
//!   trait, tested against a model of the controller.
//!
//! The kernel's shells are `kernel/src/input/ps2.rs` and `kernel/src/input/usb/`.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod i8042;
pub mod keys;
pub mod reset_keys;
pub mod scancode;
pub mod scancode_queue;
