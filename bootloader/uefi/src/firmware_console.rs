//! Patched (issue 48): whether the firmware already copies its console to
//! COM1, so that a loader line written to both comes out once there
//! (`loader_logic::console`). Both UEFI loaders use this one file:
//! `BOOTX64.EFI` as its module, `BOOTIA32.EFI` (`../../uefi-ia32`) by path.

use core::sync::atomic::{AtomicU8, Ordering};
use uefi::boot::{self, OpenProtocolAttributes, OpenProtocolParams, SearchType};
use uefi::guid;
use uefi::proto::device_path::DevicePath;

/// `EFI_CONSOLE_OUT_DEVICE_GUID`: the firmware marks each device its
/// console writes to with it (EDK2's ConPlatform, for the devices in
/// `ConOut`).
const CONSOLE_OUT_DEVICE: uefi::Guid = guid!("d3b36f2c-d551-11d4-9a46-0090273fc14d");

/// [`copies_to_com1`]'s answer once found: 0 not yet, 1 no, 2 yes.
static COPIES_TO_COM1: AtomicU8 = AtomicU8::new(0);

/// Whether one of the firmware's console output devices is a terminal on
/// COM1, found on the first call (boot services must be running then) and
/// kept. A failed lookup is `false`: the loader then writes COM1 itself.
pub fn copies_to_com1() -> bool {
    match COPIES_TO_COM1.load(Ordering::Relaxed) {
        0 => {
            let copies = look_up();
            COPIES_TO_COM1.store(if copies { 2 } else { 1 }, Ordering::Relaxed);
            copies
        }
        known => known == 2,
    }
}

fn look_up() -> bool {
    let Ok(handles) = boot::locate_handle_buffer(SearchType::ByProtocol(&CONSOLE_OUT_DEVICE))
    else {
        return false;
    };
    handles.iter().any(|&handle| {
        let params = OpenProtocolParams {
            handle,
            agent: boot::image_handle(),
            controller: None,
        };
        // SAFETY: GetProtocol opens without taking the protocol from its
        // driver; the path is only read, while the handle stays open.
        let path = unsafe {
            boot::open_protocol::<DevicePath>(params, OpenProtocolAttributes::GetProtocol)
        };
        path.is_ok_and(|path| loader_logic::console::reaches_com1(path.as_bytes()))
    })
}
