//! The device layer against the loopback controller over the device tree:
//! keyboards end to end in both protocols, hubs to five tiers, transaction
//! translators, hot-plug, a thousand plug cycles, devices that lie, stall,
//! fail or never answer, and what an idle poll costs.

use super::*;
use crate::model::devices::{UsbDevice, UsbTree};
use crate::model::loopback::Loopback;
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// Model time one poll may take: its own work, never a wait.
const POLL_MICROS_BOUND: u64 = 1_000;
/// Polls [`settle`] allows before it calls the enumeration endless.
const MOST_POLLS: u32 = 100_000;

fn bus(kind: ControllerKind, root_ports: u8) -> Bus<Loopback> {
    Bus::new(Loopback::new(kind, root_ports))
}

fn tree(bus: &mut Bus<Loopback>) -> &mut UsbTree {
    &mut bus.controller().tree
}

fn poll(bus: &mut Bus<Loopback>) -> Vec<u8> {
    let mut bytes = Vec::new();
    bus.poll(&mut |b| bytes.push(b));
    bytes
}

/// Polls a frame (1 ms of model time) apart, at least once and then until
/// nothing is left to enumerate, each poll within [`POLL_MICROS_BOUND`];
/// gives the bytes typed meanwhile.
fn settle(bus: &mut Bus<Loopback>) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut polls = 0;
    while polls == 0 || !bus.enumeration_idle() {
        polls += 1;
        assert!(
            polls < MOST_POLLS,
            "enumeration never ends: {:#?}",
            log(bus)
        );
        let before = bus.controller().now;
        bus.poll(&mut |b| bytes.push(b));
        let took = bus.controller().now - before;
        assert!(
            took <= POLL_MICROS_BOUND,
            "a poll took {took} us of model time"
        );
        bus.controller().now += 1_000;
    }
    bytes
}

/// Lets `micros` of model time pass, polling every millisecond.
fn run_for(bus: &mut Bus<Loopback>, micros: u64) -> Vec<u8> {
    let mut bytes = Vec::new();
    let end = bus.controller().now + micros;
    while bus.controller().now < end {
        bus.poll(&mut |b| bytes.push(b));
        bus.controller().now += 1_000;
    }
    bytes
}

fn log(bus: &mut Bus<Loopback>) -> Vec<String> {
    bus.controller().log.clone()
}

fn logged(bus: &mut Bus<Loopback>, text: &str) -> bool {
    bus.controller().log.iter().any(|line| line.contains(text))
}

/// Neither the loopback nor the devices saw anything a correct host never does.
fn assert_clean(bus: &mut Bus<Loopback>) {
    let errors = bus.controller().errors.clone();
    assert!(
        errors.is_empty(),
        "loopback: {errors:#?}\nlog: {:#?}",
        log(bus)
    );
    let errors: Vec<String> = tree(bus).errors().to_vec();
    assert!(
        errors.is_empty(),
        "devices: {errors:#?}\nlog: {:#?}",
        log(bus)
    );
}

fn keyboards(bus: &Bus<Loopback>) -> Vec<String> {
    bus.keyboards().map(|at| format!("{at}")).collect()
}

const LEFT: [u8; 8] = [0, 0, 0x50, 0, 0, 0, 0, 0];
const A: [u8; 8] = [0, 0, 0x04, 0, 0, 0, 0, 0];
const NOTHING: [u8; 8] = [0; 8];

#[test]
fn a_keyboard_on_a_root_port_types_set_1_bytes_and_repeats() {
    let mut bus = bus(ControllerKind::Uhci, 2);
    let keyboard = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 1, "{:#?}", log(&mut bus));
    assert_eq!(keyboards(&bus), ["1"]);
    assert_eq!(bus.kind(), ControllerKind::Uhci);
    // Configured, kept in the report protocol (its descriptor describes
    // it), at the first address.
    assert_eq!(tree(&mut bus).keyboard_state(keyboard), (1, 1, 1));
    assert_eq!(tree(&mut bus).idle(keyboard), 0);
    assert!(logged(
        &mut bus,
        "keyboard: USB keyboard, read by its report descriptor (2 key fields, 8-byte reports), on uhci port 1"
    ));
    assert_eq!(poll(&mut bus), []);
    assert!(tree(&mut bus).send_report(keyboard, LEFT));
    assert_eq!(poll(&mut bus), [0xE0, 0x4B]);
    // Held: repeats after 500 ms by the controller's clock.
    bus.controller().now += 550_000;
    assert_eq!(poll(&mut bus), [0xE0, 0x4B]);
    assert!(tree(&mut bus).send_report(keyboard, NOTHING));
    assert_eq!(poll(&mut bus), [0xE0, 0xCB]);
    bus.controller().now += 600_000;
    assert_eq!(poll(&mut bus), []);
    assert_clean(&mut bus);
}

#[test]
fn a_keyboard_whose_report_descriptor_cannot_be_read_is_put_in_the_boot_protocol() {
    let mut bus = bus(ControllerKind::Ohci, 2);
    // GET_DESCRIPTOR(report) goes to the interface: stalled, as some
    // keyboards do.
    bus.controller().stall_requests.push((0x81, GET_DESCRIPTOR));
    let keyboard = tree(&mut bus).plug(&[2], UsbDevice::Keyboard(Speed::Low));
    assert_eq!(bus.enumerate(), 1, "{:#?}", log(&mut bus));
    assert_eq!(tree(&mut bus).keyboard_state(keyboard), (0, 1, 1));
    assert!(logged(
        &mut bus,
        "usb: ohci port 2: keyboard: no report descriptor (request stalled); boot protocol"
    ));
    assert!(logged(
        &mut bus,
        "keyboard: USB keyboard, boot protocol, on ohci port 2"
    ));
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    assert!(tree(&mut bus).send_report(keyboard, NOTHING));
    assert_eq!(poll(&mut bus), [0x9E]);
    assert_clean(&mut bus);
}

#[test]
fn hubs_chain_to_five_tiers_and_the_keyboard_below_them_types() {
    let mut bus = bus(ControllerKind::Ohci, 1);
    let hub = UsbDevice::Hub {
        speed: Speed::Full,
        ports: 4,
        multi_tt: false,
    };
    let mut path = vec![1];
    for port in [4, 3, 2, 1] {
        tree(&mut bus).plug(&path, hub.clone());
        path.push(port);
    }
    tree(&mut bus).plug(&path, hub);
    path.push(4);
    let keyboard = tree(&mut bus).plug(&path, UsbDevice::Keyboard(Speed::Low));
    assert_eq!(bus.enumerate(), 1, "{:#?}", log(&mut bus));
    assert_eq!(keyboards(&bus), ["1.4.3.2.1.4"]);
    assert_eq!(bus.controller().hubs().len(), 5);
    assert_eq!(bus.devices(), 6);
    assert_eq!(bus.addresses_in_use(), 6);
    assert!(logged(
        &mut bus,
        "usb: ohci port 1.4.3.2.1: hub with 4 ports set up"
    ));
    assert!(tree(&mut bus).send_report(keyboard, LEFT));
    assert_eq!(poll(&mut bus), [0xE0, 0x4B]);
    assert_clean(&mut bus);
}

#[test]
fn translators_name_the_nearest_high_speed_hub_and_the_port_below_it() {
    let mut bus = bus(ControllerKind::Ehci, 3);
    let high_speed_hub = |multi_tt| UsbDevice::Hub {
        speed: Speed::High,
        ports: 4,
        multi_tt,
    };
    let top = tree(&mut bus).plug(&[1], high_speed_hub(false));
    let middle = tree(&mut bus).plug(&[1, 2], high_speed_hub(true));
    let full = tree(&mut bus).plug(&[1, 2, 3], UsbDevice::Keyboard(Speed::Full));
    tree(&mut bus).plug(
        &[1, 2, 4],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    let low = tree(&mut bus).plug(&[1, 2, 4, 1], UsbDevice::Keyboard(Speed::Low));
    let high = tree(&mut bus).plug(&[1, 1], UsbDevice::Keyboard(Speed::High));
    tree(&mut bus).plug(&[2], UsbDevice::Keyboard(Speed::Full));
    let root_high = tree(&mut bus).plug(&[3], UsbDevice::Keyboard(Speed::High));
    assert_eq!(bus.enumerate(), 4, "{:#?}", log(&mut bus));
    let mut found = keyboards(&bus);
    found.sort();
    assert_eq!(found, ["1.1", "1.2.3", "1.2.4.1", "3"]);
    assert!(logged(
        &mut bus,
        "usb: ehci port 2: a full- or low-speed device: handed to the companion controller"
    ));
    let address = |bus: &mut Bus<Loopback>, device| tree(bus).keyboard_state(device).2;
    let middle_address = address(&mut bus, middle);
    let translator = |port| {
        Some(TransactionTranslator {
            hub_address: middle_address,
            hub_port: port,
        })
    };
    let translators = bus.controller().translators();
    let of = |device_address: u8| {
        translators
            .iter()
            .find(|(a, _)| *a == device_address)
            .map(|(_, tt)| *tt)
    };
    assert_eq!(of(address(&mut bus, full)), Some(translator(3)));
    // Below a full-speed hub: the translator its hub is reached through.
    assert_eq!(of(address(&mut bus, low)), Some(translator(4)));
    assert_eq!(of(address(&mut bus, high)), Some(None));
    assert_eq!(of(address(&mut bus, root_high)), Some(None));
    // The multi-TT hub got its translator per port.
    let top_address = address(&mut bus, top);
    let mut hubs = bus.controller().hubs();
    hubs.sort();
    assert!(hubs.contains(&(top_address, 4, false)), "{hubs:?}");
    assert!(hubs.contains(&(middle_address, 4, true)), "{hubs:?}");
    // Every split went to that hub, and the tree (which checks each one
    // against the topology) answered them.
    let splits: Vec<_> = tree(&mut bus).splits().iter().map(|(s, _)| *s).collect();
    assert!(!splits.is_empty());
    assert!(splits
        .iter()
        .all(|s| s.hub_address == middle_address && (s.hub_port == 3 || s.hub_port == 4)));
    for (keyboard, bytes) in [
        (full, [0x1E]),
        (low, [0x1E]),
        (high, [0x1E]),
        (root_high, [0x1E]),
    ] {
        assert!(tree(&mut bus).send_report(keyboard, A));
        assert_eq!(poll(&mut bus), bytes);
        assert!(tree(&mut bus).send_report(keyboard, NOTHING));
        assert_eq!(poll(&mut bus), [0x9E]);
    }
    assert_clean(&mut bus);
}

#[test]
fn keyboards_plugged_in_and_pulled_out_at_root_and_hub_ports_come_and_go() {
    let mut bus = bus(ControllerKind::Uhci, 2);
    tree(&mut bus).plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    assert_eq!(bus.enumerate(), 0);
    settle(&mut bus);
    // Behind the hub.
    let keyboard = tree(&mut bus).plug(&[1, 3], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert_eq!(keyboards(&bus), ["1.3"]);
    assert!(logged(&mut bus, "usb: uhci port 1.3: device plugged in"));
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    // Pulled out with A held: released.
    tree(&mut bus).unplug(&[1, 3]);
    assert_eq!(settle(&mut bus), [0x9E]);
    assert_eq!(keyboards(&bus), Vec::<String>::new());
    assert!(logged(
        &mut bus,
        "usb: uhci port 1.3: keyboard gone; its keys released"
    ));
    // At the root.
    let keyboard = tree(&mut bus).plug(&[2], UsbDevice::Keyboard(Speed::Low));
    settle(&mut bus);
    assert_eq!(keyboards(&bus), ["2"]);
    assert!(tree(&mut bus).send_report(keyboard, LEFT));
    assert_eq!(poll(&mut bus), [0xE0, 0x4B]);
    tree(&mut bus).unplug(&[2]);
    assert_eq!(settle(&mut bus), [0xE0, 0xCB]);
    assert_eq!(keyboards(&bus), Vec::<String>::new());
    // The hub pulled out with a keyboard below it: both go.
    let keyboard = tree(&mut bus).plug(&[1, 1], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    tree(&mut bus).unplug(&[1]);
    assert_eq!(settle(&mut bus), [0x9E]);
    assert!(logged(&mut bus, "usb: uhci port 1: hub gone"));
    assert_eq!(bus.devices(), 0);
    assert_eq!(bus.addresses_in_use(), 0);
    assert_eq!(bus.controller().devices_open(), 0);
    assert_eq!(bus.controller().pipes_open(), 0);
    assert_clean(&mut bus);
}

#[test]
fn a_thousand_plug_cycles_leave_every_table_as_it_was() {
    let mut bus = bus(ControllerKind::Ohci, 2);
    tree(&mut bus).plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    bus.enumerate();
    settle(&mut bus);
    let tables = |bus: &mut Bus<Loopback>| {
        (
            bus.devices(),
            bus.addresses_in_use(),
            bus.controller().devices_open(),
            bus.controller().pipes_open(),
        )
    };
    let before = tables(&mut bus);
    assert_eq!(before, (1, 1, 1, 1));
    for cycle in 0..1_000u32 {
        let path = if cycle % 2 == 0 {
            vec![1, 1 + (cycle / 2 % 4) as u8]
        } else {
            vec![2]
        };
        let keyboard = tree(&mut bus).plug(&path, UsbDevice::Keyboard(Speed::Full));
        settle(&mut bus);
        assert_eq!(
            keyboards(&bus).len(),
            1,
            "cycle {cycle}: {:#?}",
            log(&mut bus)
        );
        assert!(tree(&mut bus).send_report(keyboard, A));
        assert_eq!(poll(&mut bus), [0x1E], "cycle {cycle}");
        tree(&mut bus).unplug(&path);
        assert_eq!(settle(&mut bus), [0x9E], "cycle {cycle}");
        assert_eq!(tables(&mut bus), before, "cycle {cycle}");
    }
    assert_clean(&mut bus);
}

#[test]
fn a_keyboard_whose_configuration_lies_about_its_length_is_refused() {
    let mut bus = bus(ControllerKind::Uhci, 2);
    tree(&mut bus).plug(&[1], UsbDevice::LyingKeyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 0);
    assert!(
        logged(&mut bus, "usb: uhci port 1: ")
            && logged(&mut bus, "bytes came of the")
            && logged(&mut bus, "while reading the configuration; port disabled"),
        "{:#?}",
        log(&mut bus)
    );
    assert!(!bus.controller().port_enabled(1));
    assert_eq!(bus.devices(), 0);
    assert_eq!(bus.addresses_in_use(), 0);
    assert_eq!(bus.controller().devices_open(), 0);
    // Left alone: nothing more goes to it.
    let sent = bus.controller().transactions[0];
    run_for(&mut bus, 3_000_000);
    assert_eq!(bus.controller().transactions[0], sent);
    assert_clean(&mut bus);
}

#[test]
fn a_lying_keyboard_behind_a_hub_has_its_hub_port_disabled() {
    let mut bus = bus(ControllerKind::Ohci, 1);
    let hub = tree(&mut bus).plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    tree(&mut bus).plug(&[1, 2], UsbDevice::LyingKeyboard(Speed::Low));
    assert_eq!(bus.enumerate(), 0);
    settle(&mut bus);
    assert!(
        logged(&mut bus, "usb: ohci port 1.2: "),
        "{:#?}",
        log(&mut bus)
    );
    let status = tree(&mut bus).port_status(hub, 2).unwrap();
    assert_eq!(status & 0b11, 0b01, "connected, not enabled: {status:#x}");
    assert_eq!(bus.devices(), 1);
    // Left alone until it changes: one failure said, however long it sits there.
    run_for(&mut bus, 3_000_000);
    let failures = log(&mut bus)
        .iter()
        .filter(|l| l.contains("port 1.2:") && l.contains("port disabled"))
        .count();
    assert_eq!(failures, 1);
    assert_clean(&mut bus);
}

#[test]
fn a_stalled_keyboard_has_its_halt_cleared_and_types_on() {
    let mut bus = bus(ControllerKind::Ohci, 1);
    let keyboard = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 1);
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    tree(&mut bus).stall_interrupt(keyboard);
    // Its keys are let go at the stall (their release may be lost).
    assert_eq!(run_for(&mut bus, 10_000), [0x9E]);
    assert!(logged(
        &mut bus,
        "usb: ohci port 1: keyboard: interrupt endpoint stalled; clearing the halt"
    ));
    assert!(logged(
        &mut bus,
        "usb: ohci port 1: halt cleared; recovered"
    ));
    assert!(bus.controller().calls.contains(&"interrupt_restart"));
    // The toggle starts over on both sides.
    for _ in 0..3 {
        assert!(tree(&mut bus).send_report(keyboard, LEFT));
        assert_eq!(poll(&mut bus), [0xE0, 0x4B]);
        assert!(tree(&mut bus).send_report(keyboard, NOTHING));
        assert_eq!(poll(&mut bus), [0xE0, 0xCB]);
    }
    assert_eq!(keyboards(&bus), ["1"]);
    assert_clean(&mut bus);
}

#[test]
fn a_report_sent_again_with_the_old_toggle_is_dropped() {
    let mut bus = bus(ControllerKind::Uhci, 1);
    let keyboard = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 1);
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    tree(&mut bus).repeat_next_toggle(keyboard);
    assert!(tree(&mut bus).send_report(keyboard, NOTHING));
    assert_eq!(run_for(&mut bus, 5_000), [0x9E]);
    assert_clean(&mut bus);
}

#[test]
fn errors_on_the_interrupt_pipe_are_recovered_until_they_never_stop() {
    let mut bus = bus(ControllerKind::Uhci, 1);
    let keyboard = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 1);
    // Two failed transfers (three errors each): restarted, toggle kept.
    bus.controller().interrupt_errors = 6;
    run_for(&mut bus, 10_000);
    assert!(logged(
        &mut bus,
        "usb: uhci port 1: keyboard: report failed (no response); recovering"
    ));
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(run_for(&mut bus, 2_000), [0x1E]);
    assert!(tree(&mut bus).send_report(keyboard, NOTHING));
    assert_eq!(run_for(&mut bus, 2_000), [0x9E]);
    assert_eq!(keyboards(&bus), ["1"]);
    // Errors that never stop: given up after MAX_RECOVERIES in a row.
    bus.controller().interrupt_errors = u32::MAX;
    run_for(&mut bus, 100_000);
    assert!(logged(
        &mut bus,
        "usb: uhci port 1: keyboard not recovered (no response); keyboard given up"
    ));
    assert_eq!(keyboards(&bus), Vec::<String>::new());
    assert_eq!(bus.controller().pipes_open(), 0);
    let restarts = bus
        .controller()
        .calls
        .iter()
        .filter(|c| **c == "interrupt_restart")
        .count();
    assert_eq!(restarts as u32, 2 + MAX_RECOVERIES);
    // Pulled out later: its device goes, its closed pipe is not closed again.
    bus.controller().interrupt_errors = 0;
    tree(&mut bus).unplug(&[1]);
    settle(&mut bus);
    assert_eq!(bus.devices(), 0);
    assert_eq!(bus.controller().devices_open(), 0);
    assert_clean(&mut bus);
}

/// A device that fails its first two enumerations (its device descriptor
/// stalled) is found on the third, the old scheme's first, each failure
/// said with its cause, a port reset before each try; at a root port and
/// behind a hub, on every kind of controller.
#[test]
fn a_device_that_fails_its_first_two_enumerations_is_found_on_the_third() {
    for kind in [
        ControllerKind::Uhci,
        ControllerKind::Ohci,
        ControllerKind::Ehci,
    ] {
        let mut bus = bus(kind, 2);
        let speed = if kind == ControllerKind::Ehci {
            Speed::High
        } else {
            Speed::Full
        };
        let hub = UsbDevice::Hub {
            speed,
            ports: 4,
            multi_tt: false,
        };
        let on_root = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(speed));
        tree(&mut bus).plug(&[2], hub);
        let behind_hub = tree(&mut bus).plug(&[2, 3], UsbDevice::Keyboard(Speed::Full));
        tree(&mut bus).stall_device_descriptor(on_root, 2);
        tree(&mut bus).stall_device_descriptor(behind_hub, 2);
        bus.enumerate();
        settle(&mut bus);
        assert_eq!(
            keyboards(&bus),
            ["1", "2.3"],
            "{kind}: {:#?}",
            log(&mut bus)
        );
        for at in ["1", "2.3"] {
            for (try_, scheme) in [(1, "new"), (2, "old")] {
                let said = format!(
                    "port {at}: request stalled while reading the device descriptor's first 8 bytes, try {try_} of 4"
                );
                let next = format!("the port is reset for try {} ({scheme} scheme)", try_ + 1);
                assert!(
                    log(&mut bus)
                        .iter()
                        .any(|l| l.contains(&said) && l.contains(&next)),
                    "{kind} {at} try {try_}: {:#?}",
                    log(&mut bus)
                );
            }
        }
        assert!(tree(&mut bus).send_report(behind_hub, A));
        assert_eq!(poll(&mut bus), [0x1E]);
        assert_eq!(bus.devices(), 3);
        assert_eq!(
            bus.addresses_in_use(),
            3,
            "the failed tries' addresses given back"
        );
        assert_clean(&mut bus);
    }
}

/// A device that fails every try is given up after the fourth.
#[test]
fn a_device_that_fails_four_enumerations_is_given_up() {
    let mut bus = bus(ControllerKind::Uhci, 1);
    let keyboard = tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    tree(&mut bus).stall_device_descriptor(keyboard, 4);
    bus.enumerate();
    settle(&mut bus);
    assert_eq!(keyboards(&bus), Vec::<String>::new());
    assert!(
        logged(&mut bus, "port 1: request stalled while reading the device descriptor's first 8 bytes; port disabled after 4 tries"),
        "{:#?}",
        log(&mut bus)
    );
    assert!(!bus.controller().port_enabled(1));
    assert_eq!((bus.devices(), bus.addresses_in_use()), (0, 0));
    assert_clean(&mut bus);
}

#[test]
fn a_dead_device_is_given_up_and_its_port_left_alone() {
    let mut bus = bus(ControllerKind::Uhci, 2);
    tree(&mut bus).plug(&[2], UsbDevice::Dead(Speed::Full));
    assert_eq!(bus.enumerate(), 0);
    assert!(
        logged(
            &mut bus,
            "usb: uhci port 2: control transfer failed (no response) while reading the device descriptor's first 8 bytes, try 1 of 4"
        ) && logged(
            &mut bus,
            "usb: uhci port 2: control transfer failed (no response) while setting the address; port disabled after 4 tries"
        ),
        "{:#?}",
        log(&mut bus)
    );
    assert_eq!((bus.devices(), bus.addresses_in_use()), (0, 0));
    assert_eq!(bus.controller().devices_open(), 0);
    assert!(!bus.controller().port_enabled(2));
    let sent = bus.controller().transactions[1];
    run_for(&mut bus, 10_000_000);
    let now_sent = bus.controller().transactions[1];
    assert_eq!(now_sent, sent, "{:#?}", log(&mut bus));
    assert_clean(&mut bus);
}

#[test]
fn a_control_transfer_that_never_ends_is_cancelled_after_five_seconds() {
    let mut bus = bus(ControllerKind::Ohci, 1);
    tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    bus.controller().wedged = true;
    assert_eq!(bus.enumerate(), 0);
    assert!(logged(&mut bus, "usb: ohci: boot enumeration cut short after 2000 ms, port 1 still reading the device descriptor's first 8 bytes"));
    let began = bus.controller().now;
    let started = bus
        .job
        .as_ref()
        .and_then(|job| job.control_started())
        .unwrap();
    while !logged(&mut bus, "control transfer not completed in 5000 ms") {
        assert!(
            bus.controller().now - began < 10_000_000,
            "{:#?}",
            log(&mut bus)
        );
        poll(&mut bus);
        bus.controller().now += 1_000;
    }
    // Given up at the first poll past the bound (polls are 1 ms apart).
    let waited = bus.controller().now - started;
    assert!(
        (TRANSFER_MICROS..TRANSFER_MICROS + 2_000).contains(&waited),
        "{waited} us"
    );
    let calls = &bus.controller().calls;
    let cancel = calls.iter().position(|c| *c == "control_cancel").unwrap();
    assert!(calls[cancel..].contains(&"device_remove"));
    assert!(calls[cancel..].contains(&"port_disable"));
    assert!(bus.enumeration_idle());
    assert_eq!(bus.controller().devices_open(), 0);
    assert_clean(&mut bus);
}

#[test]
fn an_idle_poll_asks_the_controller_once_and_nothing_else() {
    let mut bus = bus(ControllerKind::Ehci, 2);
    tree(&mut bus).plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 4,
            multi_tt: false,
        },
    );
    let keyboard = tree(&mut bus).plug(&[1, 4], UsbDevice::Keyboard(Speed::Full));
    assert_eq!(bus.enumerate(), 1);
    settle(&mut bus);
    bus.controller().calls.clear();
    for _ in 0..100 {
        assert_eq!(poll(&mut bus), []);
    }
    assert_eq!(bus.controller().calls, vec!["anything_happened"; 100]);
    // A key held: its repeat needs the clock, and only that.
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    bus.controller().calls.clear();
    assert_eq!(poll(&mut bus), []);
    assert_eq!(bus.controller().calls, ["anything_happened", "now_micros"]);
    assert!(tree(&mut bus).send_report(keyboard, NOTHING));
    assert_eq!(poll(&mut bus), [0x9E]);
    bus.controller().calls.clear();
    assert_eq!(poll(&mut bus), []);
    assert_eq!(bus.controller().calls, ["anything_happened"]);
    assert_clean(&mut bus);
}

#[test]
fn past_thirty_two_devices_there_is_no_room() {
    let mut bus = bus(ControllerKind::Ohci, 3);
    let hub = UsbDevice::Hub {
        speed: Speed::Full,
        ports: 15,
        multi_tt: false,
    };
    tree(&mut bus).plug(&[1], hub.clone());
    tree(&mut bus).plug(&[2], hub);
    for root in [1, 2] {
        for port in 1..=15 {
            tree(&mut bus).plug(&[root, port], UsbDevice::Keyboard(Speed::Low));
        }
    }
    bus.enumerate();
    settle(&mut bus);
    assert_eq!(bus.devices(), MAX_DEVICES);
    assert_eq!(keyboards(&bus).len(), 30);
    tree(&mut bus).plug(&[3], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert!(
        logged(&mut bus, "usb: ohci port 3: no room: 32 devices kept already while recovering from the reset; port disabled"),
        "{:#?}",
        log(&mut bus)
    );
    assert_eq!(bus.devices(), MAX_DEVICES);
    // Room made: the keyboard is found when it is plugged in again.
    tree(&mut bus).unplug(&[2, 15]);
    settle(&mut bus);
    tree(&mut bus).unplug(&[3]);
    settle(&mut bus);
    let keyboard = tree(&mut bus).plug(&[3], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert!(keyboards(&bus).contains(&String::from("3")));
    assert!(tree(&mut bus).send_report(keyboard, A));
    assert_eq!(poll(&mut bus), [0x1E]);
    assert_clean(&mut bus);
}

#[test]
fn a_connection_that_never_settles_is_dropped_after_two_seconds() {
    let mut bus = bus(ControllerKind::Uhci, 1);
    bus.enumerate();
    let began = bus.controller().now;
    let mut plugged = false;
    while !logged(
        &mut bus,
        "usb: uhci port 1: connection never settled within 2000 ms",
    ) {
        assert!(
            bus.controller().now - began < 3_000_000,
            "{:#?}",
            log(&mut bus)
        );
        if plugged {
            tree(&mut bus).unplug(&[1]);
        } else {
            tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
        }
        plugged = !plugged;
        run_for(&mut bus, 40_000);
    }
    if !plugged {
        tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
        plugged = true;
        run_for(&mut bus, 1_000);
    }
    assert!(plugged);
    // Still, now, but left until it changes again.
    run_for(&mut bus, 1_000_000);
    assert_eq!(keyboards(&bus), Vec::<String>::new());
    assert!(bus.enumeration_idle());
    tree(&mut bus).unplug(&[1]);
    run_for(&mut bus, 10_000);
    tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert_eq!(keyboards(&bus), ["1"]);
    assert_clean(&mut bus);
}

#[test]
fn a_hub_pulled_out_during_an_enumeration_below_it_stops_it() {
    let mut bus = bus(ControllerKind::Ohci, 1);
    tree(&mut bus).plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    tree(&mut bus).plug(&[1, 2], UsbDevice::Keyboard(Speed::Full));
    bus.scan_at = Some(0);
    let below = Location::root(1).below(2);
    let mut polls = 0;
    while bus.job.as_ref().map(|job| (Some(job.location), job.step))
        != Some((below, enumeration::Step::ReadingConfiguration))
    {
        polls += 1;
        assert!(polls < MOST_POLLS, "{:#?}", log(&mut bus));
        poll(&mut bus);
        bus.controller().now += 1_000;
    }
    tree(&mut bus).unplug(&[1]);
    settle(&mut bus);
    assert!(logged(&mut bus, "usb: ohci port 1.2: the device went away while reading the configuration; enumeration stopped"));
    assert_eq!(bus.devices(), 0);
    assert_eq!(bus.addresses_in_use(), 0);
    assert_eq!(bus.controller().devices_open(), 0);
    assert_eq!(bus.controller().pipes_open(), 0);
    assert!(bus.controller().calls.contains(&"control_cancel"));
    assert_clean(&mut bus);
}

#[test]
fn a_device_pulled_out_during_its_root_port_reset_has_the_reset_ended() {
    let mut bus = bus(ControllerKind::Uhci, 1);
    tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    bus.scan_at = Some(0);
    while bus.job.as_ref().map(|job| job.step) != Some(enumeration::Step::ResettingRootPort) {
        poll(&mut bus);
        bus.controller().now += 1_000;
    }
    tree(&mut bus).unplug(&[1]);
    settle(&mut bus);
    let calls = &bus.controller().calls;
    let begun = calls.iter().filter(|c| **c == "port_reset_begin").count();
    assert_eq!(begun, 1);
    assert!(
        !bus.controller().resetting(1),
        "the reset was polled to its end"
    );
    assert_eq!(bus.controller().devices_open(), 0);
    // Plugged in again: found.
    tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::Full));
    settle(&mut bus);
    assert_eq!(keyboards(&bus), ["1"]);
    assert_clean(&mut bus);
}

#[test]
fn shut_down_halts_the_controller_and_touches_it_no_more() {
    let mut bus = bus(ControllerKind::Ehci, 1);
    tree(&mut bus).plug(&[1], UsbDevice::Keyboard(Speed::High));
    assert_eq!(bus.enumerate(), 1);
    assert!(bus.shut_down());
    assert!(bus.controller().halted);
    bus.controller().calls.clear();
    poll(&mut bus);
    assert!(bus.controller().calls.is_empty());
    assert_eq!(keyboards(&bus), Vec::<String>::new());
}

#[test]
fn locations_read_as_the_ports_down_from_the_root() {
    let root = Location::root(1);
    let below = root.below(3).and_then(|hub| hub.below(2)).unwrap();
    assert_eq!(format!("{root}"), "1");
    assert_eq!(format!("{below}"), "1.3.2");
    assert_eq!(below.hub_ports(), [3, 2]);
    assert_eq!((below.root_port(), below.depth(), below.port()), (1, 2, 2));
    assert_eq!(below.hub(), root.below(3));
    assert!(root.holds(below) && !below.holds(root) && below.holds(below));
    assert!(!Location::root(2).holds(below));
    assert!(!root.below(2).unwrap().holds(below));
    let mut deepest = root;
    for port in 1..=5 {
        deepest = deepest.below(port).unwrap();
    }
    assert_eq!(format!("{deepest}"), "1.1.2.3.4.5");
    assert_eq!(deepest.below(1), None);
}

#[test]
fn packets_make_reports_by_their_id_and_one_too_long_is_dropped_whole() {
    use crate::model::devices::ROLLOVER_REPORT_DESCRIPTOR;
    // The rollover keyboard's keys as report 1, and a 100-byte vendor
    // report 2 beside them.
    let mut descriptor = ROLLOVER_REPORT_DESCRIPTOR[..6].to_vec();
    descriptor.extend([0x85, 0x01]);
    descriptor.extend(&ROLLOVER_REPORT_DESCRIPTOR[6..44]);
    descriptor.extend([0x85, 0x02, 0x06, 0x00, 0xFF, 0x09, 0x01]);
    descriptor.extend([
        0x15, 0x00, 0x25, 0x01, 0x75, 0x08, 0x95, 100, 0x81, 0x02, 0xC0,
    ]);
    let layout = crate::hid::parse(&descriptor).expect("parses");
    assert_eq!(
        (layout.report_length(1), layout.report_length(2)),
        (21, 101)
    );
    assert_eq!(layout.report_length(9), 101, "an unknown ID: the longest");
    let format = ReportFormat::Described(layout);
    let mut packets = Packets::new(8);
    let mut take = |packet: &[u8]| match packets.take(packet, &format) {
        Assembled::Pending => None,
        Assembled::Report(length) => Some(Ok(length)),
        Assembled::TooLong(length) => Some(Err(length)),
    };
    // Report 2: thirteen packets, the last of 5 bytes, dropped whole.
    let mut vendor = [0xAA; 101];
    vendor[0] = 2;
    let ends: Vec<_> = vendor.chunks(8).map(&mut take).collect();
    assert_eq!(ends[..12], [None; 12]);
    assert_eq!(ends[12], Some(Err(101)));
    // Report 1 after it: 21 bytes in three packets.
    let mut keys = [0u8; 21];
    keys[0] = 1;
    let ends: Vec<_> = keys.chunks(8).map(&mut take).collect();
    assert_eq!(ends, [None, None, Some(Ok(21))]);
    // A zero-length packet between reports is nothing; a short packet
    // ends a report early (the decoder then finds it too short).
    assert_eq!(take(&[]), None);
    assert_eq!(take(&[1, 0, 0]), Some(Ok(3)));
}
