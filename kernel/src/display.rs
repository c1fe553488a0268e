//! The display, chosen and started: true Mode X on the VGA's registers, the
//! software VGA presented into the firmware's framebuffer, or no picture.
//! The choice itself is `firmware::display::choose`, tested on the host;
//! this file gathers its inputs and starts what it chose.

use crate::{facts, framebuffer, legacy_vga, pci, run, serial_println};
use bootloader_api::BootInfo;
use firmware::acpi::Presence;
use firmware::boot_firmware::Firmware;
use firmware::display::{choose, Display};
use protocol::{BootOption, BootRequest};

/// Chooses the display by how the machine booted, logs why, and runs the
/// screen on it (`crate::run_screen`).
pub fn start(
    boot_info: &'static mut BootInfo,
    booted_by: Firmware,
    physical_memory_offset: u64,
    acpi_vga: Presence,
    request: &BootRequest,
) -> ! {
    let (force_true_mode_x, option) = (request.true_mode_x, request.option);
    let adapter = pci::display_controller();
    facts::record(|facts| {
        facts.firmware = Some(booted_by);
        facts.adapter = adapter;
    });
    // The FADT's "VGA not present" is only a hint (firmware gets it wrong):
    // the probe reads before it writes, so it is safe where nothing answers,
    // and it decides.
    if acpi_vga == Presence::Absent {
        serial_println!("display: the ACPI tables say there is no VGA; a hint, the probe decides");
    }
    // SAFETY: the bootloader maps all physical memory at this offset (asked for
    // in BOOTLOADER_CONFIG), and from here on only this bus touches the VGA.
    let mut bus = unsafe { crate::vga_bus::PortBus::new(physical_memory_offset) };
    let has_framebuffer = boot_info.framebuffer.as_ref().is_some();
    let choice = choose(booted_by, force_true_mode_x, has_framebuffer, || {
        modex::legacy_vga_present(&mut bus)
    });
    for line in choice.log_lines() {
        serial_println!("{}", line);
    }
    match choice.display {
        Display::TrueModeX => {
            let card = legacy_vga::card();
            let regions = &boot_info.memory_regions;
            let mut vga =
                legacy_vga::set_mode_x(bus, card, booted_by, regions, physical_memory_offset);
            crate::fault::report_on_screen(physical_memory_offset, card);
            crate::run_screen(&mut vga, option)
        }
        // The same Mode X code draws on the software VGA, and each flip is
        // presented into the firmware's framebuffer. The real ports are never
        // mode-set, which would kill that framebuffer.
        Display::Framebuffer => {
            let Some(target) = boot_info.framebuffer.as_mut() else {
                unreachable!("chosen only with a framebuffer");
            };
            let (soft, display) = framebuffer::take_over(target, physical_memory_offset);
            run_on_soft_vga(soft, Some(display), option)
        }
        // No picture anywhere (e.g. UEFI with only a Blt-only virtio-gpu GOP):
        // the demo runs on the software VGA unseen; serial and keys work.
        Display::Nothing => {
            run::NO_DISPLAY.store(true, core::sync::atomic::Ordering::Relaxed);
            facts::record(|facts| {
                facts.display = demo::facts::Display::Nothing("no legacy VGA, no framebuffer")
            });
            run_on_soft_vga(framebuffer::soft_vga_alone(), None, option)
        }
    }
}

/// Mode X on the software VGA, each flip presented into the firmware's
/// framebuffer when there is one. One mirror type for both cases, so the
/// screens that are generic over the VGA bus (the demo, the bench, the report)
/// are built once for the software VGA: a closure type for each case built
/// them twice, 21 KB more of the kernel file.
fn run_on_soft_vga(
    soft: &'static mut modex::soft::SoftVga,
    mut display: Option<&'static mut framebuffer::Display>,
    option: Option<BootOption>,
) -> ! {
    let seen = display.is_some();
    let mirror = modex::MirroredVga::new(soft, move |soft| {
        if let Some(display) = display.as_mut() {
            display.present(soft);
        }
    });
    let mut vga = modex::ModeX::new(mirror);
    vga.set_mode();
    if seen {
        serial_println!("vga: Mode X 320x240 set on the software VGA");
    }
    crate::run_screen(&mut vga, option)
}
