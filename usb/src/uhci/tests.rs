//! The UHCI driver against its register model and the shared device tree:
//! keyboards through the device layer ([`Bus`]) on a root port and behind
//! a hub, and the driver's own calls for what the device layer hides
//! (reports one by one, toggles, stalls, plug cycles, the BIOS, halting,
//! the idle poll's cost, registers that lie).

use super::{
    Uhci, UhciError, DMA_BYTES_NEEDED, FRAME_WAIT_MICROS, HALT_MICROS, HANDOFF_MICROS,
    HOST_RESET_MICROS, MAX_DEVICES, MAX_PIPES, PORT_CHECK_EVERY, PORT_ENABLE_MICROS,
};
use crate::bus::Bus;
use crate::host::{
    DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, ResetOutcome, Setup, Speed,
    Transfer, TransferError, ROOT_RESET_MICROS,
};
use crate::model::devices::{UsbDevice, KEYBOARD_DEVICE, LOW_SPEED_KEYBOARD_DEVICE};
use crate::model::uhci::{UhciModel, BIOS_LEGSUP, DMA_BASE, DMA_BYTES};
use std::vec;
use std::vec::Vec;

const KEY_A: [u8; 8] = [0, 0, 0x04, 0, 0, 0, 0, 0];
const KEY_B: [u8; 8] = [0, 0, 0x05, 0, 0, 0, 0, 0];
const RELEASED: [u8; 8] = [0; 8];

fn driver(model: UhciModel) -> Uhci<UhciModel> {
    Uhci::new(model, DMA_BASE, DMA_BYTES).unwrap()
}

/// A controller taken from the firmware, reset and running.
fn started(model: UhciModel) -> Uhci<UhciModel> {
    let mut uhci = driver(model);
    uhci.take_ownership();
    uhci.reset_and_start().unwrap();
    uhci
}

/// Nothing the model or the devices saw was wrong.
fn assert_clean(model: &UhciModel) {
    assert!(model.errors.is_empty(), "model: {:#?}", model.errors);
    assert!(
        model.tree.errors().is_empty(),
        "devices: {:#?}",
        model.tree.errors()
    );
}

/// Lets `micros` of model time pass.
fn wait(uhci: &mut Uhci<UhciModel>, micros: u64) {
    uhci.hardware().now += micros;
}

/// A whole control transfer, the model's clock moved on a frame per poll.
fn control(
    uhci: &mut Uhci<UhciModel>,
    device: DeviceId,
    setup: Setup,
    out: &[u8],
    into: &mut [u8],
) -> Transfer {
    uhci.control_begin(device, setup, out).unwrap();
    for _ in 0..100 {
        wait(uhci, 1_000);
        match uhci.control_poll(device, into) {
            Transfer::Pending => {}
            done => return done,
        }
    }
    panic!(
        "control transfer {setup:?} never ended: {:?}",
        uhci.hardware().log
    );
}

fn get_descriptor(kind: u8, length: u16) -> Setup {
    Setup {
        request_type: 0x80,
        request: 6,
        value: u16::from(kind) << 8,
        index: 0,
        length,
    }
}

fn set_request(request: u8, value: u16) -> Setup {
    Setup {
        request_type: 0,
        request,
        value,
        index: 0,
        length: 0,
    }
}

/// Resets root port `port` as the device layer does.
fn reset_port(uhci: &mut Uhci<UhciModel>, port: u8) -> ResetOutcome {
    crate::model::reset_root_port(uhci, port)
}

/// What the device layer does for a boot keyboard on root port `port`,
/// done by hand: reset, address, configuration, boot protocol, its pipe.
fn keyboard_by_hand(uhci: &mut Uhci<UhciModel>, port: u8, address: u8) -> (DeviceId, PipeId) {
    let ResetOutcome::Enabled(speed) = reset_port(uhci, port) else {
        panic!("port {port} did not enable: {:?}", uhci.hardware().log);
    };
    let device = uhci
        .device_new(DeviceInfo {
            route: Some(0),
            speed,
            root_port: port,
            translator: None,
        })
        .unwrap();
    let mut buffer = [0; 18];
    let got = control(uhci, device, get_descriptor(1, 8), &[], &mut buffer);
    assert_eq!(got, Transfer::Complete(8));
    uhci.device_set_max_packet(device, u16::from(buffer[7]))
        .unwrap();
    let got = control(uhci, device, set_request(5, address.into()), &[], &mut []);
    assert_eq!(got, Transfer::Complete(0));
    uhci.device_set_address(device, address).unwrap();
    wait(uhci, 2_000);
    let got = control(uhci, device, set_request(9, 1), &[], &mut []);
    assert_eq!(got, Transfer::Complete(0));
    let set_protocol = Setup {
        request_type: 0x21,
        request: 0x0B,
        value: 0,
        index: 0,
        length: 0,
    };
    let got = control(uhci, device, set_protocol, &[], &mut []);
    assert_eq!(got, Transfer::Complete(0));
    let pipe = uhci.interrupt_open(device, 1, 8, 10).unwrap();
    (device, pipe)
}

/// Polls the pipe a frame apart until a report comes (at most `frames`).
fn next_report(uhci: &mut Uhci<UhciModel>, pipe: PipeId, frames: u32) -> Option<Transfer> {
    let mut report = [0; 8];
    for _ in 0..frames {
        wait(uhci, 1_000);
        match uhci.interrupt_poll(pipe, &mut report) {
            Transfer::Pending => {}
            Transfer::Complete(n) => {
                assert_eq!(n, 8);
                return Some(Transfer::Complete(usize::from(report[2])));
            }
            other => return Some(other),
        }
    }
    None
}

/// A keyboard's reports, each given as the key code it holds (byte 2).
fn reports(uhci: &mut Uhci<UhciModel>, pipe: PipeId, frames: u32) -> Vec<u8> {
    let mut keys = Vec::new();
    while let Some(got) = next_report(uhci, pipe, frames) {
        match got {
            Transfer::Complete(key) => keys.push(key as u8),
            other => panic!("{other:?}"),
        }
    }
    keys
}

fn bus_with(model: UhciModel) -> Bus<Uhci<UhciModel>> {
    Bus::new(started(model))
}

/// Polls the device layer a frame apart; the set-1 bytes typed.
fn typed(bus: &mut Bus<Uhci<UhciModel>>, frames: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    for _ in 0..frames {
        bus.controller().hardware().now += 1_000;
        bus.poll(&mut |b| bytes.push(b));
    }
    bytes
}

// ---------------------------------------------------------------------------
// Through the device layer.

#[test]
fn a_keyboard_on_a_root_port_types_through_the_device_layer() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1, "{:?}", bus.controller().hardware().log);
    let model = bus.controller().hardware();
    let (_, configuration, address) = model.tree.keyboard_state(keyboard);
    assert_eq!(configuration, 1);
    assert_ne!(address, 0);
    assert!(model.tree.send_report(keyboard, KEY_A));
    assert!(model.tree.send_report(keyboard, RELEASED));
    assert_eq!(typed(&mut bus, 100), [0x1E, 0x9E]);
    assert_clean(bus.controller().hardware());
}

#[test]
fn a_low_speed_keyboard_is_reached_with_the_ls_bit() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[2], UsbDevice::Keyboard(Speed::Low));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1, "{:?}", bus.controller().hardware().log);
    let model = bus.controller().hardware();
    assert!(model.tree.send_report(keyboard, KEY_B));
    assert!(model.tree.send_report(keyboard, RELEASED));
    assert_eq!(typed(&mut bus, 100), [0x30, 0xB0]);
    assert_clean(bus.controller().hardware());
}

#[test]
fn a_connect_change_the_port_reset_makes_is_not_a_new_device() {
    // Bochs 2.7's UHCI (and its EHCI's UHCI companions) sets Connect
    // Status Change as the reset starts: the device is still there, and
    // is found at boot, not taken for one plugged in again.
    let mut model = UhciModel::new(2);
    model.reset_sets_connect_change = true;
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Low));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1, "{:?}", bus.controller().hardware().log);
    let model = bus.controller().hardware();
    assert!(
        !model.log.iter().any(|line| line.contains("went away")),
        "{:?}",
        model.log
    );
    assert!(
        model
            .log
            .iter()
            .any(|line| line.starts_with("usb: uhci port 1: enumerated in ")
                && line.contains(" us at low speed, ")),
        "{:?}",
        model.log
    );
    assert!(model.tree.send_report(keyboard, KEY_B));
    assert!(model.tree.send_report(keyboard, RELEASED));
    assert_eq!(typed(&mut bus, 100), [0x30, 0xB0]);
    assert_clean(bus.controller().hardware());
}

#[test]
fn keyboards_behind_a_hub_type_through_the_device_layer() {
    let mut model = UhciModel::new(2);
    model.plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    let low = model.plug(&[1, 2], UsbDevice::Keyboard(Speed::Low));
    let full = model.plug(&[1, 4], UsbDevice::Keyboard(Speed::Full));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 2, "{:?}", bus.controller().hardware().log);
    let model = bus.controller().hardware();
    assert!(model.tree.send_report(low, KEY_A));
    assert!(model.tree.send_report(low, RELEASED));
    let mut bytes = typed(&mut bus, 100);
    let model = bus.controller().hardware();
    assert!(model.tree.send_report(full, KEY_B));
    assert!(model.tree.send_report(full, RELEASED));
    bytes.extend(typed(&mut bus, 100));
    assert_eq!(bytes, [0x1E, 0x9E, 0x30, 0xB0]);
    assert_clean(bus.controller().hardware());
}

#[test]
fn a_keyboard_plugged_pulled_and_plugged_again_is_found_each_time() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1);
    for round in 0..5 {
        bus.controller().hardware().unplug(&[1]);
        typed(&mut bus, 300);
        assert_eq!(bus.keyboards().count(), 0, "round {round}");
        let keyboard = bus
            .controller()
            .hardware()
            .plug(&[1], UsbDevice::Keyboard(Speed::Full));
        typed(&mut bus, 500);
        assert_eq!(
            bus.keyboards().count(),
            1,
            "round {round}: {:?}",
            bus.controller().hardware().log
        );
        let model = bus.controller().hardware();
        assert!(model.tree.send_report(keyboard, KEY_A));
        assert!(model.tree.send_report(keyboard, RELEASED));
        assert_eq!(typed(&mut bus, 100), [0x1E, 0x9E], "round {round}");
    }
    assert_eq!(bus.controller().slots_in_use(), (1, 1));
    assert_clean(bus.controller().hardware());
}

#[test]
fn the_device_layer_shuts_the_controller_down() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1);
    assert!(bus.shut_down());
    let model = bus.controller().hardware();
    assert_ne!(model.usbsts() & 0x20, 0, "HCHalted");
    assert_eq!(model.usbcmd() & 1, 0, "Run/Stop");
    assert_clean(model);
}

// ---------------------------------------------------------------------------
// The driver's own calls.

#[test]
fn the_device_descriptor_is_read_whatever_the_packet_size_and_length() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Full));
    let device = uhci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    // 8 bytes: one data TD. 18: 8 + 8 + 2. 64 and 255: the device's short
    // packet of 2 ends the data stage early (short packet detect).
    for length in [8u16, 18, 64, 255] {
        let mut buffer = [0xEE; 255];
        let got = control(
            &mut uhci,
            device,
            get_descriptor(1, length),
            &[],
            &mut buffer,
        );
        let expected = usize::from(length).min(18);
        assert_eq!(got, Transfer::Complete(expected), "wLength {length}");
        assert_eq!(buffer[..expected], KEYBOARD_DEVICE[..expected]);
        assert!(buffer[expected..].iter().all(|&b| b == 0xEE));
    }
    // A buffer shorter than the data: only what fits is copied.
    let mut short = [0; 4];
    let got = control(&mut uhci, device, get_descriptor(1, 18), &[], &mut short);
    assert_eq!(got, Transfer::Complete(4));
    assert_eq!(short, KEYBOARD_DEVICE[..4]);
    assert_clean(uhci.hardware());
}

#[test]
fn reports_arrive_each_once_and_in_order() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (_, pipe) = keyboard_by_hand(&mut uhci, 1, 1);
    let keys = [4u8, 5, 6, 7, 8, 9, 10];
    for key in keys {
        let report = [0, 0, key, 0, 0, 0, 0, 0];
        assert!(uhci.hardware().tree.send_report(keyboard, report));
    }
    assert_eq!(reports(&mut uhci, pipe, 40), keys);
    assert_eq!(uhci.hardware().toggle_mismatches, 0);
    assert_clean(uhci.hardware());
}

#[test]
fn a_low_speed_keyboard_on_a_root_port_works_by_hand() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Low));
    let mut uhci = started(model);
    let (device, pipe) = keyboard_by_hand(&mut uhci, 1, 9);
    let mut buffer = [0; 18];
    let got = control(&mut uhci, device, get_descriptor(1, 18), &[], &mut buffer);
    assert_eq!(got, Transfer::Complete(18));
    assert_eq!(buffer, LOW_SPEED_KEYBOARD_DEVICE);
    // Low speed takes no packet size but 8, and no report over 8 bytes.
    assert_eq!(
        uhci.device_set_max_packet(device, 64),
        Err(HostError::Invalid)
    );
    assert_eq!(
        uhci.interrupt_open(device, 2, 16, 10),
        Err(HostError::Invalid)
    );
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_A));
    assert_eq!(reports(&mut uhci, pipe, 40), [4]);
    assert_clean(uhci.hardware());
}

#[test]
fn a_repeated_report_with_the_old_toggle_is_dropped_and_the_toggles_stay_in_step() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (_, pipe) = keyboard_by_hand(&mut uhci, 1, 3);
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_A));
    assert_eq!(reports(&mut uhci, pipe, 40), [4]);
    // The keyboard missed the ACK of KEY_A: it sends it again with the old
    // toggle before KEY_B. The controller drops it; KEY_B comes once.
    uhci.hardware().tree.repeat_next_toggle(keyboard);
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_B));
    assert!(uhci.hardware().tree.send_report(keyboard, RELEASED));
    assert_eq!(reports(&mut uhci, pipe, 40), [5, 0]);
    assert_eq!(uhci.hardware().toggle_mismatches, 1);
    assert_clean(uhci.hardware());
}

#[test]
fn a_stalled_pipe_waits_for_its_restart_and_starts_again_at_data0() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (device, pipe) = keyboard_by_hand(&mut uhci, 1, 4);
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_A));
    assert_eq!(reports(&mut uhci, pipe, 40), [4]);
    uhci.hardware().tree.stall_interrupt(keyboard);
    assert_eq!(next_report(&mut uhci, pipe, 40), Some(Transfer::Stalled));
    // It waits: nothing more until the restart, however long.
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_B));
    assert_eq!(next_report(&mut uhci, pipe, 40), None);
    let polls_while_waiting = uhci.hardware().interrupt_polls[&(4, 1)];
    wait(&mut uhci, 50_000);
    let _ = uhci.interrupt_poll(pipe, &mut [0; 8]);
    assert_eq!(
        uhci.hardware().interrupt_polls[&(4, 1)],
        polls_while_waiting
    );
    // CLEAR_FEATURE(ENDPOINT_HALT) on endpoint 0x81 resets the device's
    // toggle to DATA0, and so does the restart.
    let clear_halt = Setup {
        request_type: 0x02,
        request: 1,
        value: 0,
        index: 0x81,
        length: 0,
    };
    assert_eq!(
        control(&mut uhci, device, clear_halt, &[], &mut []),
        Transfer::Complete(0)
    );
    uhci.interrupt_restart(pipe, true).unwrap();
    assert_eq!(uhci.interrupt_restart(pipe, true), Err(HostError::Busy));
    assert!(uhci.hardware().tree.send_report(keyboard, RELEASED));
    assert_eq!(reports(&mut uhci, pipe, 40), [5, 0]);
    assert_eq!(uhci.hardware().toggle_mismatches, 0);
    assert_clean(uhci.hardware());
}

#[test]
fn a_device_that_never_answers_fails_after_three_strikes() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Dead(Speed::Full));
    let mut uhci = started(model);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Full));
    let device = uhci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    let before = uhci.hardware().transactions;
    let got = control(&mut uhci, device, get_descriptor(1, 8), &[], &mut [0; 8]);
    assert_eq!(got, Transfer::Failed(TransferError::NoResponse));
    assert_eq!(uhci.hardware().transactions - before, 3, "C_ERR 3");
    // The device is still there to be tried again, or removed.
    let got = control(&mut uhci, device, get_descriptor(1, 8), &[], &mut [0; 8]);
    assert_eq!(got, Transfer::Failed(TransferError::NoResponse));
    uhci.device_remove(device);
    assert_eq!(uhci.slots_in_use(), (0, 0));
    assert_clean(uhci.hardware());
}

#[test]
fn a_cancelled_transfer_leaves_the_device_ready_for_the_next() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Full));
    let device = uhci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    uhci.control_begin(device, get_descriptor(1, 8), &[])
        .unwrap();
    assert_eq!(
        uhci.control_begin(device, get_descriptor(1, 8), &[]),
        Err(HostError::Busy)
    );
    uhci.control_cancel(device);
    let frame = uhci.hardware().frames;
    let mut buffer = [0; 18];
    let got = control(&mut uhci, device, get_descriptor(1, 18), &[], &mut buffer);
    assert_eq!(got, Transfer::Complete(18));
    assert_eq!(buffer, KEYBOARD_DEVICE);
    assert!(uhci.hardware().frames > frame);
    assert_clean(uhci.hardware());
}

#[test]
fn a_thousand_plug_cycles_never_run_the_pools_dry() {
    let mut model = UhciModel::new(2);
    let mut keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    for cycle in 0..1_000u32 {
        let address = (cycle % 127 + 1) as u8;
        let (device, pipe) = keyboard_by_hand(&mut uhci, 1, address);
        assert_eq!(uhci.slots_in_use(), (1, 1), "cycle {cycle}");
        let key = (cycle % 26 + 4) as u8;
        let report = [0, 0, key, 0, 0, 0, 0, 0];
        assert!(uhci.hardware().tree.send_report(keyboard, report));
        assert_eq!(
            next_report(&mut uhci, pipe, 40),
            Some(Transfer::Complete(key.into())),
            "cycle {cycle}"
        );
        uhci.hardware().unplug(&[1]);
        assert!(uhci.port_status(1).connect_changed);
        uhci.clear_port_change(1);
        uhci.device_remove(device);
        assert_eq!(uhci.slots_in_use(), (0, 0), "cycle {cycle}");
        keyboard = uhci.hardware().plug(&[1], UsbDevice::Keyboard(Speed::Full));
        uhci.clear_port_change(1);
    }
    let model = uhci.hardware();
    assert!(model.dma_high_water <= DMA_BASE + u64::from(DMA_BYTES_NEEDED));
    assert_clean(model);
}

#[test]
fn every_slot_can_be_taken_and_the_next_is_refused() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 1,
        translator: None,
    };
    let devices: Vec<DeviceId> = (0..MAX_DEVICES)
        .map(|_| uhci.device_new(info).unwrap())
        .collect();
    assert_eq!(uhci.device_new(info), Err(HostError::NoRoom));
    let pipes: Vec<PipeId> = (0..MAX_PIPES)
        .map(|i| {
            uhci.interrupt_open(devices[i % 4], 1, 8, 1 << (i % 6))
                .unwrap()
        })
        .collect();
    assert_eq!(
        uhci.interrupt_open(devices[0], 1, 8, 8),
        Err(HostError::NoRoom)
    );
    for _ in 0..64 {
        wait(&mut uhci, 1_000);
        let _ = uhci.anything_happened();
    }
    for pipe in pipes {
        uhci.interrupt_close(pipe);
    }
    for device in devices {
        uhci.device_remove(device);
    }
    assert_eq!(uhci.slots_in_use(), (0, 0));
    // Handles given up are refused.
    assert_eq!(
        uhci.device_set_address(DeviceId(0), 5),
        Err(HostError::UnknownHandle)
    );
    assert_eq!(
        uhci.interrupt_restart(PipeId(0), false),
        Err(HostError::UnknownHandle)
    );
    assert_eq!(
        uhci.device_set_address(DeviceId(200), 5),
        Err(HostError::UnknownHandle)
    );
    assert_clean(uhci.hardware());
}

#[test]
fn each_pipe_is_polled_at_its_interval() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (device, first) = keyboard_by_hand(&mut uhci, 1, 1);
    uhci.interrupt_close(first);
    // One pipe at a time on the keyboard's endpoint, which NAKs (no key):
    // every poll is a transaction the model counts.
    for (interval, period) in [
        (1u8, 1u64),
        (2, 2),
        (3, 2),
        (4, 4),
        (8, 8),
        (10, 8),
        (16, 16),
        (32, 32),
        (255, 32),
    ] {
        let pipe = uhci.interrupt_open(device, 1, 8, interval).unwrap();
        let polls = |uhci: &mut Uhci<UhciModel>| {
            let counts = &uhci.hardware().interrupt_polls;
            counts.get(&(1, 1)).copied().unwrap_or(0)
        };
        let before = polls(&mut uhci);
        for _ in 0..256 {
            wait(&mut uhci, 1_000);
            assert_eq!(uhci.interrupt_poll(pipe, &mut [0; 8]), Transfer::Pending);
        }
        let polled = polls(&mut uhci) - before;
        assert_eq!(polled, 256 / period, "interval {interval}");
        uhci.interrupt_close(pipe);
    }
    assert_clean(uhci.hardware());
}

#[test]
fn an_idle_poll_reads_one_register_and_port_changes_are_seen_within_16() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (_, pipe) = keyboard_by_hand(&mut uhci, 1, 1);
    // Settle: whatever enumeration left in USBSTS is taken.
    for _ in 0..PORT_CHECK_EVERY {
        let _ = uhci.anything_happened();
    }
    for call in 0..64 {
        wait(&mut uhci, 1_000);
        let (reads, dma) = (uhci.hardware().register_reads, uhci.hardware().dma_reads);
        assert!(!uhci.anything_happened(), "call {call}: nothing happened");
        let model = uhci.hardware();
        assert_eq!(model.register_reads - reads, 1, "call {call}");
        assert_eq!(model.dma_reads - dma, 0, "call {call}");
    }
    // A report: seen at the next call or the one after (a port check).
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_A));
    wait(&mut uhci, 20_000);
    assert!(uhci.anything_happened() || uhci.anything_happened());
    assert_eq!(next_report(&mut uhci, pipe, 1), Some(Transfer::Complete(4)));
    // A device plugged into port 2: no USBSTS bit says so; the port check
    // finds it within PORT_CHECK_EVERY calls per port.
    uhci.hardware().plug(&[2], UsbDevice::Keyboard(Speed::Full));
    let seen = (0..2 * PORT_CHECK_EVERY).position(|_| uhci.anything_happened());
    assert!(seen.is_some(), "the new connection was never seen");
    assert!(uhci.port_status(2).connect_changed);
    uhci.clear_port_change(2);
    assert!(!uhci.port_status(2).connect_changed);
    assert!(uhci.port_status(2).connected);
    assert_clean(uhci.hardware());
}

#[test]
fn the_bios_is_relieved_of_the_controller_as_linux_does() {
    let mut model = UhciModel::owned_by_bios(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = driver(model);
    let handoff = uhci.take_ownership();
    assert!(matches!(handoff, Handoff::Released { .. }), "{handoff:?}");
    let model = uhci.hardware();
    assert_eq!(model.legsup() & 0x20BF, 0, "SMI and PIRQ enables off");
    assert_eq!(model.legsup() & 0x8F00, 0, "trap status cleared");
    assert_eq!(model.legsup_writes[..2], [0x8F00, 0]);
    assert_eq!(model.usbintr(), 0);
    assert_eq!(model.usbcmd() & 1, 0, "the BIOS schedule stopped");
    uhci.reset_and_start().unwrap();
    assert!(!uhci.hardware().bios_schedule_runs());
    assert_eq!(u64::from(uhci.hardware().frame_list()), DMA_BASE);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Full));
    assert_clean(uhci.hardware());
}

#[test]
fn a_controller_the_bios_does_not_use_is_not_owned() {
    let mut uhci = driver(UhciModel::new(2));
    assert_eq!(uhci.take_ownership(), Handoff::NotOwned);
    assert_eq!(uhci.hardware().legsup(), 0, "PIRQ off: the driver polls");
    uhci.reset_and_start().unwrap();
    assert_eq!(uhci.root_ports(), 2);
    assert_eq!(uhci.hardware().sofmod(), 64, "SOFMOD left alone");
    assert_clean(uhci.hardware());
}

#[test]
fn a_bios_that_never_lets_go_is_left_alone_after_a_bounded_wait() {
    let mut model = UhciModel::owned_by_bios(2);
    model.bios_keeps_legsup = true;
    let mut uhci = driver(model);
    let start = uhci.hardware().now;
    assert_eq!(uhci.take_ownership(), Handoff::NeverReleased);
    let took = uhci.hardware().now - start;
    assert!(took <= HANDOFF_MICROS + 1_000, "{took} us");
    let writes = uhci.hardware().register_writes;
    assert_eq!(uhci.reset_and_start(), Err(UhciError::FirmwareOwns));
    assert!(!uhci.halt());
    let model = uhci.hardware();
    assert_eq!(model.register_writes, writes, "the controller untouched");
    assert!(model.bios_schedule_runs());
    assert_eq!(model.legsup() & BIOS_LEGSUP, BIOS_LEGSUP & 0x20BF);
    assert!(model.log.iter().any(|line| line.contains("left alone")));
    assert_clean(model);
}

#[test]
fn halt_stops_the_controller_and_leaves_legsup_as_linux_does() {
    let mut model = UhciModel::owned_by_bios(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (_, pipe) = keyboard_by_hand(&mut uhci, 1, 1);
    let start = uhci.hardware().now;
    assert!(uhci.halt());
    assert!(uhci.hardware().now - start <= HALT_MICROS);
    let model = uhci.hardware();
    assert_ne!(model.usbsts() & 0x20, 0, "HCHalted");
    assert_eq!(model.usbcmd() & 1, 0);
    assert_eq!(model.usbintr(), 0);
    assert_eq!(model.legsup(), 0, "SMI and PIRQ off, trap status clear");
    assert_eq!(model.legsup_writes.last(), Some(&0x8F00));
    // Halted: no schedule runs, the driver takes nothing more.
    let frames = model.frames;
    assert!(model.tree.send_report(keyboard, KEY_A));
    wait(&mut uhci, 20_000);
    assert!(!uhci.anything_happened());
    assert_eq!(uhci.hardware().frames, frames);
    assert_eq!(
        uhci.interrupt_poll(pipe, &mut [0; 8]),
        Transfer::Failed(TransferError::Controller)
    );
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 1,
        translator: None,
    };
    assert_eq!(uhci.device_new(info), Err(HostError::ControllerGone));
    assert_clean(uhci.hardware());
}

#[test]
fn a_controller_that_never_halts_is_given_up_within_the_bound() {
    let mut uhci = started(UhciModel::new(2));
    uhci.hardware().never_halts = true;
    let start = uhci.hardware().now;
    assert!(!uhci.halt());
    let took = uhci.hardware().now - start;
    assert!(took <= HALT_MICROS + 1_000, "{took} us");
    assert!(uhci
        .hardware()
        .log
        .iter()
        .any(|l| l.contains("did not halt")));
    assert_clean(uhci.hardware());
}

#[test]
fn a_host_reset_that_never_ends_is_given_up_within_the_bound() {
    let mut model = UhciModel::new(2);
    model.host_reset_stuck = true;
    let mut uhci = driver(model);
    uhci.take_ownership();
    let start = uhci.hardware().now;
    assert_eq!(uhci.reset_and_start(), Err(UhciError::ResetTimeout));
    let took = uhci.hardware().now - start;
    assert!(took <= 20_000 + HOST_RESET_MICROS + 1_000, "{took} us");
}

#[test]
fn a_host_system_error_gives_the_controller_up() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (device, pipe) = keyboard_by_hand(&mut uhci, 1, 1);
    uhci.hardware().host_system_error();
    assert!(uhci.anything_happened());
    assert!(uhci.hardware().log.iter().any(|l| l.contains("given up")));
    assert_eq!(
        uhci.interrupt_poll(pipe, &mut [0; 8]),
        Transfer::Failed(TransferError::Controller)
    );
    assert_eq!(
        uhci.control_begin(device, get_descriptor(1, 8), &[]),
        Err(HostError::ControllerGone)
    );
    assert!(!uhci.anything_happened());
}

#[test]
fn the_root_ports_are_counted_as_linux_does() {
    for (ports, counted) in [(1, 1), (2, 2), (3, 3), (7, 7), (8, 2)] {
        let uhci = started(UhciModel::new(ports));
        assert_eq!(uhci.root_ports(), counted, "{ports} port registers");
    }
    let mut model = UhciModel::new(2);
    model.port_nonsense = Some(0xFFFF);
    let mut uhci = driver(model);
    uhci.take_ownership();
    assert_eq!(uhci.reset_and_start(), Err(UhciError::NoRootPorts));
}

#[test]
fn port_registers_that_read_nonsense_cost_a_bounded_wait_and_no_device() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    // All ones: the controller is gone; nothing is there.
    uhci.hardware().port_nonsense = Some(0xFFFF);
    assert_eq!(uhci.port_status(1), Default::default());
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Failed);
    // Connected, in reset for ever, changes that never clear.
    uhci.hardware().port_nonsense = Some(0x0F8B | 0x0200);
    let start = uhci.hardware().now;
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Failed);
    let took = uhci.hardware().now - start;
    assert!(
        took <= ROOT_RESET_MICROS + PORT_ENABLE_MICROS + 1_000,
        "{took} us"
    );
    // Ports that are not there.
    assert_eq!(uhci.port_status(0), Default::default());
    assert_eq!(uhci.port_status(3), Default::default());
    assert_eq!(uhci.port_reset_poll(9), Some(ResetOutcome::Failed));
}

#[test]
fn a_port_that_refuses_its_first_enables_is_tried_again() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Low));
    model.port_enable_refusals = 3;
    let mut uhci = started(model);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Low));
    let status = uhci.port_status(1);
    assert!(status.connected && status.enabled && status.low_speed);
    uhci.port_disable(1);
    assert!(!uhci.port_status(1).enabled);
    assert!(uhci.port_status(1).connected);
    // More refusals than tries: the reset fails, bounded.
    uhci.hardware().port_enable_refusals = 100;
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Failed);
    assert_clean(uhci.hardware());
}

#[test]
fn an_empty_port_resets_to_nothing() {
    let mut uhci = started(UhciModel::new(2));
    assert_eq!(reset_port(&mut uhci, 2), ResetOutcome::Failed);
    assert!(!uhci.port_status(2).connected);
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::High,
        root_port: 1,
        translator: None,
    };
    assert_eq!(uhci.device_new(info), Err(HostError::Invalid));
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 3,
        translator: None,
    };
    assert_eq!(uhci.device_new(info), Err(HostError::Invalid));
    assert_clean(uhci.hardware());
}

#[test]
fn memory_is_reused_only_after_the_frame_has_moved_on() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 1,
        translator: None,
    };
    // Every slot freed in this frame: the next device must wait for the
    // frame number to change before its queue head is written again.
    let devices: Vec<DeviceId> = (0..MAX_DEVICES)
        .map(|_| uhci.device_new(info).unwrap())
        .collect();
    for device in devices {
        uhci.device_remove(device);
    }
    let frame_before = uhci.hardware().frames;
    let start = uhci.hardware().now;
    uhci.device_new(info).unwrap();
    let took = uhci.hardware().now - start;
    assert!(uhci.hardware().frames > frame_before, "no frame passed");
    assert!(took <= FRAME_WAIT_MICROS, "{took} us");
    assert_clean(uhci.hardware());
}

/// A frame timer that runs late (QEMU's on a busy host) makes the wait
/// for reuse end at its bound, logged, and the controller goes on: a
/// pipe restarted in the frame its transfer stalled reads reports after.
#[test]
fn a_late_frame_timer_costs_a_bounded_wait_and_never_the_controller() {
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let (_, pipe) = keyboard_by_hand(&mut uhci, 1, 4);
    uhci.hardware().tree.stall_interrupt(keyboard);
    assert!(uhci.hardware().tree.send_report(keyboard, KEY_A));
    assert_eq!(next_report(&mut uhci, pipe, 40), Some(Transfer::Stalled));
    // Restarted in the same frame, while the frame number stands still
    // for longer than the driver waits.
    let now = uhci.hardware().now;
    uhci.hardware().frames_late_until = now + 2 * FRAME_WAIT_MICROS;
    let start = uhci.hardware().now;
    uhci.interrupt_restart(pipe, false).unwrap();
    let took = uhci.hardware().now - start;
    assert!(took <= FRAME_WAIT_MICROS + 100, "{took} us");
    assert!(
        uhci.hardware()
            .log
            .iter()
            .any(|line| line.contains("frame number stuck")),
        "{:?}",
        uhci.hardware().log
    );
    // The device still stalls (its halt was never cleared): the
    // controller ran the restarted transfer, so it is still in service.
    assert_eq!(next_report(&mut uhci, pipe, 40), Some(Transfer::Stalled));
}

#[test]
fn requests_the_driver_cannot_do_are_refused() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    let device = uhci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    let too_long = get_descriptor(2, 1025);
    assert_eq!(
        uhci.control_begin(device, too_long, &[]),
        Err(HostError::Invalid)
    );
    let out = Setup {
        request_type: 0x21,
        request: 9,
        value: 0x200,
        index: 0,
        length: 4,
    };
    assert_eq!(
        uhci.control_begin(device, out, &[1, 2]),
        Err(HostError::Invalid)
    );
    for max_packet in [0, 7, 9, 128] {
        assert_eq!(
            uhci.device_set_max_packet(device, max_packet),
            Err(HostError::Invalid)
        );
    }
    for address in [0, 128, 255] {
        assert_eq!(
            uhci.device_set_address(device, address),
            Err(HostError::Invalid)
        );
    }
    assert_eq!(
        uhci.interrupt_open(device, 0, 8, 10),
        Err(HostError::Invalid)
    );
    assert_eq!(
        uhci.interrupt_open(device, 16, 8, 10),
        Err(HostError::Invalid)
    );
    assert_eq!(
        uhci.interrupt_open(device, 1, 65, 10),
        Err(HostError::Invalid)
    );
    assert_eq!(
        uhci.control_poll(device, &mut []),
        Transfer::Failed(TransferError::Controller)
    );
    assert_eq!(
        Uhci::new(UhciModel::new(2), DMA_BASE, 4096).err(),
        Some(UhciError::DmaRegion)
    );
    assert_eq!(
        Uhci::new(UhciModel::new(2), 0xFFFF_0000, DMA_BYTES).err(),
        Some(UhciError::DmaRegion)
    );
    let _ = vec![0u8; 0];
    assert_clean(uhci.hardware());
}

#[test]
fn port_writes_keep_the_change_bits_they_do_not_mean_to_clear() {
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    assert!(uhci.port_status(1).connect_changed);
    assert_eq!(reset_port(&mut uhci, 1), ResetOutcome::Enabled(Speed::Full));
    uhci.clear_port_change(1);
    assert!(!uhci.port_status(1).connect_changed);
    // Pulled and plugged again behind the driver's back: a disable or a
    // reset begun now must not swallow the connect change.
    uhci.hardware().unplug(&[1]);
    uhci.hardware().plug(&[1], UsbDevice::Keyboard(Speed::Full));
    uhci.port_disable(1);
    assert!(uhci.port_status(1).connect_changed);
    uhci.port_reset_begin(1);
    assert!(uhci.port_status(1).connect_changed);
    // The reset's end clears what the reset itself changed.
    assert_eq!(
        crate::model::reset_polled(&mut uhci, 1),
        ResetOutcome::Enabled(Speed::Full)
    );
    assert_clean(uhci.hardware());
}

#[test]
fn a_keyboard_plugged_into_a_hub_after_boot_is_found() {
    let mut model = UhciModel::new(2);
    model.plug(
        &[2],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 0);
    let keyboard = bus
        .controller()
        .hardware()
        .plug(&[2, 1], UsbDevice::Keyboard(Speed::Low));
    typed(&mut bus, 1_000);
    assert_eq!(
        bus.keyboards().count(),
        1,
        "{:?}",
        bus.controller().hardware().log
    );
    let model = bus.controller().hardware();
    assert!(model.tree.send_report(keyboard, KEY_A));
    assert!(model.tree.send_report(keyboard, RELEASED));
    assert_eq!(typed(&mut bus, 100), [0x1E, 0x9E]);
    bus.controller().hardware().unplug(&[2, 1]);
    typed(&mut bus, 1_000);
    assert_eq!(bus.keyboards().count(), 0);
    assert_eq!(
        bus.controller().slots_in_use(),
        (1, 1),
        "the hub and its pipe"
    );
    assert_clean(bus.controller().hardware());
}

#[test]
fn a_twenty_byte_report_in_eight_byte_packets_is_put_back_together() {
    use crate::model::devices::rollover_report;
    let mut model = UhciModel::new(2);
    let keyboard = model.plug(&[1], UsbDevice::RolloverKeyboard(Speed::Low));
    let mut bus = bus_with(model);
    assert_eq!(bus.enumerate(), 1, "{:?}", bus.controller().hardware().log);
    let logged = |bus: &mut Bus<Uhci<UhciModel>>, text: &str| {
        bus.controller()
            .hardware()
            .log
            .iter()
            .any(|l| l.contains(text))
    };
    assert!(logged(&mut bus, "(2 key fields, 20-byte reports)"));
    let a_and_b = rollover_report(&[0x04, 0x05]);
    let tree = &mut bus.controller().hardware().tree;
    assert!(tree.send_packets(keyboard, &a_and_b, false));
    assert_eq!(typed(&mut bus, 100), [0x1E, 0x30]);
    // Cut short after 10 bytes: dropped, and the next report is whole.
    let tree = &mut bus.controller().hardware().tree;
    assert!(tree.send_packets(keyboard, &a_and_b[..10], false));
    assert!(tree.send_packets(keyboard, &rollover_report(&[]), false));
    assert_eq!(typed(&mut bus, 100), [0x9E, 0xB0]);
    assert!(logged(
        &mut bus,
        "keyboard: 1 unreadable reports dropped (the last 10 bytes)"
    ));
    assert_clean(bus.controller().hardware());
}

#[test]
fn a_root_port_reset_polled_late_still_tries_to_enable_the_port() {
    // A busy host (or an SMI) can hold the device layer off for longer than
    // the enable's whole bound between two polls: the driver must still
    // write Port Enable before it gives up.
    let mut model = UhciModel::new(2);
    model.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut uhci = started(model);
    uhci.port_reset_begin(1);
    let outcome = loop {
        // Each poll 20 ms after the last, four times the enable's bound.
        uhci.hardware().now += 20_000;
        if let Some(outcome) = uhci.port_reset_poll(1) {
            break outcome;
        }
    };
    assert_eq!(
        outcome,
        ResetOutcome::Enabled(Speed::Full),
        "{:?}",
        uhci.hardware().log
    );
}
