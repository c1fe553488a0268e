//! The kernel's logic that needs no hardware, so that the host can test it:
//! which clock source to trust and the arithmetic that calibrates the
//! time-stamp counter against it, the ACPI values for power-off and reset, the
//! bookkeeping that counts missed vertical retraces, telling from the
//! memory map which firmware booted the machine, finding the boot option
//! in QEMU's fw_cfg file directory, and the USB keyboard driver ([`usb`]:
//! an xHCI controller driven through a trait over its registers and DMA
//! memory, which the host tests implement with a model of the controller).
//! It also owns the keyboard's vocabulary: set 1's scan codes by key name
//! ([`keys`], shared with the runner and the simulator) and the queue that
//! carries them from the keyboard interrupt to the render loop
//! ([`scancode_queue`]).
//!
//! The kernel supplies the readings (port reads, `rdtsc`, MMIO); everything
//! that decides what those readings mean lives here.
//!
//! # Example
//!
//! Counting retraces from flip times in microseconds, as the kernel does
//! from its clock:
//!
//! ```
//! use machine::pacing::{Pacing, FRAME_MICROS};
//!
//! let mut pacing = Pacing::default();
//! pacing.flipped(0, false);
//! pacing.flipped(FRAME_MICROS, false); // on time
//! pacing.flipped(4 * FRAME_MICROS, false); // three refreshes later: two missed
//! assert_eq!((pacing.flips, pacing.missed), (3, 2));
//! ```

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod acpi;
pub mod calibration;
pub mod clock;
pub mod firmware;
pub mod fw_cfg;
pub mod keys;
pub mod log;
pub mod pacing;
pub mod pat;
pub mod protocol;
pub mod reset_keys;
pub mod scale;
pub mod scancode;
pub mod scancode_queue;
pub mod stack;
pub mod trampoline;
pub mod usb;
