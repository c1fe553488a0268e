//! The kernel: boots, brings up the hardware layer, then hands the screen and
//! keyboard to the portable cube demo.

#![no_std]
#![no_main]
#![feature(abi_x86_interrupt)]

mod bench;
mod clock;
mod diagnostics;
mod fault;
mod firmware;
mod framebuffer;
mod gdt;
mod goodbye;
mod interrupts;
mod keyboard;
mod pat;
mod pit;
mod qemu;
mod run;
mod selftest;
mod serial;
mod vga_bus;

use bootloader_api::config::{BootloaderConfig, Mapping};
use bootloader_api::{entry_point, BootInfo};
use machine::firmware::Firmware;

const BOOTLOADER_CONFIG: BootloaderConfig = {
    let mut config = BootloaderConfig::new_default();
    // VGA memory at 0xA0000 is reached through the map of all physical memory.
    config.mappings.physical_memory = Some(Mapping::Dynamic);
    // The demo keeps three 75 KiB images of the screen (the next frame and a
    // shadow of each page) in its state on the stack.
    config.kernel_stack_size = 1024 * 1024;
    config
};
entry_point!(kernel_main, config = &BOOTLOADER_CONFIG);

fn kernel_main(boot_info: &'static mut BootInfo) -> ! {
    serial::init();
    serial_println!("modex-cube kernel v{}", env!("CARGO_PKG_VERSION"));
    gdt::init();
    interrupts::init();
    pit::init();
    if let Err(problem) = keyboard::init() {
        serial_println!("keyboard: {}", problem);
    }
    x86_64::instructions::interrupts::enable();
    match clock::init() {
        Ok(calibration) => serial_println!(
            "clock: TSC {} kHz, measured over {} PIT ticks, error under {} ppm",
            calibration.tsc_hz / 1000,
            calibration.pit_ticks,
            calibration.error_ppm
        ),
        Err(problem) => {
            serial_println!(
                "clock: TSC not calibrated ({:?}); counting PIT ticks",
                problem
            )
        }
    }
    serial_println!("kernel: initialised");

    let mut option_buffer = [0u8; 64];
    let option = qemu::boot_option(&mut option_buffer);
    if let Some(option) = option {
        serial_println!("boot option: {}", option);
    }

    let booted_by = firmware::firmware(&boot_info.memory_regions);
    serial_println!("firmware: {:?} (told by the memory map)", booted_by);

    let Some(physical_memory_offset) = boot_info.physical_memory_offset.into_option() else {
        panic!("the bootloader did not map physical memory, so VGA memory is out of reach");
    };
    let (force_true_mode_x, option) = take_display_option(option);
    // SAFETY: the bootloader maps all physical memory at this offset (asked for
    // in BOOTLOADER_CONFIG), and from here on only this bus touches the VGA.
    let mut bus = unsafe { vga_bus::PortBus::new(physical_memory_offset) };
    // By how the machine booted, not by whether the registers answer: on UEFI
    // the card may scan out the firmware's framebuffer whatever the VGA
    // registers say (Intel iGPUs answer them with the VGA plane disabled), so
    // true Mode X would be a black screen.
    let true_mode_x = if booted_by == Firmware::Uefi && !force_true_mode_x {
        serial_println!(
            "display: UEFI boot: drawing through the firmware framebuffer \
             (true Mode X needs a BIOS or CSM boot)"
        );
        false
    } else {
        if force_true_mode_x {
            serial_println!("display: true Mode X asked for by the boot option");
        }
        modex::legacy_vga_present(&mut bus)
    };
    if true_mode_x {
        serial_println!("display: legacy VGA found");
        let mut vga = modex::ModeX::new(bus);
        vga.set_mode();
        fault::report_on_screen(physical_memory_offset);
        serial_println!("vga: Mode X 320x240 set");
        run_screen(&mut vga, option)
    }

    // The same Mode X code draws on the software VGA, and each flip is
    // presented into the firmware's framebuffer. The real ports are never
    // mode-set, which would kill that framebuffer.
    if booted_by != Firmware::Uefi || force_true_mode_x {
        serial_println!("display: no legacy VGA; Mode X runs on the software VGA");
    }
    let Some(framebuffer) = boot_info.framebuffer.as_mut() else {
        panic!("no display: neither a legacy VGA nor a framebuffer from the bootloader");
    };
    let (soft, display) = framebuffer::take_over(framebuffer, physical_memory_offset);
    let mirror = modex::MirroredVga::new(soft, move |soft| display.present(soft));
    let mut vga = modex::ModeX::new(mirror);
    vga.set_mode();
    serial_println!("vga: Mode X 320x240 set on the software VGA");
    run_screen(&mut vga, option)
}

/// QEMU only: `modex=true-mode-x`, alone or before another option (separated
/// by a space), forces true Mode X on a UEFI boot, so that OVMF with QEMU's
/// standard VGA still tests the real registers.
fn take_display_option(option: Option<&str>) -> (bool, Option<&str>) {
    const TRUE_MODE_X: &str = "modex=true-mode-x";
    let Some(option) = option else {
        return (false, None);
    };
    match option.split_once(' ').unwrap_or((option, "")) {
        (TRUE_MODE_X, rest) => (true, Some(rest.trim()).filter(|rest| !rest.is_empty())),
        _ => (false, Some(option)),
    }
}

/// What the screen shows: the cube, or a diagnostic asked for by a boot option.
fn run_screen<B: modex::VgaBus>(vga: &mut modex::ModeX<B>, option: Option<&str>) -> ! {
    match option {
        Some("test-pattern") => diagnostics::test_pattern(vga),
        Some("bench") => {
            bench::run(vga);
            run::run_demo(vga)
        }
        Some("clock-check") => {
            diagnostics::clock_check();
            run::run_demo(vga)
        }
        Some("flip-rate") => {
            diagnostics::flip_rate(vga);
            run::run_demo(vga)
        }
        Some(request) if request.starts_with("fault=") || request.starts_with("exit=") => {
            selftest::run(request);
            run::run_demo(vga)
        }
        _ => run::run_demo(vga),
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    fault::halt_with_panic(info)
}
