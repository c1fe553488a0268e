//! The OHCI driver against the OHCI register model and the shared device
//! tree: the firmware hand-off, the reset, root ports, keyboards at full
//! and low speed on root ports and behind a hub, toggle errors and stalls
//! recovered, plug cycles that must not use up the pools, and halting.
//! Enumeration here is done by hand through [`HostController`], as the
//! device layer would.

use super::*;
use crate::host::POLL_INTERVAL_MICROS;
use crate::model::devices::UsbDevice;
use crate::model::ohci::{OhciModel, PowerSwitching, BAR_BYTES, DMA_BASE, DMA_BYTES};
use crate::Platform;
use std::vec::Vec;

const GET_STATUS: u8 = 0;
const CLEAR_FEATURE: u8 = 1;
const SET_FEATURE: u8 = 3;
const SET_ADDRESS: u8 = 5;
const GET_DESCRIPTOR: u8 = 6;
const SET_CONFIGURATION: u8 = 9;
const SET_PROTOCOL: u8 = 0x0B;
const PORT_RESET: u16 = 4;
const PORT_POWER: u16 = 8;
const C_PORT_CONNECTION: u16 = 16;
const C_PORT_RESET: u16 = 20;

type Driver = Ohci<OhciModel>;

fn setup(request_type: u8, request: u8, value: u16, index: u16, length: u16) -> Setup {
    Setup {
        request_type,
        request,
        value,
        index,
        length,
    }
}

fn driver(model: OhciModel) -> Driver {
    Ohci::new(model, BAR_BYTES, DMA_BASE, DMA_BYTES).expect("the region fits")
}

fn started(model: OhciModel) -> Driver {
    let mut ohci = driver(model);
    assert_eq!(ohci.take_ownership(), Handoff::NotOwned);
    ohci.reset_and_start().expect("the controller starts");
    ohci
}

/// Lets `micros` of model time pass through the driver's clock.
fn wait(ohci: &mut Driver, micros: u64) {
    let start = ohci.hardware().now_micros();
    while ohci.hardware().now_micros() - start < micros {}
}

/// Runs a control transfer to its end, as the device layer would poll it
/// (the idle check, then the transfer), bounded by 1 s of model time.
fn control(
    ohci: &mut Driver,
    device: DeviceId,
    request: Setup,
    out: &[u8],
) -> core::result::Result<Vec<u8>, Transfer> {
    ohci.control_begin(device, request, out)
        .expect("the transfer starts");
    let deadline = ohci.hardware().now_micros() + 1_000_000;
    let mut buffer = [0u8; MAX_CONTROL_DATA];
    loop {
        ohci.anything_happened();
        match ohci.control_poll(device, &mut buffer) {
            Transfer::Pending => assert!(
                ohci.hardware().now_micros() < deadline,
                "a control transfer never ended"
            ),
            Transfer::Complete(length) => return Ok(buffer[..length].to_vec()),
            other => return Err(other),
        }
    }
}

/// Polls the pipe for up to `micros`: the report, or how it ended.
fn report(ohci: &mut Driver, pipe: PipeId, micros: u64) -> Transfer {
    let deadline = ohci.hardware().now_micros() + micros;
    let mut buffer = [0u8; MAX_REPORT];
    loop {
        ohci.anything_happened();
        let result = ohci.interrupt_poll(pipe, &mut buffer);
        if result != Transfer::Pending || ohci.hardware().now_micros() > deadline {
            return result;
        }
    }
}

fn report_bytes(ohci: &mut Driver, pipe: PipeId) -> Vec<u8> {
    let deadline = ohci.hardware().now_micros() + 200_000;
    let mut buffer = [0u8; MAX_REPORT];
    loop {
        ohci.anything_happened();
        match ohci.interrupt_poll(pipe, &mut buffer) {
            Transfer::Complete(length) => return buffer[..length].to_vec(),
            Transfer::Pending => assert!(ohci.hardware().now_micros() < deadline, "no report came"),
            other => panic!("the report ended in {other:?}"),
        }
    }
}

/// Resets a root port as the device layer does and gives the speed.
fn reset_root_port(ohci: &mut Driver, port: u8) -> Speed {
    match crate::model::reset_root_port(ohci, port) {
        ResetOutcome::Enabled(speed) => speed,
        other => panic!("port {port} reset: {other:?}"),
    }
}

/// Enumerates the device at the default address: its packet size, its
/// address, its descriptors, configuration 1.
fn enumerate(ohci: &mut Driver, speed: Speed, root_port: u8, address: u8) -> DeviceId {
    let device = ohci
        .device_new(DeviceInfo {
            route: Some(0),
            speed,
            root_port,
            translator: None,
        })
        .expect("room for the device");
    let head = control(ohci, device, setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8), &[]).unwrap();
    assert_eq!(head.len(), 8);
    ohci.device_set_max_packet(device, u16::from(head[7]))
        .unwrap();
    control(
        ohci,
        device,
        setup(0, SET_ADDRESS, address.into(), 0, 0),
        &[],
    )
    .unwrap();
    ohci.device_set_address(device, address).unwrap();
    let descriptor = control(
        ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 18),
        &[],
    )
    .unwrap();
    assert_eq!(descriptor.len(), 18);
    assert_eq!(&descriptor[..8], &head[..]);
    let header = control(ohci, device, setup(0x80, GET_DESCRIPTOR, 0x0200, 0, 9), &[]).unwrap();
    let total = u16::from_le_bytes([header[2], header[3]]);
    // Asked for more than there is: a short packet ends the data stage.
    let configuration = control(
        ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0200, 0, total + 100),
        &[],
    )
    .unwrap();
    assert_eq!(configuration.len(), usize::from(total));
    control(ohci, device, setup(0, SET_CONFIGURATION, 1, 0, 0), &[]).unwrap();
    device
}

/// A keyboard enumerated, in the boot protocol, its report pipe open.
fn keyboard(ohci: &mut Driver, speed: Speed, root_port: u8, address: u8) -> (DeviceId, PipeId) {
    let device = enumerate(ohci, speed, root_port, address);
    control(ohci, device, setup(0x21, SET_PROTOCOL, 0, 0, 0), &[]).unwrap();
    let pipe = ohci
        .interrupt_open(device, 1, 8, 10)
        .expect("room for the pipe");
    (device, pipe)
}

fn key(usage: u8) -> [u8; 8] {
    [0, 0, usage, 0, 0, 0, 0, 0]
}

fn assert_clean(ohci: &mut Driver) {
    let errors = ohci.hardware().all_errors();
    assert!(errors.is_empty(), "the model saw: {errors:#?}");
}

#[test]
fn a_full_speed_keyboard_on_a_root_port_types() {
    let mut model = OhciModel::new(2);
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    assert_eq!(ohci.root_ports(), 2);
    let status = ohci.port_status(1);
    assert!(status.connected && status.connect_changed && !status.enabled && !status.low_speed);
    assert!(!ohci.port_status(2).connected);
    ohci.clear_port_change(1);
    assert!(!ohci.port_status(1).connect_changed);
    assert_eq!(reset_root_port(&mut ohci, 1), Speed::Full);
    assert!(ohci.port_status(1).enabled);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 5);
    assert_eq!(ohci.hardware().tree.keyboard_state(handle), (0, 1, 5));
    // No key: the keyboard NAKs and the pipe stays pending.
    assert_eq!(report(&mut ohci, pipe, 30_000), Transfer::Pending);
    for usage in [4, 5, 0] {
        assert!(ohci.hardware().tree.send_report(handle, key(usage)));
        assert_eq!(report_bytes(&mut ohci, pipe), key(usage));
    }
    // A restart of a pipe that is running keeps it in step.
    ohci.interrupt_restart(pipe, false).unwrap();
    assert!(ohci.hardware().tree.send_report(handle, key(7)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(7));
    assert!(
        ohci.done_heads_consumed() > 0,
        "the done queue was never taken"
    );
    assert_clean(&mut ohci);
}

#[test]
fn a_low_speed_keyboard_on_a_root_port_types() {
    let mut model = OhciModel::new(2);
    let handle = model.tree.plug(&[2], UsbDevice::Keyboard(Speed::Low));
    let mut ohci = started(model);
    let status = ohci.port_status(2);
    assert!(status.connected && status.low_speed);
    assert_eq!(reset_root_port(&mut ohci, 2), Speed::Low);
    let (_, pipe) = keyboard(&mut ohci, Speed::Low, 2, 1);
    assert_eq!(ohci.hardware().tree.keyboard_state(handle), (0, 1, 1));
    assert!(ohci.hardware().tree.send_report(handle, key(0x29)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(0x29));
    assert_clean(&mut ohci);
}

#[test]
fn keyboards_behind_a_hub_type_at_full_and_low_speed() {
    let mut model = OhciModel::new(2);
    model.tree.plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::Full,
            ports: 4,
            multi_tt: false,
        },
    );
    let low = model.tree.plug(&[1, 2], UsbDevice::Keyboard(Speed::Low));
    let full = model.tree.plug(&[1, 3], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    assert_eq!(reset_root_port(&mut ohci, 1), Speed::Full);
    let hub = enumerate(&mut ohci, Speed::Full, 1, 1);
    let descriptor = control(
        &mut ohci,
        hub,
        setup(0xA0, GET_DESCRIPTOR, 0x2900, 0, 71),
        &[],
    )
    .unwrap();
    assert_eq!(descriptor[2], 4);
    ohci.device_is_hub(hub, 4, false).unwrap();
    for port in 1..=4 {
        control(
            &mut ohci,
            hub,
            setup(0x23, SET_FEATURE, PORT_POWER, port, 0),
            &[],
        )
        .unwrap();
    }
    let changes = ohci.interrupt_open(hub, 1, 1, 255).unwrap();
    // The status change endpoint reports ports 2 and 3.
    let bitmap = report_bytes(&mut ohci, changes);
    assert_eq!(bitmap, [0b1100]);
    for (port, speed, handle, address) in [(2u16, Speed::Low, low, 2), (3, Speed::Full, full, 3)] {
        let status = control(&mut ohci, hub, setup(0xA3, GET_STATUS, 0, port, 4), &[]).unwrap();
        assert_eq!(status[0] & 1, 1, "port {port} connected");
        assert_eq!(status[1] & 2 != 0, speed == Speed::Low);
        control(
            &mut ohci,
            hub,
            setup(0x23, CLEAR_FEATURE, C_PORT_CONNECTION, port, 0),
            &[],
        )
        .unwrap();
        control(
            &mut ohci,
            hub,
            setup(0x23, SET_FEATURE, PORT_RESET, port, 0),
            &[],
        )
        .unwrap();
        let status = control(&mut ohci, hub, setup(0xA3, GET_STATUS, 0, port, 4), &[]).unwrap();
        assert_eq!(status[0] & 2, 2, "port {port} enabled");
        control(
            &mut ohci,
            hub,
            setup(0x23, CLEAR_FEATURE, C_PORT_RESET, port, 0),
            &[],
        )
        .unwrap();
        let (_, pipe) = keyboard(&mut ohci, speed, 1, address);
        assert_eq!(ohci.hardware().tree.keyboard_state(handle), (0, 1, address));
        assert!(ohci.hardware().tree.send_report(handle, key(address + 3)));
        assert_eq!(report_bytes(&mut ohci, pipe), key(address + 3));
    }
    assert_clean(&mut ohci);
}

#[test]
fn a_report_repeated_with_the_old_toggle_is_dropped() {
    let mut model = OhciModel::new(1);
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 1);
    assert!(ohci.hardware().tree.send_report(handle, key(4)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(4));
    // The ACK of that report was lost: the keyboard sends it again with
    // the old toggle, which the controller must drop, then the next one.
    ohci.hardware().tree.repeat_next_toggle(handle);
    assert!(ohci.hardware().tree.send_report(handle, key(5)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(5));
    assert!(ohci.hardware().tree.send_report(handle, key(6)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(6));
    assert_eq!(report(&mut ohci, pipe, 30_000), Transfer::Pending);
    assert_eq!(ohci.hardware().toggle_mismatches, 1);
    assert_clean(&mut ohci);
}

#[test]
fn a_keyboard_asking_for_10_ms_is_polled_every_8_frames() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 4);
    // A second pipe of the same interval (12 rounds down to 8), on a
    // device that does not answer, goes on another branch.
    let silent = ohci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    ohci.device_set_address(silent, 77).unwrap();
    let other = ohci.interrupt_open(silent, 2, 8, 12).unwrap();
    ohci.hardware().record_visits = true;
    wait(&mut ohci, 64_000);
    let visits = ohci.hardware().visits.clone();
    for (address, endpoint) in [(4, 1), (77, 2)] {
        let frames: Vec<u16> = visits
            .iter()
            .filter(|v| (v.1, v.2) == (address, endpoint))
            .map(|v| v.0)
            .collect();
        assert!(frames.len() >= 7, "{address}: {frames:?}");
        assert!(
            frames.windows(2).all(|w| w[1].wrapping_sub(w[0]) == 8),
            "{address}: {frames:?}"
        );
    }
    let branch = |address: u8| visits.iter().find(|v| v.1 == address).unwrap().0 % 8;
    assert_ne!(branch(4), branch(77), "both pipes on one branch");
    let _ = (pipe, other);
}

#[test]
fn an_idle_poll_reads_one_register_and_nothing_else() {
    let mut model = OhciModel::new(2);
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 1);
    assert!(ohci.hardware().tree.send_report(handle, key(4)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(4));
    // Settle: the last done queue taken, the root hub quiet.
    for _ in 0..10 {
        wait(&mut ohci, 2_000);
        ohci.anything_happened();
    }
    for _ in 0..100 {
        let (registers, memory) = {
            let model = ohci.hardware();
            (model.register_reads, model.memory_reads)
        };
        assert!(!ohci.anything_happened());
        let model = ohci.hardware();
        assert_eq!(
            (
                model.register_reads - registers,
                model.memory_reads - memory
            ),
            (1, 0)
        );
    }
    // A key: the done queue comes back (WDH) and the poll says so.
    assert!(ohci.hardware().tree.send_report(handle, key(5)));
    let deadline = ohci.hardware().now_micros() + 50_000;
    while !ohci.anything_happened() {
        assert!(
            ohci.hardware().now_micros() < deadline,
            "the report never showed"
        );
    }
    assert_eq!(report_bytes(&mut ohci, pipe), key(5));
    assert_clean(&mut ohci);
}

#[test]
fn a_stalled_interrupt_endpoint_waits_for_the_restart_then_types() {
    let mut model = OhciModel::new(1);
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let (device, pipe) = keyboard(&mut ohci, Speed::Full, 1, 1);
    // One report first, so the device's toggle is DATA1 when it stalls.
    assert!(ohci.hardware().tree.send_report(handle, key(4)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(4));
    ohci.hardware().tree.stall_interrupt(handle);
    assert_eq!(report(&mut ohci, pipe, 50_000), Transfer::Stalled);
    assert!(ohci.hardware().tree.send_report(handle, key(5)));
    // The pipe waits for its restart.
    assert_eq!(report(&mut ohci, pipe, 50_000), Transfer::Pending);
    control(
        &mut ohci,
        device,
        setup(0x02, CLEAR_FEATURE, 0, 0x81, 0),
        &[],
    )
    .unwrap();
    ohci.interrupt_restart(pipe, true).unwrap();
    assert_eq!(report_bytes(&mut ohci, pipe), key(5));
    assert!(ohci.hardware().tree.send_report(handle, key(6)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(6));
    assert_clean(&mut ohci);
}

#[test]
fn a_refused_request_stalls_and_the_next_one_works() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let device = enumerate(&mut ohci, Speed::Full, 1, 3);
    // String descriptor 9 does not exist.
    let refused = control(
        &mut ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0309, 0x0409, 64),
        &[],
    );
    assert_eq!(refused, Err(Transfer::Stalled));
    let descriptor = control(
        &mut ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 18),
        &[],
    )
    .unwrap();
    assert_eq!(descriptor.len(), 18);
    // An OUT data stage: the keyboard's LEDs.
    control(&mut ohci, device, setup(0x21, 0x09, 0x0200, 0, 1), &[0b101]).unwrap();
    let handle = ohci.hardware().tree.handle_at(&[1]).unwrap();
    assert_eq!(ohci.hardware().tree.leds(handle), 0b101);
    assert_clean(&mut ohci);
}

#[test]
fn a_dead_device_fails_with_no_response_and_a_cancel_frees_endpoint_0() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Dead(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let device = ohci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::Full,
            root_port: 1,
            translator: None,
        })
        .unwrap();
    let result = control(
        &mut ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8),
        &[],
    );
    assert_eq!(result, Err(Transfer::Failed(TransferError::NoResponse)));
    // Started and given up by the device layer's timeout.
    ohci.control_begin(device, setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8), &[])
        .unwrap();
    assert_eq!(
        ohci.control_begin(device, setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8), &[]),
        Err(HostError::Busy)
    );
    ohci.control_cancel(device);
    let result = control(
        &mut ohci,
        device,
        setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8),
        &[],
    );
    assert_eq!(result, Err(Transfer::Failed(TransferError::NoResponse)));
    ohci.device_remove(device);
    assert_eq!(ohci.devices_in_use(), 0);
    assert_clean(&mut ohci);
}

#[test]
fn a_thousand_plug_cycles_use_no_more_descriptors_than_one() {
    let mut model = OhciModel::new(2);
    model.power_switching = PowerSwitching::Ganged;
    let mut ohci = started(model);
    for cycle in 0..1_000u32 {
        let speed = if cycle % 2 == 0 {
            Speed::Full
        } else {
            Speed::Low
        };
        let handle = ohci.hardware().tree.plug(&[1], UsbDevice::Keyboard(speed));
        // The root hub says so (RHSC) at the idle poll.
        let deadline = ohci.hardware().now_micros() + 10_000;
        while !ohci.anything_happened() {
            assert!(
                ohci.hardware().now_micros() < deadline,
                "cycle {cycle}: no root hub change"
            );
        }
        assert!(ohci.port_status(1).connect_changed);
        ohci.clear_port_change(1);
        assert_eq!(reset_root_port(&mut ohci, 1), speed);
        let address = (cycle % 127) as u8 + 1;
        let (device, pipe) = keyboard(&mut ohci, speed, 1, address);
        assert!(ohci
            .hardware()
            .tree
            .send_report(handle, key(4 + (cycle % 20) as u8)));
        assert_eq!(report_bytes(&mut ohci, pipe), key(4 + (cycle % 20) as u8));
        ohci.hardware().tree.unplug(&[1]);
        wait(&mut ohci, 1_000);
        let status = ohci.port_status(1);
        assert!(!status.connected && !status.enabled && status.connect_changed);
        ohci.clear_port_change(1);
        ohci.device_remove(device);
        ohci.port_disable(1);
        assert_eq!(
            (ohci.devices_in_use(), ohci.pipes_in_use()),
            (0, 0),
            "cycle {cycle}"
        );
    }
    assert_clean(&mut ohci);
}

#[test]
fn every_device_and_pipe_slot_can_be_used_and_the_next_is_refused() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let info = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 1,
        translator: None,
    };
    // At addresses nothing answers: their pipes end in no response.
    let devices: Vec<DeviceId> = (0..MAX_DEVICES)
        .map(|i| {
            let device = ohci.device_new(info).unwrap();
            ohci.device_set_address(device, 90 + i as u8).unwrap();
            device
        })
        .collect();
    assert_eq!(ohci.device_new(info), Err(HostError::NoRoom));
    let pipes: Vec<PipeId> = (0..MAX_PIPES)
        .map(|i| {
            ohci.interrupt_open(devices[i % 3], 1, 8, 1 << (i % 6))
                .unwrap()
        })
        .collect();
    assert_eq!(
        ohci.interrupt_open(devices[0], 1, 8, 8),
        Err(HostError::NoRoom)
    );
    // A slot given back is reused at once: the controller must be off it.
    wait(&mut ohci, 5_000);
    ohci.interrupt_close(pipes[5]);
    assert_eq!(ohci.interrupt_open(devices[1], 1, 8, 8), Ok(pipes[5]));
    ohci.device_remove(devices[31]);
    assert_eq!(ohci.device_new(info), Ok(devices[31]));
    for pipe in pipes.iter().step_by(2) {
        ohci.interrupt_close(*pipe);
    }
    for device in devices {
        ohci.device_remove(device);
    }
    assert_eq!((ohci.devices_in_use(), ohci.pipes_in_use()), (0, 0));
    // The tree is back to its static EDs: a new keyboard still types.
    let handle = ohci.hardware().tree.handle_at(&[1]).unwrap();
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 9);
    assert!(ohci.hardware().tree.send_report(handle, key(7)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(7));
    assert_clean(&mut ohci);
}

#[test]
fn handles_and_requests_the_driver_never_gave_are_refused() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Low));
    let mut ohci = started(model);
    let low = DeviceInfo {
        route: Some(0),
        speed: Speed::Low,
        root_port: 1,
        translator: None,
    };
    assert_eq!(
        ohci.device_new(DeviceInfo {
            route: Some(0),
            root_port: 2,
            ..low
        }),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ohci.device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::High,
            ..low
        }),
        Err(HostError::Invalid)
    );
    let device = ohci.device_new(low).unwrap();
    assert_eq!(
        ohci.device_set_max_packet(device, 64),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ohci.device_set_address(device, 128),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ohci.interrupt_open(device, 0, 8, 10),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ohci.interrupt_open(device, 1, 65, 10),
        Err(HostError::Invalid)
    );
    let long = setup(0x80, GET_DESCRIPTOR, 0x0200, 0, MAX_CONTROL_DATA as u16 + 1);
    assert_eq!(
        ohci.control_begin(device, long, &[]),
        Err(HostError::Invalid)
    );
    let short_out = setup(0x21, 0x09, 0x0200, 0, 2);
    assert_eq!(
        ohci.control_begin(device, short_out, &[1]),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ohci.device_set_address(DeviceId(7), 1),
        Err(HostError::UnknownHandle)
    );
    assert_eq!(
        ohci.device_set_address(DeviceId(200), 1),
        Err(HostError::UnknownHandle)
    );
    assert_eq!(
        ohci.interrupt_restart(PipeId(3), true),
        Err(HostError::UnknownHandle)
    );
    let mut buffer = [0u8; 8];
    assert_eq!(
        ohci.interrupt_poll(PipeId(40), &mut buffer),
        Transfer::Failed(TransferError::Controller)
    );
    assert_eq!(ohci.port_status(0), PortStatus::default());
    assert_eq!(ohci.port_reset_poll(9), Some(ResetOutcome::Failed));
    assert_clean(&mut ohci);
}

#[test]
fn smm_lets_go_after_the_ownership_change_request() {
    let mut model = OhciModel::new(1);
    model.smm_owns(Some(30_000));
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = driver(model);
    match ohci.take_ownership() {
        Handoff::Released { micros } => assert!((30_000..40_000).contains(&micros), "{micros} us"),
        other => panic!("{other:?}"),
    }
    assert!(!ohci.hardware().interrupt_routing());
    ohci.reset_and_start().unwrap();
    assert_eq!(ohci.hardware().software_resets, 1);
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Full, 1, 1);
    assert!(ohci.hardware().tree.send_report(handle, key(4)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(4));
    assert!(ohci.hardware().writes_while_owned.is_empty());
    assert_clean(&mut ohci);
}

#[test]
fn smm_that_never_lets_go_keeps_the_controller_untouched() {
    let mut model = OhciModel::new(1);
    model.smm_owns(None);
    let mut ohci = driver(model);
    let start = ohci.hardware().now;
    assert_eq!(ohci.take_ownership(), Handoff::NeverReleased);
    let took = ohci.hardware().now - start;
    assert!(
        (HANDOFF_MICROS..HANDOFF_MICROS + 10_000).contains(&took),
        "{took} us"
    );
    assert!(ohci
        .hardware()
        .log
        .iter()
        .any(|line| line.contains("SMM kept")));
    assert_eq!(ohci.reset_and_start(), Err(OhciError::OwnedByFirmware));
    assert!(!ohci.halt());
    let model = ohci.hardware();
    assert!(model.interrupt_routing());
    assert_eq!(model.functional_state(), 2, "SMM's schedule still runs");
    assert_eq!(model.software_resets, 0);
    assert!(
        model.writes_while_owned.is_empty(),
        "{:?}",
        model.writes_while_owned
    );
}

/// OHCI's waits are paced as every driver's are (`host::wait_until`): SMM
/// that never lets go is asked once per `POLL_INTERVAL_MICROS` for the
/// whole 500 ms, not read back to back (which under QEMU keeps its global
/// lock from the thread that runs the controller).
#[test]
fn waits_read_their_register_once_per_poll_interval() {
    let mut model = OhciModel::new(1);
    model.smm_owns(None);
    let mut ohci = driver(model);
    let (start, reads_before) = (ohci.hardware().now, ohci.hardware().register_reads);
    assert_eq!(ohci.take_ownership(), Handoff::NeverReleased);
    let waited = ohci.hardware().now - start;
    let reads = ohci.hardware().register_reads - reads_before;
    // A read at the wait's start and at its end, and a few outside it.
    let most = waited / POLL_INTERVAL_MICROS + 2 + 4;
    assert!(
        reads <= most,
        "{reads} register reads in {waited} us (at most {most})"
    );
    assert!(
        reads >= most / 2,
        "{reads} register reads: the wait stopped asking"
    );
}

#[test]
fn a_controller_the_firmware_left_running_is_reset_and_types() {
    let mut model = OhciModel::new(1);
    model.firmware_left_running();
    let handle = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Low));
    let mut ohci = started(model);
    assert_eq!(ohci.hardware().software_resets, 1);
    reset_root_port(&mut ohci, 1);
    let (_, pipe) = keyboard(&mut ohci, Speed::Low, 1, 1);
    assert!(ohci.hardware().tree.send_report(handle, key(4)));
    assert_eq!(report_bytes(&mut ohci, pipe), key(4));
    assert_clean(&mut ohci);
}

#[test]
fn what_the_firmware_left_is_stopped_as_linux_does_before_the_reset() {
    /// How the firmware leaves the controller.
    type Leave = fn(&mut OhciModel);
    // (firmware state, HCFS the driver writes first, the wait before HCR)
    let cases: [(Leave, u32, u64); 3] = [
        (|_| {}, 0, 50_000),
        (OhciModel::firmware_left_suspended, 1, 10_000),
        (OhciModel::firmware_left_running, 2, 0),
    ];
    for (leave, state, wait) in cases {
        let mut model = OhciModel::new(1);
        leave(&mut model);
        let mut ohci = started(model);
        let model = ohci.hardware();
        let (written_at, value) = model.control_writes[0];
        assert_eq!((value >> 6) & 3, state, "{:#x?}", model.control_writes);
        let reset_at = model.software_resets_at[0];
        assert!(
            (wait..wait + 2_000).contains(&(reset_at - written_at)),
            "HCFS {state}: the reset came {} us later",
            reset_at - written_at
        );
        assert_eq!(model.functional_state(), 2);
        assert_clean(&mut ohci);
    }
}

#[test]
fn an_implausible_frame_interval_from_the_firmware_is_replaced() {
    let mut model = OhciModel::new(1);
    model.firmware_frame_interval = 0;
    model.firmware_left_running();
    let mut ohci = started(model);
    assert!(ohci
        .hardware()
        .log
        .iter()
        .any(|line| line.contains("frame interval")));
    assert_clean(&mut ohci);
}

#[test]
fn ports_are_powered_as_the_root_hub_says_and_waited_for() {
    for switching in [
        PowerSwitching::None,
        PowerSwitching::Ganged,
        PowerSwitching::PerPort,
    ] {
        let mut model = OhciModel::new(3);
        model.power_switching = switching;
        model.power_on_to_good = 100;
        model.tree.plug(&[3], UsbDevice::Keyboard(Speed::Full));
        let start = model.now;
        let mut ohci = started(model);
        let took = ohci.hardware().now - start;
        // 200 ms of POTPGT before the ports are used.
        assert!(took >= 200_000, "{switching:?}: {took} us");
        if switching != PowerSwitching::None {
            assert!(
                (1..=3).all(|port| ohci.hardware().port_powered(port)),
                "{switching:?}"
            );
        }
        assert!(ohci.port_status(3).connected, "{switching:?}");
        assert_clean(&mut ohci);
    }
}

#[test]
fn a_nonsense_port_count_is_bounded() {
    for (reported, expected) in [(200, 15), (0, 0), (15, 15)] {
        let mut model = OhciModel::new(2);
        model.reported_ports = reported;
        model.tree.plug(&[2], UsbDevice::Keyboard(Speed::Full));
        let mut ohci = started(model);
        assert_eq!(ohci.root_ports(), expected, "NDP {reported}");
        if expected > 0 {
            assert!(ohci.port_status(2).connected);
            assert!(!ohci.port_status(expected).connected);
        }
        assert_eq!(ohci.port_status(expected + 1), PortStatus::default());
        assert_clean(&mut ohci);
    }
    // A BAR too small for all the ports it reports bounds them too.
    let mut model = OhciModel::new(2);
    model.reported_ports = 15;
    let mut ohci = Ohci::new(model, 0x60, DMA_BASE, DMA_BYTES).unwrap();
    ohci.reset_and_start().unwrap();
    assert_eq!(ohci.root_ports(), 3);
}

#[test]
fn halt_leaves_the_controller_in_usb_reset_with_the_ports_powered() {
    let mut model = OhciModel::new(1);
    model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    let mut ohci = started(model);
    reset_root_port(&mut ohci, 1);
    let (device, _) = keyboard(&mut ohci, Speed::Full, 1, 1);
    assert!(ohci.halt());
    assert_eq!(ohci.hardware().functional_state(), 0);
    assert!(ohci.hardware().port_powered(1));
    assert!(!ohci.anything_happened());
    assert_eq!(
        ohci.control_begin(device, setup(0x80, GET_DESCRIPTOR, 0x0100, 0, 8), &[]),
        Err(HostError::ControllerGone)
    );
    let frames = ohci.hardware().frames;
    wait(&mut ohci, 10_000);
    assert_eq!(ohci.hardware().frames, frames, "frames after the halt");
    assert_clean(&mut ohci);
}

#[test]
fn a_controller_that_never_halts_is_given_up_within_the_bound() {
    let mut model = OhciModel::new(1);
    model.never_halts = true;
    let mut ohci = started(model);
    let start = ohci.hardware().now;
    assert!(!ohci.halt());
    let took = ohci.hardware().now - start;
    assert!(took <= HALT_MICROS + 1_000, "{took} us");
    assert!(ohci
        .hardware()
        .log
        .iter()
        .any(|line| line.contains("did not halt")));
}

#[test]
fn a_software_reset_that_never_ends_fails_within_the_bound() {
    let mut model = OhciModel::new(1);
    model.reset_stuck = true;
    let mut ohci = driver(model);
    assert_eq!(ohci.reset_and_start(), Err(OhciError::ResetTimedOut));
    assert!(ohci.hardware().now < USB_RESET_MICROS + RESET_MICROS + 10_000);
    assert!(!ohci.anything_happened());
}

#[test]
fn registers_and_memory_the_driver_cannot_use_are_refused() {
    assert_eq!(
        Ohci::new(OhciModel::new(1), 0x20, DMA_BASE, DMA_BYTES).err(),
        Some(OhciError::RegistersTooSmall)
    );
    assert_eq!(
        Ohci::new(OhciModel::new(1), BAR_BYTES, DMA_BASE, 4096).err(),
        Some(OhciError::BadDmaRegion)
    );
    assert_eq!(
        Ohci::new(OhciModel::new(1), BAR_BYTES, 0xFFFF_F000, DMA_BYTES).err(),
        Some(OhciError::BadDmaRegion)
    );
    assert_eq!(
        Ohci::new(OhciModel::new(1), BAR_BYTES, u64::MAX - 10, DMA_BYTES).err(),
        Some(OhciError::BadDmaRegion)
    );
}

// ---------------------------------------------------------------------------
// Through the device layer, as the kernel runs it.

mod through_the_bus {
    use super::*;
    use crate::bus::Bus;
    use crate::host::ROOT_RESET_MICROS;
    use std::format;
    use std::string::String;
    use std::vec;

    const A: [u8; 8] = [0, 0, 0x04, 0, 0, 0, 0, 0];

    fn bus(model: OhciModel) -> Bus<Driver> {
        Bus::new(started(model))
    }

    fn hw(bus: &mut Bus<Driver>) -> &mut OhciModel {
        bus.controller().hardware()
    }

    /// Polls a frame apart for `micros` of model time; the bytes typed.
    fn run_for(bus: &mut Bus<Driver>, micros: u64) -> Vec<u8> {
        let mut bytes = Vec::new();
        let end = hw(bus).now + micros;
        while hw(bus).now < end {
            bus.poll(&mut |b| bytes.push(b));
            hw(bus).now += 1_000;
        }
        bytes
    }

    /// Polls a frame apart until nothing is left to enumerate.
    fn settle(bus: &mut Bus<Driver>) -> Vec<u8> {
        let mut bytes = Vec::new();
        let mut polls = 0;
        while polls == 0 || !bus.enumeration_idle() {
            polls += 1;
            assert!(
                polls < 100_000,
                "enumeration never ends: {:#?}",
                hw(bus).log
            );
            bus.poll(&mut |b| bytes.push(b));
            hw(bus).now += 1_000;
        }
        bytes
    }

    /// Polls until `count` bytes came, bounded.
    fn typed(bus: &mut Bus<Driver>, count: usize) -> Vec<u8> {
        let mut bytes = Vec::new();
        for _ in 0..200 {
            bus.poll(&mut |b| bytes.push(b));
            if bytes.len() >= count {
                break;
            }
            hw(bus).now += 1_000;
        }
        bytes
    }

    fn keyboards(bus: &Bus<Driver>) -> Vec<String> {
        bus.keyboards().map(|at| format!("{at}")).collect()
    }

    fn assert_clean(bus: &mut Bus<Driver>) {
        let errors = hw(bus).all_errors();
        assert!(errors.is_empty(), "{errors:#?}\nlog: {:#?}", hw(bus).log);
    }

    #[test]
    fn a_keyboard_on_a_root_port_is_found_at_boot_and_types() {
        let mut model = OhciModel::new(2);
        let keyboard = model.tree.plug(&[2], UsbDevice::Keyboard(Speed::Full));
        let mut bus = bus(model);
        assert_eq!(bus.enumerate(), 1, "{:#?}", model_log(&mut bus));
        assert_eq!(keyboards(&bus), ["2"]);
        assert!(hw(&mut bus).tree.send_report(keyboard, A));
        assert_eq!(typed(&mut bus, 1), [0x1E]);
        assert!(hw(&mut bus).tree.send_report(keyboard, [0; 8]));
        assert_eq!(typed(&mut bus, 1), [0x9E]);
        assert!(bus.shut_down());
        assert_eq!(hw(&mut bus).functional_state(), 0);
        assert_clean(&mut bus);
    }

    /// As Linux's `root_port_reset`: the controller's 10 ms pulses, each
    /// begun once the last has ended, until the port has been in reset
    /// 50 ms, with the device layer polling frame by frame.
    #[test]
    fn a_root_port_reset_is_repeated_in_pulses_until_50_ms() {
        let mut model = OhciModel::new(2);
        let keyboard = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        let mut bus = bus(model);
        bus.start_enumeration();
        settle(&mut bus);
        assert_eq!(keyboards(&bus), ["1"], "{:#?}", model_log(&mut bus));
        let pulses = hw(&mut bus).port_resets_at.clone();
        assert!(pulses.iter().all(|&(port, _)| port == 1), "{pulses:?}");
        let times: Vec<u64> = pulses.iter().map(|&(_, at)| at).collect();
        assert!(times.len() >= 5, "only {} pulses: {times:?}", times.len());
        for pair in times.windows(2) {
            assert!(pair[1] - pair[0] >= PORT_RESET_PULSE_MICROS, "{times:?}");
            // Each pulse starts at the first poll after the last one ended.
            assert!(
                pair[1] - pair[0] <= PORT_RESET_PULSE_MICROS + 2_000,
                "{times:?}"
            );
        }
        let in_reset = times[times.len() - 1] + PORT_RESET_PULSE_MICROS - times[0];
        assert!(in_reset >= ROOT_RESET_MICROS, "in reset {in_reset} us");
        assert!(in_reset < ROOT_RESET_MICROS + PORT_RESET_PULSE_MICROS + 2_000);
        assert!(hw(&mut bus).tree.send_report(keyboard, A));
        assert_eq!(typed(&mut bus, 1), [0x1E]);
        assert_clean(&mut bus);
    }

    #[test]
    fn a_low_speed_keyboard_behind_a_hub_is_found_and_types() {
        let mut model = OhciModel::new(2);
        model.tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let keyboard = model.tree.plug(&[1, 3], UsbDevice::Keyboard(Speed::Low));
        let mut bus = bus(model);
        assert_eq!(bus.enumerate(), 1, "{:#?}", model_log(&mut bus));
        assert_eq!(keyboards(&bus), ["1.3"]);
        assert!(hw(&mut bus).tree.send_report(keyboard, A));
        assert_eq!(typed(&mut bus, 1), [0x1E]);
        assert_clean(&mut bus);
    }

    #[test]
    fn a_keyboard_plugged_in_and_pulled_out_a_thousand_times_comes_and_goes() {
        let mut model = OhciModel::new(2);
        model.tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let mut bus = bus(model);
        bus.enumerate();
        settle(&mut bus);
        let tables = |bus: &mut Bus<Driver>| {
            (
                bus.devices(),
                bus.controller().devices_in_use(),
                bus.controller().pipes_in_use(),
            )
        };
        let before = tables(&mut bus);
        assert_eq!(before, (1, 1, 1));
        for cycle in 0..1_000u32 {
            let (path, speed) = match cycle % 4 {
                0 => (vec![2], Speed::Full),
                1 => (vec![2], Speed::Low),
                2 => (vec![1, 1 + (cycle / 4 % 4) as u8], Speed::Full),
                _ => (vec![1, 1 + (cycle / 4 % 4) as u8], Speed::Low),
            };
            let keyboard = hw(&mut bus).tree.plug(&path, UsbDevice::Keyboard(speed));
            // A hub's status change endpoint is polled every 32 ms.
            run_for(&mut bus, 50_000);
            settle(&mut bus);
            assert_eq!(
                keyboards(&bus).len(),
                1,
                "cycle {cycle}: {:#?}",
                model_log(&mut bus)
            );
            assert!(hw(&mut bus).tree.send_report(keyboard, A));
            assert_eq!(typed(&mut bus, 1), [0x1E], "cycle {cycle}");
            hw(&mut bus).tree.unplug(&path);
            let mut bytes = settle(&mut bus);
            bytes.extend(run_for(&mut bus, 50_000));
            assert_eq!(bytes, [0x9E], "cycle {cycle}");
            assert_eq!(tables(&mut bus), before, "cycle {cycle}");
        }
        assert_clean(&mut bus);
    }

    #[test]
    fn a_stall_and_a_repeated_toggle_are_recovered_and_no_key_is_lost_or_doubled() {
        let mut model = OhciModel::new(1);
        let keyboard = model.tree.plug(&[1], UsbDevice::Keyboard(Speed::Low));
        let mut bus = bus(model);
        assert_eq!(bus.enumerate(), 1);
        assert!(hw(&mut bus).tree.send_report(keyboard, A));
        assert_eq!(typed(&mut bus, 1), [0x1E]);
        // The ACK was lost: the release comes after a repeat of A.
        hw(&mut bus).tree.repeat_next_toggle(keyboard);
        assert!(hw(&mut bus).tree.send_report(keyboard, [0; 8]));
        let mut bytes = typed(&mut bus, 1);
        bytes.extend(run_for(&mut bus, 50_000));
        assert_eq!(bytes, [0x9E]);
        assert_eq!(hw(&mut bus).toggle_mismatches, 1);
        // A stall: the bus clears the halt and the pipe starts again.
        hw(&mut bus).tree.stall_interrupt(keyboard);
        assert!(hw(&mut bus).tree.send_report(keyboard, A));
        let mut bytes = typed(&mut bus, 1);
        bytes.extend(run_for(&mut bus, 50_000));
        assert_eq!(bytes, [0x1E], "{:#?}", model_log(&mut bus));
        assert_eq!(keyboards(&bus), ["1"]);
        assert_clean(&mut bus);
    }

    #[test]
    fn a_twenty_byte_report_in_eight_byte_packets_is_put_back_together() {
        use crate::model::devices::rollover_report;
        let mut model = OhciModel::new(1);
        let keyboard = model
            .tree
            .plug(&[1], UsbDevice::RolloverKeyboard(Speed::Full));
        let mut bus = bus(model);
        assert_eq!(bus.enumerate(), 1, "{:#?}", model_log(&mut bus));
        let logged =
            |bus: &mut Bus<Driver>, text: &str| hw(bus).log.iter().any(|line| line.contains(text));
        assert!(logged(&mut bus, "(2 key fields, 20-byte reports)"));
        let a_and_b = rollover_report(&[0x04, 0x05]);
        assert!(hw(&mut bus).tree.send_packets(keyboard, &a_and_b, false));
        assert_eq!(typed(&mut bus, 2), [0x1E, 0x30]);
        // Cut short after 10 bytes: dropped, and the next report is whole.
        assert!(hw(&mut bus)
            .tree
            .send_packets(keyboard, &a_and_b[..10], false));
        assert!(hw(&mut bus)
            .tree
            .send_packets(keyboard, &rollover_report(&[]), false));
        assert_eq!(typed(&mut bus, 2), [0x9E, 0xB0]);
        assert!(logged(
            &mut bus,
            "keyboard: 1 unreadable reports dropped (the last 10 bytes)"
        ));
        assert_clean(&mut bus);
    }

    fn model_log(bus: &mut Bus<Driver>) -> Vec<String> {
        hw(bus).log.clone()
    }
}
