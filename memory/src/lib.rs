//! The memory the kernel sets up, as data the host can check: the Page
//! Attribute Table arithmetic behind the write-combining framebuffer
//! ([`pat`]), the low-memory layout and descriptors of the trampoline to real
//! mode that calls the video BIOS ([`trampoline`]), and the stack's
//! high-water mark ([`stack`]).
//!
//! The kernel's shells are `kernel/src/pat.rs` (the MSR and page tables),
//! `kernel/src/stack.rs` and `kernel/src/bios/` (the trampoline's assembly).

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod pat;
pub mod stack;
pub mod trampoline;
