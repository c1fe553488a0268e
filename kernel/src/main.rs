//! The kernel: boots, brings up the hardware layer, then hands the screen and
//! keyboard to the portable cube demo.

#![no_std]
#![no_main]
#![feature(abi_x86_interrupt)]
// Every `unsafe` block says why it is sound (docs/contributing.md); clippy checks it.
#![deny(clippy::undocumented_unsafe_blocks)]

mod bench;
mod bios;
mod diagnostics;
mod dma;
mod facts;
mod fault;
mod fpu;
mod framebuffer;
mod gdt;
mod goodbye;
mod idle;
mod input;
mod interrupts;
mod legacy_vga;
mod log;
mod pat;
mod pci;
mod platform;
mod report;
mod run;
mod selftest;
mod serial;
mod stack;
mod time;
mod vga_bus;

use bootloader_api::config::{BootloaderConfig, Mapping};
use bootloader_api::{entry_point, BootInfo};
use firmware::acpi::Presence;
use firmware::boot_firmware::Firmware;
use input::{ps2, xhci};
use keyboard::i8042::FirmwareSays;
use platform::{acpi, boot_firmware, qemu};
use protocol::{BootOption, BootRequest};
use time::pit;

const BOOTLOADER_CONFIG: BootloaderConfig = {
    let mut config = BootloaderConfig::new_default();
    // VGA memory at 0xA0000 is reached through the map of all physical memory.
    config.mappings.physical_memory = Some(Mapping::Dynamic);
    // The demo's frame images live in static memory (`run::RENDERER`); the
    // stack holds the scene and the frames of the drawing code. `stack.rs`
    // measures it, and tests/stack.rs fails if a run uses over half.
    config.kernel_stack_size = 1024 * 1024;
    config
};
entry_point!(kernel_main, config = &BOOTLOADER_CONFIG);

fn kernel_main(boot_info: &'static mut BootInfo) -> ! {
    stack::paint(boot_info.kernel_stack_bottom, boot_info.kernel_stack_len);
    serial::init();
    serial_println!(
        "{}{}",
        protocol::line::KERNEL_BANNER,
        env!("CARGO_PKG_VERSION")
    );
    facts::record_cpu();
    gdt::init();
    interrupts::init();
    pit::init();
    let Some(physical_memory_offset) = boot_info.physical_memory_offset.into_option() else {
        panic!("the bootloader did not map physical memory, so VGA memory is out of reach");
    };
    let acpi = acpi::init(
        boot_info.rsdp_addr.into_option(),
        physical_memory_offset,
        mapped_physical_memory_end(&boot_info.memory_regions),
    );
    // The FADT's word is a hint (firmware gets it wrong): the probe decides.
    let ps2_state = ps2::init(match acpi.legacy.i8042 {
        Presence::Present => FirmwareSays::Present,
        Presence::Absent => FirmwareSays::Absent,
        Presence::Unknown => FirmwareSays::Nothing,
    });
    facts::record(|facts| facts.ps2 = ps2_state);
    x86_64::instructions::interrupts::enable();

    let mut option_buffer = [0u8; 64];
    let request = match qemu::boot_option(&mut option_buffer).map(BootRequest::parse) {
        None => BootRequest::default(),
        Some(Ok(request)) => {
            serial_println!("boot option: {}", request);
            request
        }
        Some(Err(unknown)) => {
            serial_println!("boot option ignored: {}", unknown);
            BootRequest::default()
        }
    };
    let (force_true_mode_x, option) = (request.true_mode_x, request.option);
    if request.irq1_masked {
        interrupts::mask_keyboard_irq();
        serial_println!(
            "keyboard: IRQ 1 masked at the PIC for the whole run; PS/2 keys are polled"
        );
    }
    run::ECHO_SCANCODES.store(
        request.echo_scancodes,
        core::sync::atomic::Ordering::Relaxed,
    );
    let rate = time::init(acpi, physical_memory_offset, request.clock);
    facts::record(|facts| facts.clock = Some(rate));
    xhci::init(&boot_info.memory_regions, physical_memory_offset);
    serial_println!("kernel: initialised");

    let booted_by = boot_firmware::firmware(&boot_info.memory_regions);
    serial_println!("firmware: {:?} (told by the memory map)", booted_by);
    let secure_boot = platform::secure_boot::state(boot_info, booted_by);
    if let firmware::secure_boot::SecureBoot::Unknown(why) = secure_boot {
        serial_println!("secure boot: unknown ({why:?})");
    }
    let adapter = pci::display_controller();
    facts::record(|facts| {
        facts.firmware = Some(booted_by);
        facts.adapter = adapter;
        facts.secure_boot = Some(secure_boot);
    });

    // SAFETY: the bootloader maps all physical memory at this offset (asked for
    // in BOOTLOADER_CONFIG), and from here on only this bus touches the VGA.
    let mut bus = unsafe { vga_bus::PortBus::new(physical_memory_offset) };
    // By how the machine booted, not by whether the registers answer: on UEFI
    // the card may scan out the firmware's framebuffer whatever the VGA
    // registers say (Intel iGPUs answer them with the VGA plane disabled), so
    // true Mode X would be a black screen.
    // The FADT's "VGA not present" is only a hint (firmware gets it wrong):
    // the probe below reads before it writes, so it is safe where nothing
    // answers, and it decides.
    if acpi.legacy.vga == Presence::Absent {
        serial_println!("display: the ACPI tables say there is no VGA; a hint, the probe decides");
    }
    let true_mode_x = if booted_by == Firmware::Uefi && !force_true_mode_x {
        // Said only where there is a framebuffer; without one, the line
        // below says there is no picture.
        if boot_info.framebuffer.as_ref().is_some() {
            serial_println!(
                "display: UEFI boot: drawing through the firmware framebuffer \
                 (true Mode X needs a BIOS or CSM boot)"
            );
        }
        false
    } else {
        if force_true_mode_x {
            serial_println!("display: true Mode X asked for by the boot option");
        }
        modex::legacy_vga_present(&mut bus)
    };
    if true_mode_x {
        serial_println!("display: legacy VGA found");
        let card = legacy_vga::card();
        let mut vga = legacy_vga::set_mode_x(
            bus,
            card,
            booted_by,
            &boot_info.memory_regions,
            physical_memory_offset,
        );
        fault::report_on_screen(physical_memory_offset, card);
        run_screen(&mut vga, option)
    }

    // The same Mode X code draws on the software VGA, and each flip is
    // presented into the firmware's framebuffer. The real ports are never
    // mode-set, which would kill that framebuffer.
    if booted_by != Firmware::Uefi || force_true_mode_x {
        serial_println!("display: no legacy VGA; Mode X runs on the software VGA");
    }
    let Some(framebuffer) = boot_info.framebuffer.as_mut() else {
        // No picture anywhere (e.g. UEFI with only a Blt-only virtio-gpu GOP):
        // the demo runs on the software VGA unseen; serial and keys work.
        serial_println!(
            "display: none: no legacy VGA and no framebuffer from the bootloader \
             (its log says why: no usable GOP, or no VESA linear mode); \
             running without a picture"
        );
        run::NO_DISPLAY.store(true, core::sync::atomic::Ordering::Relaxed);
        facts::record(|facts| {
            facts.display = demo::facts::Display::Nothing("no legacy VGA, no framebuffer")
        });
        let mut vga = modex::ModeX::new(modex::MirroredVga::new(
            framebuffer::soft_vga_alone(),
            |_| {},
        ));
        vga.set_mode();
        run_screen(&mut vga, option)
    };
    let (soft, display) = framebuffer::take_over(framebuffer, physical_memory_offset);
    let mirror = modex::MirroredVga::new(soft, move |soft| display.present(soft));
    let mut vga = modex::ModeX::new(mirror);
    vga.set_mode();
    serial_println!("vga: Mode X 320x240 set on the software VGA");
    run_screen(&mut vga, option)
}

/// The end of the bootloader's map of physical memory: every region it was
/// told of, and at least the first 4 GiB (bootloader 0.11's
/// `max_phys_addr`).
fn mapped_physical_memory_end(regions: &bootloader_api::info::MemoryRegions) -> u64 {
    const FOUR_GIB: u64 = 1 << 32;
    regions
        .iter()
        .map(|region| region.end)
        .fold(FOUR_GIB, u64::max)
}

/// What the screen shows: the cube, or a diagnostic asked for by a boot option.
fn run_screen<B: modex::VgaBus>(vga: &mut modex::ModeX<B>, option: Option<BootOption>) -> ! {
    facts::log();
    match option {
        Some(BootOption::TestPattern) => diagnostics::test_pattern(vga),
        Some(BootOption::Bench) => bench::run(vga),
        Some(BootOption::ClockCheck) => diagnostics::clock_check(),
        Some(BootOption::FlipRate) => diagnostics::flip_rate(vga),
        Some(BootOption::Fault(fault)) => selftest::raise(fault),
        Some(BootOption::Exit(exit)) => selftest::exit(exit),
        None => {}
    }
    run::run_demo(vga)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    fault::halt_with_panic(info)
}
