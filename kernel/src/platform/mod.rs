//! What the firmware and the emulator give the kernel: the ACPI tables
//! ([`acpi`]), power-off and reset ([`power`]), which firmware booted the
//! machine ([`boot_firmware`]), whether Secure Boot was on ([`secure_boot`]),
//! and QEMU's debug-exit and fw_cfg devices
//! ([`qemu`]). The decisions on what the tables say are the `firmware`
//! crate's, tested on the host.

pub mod acpi;
pub mod boot_firmware;
pub mod power;
pub mod qemu;
pub mod secure_boot;
