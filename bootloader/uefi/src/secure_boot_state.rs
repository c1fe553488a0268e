//! Patched (issue 39): the Secure Boot state, read from the firmware and
//! handed to the kernel as `loader_logic::secure_boot::Record` in a
//! one-page synthetic ramdisk (the kernel finds it at `BootInfo::ramdisk_addr`
//! and checks its magic, version and checksum; see `../CHANGES.md`).
//!
//! Each fact is read, never assumed: a variable that cannot be read, or
//! reads as neither 0 nor 1, is `Reading::Unknown`, which the kernel shows
//! as "unknown".

use core::ptr::{self, NonNull};
use core::slice;
use loader_logic::secure_boot::{Key, MalformedDatabase, RECORD_LEN, Reading, Record};
use uefi::proto::shim::ShimLock;
use uefi::runtime::{self, VariableVendor};
use uefi::{CStr16, Status, boot, boot::MemoryType, cstr16, guid};

/// Patched (issue 39): the SHA-256 of the certificate (DER) that signs this
/// loader, written into this section by the runner before it signs the
/// loader (boot/secure_boot.rs). All zeros: not a signed
/// stick's loader, and no database is searched.
#[used]
#[unsafe(link_section = ".kcert")]
static KEY_CERT_SHA256: [u8; 32] = [0; 32];

/// Shim's variables' vendor GUID (its lock protocol's GUID).
const SHIM_VENDOR: VariableVendor = VariableVendor(guid!("605dab50-e046-4300-abb6-3dd810dd8b23"));

/// Reads the state. Boot services must still be running.
pub fn read() -> Record {
    // SAFETY: a read of a static of plain bytes; volatile so that the zeros
    // it was built with are not folded in (the runner changes them in the
    // file).
    let cert_sha256 = unsafe { ptr::read_volatile(&raw const KEY_CERT_SHA256) };
    let signed = cert_sha256 != [0; 32];
    let key_in = |name: &CStr16, vendor: &VariableVendor| {
        if signed {
            key_in_database(name, vendor, &cert_sha256)
        } else {
            Key::NotSigned
        }
    };
    Record {
        secure_boot: boolean(
            cstr16!("SecureBoot"),
            &VariableVendor::GLOBAL_VARIABLE,
            None,
        ),
        setup_mode: boolean(cstr16!("SetupMode"), &VariableVendor::GLOBAL_VARIABLE, None),
        shim: match boot::get_handle_for_protocol::<ShimLock>() {
            Ok(_) => Reading::Yes,
            Err(error) if error.status() == Status::NOT_FOUND => Reading::No,
            Err(_) => Reading::Unknown,
        },
        // Shim sets MokSBStateRT only when the user switched its checks off.
        shim_validation_off: boolean(cstr16!("MokSBStateRT"), &SHIM_VENDOR, Some(Reading::No)),
        key_in_db: key_in(cstr16!("db"), &VariableVendor::IMAGE_SECURITY_DATABASE),
        key_in_mok: key_in(cstr16!("MokListRT"), &SHIM_VENDOR),
    }
}

/// A one-byte boolean variable; `absent` is the answer when it does not
/// exist (`None`: its absence is unknown too).
fn boolean(name: &CStr16, vendor: &VariableVendor, absent: Option<Reading>) -> Reading {
    let mut buffer = [0u8; 8];
    match runtime::get_variable(name, vendor, &mut buffer) {
        Ok((value, _)) => Reading::of_variable(Some(value)),
        Err(error) if error.status() == Status::NOT_FOUND => absent.unwrap_or(Reading::Unknown),
        Err(_) => Reading::Unknown,
    }
}

/// Whether the signature database variable holds the certificate whose
/// SHA-256 is `cert_sha256`.
fn key_in_database(name: &CStr16, vendor: &VariableVendor, cert_sha256: &[u8; 32]) -> Key {
    let size = match runtime::get_variable(name, vendor, &mut []) {
        Ok(_) => return Key::Absent, // empty
        Err(error) if error.status() == Status::NOT_FOUND => return Key::Absent,
        Err(error) => match (error.status(), *error.data()) {
            (Status::BUFFER_TOO_SMALL, Some(size)) => size,
            _ => return Key::Unknown,
        },
    };
    let Ok(pool) = boot::allocate_pool(MemoryType::LOADER_DATA, size) else {
        return Key::Unknown;
    };
    // SAFETY: the pool just allocated holds `size` bytes, and is freed below
    // after its last use.
    let buffer = unsafe { slice::from_raw_parts_mut(pool.as_ptr(), size) };
    let answer = match runtime::get_variable(name, vendor, buffer) {
        Ok((value, _)) => {
            match loader_logic::secure_boot::database_holds_cert(value, cert_sha256, sha256) {
                Ok(true) => Key::Present,
                Ok(false) => Key::Absent,
                Err(MalformedDatabase) => Key::Unknown,
            }
        }
        Err(_) => Key::Unknown,
    };
    // SAFETY: allocated above by allocate_pool; `buffer` is not used again.
    let _ = unsafe { boot::free_pool(pool) };
    answer
}

fn sha256(bytes: &[u8]) -> [u8; 32] {
    loader_logic::file_hash::sha256(bytes)
}

/// Patched (issue 39): the record, read now, in a page of its own, for the
/// kernel as its ramdisk (only when no ramdisk file was found). `None` if no
/// page could be had: the kernel then says "unknown".
pub fn record_as_ramdisk() -> Option<&'static mut [u8]> {
    let record = read();
    crate::write_com1(format_args!("loader: secure boot state {record:?}\n"));
    let page: NonNull<u8> =
        boot::allocate_pages(boot::AllocateType::AnyPages, MemoryType::LOADER_DATA, 1).ok()?;
    // SAFETY: one page just allocated for this, never freed: the bootloader
    // maps it for the kernel as the ramdisk.
    let bytes = unsafe { slice::from_raw_parts_mut(page.as_ptr(), RECORD_LEN) };
    bytes.copy_from_slice(&record.encode());
    Some(bytes)
}
