//! USB keyboards on every legacy host controller QEMU emulates (issue 40):
//! UHCI (`piix3-usb-uhci`), OHCI (`pci-ohci`), EHCI (`usb-ehci`, with a
//! high-speed `usb-kbd`) and ICH9's EHCI with three UHCI companions (QEMU's
//! `docs/config/ich9-ehci-uhci.cfg` layout), each with its keys checked
//! against the software VGA's pictures and Esc powering off with every
//! controller halted first (companions before EHCIs, all before ACPI S5).
//! Three boots share the checks:
//!
//! - OVMF on a Q35 without i8042 or PIT: a keyboard behind a `usb-hub` on
//!   the UHCI and one behind a hub on the OHCI, found at boot; the cube
//!   test's keys alternate between them; then a keyboard plugged in after
//!   boot (`device_add`), typed on and pulled (`device_del`) on the EHCI,
//!   the UHCI and the OHCI in turn.
//! - OVMF likewise, with ICH9's EHCI and companions: a full-speed keyboard
//!   on an EHCI port is handed to the UHCI companion for that port, a
//!   high-speed one stays on the EHCI; the keys alternate between them;
//!   then a full-speed keyboard plugged in after boot goes to another
//!   companion, and is pulled.
//! - SeaBIOS on an i440FX with PS/2 (the firmware drives these controllers
//!   itself and leaves them running): a keyboard behind a hub on the UHCI
//!   gives the Mode X pictures; keyboards plugged in on the OHCI and on
//!   ICH9's EHCI (handed to a companion) act.
//!
//! Keys reach a keyboard alone because one is bound to the display
//! (`display=video0`, `Qemu::key_events_on`), and events sent without a
//! display go to the unbound one (with no PS/2 keyboard on the Q35).

mod common;

use boot::qemu::DISPLAY_ID;
use boot::{line, Board, Firmware, Graphics, Qemu, QemuOptions, RgbImage, UsbHost};
use common::flood::commands_done;
use common::{
    assert_cube_picture, model_picture, send_and_wait_on, soft_vga_in_mode_x,
    usb_escape_powers_off_with_every_controller_halted_first, usb_keyboards_on, BOOT_TIMEOUT,
    CUBE_KEYS, Q35_WITHOUT_PS2,
};
use demo::app::App;
use demo::command::Command;
use modex::ModeX;
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);

/// Which keyboard a key is sent to.
#[derive(Clone, Copy, Debug)]
enum Keyboard {
    /// The one bound to the display (`display=video0`).
    Bound,
    /// The one bound to none: events sent without a display.
    Unbound,
}

impl Keyboard {
    fn send(self, qemu: &mut Qemu, events: &[(&str, bool)]) {
        match self {
            Keyboard::Bound => qemu.key_events_on(DISPLAY_ID, events).unwrap(),
            Keyboard::Unbound => qemu.key_events(events).unwrap(),
        }
    }
}

/// Boots with `devices` and no debug-exit device (Esc powers off through
/// ACPI, as on a PC), to the ready line: QEMU and the console so far.
fn boot(firmware: Firmware, board: Board, devices: Vec<String>) -> (Qemu, String) {
    let images = boot::images::publish().expect("the build script made the images");
    let image = match firmware {
        Firmware::Bios => images.bios,
        Firmware::Uefi => images.uefi,
        Firmware::Uefi32 => unreachable!("no 32-bit UEFI here"),
    };
    let mut options = QemuOptions::new(image);
    options.firmware = firmware;
    options.board = board;
    options.graphics = match firmware {
        Firmware::Bios => Graphics::StdVga,
        _ => Graphics::BochsDisplay,
    };
    options.debug_exit = false;
    options.devices = devices;
    if firmware == Firmware::Bios {
        // The standard VGA's `-vga` device has no id: a second display gives
        // the USB keyboard one to be bound to.
        options
            .devices
            .insert(0, format!("secondary-vga,id={DISPLAY_ID}"));
    }
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    (qemu, console)
}

/// A usb-kbd on `bus` at `port`, bound to the display or not.
fn keyboard(id: &str, bus: &str, port: &str, bound: bool, full_speed: bool) -> String {
    let mut device = format!("usb-kbd,id={id},bus={bus},port={port}");
    if bound {
        device.push_str(&format!(",display={DISPLAY_ID}"));
    }
    if full_speed {
        device.push_str(",usb_version=1");
    }
    device
}

/// The cube test's keys, each sent to the keyboard `route` names for it and
/// waited for, the screen compared with the software VGA's picture after
/// the same commands. Returns the commands done.
fn keys_match_the_software_vga(
    qemu: &mut Qemu,
    firmware: Firmware,
    keys: &[(&str, Command)],
    route: impl Fn(usize) -> Keyboard,
) -> u64 {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    for (n, &(key, command)) in keys.iter().enumerate() {
        let keyboard = route(n);
        keyboard.send(qemu, &[(key, true), (key, false)]);
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT)
            .unwrap_or_else(|e| panic!("key {key} on the {keyboard:?} keyboard: {e}"));
        app.apply(command);
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        let screen: RgbImage = qemu.screendump().unwrap();
        let what = format!("key {} ({key}) on the {keyboard:?} keyboard", n + 1);
        assert_cube_picture(firmware, &screen, &model_picture(&soft), &what);
    }
    keys.len() as u64
}

/// The keyboards the kernel said it found at boot, as (kind, location).
fn found(console: &str) -> Vec<(String, String)> {
    let mut found: Vec<(String, String)> = usb_keyboards_on(console)
        .into_iter()
        .map(|(kind, _, location)| (kind, location))
        .collect();
    found.sort();
    found
}

/// The facts row of USB keyboards.
fn usb_keyboard_facts(console: &str) -> line::UsbKeyboards {
    console
        .lines()
        .find_map(|text| line::UsbKeyboards::parse(text.strip_prefix(line::MACHINE_FACT)?))
        .unwrap_or_else(|| panic!("no USB keyboards fact:\n{console}"))
}

fn facts(on: &[(&str, u8)]) -> line::UsbKeyboards {
    let mut keyboards = line::UsbKeyboards::default();
    for &(kind, count) in on {
        keyboards.on[line::usb_host_index(kind).unwrap()] = count;
    }
    keyboards
}

/// Plugs a keyboard bound to the display in after boot, waits until the
/// kernel says it has it on a controller of `kind`, types two keys on it
/// (each must act once), pulls it out and waits until the kernel has let go
/// of it. Returns the commands done.
fn plug_in_type_and_pull(
    qemu: &mut Qemu,
    properties: &[(&str, &str)],
    kind: &str,
    done: u64,
) -> u64 {
    let announced = format!("usb: keyboard on {kind} ");
    let before = qemu.serial().matches(&announced).count();
    let gone_before = qemu.serial().matches(GONE).count();
    let mut with_display = properties.to_vec();
    with_display.push(("display", DISPLAY_ID));
    qemu.device_add("usb-kbd", &with_display).unwrap();
    qemu.wait_for_serial_count(&announced, before + 1, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("a keyboard plugged in on the {kind}: {e}"));
    let done = send_and_wait_on(qemu, DISPLAY_ID, &[("6", true), ("6", false)], done, 1);
    let done = send_and_wait_on(qemu, DISPLAY_ID, &[("4", true), ("4", false)], done, 1);
    let id = properties
        .iter()
        .find(|(name, _)| *name == "id")
        .map(|(_, id)| *id)
        .expect("the keyboard has an id");
    qemu.device_del(id).unwrap();
    qemu.wait_for_serial_count(GONE, gone_before + 1, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("the keyboard pulled from the {kind}: {e}"));
    done
}

/// What the kernel says of a device pulled out.
const GONE: &str = ": keyboard gone";

#[test]
fn uhci_ohci_and_ehci_keyboards_drive_the_demo_and_come_and_go_on_ovmf() {
    let mut devices = Vec::new();
    devices.extend(UsbHost::Uhci.devices("uhci"));
    devices.push("usb-hub,id=uhcihub,bus=uhci.0,port=1".into());
    devices.push(keyboard("kbd1", "uhci.0", "1.1", true, false));
    devices.extend(UsbHost::Ohci.devices("ohci"));
    devices.push("usb-hub,id=ohcihub,bus=ohci.0,port=1".into());
    devices.push(keyboard("kbd2", "ohci.0", "1.1", false, false));
    devices.extend(UsbHost::Ehci.devices("ehci"));
    let (mut qemu, console) = boot(Firmware::Uefi, Q35_WITHOUT_PS2, devices);
    assert_eq!(
        found(&console),
        [
            ("ohci".to_string(), "1.1".to_string()),
            ("uhci".to_string(), "1.1".to_string())
        ],
        "a keyboard behind the hub on each:\n{console}"
    );
    assert_eq!(
        usb_keyboard_facts(&console),
        facts(&[("ohci", 1), ("uhci", 1)])
    );
    assert!(console.contains("; USB on 3 hosts"), "{console}");

    // The cube's keys, by turns on the UHCI's and the OHCI's keyboard.
    let mut done = keys_match_the_software_vga(&mut qemu, Firmware::Uefi, &CUBE_KEYS, |n| {
        if n % 2 == 0 {
            Keyboard::Bound
        } else {
            Keyboard::Unbound
        }
    });

    // The UHCI's keyboard pulled from behind its hub; then one plugged in,
    // typed on and pulled on each controller's root port.
    qemu.device_del("kbd1").unwrap();
    qemu.wait_for_serial_count(GONE, 1, BOOT_TIMEOUT).unwrap();
    for (bus, kind) in [("ehci.0", "ehci"), ("uhci.0", "uhci"), ("ohci.0", "ohci")] {
        let id = format!("hot{kind}");
        done = plug_in_type_and_pull(
            &mut qemu,
            &[("id", &id), ("bus", bus), ("port", "2")],
            kind,
            done,
        );
    }
    assert_eq!(commands_done(&qemu.serial()), done);
    assert!(!qemu.serial().contains("PANIC"));

    // Esc on the OHCI's keyboard, still there.
    usb_escape_powers_off_with_every_controller_halted_first(
        &mut qemu,
        |qemu| Keyboard::Unbound.send(qemu, &[("esc", true), ("esc", false)]),
        &[("uhci", 1), ("ohci", 1), ("ehci", 1)],
        UEFI_BOOT_TIMEOUT,
    );
}

/// ICH9's companions, for the layout `UsbHost::Ich9EhciWithCompanions`
/// gives: EHCI port (1-based) to the companion's function and its port.
fn companion_of(ehci_port: u8) -> (&'static str, u8) {
    match ehci_port {
        1 | 2 => ("8086:2934 at 00:1d.0", ehci_port),
        3 | 4 => ("8086:2935 at 00:1d.1", ehci_port - 2),
        _ => ("8086:2936 at 00:1d.2", ehci_port - 4),
    }
}

#[test]
fn ich9_hands_full_speed_keyboards_to_its_uhci_companions_on_ovmf() {
    let mut devices = UsbHost::Ich9EhciWithCompanions.devices("ich9");
    // QEMU's bus ports are the EHCI's ports 1-6.
    devices.push(keyboard("fullspeed", "ich9.0", "1", true, true));
    devices.push(keyboard("highspeed", "ich9.0", "3", false, false));
    let (mut qemu, console) = boot(Firmware::Uefi, Q35_WITHOUT_PS2, devices);
    let on = usb_keyboards_on(&console);
    let (companion, port) = companion_of(1);
    assert!(
        on.contains(&("uhci".to_string(), companion.to_string(), port.to_string())),
        "the full-speed keyboard on the first companion:\n{console}"
    );
    assert!(
        on.iter().any(|(kind, function, location)| kind == "ehci"
            && function == "8086:293a at 00:1d.7"
            && location == "3"),
        "the high-speed keyboard on the EHCI:\n{console}"
    );
    assert_eq!(on.len(), 2, "{console}");
    assert_eq!(
        usb_keyboard_facts(&console),
        facts(&[("ehci", 1), ("uhci", 1)])
    );

    let mut done = keys_match_the_software_vga(&mut qemu, Firmware::Uefi, &CUBE_KEYS, |n| {
        if n % 2 == 0 {
            Keyboard::Bound
        } else {
            Keyboard::Unbound
        }
    });
    // The bound keyboard pulled, and a full-speed one plugged into EHCI
    // port 5: the third companion's first port.
    qemu.device_del("fullspeed").unwrap();
    qemu.wait_for_serial_count(GONE, 1, BOOT_TIMEOUT).unwrap();
    done = plug_in_type_and_pull(
        &mut qemu,
        &[
            ("id", "late"),
            ("bus", "ich9.0"),
            ("port", "5"),
            ("usb_version", "1"),
        ],
        "uhci",
        done,
    );
    let (companion, port) = companion_of(5);
    assert!(
        usb_keyboards_on(&qemu.serial()).contains(&(
            "uhci".to_string(),
            companion.to_string(),
            port.to_string()
        )),
        "the late keyboard on the third companion:\n{}",
        qemu.serial()
    );
    assert_eq!(commands_done(&qemu.serial()), done);

    usb_escape_powers_off_with_every_controller_halted_first(
        &mut qemu,
        |qemu| Keyboard::Unbound.send(qemu, &[("esc", true), ("esc", false)]),
        &[("uhci", 3), ("ehci", 1)],
        UEFI_BOOT_TIMEOUT,
    );
}

#[test]
fn after_seabios_drove_them_uhci_ohci_and_ich9_keyboards_act() {
    let mut devices = Vec::new();
    devices.extend(UsbHost::Uhci.devices("uhci"));
    devices.push("usb-hub,id=uhcihub,bus=uhci.0,port=1".into());
    devices.push(keyboard("kbd1", "uhci.0", "1.2", true, false));
    devices.extend(UsbHost::Ohci.devices("ohci"));
    devices.push("usb-hub,id=ohcihub,bus=ohci.0,port=1".into());
    devices.extend(UsbHost::Ich9EhciWithCompanions.devices("ich9"));
    let (mut qemu, console) = boot(Firmware::Bios, Board::PC, devices);
    assert_eq!(
        found(&console),
        [("uhci".to_string(), "1.2".to_string())],
        "{console}"
    );
    let mut done =
        keys_match_the_software_vga(&mut qemu, Firmware::Bios, &CUBE_KEYS, |_| Keyboard::Bound);
    qemu.device_del("kbd1").unwrap();
    qemu.wait_for_serial_count(GONE, 1, BOOT_TIMEOUT).unwrap();
    // Behind the OHCI's hub, then on ICH9's EHCI (a full-speed keyboard:
    // handed to a companion).
    done = plug_in_type_and_pull(
        &mut qemu,
        &[("id", "hubbed"), ("bus", "ohci.0"), ("port", "1.3")],
        "ohci",
        done,
    );
    done = plug_in_type_and_pull(
        &mut qemu,
        &[
            ("id", "companion"),
            ("bus", "ich9.0"),
            ("port", "2"),
            ("usb_version", "1"),
        ],
        "uhci",
        done,
    );
    assert_eq!(commands_done(&qemu.serial()), done);
    // Esc on the PS/2 keyboard: this PC has one.
    usb_escape_powers_off_with_every_controller_halted_first(
        &mut qemu,
        |qemu| qemu.send_key("esc").unwrap(),
        &[("uhci", 4), ("ohci", 1), ("ehci", 1)],
        BOOT_TIMEOUT,
    );
}
