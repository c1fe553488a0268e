//! The kernel: boots, brings up the hardware layer, then hands the screen and
//! keyboard to the portable cube demo.

#![no_std]
#![no_main]
#![feature(abi_x86_interrupt)]

mod diagnostics;
mod fault;
mod gdt;
mod interrupts;
mod keyboard;
mod pit;
mod qemu;
mod selftest;
mod serial;
mod vga_bus;

use bootloader_api::config::{BootloaderConfig, Mapping};
use bootloader_api::{entry_point, BootInfo};

const BOOTLOADER_CONFIG: BootloaderConfig = {
    let mut config = BootloaderConfig::new_default();
    // VGA memory at 0xA0000 is reached through the map of all physical memory.
    config.mappings.physical_memory = Some(Mapping::Dynamic);
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
    serial_println!("kernel: initialised");

    let mut option_buffer = [0u8; 64];
    let option = qemu::boot_option(&mut option_buffer);
    if let Some(option) = option {
        serial_println!("boot option: {}", option);
        if option.starts_with("fault=") || option.starts_with("exit=") {
            selftest::run(option);
        }
    }

    let Some(physical_memory_offset) = boot_info.physical_memory_offset.into_option() else {
        panic!("the bootloader did not map physical memory, so VGA memory is out of reach");
    };
    // SAFETY: the bootloader maps all physical memory at this offset (asked for
    // in BOOTLOADER_CONFIG), and from here on only this bus touches the VGA.
    let bus = unsafe { vga_bus::PortBus::new(physical_memory_offset) };
    let mut vga = modex::ModeX::new(bus);
    vga.set_mode();
    serial_println!("vga: Mode X 320x240 set");
    match option {
        Some("test-pattern") => diagnostics::test_pattern(&mut vga),
        Some("flip-rate") => diagnostics::flip_rate(&mut vga),
        _ => {}
    }
    fault::halt_forever()
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    serial::force_unlock();
    serial_println!("PANIC: {}", info);
    fault::halt_forever()
}
