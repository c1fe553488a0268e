//! Decisions of the patched bootloader (see `../CHANGES.md`) as pure
//! functions, so that they are tested on the host: the firmware calls stay in
//! the loaders, which hand their answers in here.
//!
//! - [`gop`]: which UEFI Graphics Output Protocol instance to draw on.
//! - [`e820`]: the BIOS INT 15h, AX=E820h memory-map walk and how it ends.
//! - [`uefi_map`]: the 32-bit UEFI loader's memory map for stage 4, UEFI
//!   memory types as E820 entries.
#![no_std]

pub mod e820;
pub mod gop;
pub mod uefi_map;
