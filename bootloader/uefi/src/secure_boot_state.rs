//! Patched (issue 39): the Secure Boot state, read from the firmware and
//! handed to the kernel as `loader_logic::secure_boot::Record` in a
//! one-page synthetic ramdisk (the kernel finds it at `BootInfo::ramdisk_addr`
//! and checks its magic, version and checksum; see `../CHANGES.md`).
//!
//! Both UEFI loaders use this one file (issue 48): `BOOTX64.EFI` as its
//! module, `BOOTIA32.EFI` (`../../uefi-ia32`) by path. It makes the firmware
//! calls; `loader_logic::secure_boot::read_record` decides what each answer
//! means: a variable that cannot be read, or reads as neither 0 nor 1, is
//! `Reading::Unknown`, which the kernel shows as "unknown".

use core::ptr::{self, NonNull};
use core::slice;
use loader_logic::secure_boot::{self, RECORD_LEN, Reading, Record, Variable, VariableRead};
use uefi::proto::shim::ShimLock;
use uefi::runtime::{self, VariableVendor};
use uefi::{CStr16, Guid, Status, boot, boot::MemoryType};

/// Patched (issue 39): the SHA-256 of the certificate (DER) that signs this
/// loader, written into this section by the runner before it signs the
/// loader (boot/secure_boot.rs). All zeros: not a signed
/// stick's loader, and no database is searched.
#[used]
#[unsafe(link_section = ".kcert")]
static KEY_CERT_SHA256: [u8; 32] = [0; 32];

/// Reads the state. Boot services must still be running.
pub fn read() -> Record {
    // SAFETY: a read of a static of plain bytes; volatile so that the zeros
    // it was built with are not folded in (the runner changes them in the
    // file).
    let cert_sha256 = unsafe { ptr::read_volatile(&raw const KEY_CERT_SHA256) };
    secure_boot::read_record(
        &mut RuntimeVariables,
        &cert_sha256,
        loader_logic::file_hash::sha256,
    )
}

/// The firmware's variables (runtime services) and shim's protocol (boot
/// services).
struct RuntimeVariables;

impl secure_boot::Firmware for RuntimeVariables {
    fn read_variable<R>(
        &mut self,
        variable: Variable,
        then: impl FnOnce(VariableRead<'_>) -> R,
    ) -> R {
        let mut name_buffer = [0u16; 16];
        let Ok(name) = CStr16::from_str_with_buf(variable.name(), &mut name_buffer) else {
            return then(VariableRead::Failed);
        };
        let vendor = VariableVendor(Guid::from_bytes(variable.vendor_guid()));
        let size = match runtime::get_variable(name, &vendor, &mut []) {
            Ok(_) => return then(VariableRead::Value(&[])),
            Err(error) if error.status() == Status::NOT_FOUND => {
                return then(VariableRead::NotFound);
            }
            Err(error) => match (error.status(), *error.data()) {
                (Status::BUFFER_TOO_SMALL, Some(size)) => size,
                _ => return then(VariableRead::Failed),
            },
        };
        let Ok(pool) = boot::allocate_pool(MemoryType::LOADER_DATA, size) else {
            return then(VariableRead::Failed);
        };
        // SAFETY: the pool just allocated holds `size` bytes, and is freed
        // below after its last use.
        let buffer = unsafe { slice::from_raw_parts_mut(pool.as_ptr(), size) };
        let answer = match runtime::get_variable(name, &vendor, buffer) {
            Ok((value, _)) => then(VariableRead::Value(value)),
            Err(_) => then(VariableRead::Failed),
        };
        // SAFETY: allocated above by allocate_pool; `buffer` is not used again.
        let _ = unsafe { boot::free_pool(pool) };
        answer
    }

    fn shim_lock(&mut self) -> Reading {
        match boot::get_handle_for_protocol::<ShimLock>() {
            Ok(_) => Reading::Yes,
            Err(error) if error.status() == Status::NOT_FOUND => Reading::No,
            Err(_) => Reading::Unknown,
        }
    }
}

/// Patched (issue 39): the record, read now, in a page of its own below
/// 4 GiB, for the kernel as its ramdisk (the 64-bit loader's only when no
/// ramdisk file was found). `None` if no page could be had: the kernel then
/// says "unknown".
pub fn record_as_ramdisk() -> Option<(Record, &'static mut [u8])> {
    let record = read();
    // Below 4 GiB: BIOS stage 4, which the 32-bit loader hands it to, takes
    // 32-bit addresses.
    let page: NonNull<u8> = boot::allocate_pages(
        boot::AllocateType::MaxAddress(0xFFFF_F000),
        MemoryType::LOADER_DATA,
        1,
    )
    .ok()?;
    // SAFETY: one page just allocated for this, never freed: the bootloader
    // maps it for the kernel as the ramdisk.
    let bytes = unsafe { slice::from_raw_parts_mut(page.as_ptr(), RECORD_LEN) };
    bytes.copy_from_slice(&record.encode());
    Some((record, bytes))
}
