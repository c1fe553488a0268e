//! The machine booted from a USB stick in place of its hard disk: the one
//! image (`modex-cube.img`) as a `usb-storage` device on its own USB host
//! controller, xHCI or EHCI, and no hard disk at all, under SeaBIOS (on the
//! i440FX) and OVMF (on a Q35). The firmware must find the stick and boot
//! it; then the kernel reaches the ready line, keys act (each picture as the
//! software VGA draws it: Mode X doubled under SeaBIOS, presented into the
//! GOP framebuffer under OVMF), and Esc says goodbye and switches the machine
//! off through ACPI, as on a PC (no debug-exit device: QEMU exits with 0).
//!
//! An xHCI controller is also one the kernel takes for USB keyboards: the
//! stick on it must not stop the kernel (it is no keyboard, and is left be).

mod common;

use boot::{line, Board, DiskAttachment, Firmware, Qemu, QemuOptions, UsbHost};
use common::{
    assert_pictures_equal, assert_same_picture, model_picture, presented, soft_vga_in_mode_x,
    BOOT_TIMEOUT, CUBE_KEYS,
};
use demo::app::App;
use modex::ModeX;

/// Keys from the cube test's sequence: a reset, turns, a move away.
const KEYS: usize = 7;

fn boot_from_stick(firmware: Firmware, host: UsbHost) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.disk = DiskAttachment::UsbStick(host);
    options.firmware = firmware;
    options.board = match firmware {
        Firmware::Bios => Board::PC,
        Firmware::Uefi => Board::Q35,
    };
    // As on a PC: Esc switches off through ACPI, and QEMU then exits with 0.
    options.debug_exit = false;
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

fn boots_and_runs(firmware: Firmware, host: UsbHost) {
    let what = format!("{firmware:?} from a stick on {}", host.device());
    let mut qemu = boot_from_stick(firmware, host);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert!(console.contains(line::KERNEL_BANNER), "{what}: {console}");

    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    for (n, &(key, command)) in CUBE_KEYS[..KEYS].iter().enumerate() {
        qemu.send_key(key).unwrap();
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT)
            .unwrap_or_else(|e| panic!("{what}, key {key}: {e}"));
        app.apply(command);
    }
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let screen = qemu.screendump().unwrap();
    let model = model_picture(&soft);
    match firmware {
        Firmware::Bios => assert_same_picture(&screen, &model, &what),
        Firmware::Uefi => {
            let expected = presented(&model, screen.width, screen.height);
            assert_pictures_equal(&screen, &expected, &what);
        }
    }

    qemu.send_key("esc").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{what}: not switched off after Esc: {e}"));
    let console = qemu.serial();
    assert!(console.contains(line::GOODBYE), "{what}: {console}");
    assert!(
        console.contains("power: switching off (ACPI S5"),
        "{what}: {console}"
    );
    assert_eq!(status.code(), Some(0), "{what}: {status}\n{console}");
}

#[test]
fn seabios_boots_from_a_stick_on_xhci() {
    boots_and_runs(Firmware::Bios, UsbHost::Xhci);
}

#[test]
fn seabios_boots_from_a_stick_on_ehci() {
    boots_and_runs(Firmware::Bios, UsbHost::Ehci);
}

#[test]
fn ovmf_boots_from_a_stick_on_xhci() {
    boots_and_runs(Firmware::Uefi, UsbHost::Xhci);
}

#[test]
fn ovmf_boots_from_a_stick_on_ehci() {
    boots_and_runs(Firmware::Uefi, UsbHost::Ehci);
}
