//! Decisions of the patched bootloader (see `../CHANGES.md`) as pure
//! functions, so that they are tested on the host: the firmware calls stay in
//! the loaders, which hand their answers in here.
//!
//! - [`gop`]: which UEFI Graphics Output Protocol instance to draw on.
//! - [`console`]: whether a UEFI loader writes a line to COM1 itself or
//!   the firmware's console already copies it there.
//! - [`cpu`]: whether the processor has what the kernel needs (long mode,
//!   PAE, SSE2), from CPUID, and the words of a refusal.
//! - [`e820`]: the BIOS INT 15h, AX=E820h memory-map walk and how it ends.
//! - [`file_hash`]: the SHA-256 of each file a loader starts, where the
//!   build writes it, and the words of a mismatch.
//! - [`file_read`]: reading a file through UEFI, one more try, the words of
//!   a failure.
//! - [`identity_map`]: what the UEFI loader's own page tables map.
//! - [`memory_map`]: one sanitised memory map from the firmware's list:
//!   sorted, overlaps split (the stricter kind wins), repeats merged.
//! - [`secure_boot`]: the Secure Boot state record the UEFI loaders hand to
//!   the kernel, what each variable read means, and the search of a
//!   signature database for the loader's certificate.
//! - [`uefi_map`]: the 32-bit UEFI loader's memory map for stage 4, UEFI
//!   memory types as E820 entries.
//! - [`vesa`]: BIOS stage 2's VBE mode: its pixels' size and stride, and
//!   which of two modes it takes.
#![no_std]

pub mod console;
pub mod cpu;
pub mod e820;
pub mod file_hash;
pub mod file_read;
pub mod gop;
pub mod identity_map;
pub mod memory_map;
pub mod secure_boot;
pub mod uefi_map;
pub mod vesa;

#[cfg(test)]
extern crate std;
