//! A USB keyboard through the xHCI controller, in QEMU. Five boots:
//!
//! - OVMF on a Q35 without an i8042 or a PIT (a UEFI-only desktop), the keyboard
//!   behind a `usb-hub`: the cube test's key sequence gives the software
//!   VGA's picture after each key, a held key repeats, then a flood of 2,000
//!   actions as the PS/2 one in `keyboard_abuse.rs` (the model and pacer in
//!   `common/flood.rs`: Ctrl, Alt and Delete, left, right and keypad, held
//!   across other keys, near misses of the chord, each window sent when the
//!   kernel's echo shows every earlier byte taken): the bytes taken are the
//!   bytes sent, the commands those of a model app fed the same bytes, R
//!   restores the starting picture, and a real Ctrl+Alt+Del resets the
//!   machine exactly once.
//! - SeaBIOS on a PC with both a PS/2 and a USB keyboard: keys sent to the
//!   USB keyboard alone act exactly once each (the firmware's own USB
//!   keyboard support is gone once the kernel has the controller), and PS/2
//!   keys act too.
//! - OVMF with the keyboard behind three tiers of `usb-hub`: the cube
//!   test's keys give the software VGA's pictures.
//! - OVMF with no keyboard at boot: one plugged in with QMP `device_add`
//!   after `screen: ready` is found and its keys act; pulled out
//!   (`device_del`) it is let go of; plugged in again its keys act again.
//! - OVMF without isa-debug-exit: Esc says goodbye and powers off, the xHCI
//!   halted first.
//!
//! Keys reach the USB keyboard alone because it is bound to the display
//! (`display=video0`) and sent there (`Qemu::press_key_on`); `sendkey`
//! reaches the PS/2 keyboard.

mod common;

use boot::qemu::DISPLAY_ID;
use boot::{line, Board, BootRequest, Firmware, Graphics, Qemu, QemuOptions};
use common::flood::{
    bytes_taken, commands_done, flood_then_r_then_the_chord, table_bytes, track_modifier, Flood,
    KeyBytes, Pacer, Target, TABLE_KEYS,
};
use common::{
    assert_presented, send_and_wait_on, usb_escape_powers_off_with_the_xhci_halted_first,
    usb_keys_match_the_software_vga, BOOT_TIMEOUT, CUBE_KEYS, Q35_WITHOUT_PS2,
};
use demo::app::App;
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
/// Actions in the flood (taps, holds, releases and near misses).
const FLOOD_KEYS: usize = 2000;
/// A USB boot keyboard through QEMU's usb-kbd and the kernel's driver, as
/// far as the bytes of an event go: each key's set-1 bytes from the key
/// table, the modifiers as bits of the report, so that a held modifier
/// pressed again changes nothing and gives no byte.
#[derive(Clone, Default)]
struct UsbKeyboard {
    held: Vec<&'static str>,
}

impl KeyBytes for UsbKeyboard {
    fn held(&self) -> &[&'static str] {
        &self.held
    }

    fn bytes(&mut self, key: &'static str, down: bool) -> Vec<u8> {
        let again = down && self.held.contains(&key);
        track_modifier(&mut self.held, key, down);
        if again {
            Vec::new()
        } else {
            table_bytes(key, down)
        }
    }
}

/// The USB keyboard, bound to the display so that keys can be sent to it alone.
fn usb_keyboard(bus: &str) -> String {
    format!("usb-kbd,id=usbkbd,display={DISPLAY_ID},{bus}")
}

/// OVMF on [`Q35_WITHOUT_PS2`] with `devices`, booted to the ready line:
/// QEMU and the console so far.
fn boot_uefi_without_ps2(devices: Vec<String>, boot: BootRequest) -> (Qemu, String) {
    let mut qemu = start_with(
        Firmware::Uefi,
        Graphics::BochsDisplay,
        Q35_WITHOUT_PS2,
        devices,
        boot,
    );
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    (qemu, console)
}

/// The kernel's line that says it found a USB keyboard.
fn usb_keyboard_line(console: &str) -> &str {
    console
        .lines()
        .find(|l| l.starts_with("keyboard: USB keyboard, read by its report descriptor "))
        .unwrap_or_else(|| panic!("no USB keyboard found:\n{console}"))
}

fn start(firmware: Firmware, graphics: Graphics, board: Board, devices: Vec<String>) -> Qemu {
    start_with(firmware, graphics, board, devices, BootRequest::default())
}

fn start_with(
    firmware: Firmware,
    graphics: Graphics,
    board: Board,
    devices: Vec<String>,
    boot: BootRequest,
) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let image = match firmware {
        Firmware::Bios => images.bios,
        Firmware::Uefi => images.uefi,
        Firmware::Uefi32 => unreachable!("the USB tests boot no 32-bit UEFI"),
    };
    let mut options = QemuOptions::new(image);
    options.firmware = firmware;
    options.board = board;
    options.graphics = graphics;
    options.devices = devices;
    options.boot = boot;
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_usb_keyboard_behind_a_hub_drives_the_demo_on_a_uefi_machine_without_ps2() {
    let devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        "usb-hub,id=hub,bus=xhci.0,port=1".to_string(),
        usb_keyboard("bus=xhci.0,port=1.1"),
    ];
    // The kernel says every scancode byte it takes: the flood is paced by it.
    let echo = BootRequest {
        echo_scancodes: true,
        ..BootRequest::default()
    };
    let (mut qemu, console) = boot_uefi_without_ps2(devices, echo);
    // No PS/2 here: the ACPI tables say so, or the controller does not answer.
    assert!(
        console.contains("keyboard: PS/2 controller did not answer")
            || console.contains("keyboard: the ACPI tables say there is no PS/2 controller"),
        "{console}"
    );
    assert!(console.contains("usb: xHCI 1b36:000d at "), "{console}");
    let keyboard_line = usb_keyboard_line(&console);
    assert!(
        keyboard_line.ends_with(".1"),
        "the keyboard is on the hub's port 1: {keyboard_line}"
    );

    // The cube test's keys, each compared with the software VGA.
    let mut done =
        usb_keys_match_the_software_vga(&mut qemu, DISPLAY_ID, &CUBE_KEYS, assert_presented);

    // A held key repeats: one press, three commands, no more keys sent. (At
    // least three: the kernel reports a frame's commands in one line, so on
    // a slow host repeats that arrive together skip numbers.)
    qemu.key_event_on(DISPLAY_ID, "6", true).unwrap();
    let repeated = done + 3;
    qemu.wait_for_console(
        &format!("{} or later", line::CommandDone(repeated)),
        BOOT_TIMEOUT,
        |console| commands_done(console) >= repeated,
    )
    .unwrap();
    // Released, then paused: nothing repeats after the release, so the
    // line that says paused=true counts every repeat there was.
    qemu.key_events_on(DISPLAY_ID, &[("6", false), ("q", true), ("q", false)])
        .unwrap();
    let console = qemu.wait_for_serial("paused=true", BOOT_TIMEOUT).unwrap();
    done = console
        .lines()
        .find(|l| l.contains("paused=true"))
        .and_then(line::CommandDone::parse)
        .unwrap();
    // Any key resumes (and is swallowed). Its release is the second Q
    // release the kernel takes; once it has, every byte before it has
    // been taken, and no key is held.
    done = send_and_wait_on(&mut qemu, DISPLAY_ID, &[("q", true), ("q", false)], done, 1);
    let q_release = table_bytes("q", false)[0];
    let console = qemu
        .wait_for_console("the second Q release taken", BOOT_TIMEOUT, |console| {
            bytes_taken(console)
                .iter()
                .filter(|&&byte| byte == q_release)
                .count()
                == 2
        })
        .unwrap();

    // The flood, as the PS/2 one: a model app fed the bytes the kernel must
    // take decides the commands; windows that fit QEMU's usb-hid queue,
    // each sent when the kernel's echo shows every earlier byte taken. The
    // model is fed the bytes before the flood too (the held key's repeats
    // among them), so that it stands where the kernel stands.
    let mut model = App::new();
    let mut pacer = Pacer::new(Target::BoundTo(DISPLAY_ID));
    pacer.sent = bytes_taken(&console);
    for &byte in &pacer.sent {
        model.feed_scancode(byte);
    }
    assert_eq!(
        model.commands(),
        done,
        "the model and the kernel part before the flood"
    );
    assert!(!model.paused());
    flood_then_r_then_the_chord(
        &mut qemu,
        Flood::new(UsbKeyboard::default(), TABLE_KEYS.to_vec(), true),
        model,
        pacer,
        FLOOD_KEYS,
        assert_presented,
    );
}

/// The USB flood itself, on the host: Ctrl, Alt and Delete (left, right,
/// keypad) are pressed often, modifiers are held across other keys, and the
/// bytes never make the chord.
#[test]
fn the_usb_flood_presses_ctrl_alt_and_delete_yet_never_makes_the_chord() {
    common::flood::assert_flood_presses_the_chord_keys_yet_never_makes_it(
        Flood::new(UsbKeyboard::default(), TABLE_KEYS.to_vec(), true),
        FLOOD_KEYS,
    );
}

#[test]
fn on_a_bios_boot_usb_keys_act_once_and_ps2_keys_act_too() {
    // The BIOS image needs the standard VGA (whose `-vga` device has no
    // id); a second display gives the USB keyboard one to be bound to.
    let devices = vec![
        format!("secondary-vga,id={DISPLAY_ID}"),
        "qemu-xhci,id=xhci".to_string(),
        usb_keyboard("bus=xhci.0"),
    ];
    let mut qemu = start(Firmware::Bios, Graphics::StdVga, Board::PC, devices);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("keyboard: USB keyboard, read by its report descriptor "),
        "{console}"
    );
    // The kernel's own "keyboard: PS/2 ..." lines are its problems; the
    // summary's "facts: keyboard: PS/2 ready" is not one.
    assert!(
        !console.lines().any(|l| l.starts_with("keyboard: PS/2")),
        "the PS/2 keyboard is there: {console}"
    );
    // USB and PS/2 keys in turn; each must act exactly once, in order.
    let keys = [
        ("usb", "4"),
        ("usb", "8"),
        ("ps2", "6"),
        ("usb", "a"),
        ("usb", "left"),
        ("ps2", "2"),
        ("usb", "f1"),
    ];
    for (n, &(keyboard, key)) in keys.iter().enumerate() {
        if keyboard == "usb" {
            qemu.press_key_on(DISPLAY_ID, key).unwrap();
        } else {
            qemu.send_key(key).unwrap();
        }
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT)
            .unwrap_or_else(|e| panic!("{keyboard} key {key}: {e}"));
    }
    // A last PS/2 key: had any USB key also come through the firmware's
    // emulation, it would have taken this number.
    let last = keys.len() as u64 + 1;
    qemu.send_key("r").unwrap();
    let console = qemu
        .wait_for_serial(&line::CommandDone(last).to_string(), BOOT_TIMEOUT)
        .unwrap();
    for n in 1..=last {
        let count = console
            .lines()
            .filter(|l| line::CommandDone::parse(l) == Some(n))
            .count();
        assert_eq!(count, 1, "command {n} reported {count} times:\n{console}");
    }
    assert_eq!(commands_done(&console), last, "{console}");
}

/// Esc on a machine without isa-debug-exit (a real PC's way out): before
/// ACPI S5, the kernel halts and resets the xHCI and switches its ports off,
/// as Linux's shutdown path does, and the log says so before SLP_EN.
#[test]
fn esc_powers_off_with_the_xhci_halted_first() {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.uefi);
    options.firmware = Firmware::Uefi;
    options.board = Q35_WITHOUT_PS2;
    options.graphics = Graphics::BochsDisplay;
    options.debug_exit = false;
    options.devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        usb_keyboard("bus=xhci.0,port=1"),
    ];
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    qemu.wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    usb_escape_powers_off_with_the_xhci_halted_first(&mut qemu, DISPLAY_ID, UEFI_BOOT_TIMEOUT);
}

/// The line the kernel logs when it has set up a hot-plugged usb-kbd.
const FOUND: &str = "keyboard: USB keyboard, read by its report descriptor";

/// Plugs `keyboard` in (QMP `device_add usb-kbd`), waits for the kernel to
/// have found it for the `round`th time, and types two keys, each of which
/// must act once; returns the commands done.
fn plug_in_and_type(qemu: &mut Qemu, keyboard: &[(&str, &str)], round: usize, done: u64) -> u64 {
    qemu.device_add("usb-kbd", keyboard).unwrap();
    qemu.wait_for_serial_count(FOUND, round, BOOT_TIMEOUT)
        .unwrap();
    let done = send_and_wait_on(qemu, DISPLAY_ID, &[("6", true), ("6", false)], done, 1);
    send_and_wait_on(qemu, DISPLAY_ID, &[("4", true), ("4", false)], done, 1)
}

#[test]
fn a_usb_keyboard_plugged_in_after_boot_acts_pulled_out_and_plugged_in_again_acts_again() {
    let devices = vec!["qemu-xhci,id=xhci".to_string()];
    let (mut qemu, console) = boot_uefi_without_ps2(devices, BootRequest::default());
    assert!(
        console.contains("usb: no USB keyboard on the xHCI"),
        "{console}"
    );
    // QEMU's bus port 1 is the xHCI's first USB 2 port, after its USB 3 ones.
    const PLUGGED: &str = ": device plugged in";
    const GONE: &str = ": keyboard gone";
    let keyboard = [
        ("id", "kbd2"),
        ("bus", "xhci.0"),
        ("port", "1"),
        ("display", DISPLAY_ID),
    ];
    let mut done = 0;
    for round in 1..=2 {
        done = plug_in_and_type(&mut qemu, &keyboard, round, done);
        qemu.device_del("kbd2").unwrap();
        qemu.wait_for_serial_count(GONE, round, BOOT_TIMEOUT)
            .unwrap();
    }
    let console = qemu.serial();
    assert_eq!(console.matches(PLUGGED).count(), 2, "{console}");
    // How long each enumeration took, spread over polls, and its longest
    // step, as the kernel measured them.
    let enumerations: Vec<&str> = console
        .lines()
        .filter(|l| l.contains(": enumerated in "))
        .collect();
    assert_eq!(enumerations.len(), 2, "{console}");
    eprintln!("{}", enumerations.join("\n"));
    assert_eq!(commands_done(&console), 4, "{console}");
}

/// Hot-plug behind a hub: a hub plugged in after boot, a keyboard plugged
/// into it, pulled out and plugged in again (its keys act each time), then
/// the hub pulled out with the keyboard still in it: both are let go of.
#[test]
fn a_keyboard_plugged_into_a_hub_after_boot_acts_and_goes_with_the_hub() {
    let devices = vec!["qemu-xhci,id=xhci".to_string()];
    let (mut qemu, _) = boot_uefi_without_ps2(devices, BootRequest::default());
    const GONE: &str = ": keyboard gone";
    qemu.device_add(
        "usb-hub",
        &[("id", "hub9"), ("bus", "xhci.0"), ("port", "2")],
    )
    .unwrap();
    qemu.wait_for_serial_count(": enumerated in ", 1, BOOT_TIMEOUT)
        .unwrap();
    // Port 3 of the hub on bus port 2.
    let keyboard = [
        ("id", "kbd3"),
        ("bus", "xhci.0"),
        ("port", "2.3"),
        ("display", DISPLAY_ID),
    ];
    let mut done = 0;
    for round in 1..=2 {
        done = plug_in_and_type(&mut qemu, &keyboard, round, done);
        if round == 1 {
            qemu.device_del("kbd3").unwrap();
            qemu.wait_for_serial_count(GONE, 1, BOOT_TIMEOUT).unwrap();
        }
    }
    // The hub goes with the keyboard still in it: both let go of.
    qemu.device_del("hub9").unwrap();
    qemu.wait_for_serial_count(GONE, 2, BOOT_TIMEOUT).unwrap();
    qemu.wait_for_serial_count(": hub gone", 1, BOOT_TIMEOUT)
        .unwrap();
    let console = qemu.serial();
    let found: Vec<&str> = console.lines().filter(|l| l.contains(FOUND)).collect();
    assert_eq!(found.len(), 2, "{console}");
    assert!(
        found.iter().all(|l| l.ends_with("on xhci port 6.3")),
        "the keyboard is found behind the hub, on its port 3:\n{console}"
    );
    assert_eq!(commands_done(&console), 4, "{console}");
    assert!(!console.contains("PANIC"), "{console}");
    for line in console.lines().filter(|l| l.starts_with("usb: ")) {
        eprintln!("{line}");
    }
}

/// A qemu-xhci with 30 root ports, its 15 USB 2 ones after its 15 USB 3
/// ones (QEMU's bus port n is xHCI port 15 + n): a keyboard on bus port 9
/// hangs on root port 24, past the first 15, and its keys act.
#[test]
fn a_usb_keyboard_on_root_port_24_of_30_acts() {
    let devices = vec![
        "qemu-xhci,id=xhci,p2=15,p3=15".to_string(),
        usb_keyboard("bus=xhci.0,port=9"),
    ];
    let (mut qemu, console) = boot_uefi_without_ps2(devices, BootRequest::default());
    assert!(console.contains(", 30 ports, "), "{console}");
    let keyboard_line = usb_keyboard_line(&console);
    assert!(
        keyboard_line.ends_with(" on xhci port 24"),
        "the keyboard is on root port 24: {keyboard_line}"
    );
    let done = send_and_wait_on(&mut qemu, DISPLAY_ID, &[("6", true), ("6", false)], 0, 1);
    send_and_wait_on(&mut qemu, DISPLAY_ID, &[("4", true), ("4", false)], done, 1);
}

#[test]
fn a_usb_keyboard_behind_three_tiers_of_hubs_drives_the_demo() {
    let devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        "usb-hub,bus=xhci.0,port=1".to_string(),
        "usb-hub,bus=xhci.0,port=1.1".to_string(),
        "usb-hub,bus=xhci.0,port=1.1.1".to_string(),
        usb_keyboard("bus=xhci.0,port=1.1.1.1"),
    ];
    let (mut qemu, console) = boot_uefi_without_ps2(devices, BootRequest::default());
    let keyboard_line = usb_keyboard_line(&console);
    // The root port (QEMU's bus port 1 is the first USB 2 port, after the
    // USB 3 ones), then port 1 of each hub tier.
    let location = keyboard_line.rsplit(" on xhci port ").next().unwrap();
    assert!(
        location.ends_with(".1.1.1") && location.split('.').count() == 4,
        "the keyboard is on port 1 of the third hub: {keyboard_line}"
    );
    // The cube test's keys, each compared with the software VGA.
    usb_keys_match_the_software_vga(&mut qemu, DISPLAY_ID, &CUBE_KEYS, assert_presented);
}
