//! What the firmware tells the kernel, read from its tables without touching
//! hardware: the ACPI values for power-off and reset and the FADT's
//! legacy-device flags ([`acpi`]), which firmware booted the machine, told
//! by the memory map ([`boot_firmware`]), and QEMU's fw_cfg file directory,
//! where the test harness leaves the boot option ([`fw_cfg`]), from which
//! firmware booted, which display the kernel drives ([`display`]), and
//! whether Secure Boot was on, from the UEFI loader's record ([`secure_boot`]),
//! and what an NMI's System Control Port B says and how many NMIs the log
//! tells of ([`nmi`]).
//!
//! The kernel's shell, `kernel/src/platform/`, maps the tables and does the
//! port writes.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod acpi;
pub mod boot_firmware;
pub mod display;
pub mod fw_cfg;
pub mod nmi;
pub mod secure_boot;
