//! What the kernel, the runner and the tests say to each other, defined once:
//! the boot options QEMU hands the kernel through fw_cfg (`opt/modex/boot`),
//! and the serial lines the harness waits for. A renamed option or line is a
//! compile error on every side, not a test that silently waits forever.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

mod boot_option;
pub mod line;
#[cfg(test)]
mod tests;

pub use boot_option::*;
