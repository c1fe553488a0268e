//! The kernel's logic that needs no hardware, so that the host can test it:
//! the arithmetic that calibrates the time-stamp counter against the PIT, and
//! the bookkeeping that counts missed vertical retraces.
//!
//! The kernel supplies the readings (port reads, `rdtsc`); everything that
//! decides what those readings mean lives here.

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(test)]
extern crate std;

pub mod calibration;
pub mod pacing;
