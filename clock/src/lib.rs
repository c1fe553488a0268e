//! The kernel's sense of time, without the hardware: which source gives the
//! TSC's rate ([`tsc_rate`]), the arithmetic that measures it against a
//! reference counter ([`calibration`]), and the bookkeeping that counts
//! missed vertical retraces ([`pacing`]).
//!
//! The kernel's shell, `kernel/src/time/`, reads the counters (`rdtsc`,
//! the PM timer, the HPET, PIT channel 2) and hands the readings here.
//!
//! # Example
//!
//! Counting retraces from flip times in microseconds, as the kernel does
//! from its clock:
//!
//! ```
//! use clock::pacing::{Pacing, FRAME_MICROS};
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

pub mod calibration;
pub mod pacing;
pub mod tsc_rate;
