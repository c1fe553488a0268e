//! Mode X on the machine's own VGA, whatever card it is: name the card by its
//! PCI ID, find its video BIOS if the machine booted through one, set Mode X
//! by the best route (see `modex::card::mode_set`) and say on serial which
//! route it took, why, and whether the read-back proved it.

use crate::bios::VideoBios;
use crate::vga_bus::PortBus;
use crate::{pci, serial_println};
use bootloader_api::info::MemoryRegions;
use firmware::boot_firmware::Firmware;
use modex::card::{BiosCallFailure, Card, Fallback, Route, BIOS_MODE_13H};
use modex::ModeX;
use spin::Mutex;

/// The video BIOS, kept for the goodbye screen's INT 10h mode 3.
static VIDEO_BIOS: Mutex<Option<VideoBios>> = Mutex::new(None);

/// The card, named by the display controller's PCI ID.
pub fn card() -> Card {
    match pci::display_controller() {
        Some((vendor, device)) => {
            let card = Card::from_pci_ids(vendor, device);
            serial_println!("display: PCI {:04x}:{:04x}, {:?}", vendor, device, card);
            card
        }
        None => {
            serial_println!("display: no PCI display controller; a standard VGA");
            Card::Standard
        }
    }
}

/// Sets Mode X on the real VGA and reports how.
pub fn set_mode_x(
    bus: PortBus,
    card: Card,
    booted_by: Firmware,
    regions: &MemoryRegions,
    physical_memory_offset: u64,
) -> ModeX<PortBus> {
    let mut bios = match VideoBios::find(booted_by, regions, physical_memory_offset) {
        Ok(bios) => {
            serial_println!(
                "vga: video BIOS found: {} KiB ROM, INT 10h at {:04x}:{:04x} ({:?}); trampoline at {:#x}",
                bios.rom.rom_bytes / 1024,
                bios.rom.vector.0,
                bios.rom.vector.1,
                bios.rom.handler,
                bios.area()
            );
            let [master, slave] = crate::interrupts::firmware_masks();
            serial_println!(
                "vga: its calls run at the BIOS's PIC vectors 08h/70h, with the firmware's masks {:02x}/{:02x}, the PIT at 18.2 Hz and a {} ms watchdog",
                master,
                slave,
                memory::trampoline::bios_world::limit_millis()
            );
            Some(bios)
        }
        Err(why) => {
            serial_println!("vga: the video BIOS will not be called: {}", why);
            None
        }
    };

    let mut vga = ModeX::for_card(bus, card);
    let mut call_bios = bios
        .as_mut()
        .map(|bios| move || bios.set_mode(BIOS_MODE_13H));
    let report = vga.set_mode_x_on_any_card(
        call_bios
            .as_mut()
            .map(|call| call as &mut dyn FnMut() -> Result<(), BiosCallFailure>),
    );
    match report.route {
        Route::VideoBios => serial_println!("vga: mode 13h set by the video BIOS, then tweaked"),
        Route::RegistersOnly => {
            if let Some(Fallback::BiosDidNotReturn {
                function,
                within_millis,
            }) = report.fallback
            {
                // Whatever it was waiting for, it may wait again: never
                // call it again (the goodbye sets text mode by registers).
                serial_println!(
                    "vga: the video BIOS did not return from INT 10h AH={:02X}h within {} ms; Mode X set by registers",
                    function,
                    within_millis
                );
                bios = None;
            }
            serial_println!(
                "vga: mode set by the registers alone, {:?} extensions reset ({:?})",
                card,
                report.fallback
            )
        }
    }
    match report.verified {
        Ok(()) => serial_println!("vga: Mode X 320x240 set, registers read back as written"),
        Err(mismatch) => serial_println!(
            "vga: Mode X NOT verified: {:?} reads {:#04x}, expected {:#04x}; the screen may be wrong",
            mismatch.register,
            mismatch.found,
            mismatch.expected
        ),
    }
    crate::facts::record(|facts| {
        facts.display = demo::facts::Display::ModeX {
            by_video_bios: report.route == Route::VideoBios,
            verified: Some(report.verified.is_ok()),
        }
    });
    *VIDEO_BIOS.lock() = bios;
    vga
}

/// Asks the video BIOS for 80x25 text mode (mode 3), which reloads the
/// card's own font. False if there is no BIOS or it refused.
pub fn bios_text_mode() -> bool {
    const BIOS_MODE_3: u8 = 0x03;
    let mut bios = VIDEO_BIOS.lock();
    bios.as_mut()
        .is_some_and(|bios| bios.set_mode(BIOS_MODE_3).is_ok())
}
