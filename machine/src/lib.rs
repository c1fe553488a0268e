//! The kernel's logic that needs no hardware, so that the host can test it:
//! the arithmetic that calibrates the time-stamp counter against the PIT, the
//! bookkeeping that counts missed vertical retraces, and telling from the
//! memory map which firmware booted the machine.
//!
//! The kernel supplies the readings (port reads, `rdtsc`); everything that
//! decides what those readings mean lives here.

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod calibration;
pub mod firmware;
pub mod pacing;
