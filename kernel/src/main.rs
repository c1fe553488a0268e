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
mod display;
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
mod nmi;
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
use input::ps2;
use keyboard::i8042::FirmwareSays;
use platform::{acpi, qemu};
use protocol::{line, BootOption, BootRequest};
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
    serial_println!("{}{}", line::KERNEL_BANNER, env!("CARGO_PKG_VERSION"));
    facts::record_cpu();
    gdt::init();
    interrupts::init();
    pit::init();
    let Some(physical_memory_offset) = boot_info.physical_memory_offset.into_option() else {
        panic!("the bootloader did not map physical memory, so VGA memory is out of reach");
    };
    let (rsdp, regions) = (boot_info.rsdp_addr.into_option(), &boot_info.memory_regions);
    let acpi = acpi::init(
        rsdp,
        physical_memory_offset,
        mapped_physical_memory_end(regions),
    );
    let ps2_state = ps2::init(firmware_says(acpi.legacy.i8042));
    facts::record(|facts| facts.ps2 = ps2_state);
    x86_64::instructions::interrupts::enable();
    let request = boot_request();
    let rate = time::init(acpi, physical_memory_offset, request.clock);
    facts::record(|facts| facts.clock = Some(rate));
    input::usb::init(&boot_info.memory_regions, physical_memory_offset);
    serial_println!("kernel: initialised");
    let booted_by = platform::boot_firmware::firmware(&boot_info.memory_regions);
    serial_println!("firmware: {:?} (told by the memory map)", booted_by);
    platform::secure_boot::record(boot_info, booted_by);
    display::start(
        boot_info,
        booted_by,
        physical_memory_offset,
        acpi.legacy.vga,
        &request,
    )
}

/// The FADT's word on the 8042 is a hint (firmware gets it wrong): the probe
/// in `ps2::init` decides.
fn firmware_says(presence: Presence) -> FirmwareSays {
    match presence {
        Presence::Present => FirmwareSays::Present,
        Presence::Absent => FirmwareSays::Absent,
        Presence::Unknown => FirmwareSays::Nothing,
    }
}

/// The boot option QEMU's harness left in fw_cfg (none on a real PC), with
/// the settings that act at once: IRQ 1 masked, scancodes echoed.
fn boot_request() -> BootRequest {
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
    request
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
