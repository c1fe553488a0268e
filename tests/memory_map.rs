//! The memory map the loader hands the kernel (issue 66): SeaBIOS with an
//! option ROM (`boot/roms/e820_map.asm`, built by `boot::option_rom`) that
//! answers INT 15h E820 from the BIOS's own list, changed:
//!
//! - a reserved range [top - 4 MiB, top - 2 MiB) laid inside the usable
//!   entry at the top of RAM below 4 GiB (where SMRAM, stolen graphics
//!   memory and ACPI NVS sit on real PCs), the entries answered last first:
//!   after the ready line the range still holds the ROM's pattern, though
//!   the kernel took its xHCI's DMA and register mapping from the top of
//!   usable RAM, and the cube is drawn; keyboards on an xHCI and an EHCI
//!   still act;
//! - the usable entry at the top listed twice: the cube;
//! - no usable RAM above 1 MiB: stage 4 panics, and says where and why on
//!   COM1.
//!
//! Each boot says on COM1 what the loader fixed (`loader: memory: ...`).

mod common;

use boot::option_rom::{self, E820Changes};
use boot::qemu::DISPLAY_ID;
use boot::{line, Qemu};
use common::BOOT_TIMEOUT;

/// RAM as in the issue's report: the top of RAM below 4 GiB is 2 GiB less
/// what SeaBIOS keeps.
const MEMORY_MIB: u32 = 2048;

/// Starts SeaBIOS with the E820 ROM built for `changes` and `devices`; the
/// scratch directory holds the ROM and must outlive QEMU.
fn start(changes: E820Changes, devices: Vec<String>) -> (Qemu, tempfile::TempDir) {
    common::start_with_option_rom(
        |dir| option_rom::build_e820_rom(dir, changes),
        None,
        |options| {
            options.memory_mib = MEMORY_MIB;
            options.devices = devices;
        },
    )
}

/// The reserved range the ROM added, and the E820 calls it answered.
fn rom_state(qemu: &mut Qemu) -> (u64, u64, u32) {
    let bytes = qemu
        .read_physical(option_rom::E820_RESERVED_RANGE, 12)
        .unwrap();
    let word = |i: usize| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
    (u64::from(word(0)), u64::from(word(1)), word(2))
}

/// The loader's summary line: `N entries; ...; M ranges`.
fn memory_summary(console: &str) -> &str {
    console
        .lines()
        .filter_map(|l| l.trim_end().strip_prefix(line::LOADER_MEMORY))
        .find(|rest| rest.contains(" entries; "))
        .unwrap_or_else(|| panic!("no memory map summary from the loader:\n{console}"))
}

/// The ROM hooked E820 before the loader ran, and the loader asked it.
fn assert_the_rom_answered(qemu: &mut Qemu, console: &str) {
    let hooked = console
        .find(option_rom::E820_HOOKED_LINE)
        .unwrap_or_else(|| panic!("the ROM did not hook E820:\n{console}"));
    let loader = console
        .find(line::LOADER_START)
        .unwrap_or_else(|| panic!("no loader line:\n{console}"));
    assert!(hooked < loader, "{console}");
    let (_, _, calls) = rom_state(qemu);
    assert!(calls > 0, "the loader never called the ROM's E820");
}

/// Every word of the ROM's reserved range is still its pattern; the range
/// must be where the issue had it, and named reserved in the loader's map.
fn assert_the_reserved_range_is_untouched(qemu: &mut Qemu, console: &str) {
    let (start, end, _) = rom_state(qemu);
    assert!(
        start != 0 && end - start == 2 << 20,
        "the ROM added no reserved range: {start:#x}-{end:#x}"
    );
    let named = format!(
        "{}[mem {start:#018x}-{:#018x}] reserved",
        line::LOADER_MEMORY,
        end - 1
    );
    assert!(console.contains(&named), "no `{named}`:\n{console}");
    let bytes = qemu.read_physical(start, end - start).unwrap();
    let changed: Vec<u64> = bytes
        .chunks(4)
        .enumerate()
        .filter(|(_, word)| {
            u32::from_le_bytes((*word).try_into().unwrap()) != option_rom::E820_PATTERN
        })
        .map(|(i, _)| start + 4 * i as u64)
        .collect();
    assert!(
        changed.is_empty(),
        "{} words of the reserved range {start:#x}-{end:#x} were written, from {:#x} to {:#x}",
        changed.len(),
        changed[0],
        changed[changed.len() - 1]
    );
}

#[test]
fn a_reserved_range_at_the_top_of_ram_keeps_its_pattern_and_the_cube_is_drawn() {
    // The xHCI makes the kernel take DMA and page tables from the top of
    // usable RAM, where the issue saw it write into the reserved range.
    let devices = vec![
        format!("secondary-vga,id={DISPLAY_ID}"),
        "qemu-xhci,id=xhci".to_owned(),
        format!("usb-kbd,display={DISPLAY_ID},bus=xhci.0"),
    ];
    let changes = E820Changes {
        reserve_top: true,
        reverse: true,
        ..E820Changes::default()
    };
    let (mut qemu, _rom) = start(changes, devices);
    let console = qemu.wait_for_serial(line::READY, BOOT_TIMEOUT).unwrap();
    assert_the_rom_answered(&mut qemu, &console);
    let summary = memory_summary(&console);
    assert!(
        summary.contains("sorted, 1 overlap split;"),
        "loader: memory: {summary}"
    );
    assert!(
        console.contains("usb: keyboard on xhci "),
        "the xHCI was not used:\n{console}"
    );
    assert_the_reserved_range_is_untouched(&mut qemu, &console);
    common::cube_keys_then_escape_powers_off(&mut qemu);
}

#[test]
fn usb_keyboards_are_still_heard_on_xhci_and_ehci_with_a_reserved_range_at_the_top() {
    let (xhci_display, ehci_display) = (DISPLAY_ID, "video1");
    let devices = vec![
        format!("secondary-vga,id={xhci_display}"),
        format!("secondary-vga,id={ehci_display}"),
        "qemu-xhci,id=xhci".to_owned(),
        format!("usb-kbd,display={xhci_display},bus=xhci.0"),
        "usb-ehci,id=ehci".to_owned(),
        format!("usb-kbd,display={ehci_display},bus=ehci.0"),
    ];
    let changes = E820Changes {
        reserve_top: true,
        ..E820Changes::default()
    };
    let (mut qemu, _rom) = start(changes, devices);
    let console = qemu.wait_for_serial(line::READY, BOOT_TIMEOUT).unwrap();
    assert_the_rom_answered(&mut qemu, &console);
    let kinds: Vec<String> = common::usb_keyboards_on(&console)
        .into_iter()
        .map(|(kind, _, _)| kind)
        .collect();
    assert!(
        kinds.iter().any(|k| k == "xhci") && kinds.iter().any(|k| k == "ehci"),
        "keyboards on {kinds:?}:\n{console}"
    );
    let mut done = 0;
    for (display, key) in [
        (xhci_display, "4"),
        (ehci_display, "8"),
        (xhci_display, "a"),
        (ehci_display, "r"),
    ] {
        done = common::send_and_wait_on(&mut qemu, display, &[(key, true), (key, false)], done, 1);
    }
    let console = qemu.serial();
    assert_the_reserved_range_is_untouched(&mut qemu, &console);
}

#[test]
fn the_top_usable_entry_listed_twice_still_boots_the_cube() {
    let changes = E820Changes {
        twice: true,
        ..E820Changes::default()
    };
    let (mut qemu, _rom) = start(changes, vec![]);
    let console = qemu.wait_for_serial(line::READY, BOOT_TIMEOUT).unwrap();
    assert_the_rom_answered(&mut qemu, &console);
    let summary = memory_summary(&console);
    assert!(
        summary.contains("1 duplicate merged;"),
        "loader: memory: {summary}"
    );
    common::cube_keys_then_escape_powers_off(&mut qemu);
}

#[test]
fn stage_4_says_its_panic_on_com1_when_no_ram_above_1_mib_is_usable() {
    let changes = E820Changes {
        no_high_ram: true,
        ..E820Changes::default()
    };
    let (mut qemu, _rom) = start(changes, vec![]);
    let console = qemu
        .wait_for_serial("no usable RAM above 1 MiB", BOOT_TIMEOUT)
        .unwrap();
    assert_the_rom_answered(&mut qemu, &console);
    let panic = console
        .find(line::LOADER_PANIC)
        .map(|at| &console[at..])
        .unwrap_or_else(|| panic!("no panic line:\n{console}"));
    assert!(
        panic.starts_with("loader: PANIC: panicked at src/main.rs:"),
        "{console}"
    );
    assert!(!console.contains(boot::READY_LINE), "{console}");
}
