//! The patched bootloader on odd displays and CPUs (issue 34; see
//! `bootloader/CHANGES.md`): a UEFI machine whose only GOP is Blt-only
//! (virtio-gpu under OVMF) boots without a framebuffer and runs unseen, keys
//! and Esc working; with a Blt-only GOP first and a usable one second the
//! loader draws on the usable one; a CPU without NX boots under SeaBIOS and
//! OVMF with the cube's pictures unchanged and NX reported off. Every boot
//! starts with the loader's first serial line. The host tests of the GOP
//! choice and the E820 walk are in `bootloader/loader-logic`.

mod common;

use boot::qemu::EXIT_SUCCESS;
use boot::{line, Board, Firmware, Graphics, Qemu, QemuOptions};
use common::{assert_pictures_equal, assert_same_picture, presented, BOOT_TIMEOUT};
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
/// The fact line for no-execute off (`demo::facts`).
const NX_OFF: &str = "facts: nx: off";
const NX_ON: &str = "facts: nx: on";

fn start(firmware: Firmware, graphics: Graphics, cpu: Option<&str>) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    if firmware == Firmware::Uefi {
        options.board = Board::Q35;
    }
    options.firmware = firmware;
    options.graphics = graphics;
    options.cpu = cpu.map(str::to_owned);
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

/// The loader's first line comes before the kernel's banner.
fn assert_loader_line_first(console: &str) {
    let loader = console
        .find(line::LOADER_START)
        .unwrap_or_else(|| panic!("no loader line on serial:\n{console}"));
    let kernel = console
        .find(line::KERNEL_BANNER)
        .unwrap_or_else(|| panic!("no kernel banner on serial:\n{console}"));
    assert!(loader < kernel, "{console}");
}

#[test]
fn a_blt_only_gop_alone_boots_without_a_display_and_keys_still_act() {
    let mut qemu = start(Firmware::Uefi, Graphics::VirtioGpu, None);
    let console = qemu
        .wait_for_serial(line::READY_NO_DISPLAY, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert_loader_line_first(&console);
    assert!(
        console.contains("Blt-only (no framebuffer)"),
        "the loader says why the GOP is passed over:\n{console}"
    );
    assert!(console.contains("display: none:"), "{console}");
    assert!(
        !console.contains("drawing through the firmware framebuffer"),
        "no framebuffer, so none is said to be drawn through:\n{console}"
    );
    assert!(
        console.contains("facts: display: none: no legacy VGA, no framebuffer"),
        "{console}"
    );
    assert!(!console.contains(line::READY), "{console}");
    assert!(
        !console.contains("PANIC") && !console.contains("panicked"),
        "{console}"
    );
    // Keys act: each command is confirmed on serial.
    for (n, &(key, _)) in common::CUBE_KEYS.iter().take(4).enumerate() {
        qemu.send_key(key).unwrap();
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    }
    // Esc says goodbye and ends the machine.
    qemu.send_key("esc").unwrap();
    qemu.wait_for_serial(line::GOODBYE, BOOT_TIMEOUT).unwrap();
    let status = qemu.wait_exit(BOOT_TIMEOUT).unwrap();
    assert_eq!(status.and_then(|s| s.code()), Some(EXIT_SUCCESS));
}

#[test]
fn with_a_blt_only_gop_first_the_usable_second_one_is_drawn_on() {
    let mut qemu = start(Firmware::Uefi, Graphics::VirtioGpuThenStdVga, None);
    let console = qemu
        .wait_for_serial(line::READY, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert_loader_line_first(&console);
    assert!(console.contains("Blt-only (no framebuffer)"), "{console}");
    assert!(console.contains("loader: drawing on GOP"), "{console}");
    // The starting scene spins: still the cube first (its first key resets
    // the scene), then compare what the kernel drew with the model's frame.
    let mut soft = common::soft_vga_in_mode_x();
    let mut app = demo::app::App::new();
    for (n, &(key, command)) in common::TURNED.iter().enumerate() {
        qemu.send_key(key).unwrap();
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
        app.apply(command);
    }
    app.step(&mut modex::ModeX::new(&mut *soft), &|| 0u64);
    // The second adapter's display (`screendump` alone shows the first).
    let screen = qemu.screendump_of("vga").unwrap();
    let expected = presented(&common::model_picture(&soft), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, "the usable GOP after a Blt-only one");
}

/// The cube after each key, on a CPU without NX, equals the software VGA's.
fn cube_without_nx(firmware: Firmware) {
    let mut qemu = start(firmware, Graphics::StdVga, Some("qemu64,-nx"));
    let timeout = match firmware {
        Firmware::Uefi | Firmware::Uefi32 => UEFI_BOOT_TIMEOUT,
        Firmware::Bios => BOOT_TIMEOUT,
    };
    let console = qemu.wait_for_serial(line::READY, timeout).unwrap();
    assert_loader_line_first(&console);
    assert!(console.contains(NX_OFF), "{console}");
    assert!(!console.contains(NX_ON), "{console}");
    common::after_each_key_on(
        &mut qemu,
        &common::CUBE_KEYS,
        |screen, model, _, what| match firmware {
            Firmware::Bios => assert_same_picture(screen, model, what),
            Firmware::Uefi | Firmware::Uefi32 => {
                assert_pictures_equal(screen, &presented(model, screen.width, screen.height), what)
            }
        },
    );
}

#[test]
fn seabios_on_a_cpu_without_nx_runs_the_cube() {
    cube_without_nx(Firmware::Bios);
}

#[test]
fn ovmf_on_a_cpu_without_nx_runs_the_cube() {
    cube_without_nx(Firmware::Uefi);
}

#[test]
fn with_nx_the_log_says_it_is_on() {
    let mut qemu = start(Firmware::Bios, Graphics::StdVga, None);
    let console = qemu.wait_for_serial(line::READY, BOOT_TIMEOUT).unwrap();
    assert_loader_line_first(&console);
    assert!(console.contains(NX_ON), "{console}");
}
