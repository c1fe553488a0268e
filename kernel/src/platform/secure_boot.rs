//! Whether Secure Boot was on (issue 39), from the record the UEFI loader
//! leaves as the ramdisk when there is no ramdisk file
//! (`bootloader/uefi/src/secure_boot_state.rs`). The checks and the words
//! are `firmware::secure_boot`'s, tested on the host.

use bootloader_api::BootInfo;
use firmware::boot_firmware::Firmware;
use firmware::secure_boot::{decide, SecureBoot};

/// The state, for the facts. A ramdisk that is not the record (a real one,
/// or a damaged record) gives "unknown".
pub fn state(boot_info: &BootInfo, booted_by: Firmware) -> SecureBoot {
    let record = boot_info.ramdisk_addr.into_option().map(|address| {
        // Only the record's bytes are looked at; a larger ramdisk's rest is
        // not read.
        let len = (boot_info.ramdisk_len as usize).min(firmware::secure_boot::RECORD_LEN);
        // SAFETY: the bootloader mapped the ramdisk at `ramdisk_addr`,
        // `ramdisk_len` bytes long, readable, in the kernel's address space,
        // and nothing writes it.
        unsafe { core::slice::from_raw_parts(address as *const u8, len) }
    });
    decide(booted_by, record)
}

/// Reads the state, logs it when unknown, and records it in the facts.
pub fn record(boot_info: &BootInfo, booted_by: Firmware) {
    let secure_boot = state(boot_info, booted_by);
    if let SecureBoot::Unknown(why) = secure_boot {
        crate::serial_println!("secure boot: unknown ({why:?})");
    }
    crate::facts::record(|facts| facts.secure_boot = Some(secure_boot));
}
