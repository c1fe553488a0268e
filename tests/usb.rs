//! A USB keyboard through the xHCI controller, in QEMU. Four boots:
//!
//! - OVMF on a Q35 without an i8042 or a PIT (a UEFI-only desktop), the keyboard
//!   behind a `usb-hub`: the cube test's key sequence gives the software
//!   VGA's picture after each key, a held key repeats, a flood of 2,000 keys
//!   arrives exactly once each, R restores the starting picture, and Esc
//!   says goodbye.
//! - SeaBIOS on a PC with both a PS/2 and a USB keyboard: keys sent to the
//!   USB keyboard alone act exactly once each (the firmware's own USB
//!   keyboard support is gone once the kernel has the controller), and PS/2
//!   keys act too.
//! - OVMF with the keyboard behind three tiers of `usb-hub`: the cube
//!   test's keys give the software VGA's pictures.
//! - OVMF with no keyboard at boot: one plugged in with QMP `device_add`
//!   after `screen: ready` is found and its keys act; pulled out
//!   (`device_del`) it is let go of; plugged in again its keys act again.
//!
//! Keys reach the USB keyboard alone because it is bound to the display
//! (`display=video0`) and sent there (`Qemu::press_key_on`); `sendkey`
//! reaches the PS/2 keyboard.

mod common;

use boot::qemu::{DISPLAY_ID, EXIT_SUCCESS};
use boot::{line, Board, Chipset, Firmware, Graphics, Qemu, QemuOptions};
use common::{
    assert_pictures_equal, model_picture, presented, soft_vga_in_mode_x, BOOT_TIMEOUT, CUBE_KEYS,
};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use modex::ModeX;
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
/// Keys in the flood.
const FLOOD_KEYS: usize = 2000;
/// QEMU's usb-hid queues 16 PS/2 scancodes (an E0 key's event takes two)
/// and drops an event that does not fit: the flood is sent in bursts that
/// fit, each sent when the last has been acted on.
const HID_QUEUE_SCANCODES: usize = 16;

/// Scancodes an event of `key` takes in QEMU's usb-hid queue: two for the
/// keys PS/2 sends with an E0 prefix (the project's one key table says which).
fn queue_cost(key: &str) -> usize {
    keyboard::keys::scancode_for_name(key)
        .unwrap_or_else(|| panic!("{key:?} is not a key name"))
        .make()
        .len()
}

/// The USB keyboard, bound to the display so that keys can be sent to it alone.
fn usb_keyboard(bus: &str) -> String {
    format!("usb-kbd,id=usbkbd,display={DISPLAY_ID},{bus}")
}

fn start(firmware: Firmware, graphics: Graphics, board: Board, devices: Vec<String>) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let image = match firmware {
        Firmware::Bios => images.bios,
        Firmware::Uefi => images.uefi,
    };
    let mut options = QemuOptions::new(image);
    options.firmware = firmware;
    options.board = board;
    options.graphics = graphics;
    options.devices = devices;
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

/// The count in the kernel's last "demo: command N done" line.
fn commands_done(console: &str) -> u64 {
    console
        .lines()
        .rev()
        .find_map(line::CommandDone::parse)
        .unwrap_or(0)
}

/// Sends key events to the USB keyboard and waits until the demo has acted
/// on `commands` more keys than `done`; returns the new count.
fn send_and_wait(qemu: &mut Qemu, events: &[(&str, bool)], done: u64, commands: u64) -> u64 {
    qemu.key_events_on(DISPLAY_ID, events).unwrap();
    let target = done + commands;
    qemu.wait_for_serial(&line::CommandDone(target).to_string(), BOOT_TIMEOUT)
        .unwrap();
    target
}

/// One flood key: the events it sends and the commands it gives (a
/// modifier alone gives none; with a key, one).
fn flood_key(index: usize, state: &mut u64) -> (Vec<(&'static str, bool)>, u64) {
    /// Keys that are each one command and never pause the demo (a pause
    /// swallows the next key): digits, letters, E0 keys, the keypad with
    /// Num Lock on, function keys.
    const KEYS: &[&str] = &[
        "4", "6", "8", "2", "a", "t", "left", "right", "up", "down", "home", "end", "pgup", "pgdn",
        "f1", "f2", "kp_4", "kp_6", "kp_8", "kp_2", "spc", "l", "n", "m", "r",
    ];
    *state ^= *state << 13;
    *state ^= *state >> 7;
    *state ^= *state << 17;
    let key = KEYS[(*state % KEYS.len() as u64) as usize];
    // Letters whose capital is the same command (a shifted digit is a
    // symbol, which pauses).
    const LETTERS: &[&str] = &["a", "t", "l", "n", "m"];
    let letter = LETTERS[(*state % LETTERS.len() as u64) as usize];
    match index % 50 {
        // A key with a modifier held around it.
        17 => (
            vec![
                ("shift", true),
                (letter, true),
                (letter, false),
                ("shift", false),
            ],
            1,
        ),
        33 => (
            vec![
                ("shift_r", true),
                (letter, true),
                (letter, false),
                ("shift_r", false),
            ],
            1,
        ),
        // A modifier alone is no command.
        49 => (vec![("alt", true), ("alt", false)], 0),
        _ => (vec![(key, true), (key, false)], 1),
    }
}

#[test]
fn a_usb_keyboard_behind_a_hub_drives_the_demo_on_a_uefi_machine_without_ps2() {
    // A PC of today: no i8042, and no PIT either (recent Intel platforms
    // gate its clock), so the kernel idles without `hlt` and polls.
    let board = Board {
        chipset: Chipset::Q35,
        pit: false,
        i8042: false,
        hpet: true,
    };
    let devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        "usb-hub,id=hub,bus=xhci.0,port=1".to_string(),
        usb_keyboard("bus=xhci.0,port=1.1"),
    ];
    let mut qemu = start(Firmware::Uefi, Graphics::BochsDisplay, board, devices);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    // No PS/2 here: the ACPI tables say so, or the controller does not answer.
    assert!(
        console.contains("keyboard: PS/2 controller did not answer")
            || console.contains("keyboard: the ACPI tables say there is no PS/2 controller"),
        "{console}"
    );
    assert!(console.contains("usb: xHCI 1b36:000d at "), "{console}");
    let keyboard_line = console
        .lines()
        .find(|l| l.starts_with("keyboard: USB keyboard, read by its report descriptor "))
        .unwrap_or_else(|| panic!("no USB keyboard found:\n{console}"));
    assert!(
        keyboard_line.ends_with(".1"),
        "the keyboard is on the hub's port 1: {keyboard_line}"
    );

    // The cube test's keys, each compared with the software VGA.
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    let mut done = 0;
    for (n, &(key, command)) in CUBE_KEYS.iter().enumerate() {
        done = send_and_wait(&mut qemu, &[(key, true), (key, false)], done, 1);
        app.apply(command);
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        let screen = qemu.screendump().unwrap();
        let expected = presented(&model_picture(&soft), screen.width, screen.height);
        assert_pictures_equal(&screen, &expected, &format!("usb key {} ({key})", n + 1));
    }

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
    // Any key resumes (and is swallowed).
    done = send_and_wait(&mut qemu, &[("q", true), ("q", false)], done, 1);

    // The flood, in bursts QEMU's queue holds, each key acted on once.
    let started = std::time::Instant::now();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut burst: Vec<(&str, bool)> = Vec::new();
    let mut burst_commands = 0;
    let cost = |events: &[(&str, bool)]| {
        events
            .iter()
            .map(|&(key, _)| queue_cost(key))
            .sum::<usize>()
    };
    for index in 0..FLOOD_KEYS {
        let (events, commands) = flood_key(index, &mut state);
        // The last burst's final releases may still be queued when its last
        // key has acted: room is left for them.
        if cost(&burst) + cost(&events) > HID_QUEUE_SCANCODES - 4 {
            done = send_and_wait(&mut qemu, &burst, done, burst_commands);
            burst.clear();
            burst_commands = 0;
        }
        burst.extend(events);
        burst_commands += commands;
    }
    done = send_and_wait(&mut qemu, &burst, done, burst_commands);
    println!("{FLOOD_KEYS} keys over USB in {:.1?}", started.elapsed());
    let console = qemu.serial();
    assert_eq!(commands_done(&console), done, "a key acted twice");
    assert!(
        !console.contains("EXCEPTION") && !console.contains("PANIC"),
        "{console}"
    );
    let last_command = console
        .lines()
        .rev()
        .find(|l| line::CommandDone::parse(l).is_some())
        .unwrap_or_default();
    assert!(
        last_command.ends_with("scancodes dropped=0"),
        "{last_command}"
    );

    // R brings back the starting picture.
    send_and_wait(&mut qemu, &[("r", true), ("r", false)], done, 1);
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let screen = qemu.screendump().unwrap();
    let expected = presented(&model_picture(&soft), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, "usb flood then r");

    // Esc says goodbye.
    qemu.press_key_on(DISPLAY_ID, "esc").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("QEMU powered off after Esc: {e}"));
    assert_eq!(status.code(), Some(EXIT_SUCCESS));
    assert!(qemu.serial().contains(line::GOODBYE));
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
    let board = Board {
        chipset: Chipset::Q35,
        pit: false,
        i8042: false,
        hpet: true,
    };
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.uefi);
    options.firmware = Firmware::Uefi;
    options.board = board;
    options.graphics = Graphics::BochsDisplay;
    options.debug_exit = false;
    options.devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        usb_keyboard("bus=xhci.0,port=1"),
    ];
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    qemu.wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    qemu.press_key_on(DISPLAY_ID, "esc").unwrap();
    let status = qemu
        .wait_exit(UEFI_BOOT_TIMEOUT)
        .unwrap()
        .unwrap_or_else(|| panic!("still running after Esc:\n{}", qemu.serial()));
    let console = qemu.serial();
    let halted = console
        .find("usb: xHCI 1b36:000d at ")
        .and_then(|_| console.find(" halted and reset, ports switched off"))
        .unwrap_or_else(|| panic!("the xHCI was not shut down:\n{console}"));
    let switching_off = console
        .find("power: switching off (ACPI S5")
        .unwrap_or_else(|| panic!("no ACPI S5:\n{console}"));
    assert!(
        halted < switching_off,
        "the xHCI is shut down before SLP_EN:\n{console}"
    );
    assert!(console.contains(line::GOODBYE), "{console}");
    assert_eq!(status.code(), Some(0), "{console}");
}

#[test]
fn a_usb_keyboard_plugged_in_after_boot_acts_pulled_out_and_plugged_in_again_acts_again() {
    let board = Board {
        chipset: Chipset::Q35,
        pit: false,
        i8042: false,
        hpet: true,
    };
    let devices = vec!["qemu-xhci,id=xhci".to_string()];
    let mut qemu = start(Firmware::Uefi, Graphics::BochsDisplay, board, devices);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("usb: no USB keyboard on the xHCI"),
        "{console}"
    );
    const FOUND: &str = "keyboard: USB keyboard, read by its report descriptor";
    // QEMU's bus port 1 is the xHCI's first USB 2 port, after its USB 3 ones.
    const PLUGGED: &str = ": device plugged in";
    const GONE: &str = ": device gone";
    let keyboard = [
        ("id", "kbd2"),
        ("bus", "xhci.0"),
        ("port", "1"),
        ("display", DISPLAY_ID),
    ];
    let mut done = 0;
    for round in 1..=2 {
        qemu.device_add("usb-kbd", &keyboard).unwrap();
        qemu.wait_for_serial_count(FOUND, round, BOOT_TIMEOUT)
            .unwrap();
        // Each key acts once: two keys, two commands.
        done = send_and_wait(&mut qemu, &[("6", true), ("6", false)], done, 1);
        done = send_and_wait(&mut qemu, &[("4", true), ("4", false)], done, 1);
        qemu.device_del("kbd2").unwrap();
        qemu.wait_for_serial_count(GONE, round, BOOT_TIMEOUT)
            .unwrap();
    }
    let console = qemu.serial();
    assert_eq!(console.matches(PLUGGED).count(), 2, "{console}");
    // What each enumeration held the frame loop up for, as the kernel measured it.
    let enumerations: Vec<&str> = console
        .lines()
        .filter(|l| l.contains(": enumerated in "))
        .collect();
    assert_eq!(enumerations.len(), 2, "{console}");
    eprintln!("{}", enumerations.join("\n"));
    assert_eq!(commands_done(&console), 4, "{console}");
}

#[test]
fn a_usb_keyboard_behind_three_tiers_of_hubs_drives_the_demo() {
    let board = Board {
        chipset: Chipset::Q35,
        pit: false,
        i8042: false,
        hpet: true,
    };
    let devices = vec![
        "qemu-xhci,id=xhci".to_string(),
        "usb-hub,bus=xhci.0,port=1".to_string(),
        "usb-hub,bus=xhci.0,port=1.1".to_string(),
        "usb-hub,bus=xhci.0,port=1.1.1".to_string(),
        usb_keyboard("bus=xhci.0,port=1.1.1.1"),
    ];
    let mut qemu = start(Firmware::Uefi, Graphics::BochsDisplay, board, devices);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    let keyboard_line = console
        .lines()
        .find(|l| l.starts_with("keyboard: USB keyboard, read by its report descriptor "))
        .unwrap_or_else(|| panic!("no USB keyboard found:\n{console}"));
    // The root port (QEMU's bus port 1 is the first USB 2 port, after the
    // USB 3 ones), then port 1 of each hub tier.
    let location = keyboard_line.rsplit(" on port ").next().unwrap();
    assert!(
        location.ends_with(".1.1.1") && location.split('.').count() == 4,
        "the keyboard is on port 1 of the third hub: {keyboard_line}"
    );
    // The cube test's keys, each compared with the software VGA.
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    let mut done = 0;
    for (n, &(key, command)) in CUBE_KEYS.iter().enumerate() {
        done = send_and_wait(&mut qemu, &[(key, true), (key, false)], done, 1);
        app.apply(command);
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        let screen = qemu.screendump().unwrap();
        let expected = presented(&model_picture(&soft), screen.width, screen.height);
        assert_pictures_equal(&screen, &expected, &format!("usb key {} ({key})", n + 1));
    }
}
