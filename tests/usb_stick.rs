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
//! Two more boots put a `usb-kbd` and a `usb-tablet` beside the stick on its
//! `qemu-xhci` (OVMF on a Q35 without PS/2 or PIT, SeaBIOS on a PC with
//! PS/2): the kernel names the stick and the tablet on their ports and
//! takes neither, the cube test's keys sent to the USB keyboard act once
//! each with the software VGA's pictures, and Esc powers off with the xHCI
//! halted first.
//!
//! Two more boot from a stick on ICH9's EHCI, with its three UHCI
//! companions and a full-speed keyboard beside the stick (OVMF on a Q35
//! without PS/2 or PIT, SeaBIOS on a PC): the EHCI keeps the high-speed
//! stick and hands the keyboard to the first companion, the cube test's
//! keys on it give the software VGA's pictures, and Esc powers off with
//! the companions halted before the EHCI.

mod common;

use boot::qemu::{DISPLAY_ID, STICK_HOST_ID};
use boot::{line, Board, DiskAttachment, Firmware, Graphics, Qemu, QemuOptions, UsbHost};
use common::flood::commands_done;
use common::{
    assert_cube_picture, assert_pictures_equal, assert_presented, assert_same_picture,
    model_picture, presented, soft_vga_in_mode_x,
    usb_escape_powers_off_with_every_controller_halted_first,
    usb_escape_powers_off_with_the_xhci_halted_first, usb_keyboards_on,
    usb_keys_match_the_software_vga, BOOT_TIMEOUT, CUBE_KEYS, Q35_WITHOUT_PS2,
};
use demo::app::App;
use modex::ModeX;

/// Keys from the cube test's sequence: a reset, turns, a move away.
const KEYS: usize = 7;

fn boot_from_stick(
    firmware: Firmware,
    host: UsbHost,
    board: Board,
    graphics: Graphics,
    devices: Vec<String>,
) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.disk = DiskAttachment::UsbStick(host);
    options.firmware = firmware;
    options.board = board;
    options.graphics = graphics;
    // As on a PC: Esc switches off through ACPI, and QEMU then exits with 0.
    options.debug_exit = false;
    options.devices = devices;
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

fn boots_and_runs(firmware: Firmware, host: UsbHost) {
    let what = format!("{firmware:?} from a stick on {}", host.device());
    let board = match firmware {
        Firmware::Bios => Board::PC,
        Firmware::Uefi | Firmware::Uefi32 => Board::Q35,
    };
    let mut qemu = boot_from_stick(firmware, host, board, Graphics::StdVga, Vec::new());
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
        Firmware::Uefi | Firmware::Uefi32 => {
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

/// The stick, a USB keyboard and a USB tablet on one `qemu-xhci`, as on a
/// PC booted from a stick with a mouse beside the keyboard (issue #31): the
/// keys sent to the keyboard act once each and give the software VGA's
/// pictures; the log names the stick and the tablet, each on its port, as
/// not taken; Esc says goodbye, and the xHCI is halted before the machine is
/// switched off through ACPI (QEMU exits with 0).
fn stick_tablet_and_keyboard_on_one_xhci(firmware: Firmware) {
    let what = format!("{firmware:?} from a stick beside a keyboard and a tablet");
    let mut devices = Vec::new();
    if firmware == Firmware::Bios {
        // The standard VGA's `-vga` device has no id: a second display
        // gives the USB keyboard one to be bound to.
        devices.push(format!("secondary-vga,id={DISPLAY_ID}"));
    }
    // The stick takes QEMU's bus port 1, a USB 3 port (QEMU's usb-storage
    // does SuperSpeed): the xHCI's port 1. The keyboard and the tablet are
    // USB 2 devices: bus ports 2 and 3 are the xHCI's ports 6 and 7, after
    // its four USB 3 ones.
    devices.push(format!(
        "usb-kbd,id=usbkbd,display={DISPLAY_ID},bus={STICK_HOST_ID}.0,port=2"
    ));
    devices.push(format!("usb-tablet,id=tablet,bus={STICK_HOST_ID}.0,port=3"));
    // Under OVMF the display is a `bochs-display`, with the id the keyboard
    // is bound to.
    let (board, graphics) = match firmware {
        Firmware::Bios => (Board::PC, Graphics::StdVga),
        Firmware::Uefi | Firmware::Uefi32 => (Q35_WITHOUT_PS2, Graphics::BochsDisplay),
    };
    let mut qemu = boot_from_stick(firmware, UsbHost::Xhci, board, graphics, devices);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(
        console
            .lines()
            .filter(|l| l.starts_with("usb: xHCI 1b36:000d at ") && l.contains(" ports, "))
            .count(),
        1,
        "{what}: one xHCI, the stick's:\n{console}"
    );
    // QEMU's usb-storage is 46f4:0001, its usb-tablet 0627:0001.
    for expected in [
        // The stick is SuperSpeed: enumerated through the device layer with
        // endpoint 0's 512-byte packets, and left alone.
        "usb: xhci port 1: device 46f4:0001 (mass storage, class 08/06/50) is not a keyboard or a hub; left alone",
        "keyboard: USB keyboard, read by its report descriptor (2 key fields, 8-byte reports), on xhci port 6",
        "usb: xhci port 7: device 0627:0001 is a HID device without keys; left alone",
    ] {
        assert!(
            console.lines().any(|l| l == expected),
            "{what}: no line {expected:?}:\n{console}"
        );
    }
    assert!(!console.contains("EXCEPTION"), "{what}: {console}");

    let done =
        usb_keys_match_the_software_vga(&mut qemu, DISPLAY_ID, &CUBE_KEYS, |screen, model, key| {
            let what = format!("{what}, {key}");
            match firmware {
                Firmware::Bios => assert_same_picture(screen, model, &what),
                Firmware::Uefi | Firmware::Uefi32 => assert_presented(screen, model, &what),
            }
        });
    usb_escape_powers_off_with_the_xhci_halted_first(&mut qemu, DISPLAY_ID, BOOT_TIMEOUT);
    // Esc ends the demo without a command line: the last is the last key's.
    assert_eq!(
        commands_done(&qemu.serial()),
        done,
        "{what}: a key acted twice"
    );
}

#[test]
fn ovmf_boots_from_a_stick_beside_a_usb_keyboard_and_tablet() {
    stick_tablet_and_keyboard_on_one_xhci(Firmware::Uefi);
}

#[test]
fn seabios_boots_from_a_stick_beside_a_usb_keyboard_and_tablet() {
    stick_tablet_and_keyboard_on_one_xhci(Firmware::Bios);
}

/// The stick on ICH9's EHCI with a full-speed keyboard beside it: the
/// keyboard is handed to the UHCI companion of its port, its keys give the
/// software VGA's pictures, and Esc (on it) powers off with the three
/// companions halted before the EHCI.
fn stick_on_ich9_ehci_keyboard_on_a_companion(firmware: Firmware) {
    let what = format!("{firmware:?} from a stick on ICH9's EHCI");
    let mut devices = Vec::new();
    if firmware == Firmware::Bios {
        devices.push(format!("secondary-vga,id={DISPLAY_ID}"));
    }
    // The stick is on bus port 1; the keyboard, full speed, on port 3: the
    // second companion's first port.
    devices.push(format!(
        "usb-kbd,id=usbkbd,display={DISPLAY_ID},bus={STICK_HOST_ID}.0,port=3,usb_version=1"
    ));
    let (board, graphics) = match firmware {
        Firmware::Bios => (Board::PC, Graphics::StdVga),
        Firmware::Uefi | Firmware::Uefi32 => (Q35_WITHOUT_PS2, Graphics::BochsDisplay),
    };
    let mut qemu = boot_from_stick(
        firmware,
        UsbHost::Ich9EhciWithCompanions,
        board,
        graphics,
        devices,
    );
    let console = qemu
        .wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_eq!(
        usb_keyboards_on(&console),
        [(
            "uhci".to_string(),
            "8086:2935 at 00:1d.1".to_string(),
            "1".to_string()
        )],
        "{what}: the keyboard on the second companion:\n{console}"
    );
    let done =
        usb_keys_match_the_software_vga(&mut qemu, DISPLAY_ID, &CUBE_KEYS, |screen, model, key| {
            assert_cube_picture(firmware, screen, model, &format!("{what}, {key}"));
        });
    usb_escape_powers_off_with_every_controller_halted_first(
        &mut qemu,
        |qemu| qemu.press_key_on(DISPLAY_ID, "esc").unwrap(),
        &[("uhci", 3), ("ehci", 1)],
        BOOT_TIMEOUT,
    );
    assert_eq!(
        commands_done(&qemu.serial()),
        done,
        "{what}: a key acted twice"
    );
}

#[test]
fn ovmf_boots_from_a_stick_on_ich9_ehci_with_a_keyboard_on_a_companion() {
    stick_on_ich9_ehci_keyboard_on_a_companion(Firmware::Uefi);
}

#[test]
fn seabios_boots_from_a_stick_on_ich9_ehci_with_a_keyboard_on_a_companion() {
    stick_on_ich9_ehci_keyboard_on_a_companion(Firmware::Bios);
}
