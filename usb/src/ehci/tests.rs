//! The EHCI driver against its register model ([`crate::model::ehci`])
//! and the device tree: through the device layer ([`Bus`]) as the kernel
//! runs it, and through [`HostController`] directly where a test needs one
//! call at a time.

use super::layout::{Layout, MAX_DEVICES, MAX_PIPES};
use super::*;
use crate::bus::Bus;
use crate::host::{TransactionTranslator, POLL_INTERVAL_MICROS};
use crate::model::devices::UsbDevice;
use crate::model::ehci::{EhciModel, SplitRecord, BAR_BYTES, DMA_BASE, DMA_BYTES};
use crate::model::{reset_polled, reset_root_port};
use crate::{Hardware, Memory};
use budget::Booking;
use std::vec::Vec;

/// The boot report of the A key, and of nothing held.
const KEY_A: [u8; 8] = [0, 0, 0x04, 0, 0, 0, 0, 0];
const KEY_B: [u8; 8] = [0, 0, 0x05, 0, 0, 0, 0, 0];
const NO_KEYS: [u8; 8] = [0; 8];
/// Set-1 make and break codes of A and B.
const A_MAKE: u8 = 0x1E;
const A_BREAK: u8 = 0x9E;
const B_MAKE: u8 = 0x30;
const B_BREAK: u8 = 0xB0;

/// A driver over `model`, taken from the firmware, reset and started.
fn started(model: EhciModel) -> Ehci<EhciModel> {
    let mut ehci = Ehci::new(model, BAR_BYTES, DMA_BASE, DMA_BYTES).expect("new");
    assert!(matches!(
        ehci.take_ownership(),
        Handoff::Released { .. } | Handoff::NotOwned
    ));
    ehci.reset_and_start().expect("start");
    ehci
}

/// The device layer over a started driver, after boot enumeration.
fn enumerated(model: EhciModel) -> (Bus<Ehci<EhciModel>>, usize) {
    let mut bus = Bus::new(started(model));
    let keyboards = bus.enumerate();
    (bus, keyboards)
}

fn model(bus: &mut Bus<Ehci<EhciModel>>) -> &mut EhciModel {
    bus.controller().hardware()
}

/// Polls for `micros` of model time; the set-1 bytes that came.
fn run(bus: &mut Bus<Ehci<EhciModel>>, micros: u64) -> Vec<u8> {
    let end = model(bus).now + micros;
    let mut bytes = Vec::new();
    while model(bus).now < end {
        bus.poll(&mut |b| bytes.push(b));
    }
    bytes
}

/// Presses and releases a key on keyboard `handle`; the bytes typed.
fn type_key(bus: &mut Bus<Ehci<EhciModel>>, handle: usize, report: [u8; 8]) -> Vec<u8> {
    assert!(model(bus).tree.send_report(handle, report));
    assert!(model(bus).tree.send_report(handle, NO_KEYS));
    run(bus, 20_000)
}

/// Nothing the model or the devices noted as wrong.
fn assert_clean(model: &EhciModel) {
    assert!(model.errors.is_empty(), "controller: {:#?}", model.errors);
    assert!(
        model.tree.errors().is_empty(),
        "devices: {:#?}",
        model.tree.errors()
    );
}

fn logged(model: &EhciModel, text: &str) -> bool {
    model.log.iter().any(|line| line.contains(text))
}

#[test]
fn a_high_speed_keyboard_on_a_root_port_types() {
    let mut m = EhciModel::new(4);
    m.port_power_control = true;
    let keyboard = m.tree.plug(&[2], UsbDevice::Keyboard(Speed::High));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(keyboards, 1, "{:#?}", model(&mut bus).log);
    let (_, configuration, address) = model(&mut bus).tree.keyboard_state(keyboard);
    assert_eq!(configuration, 1);
    assert_ne!(address, 0);
    assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
    assert_eq!(type_key(&mut bus, keyboard, KEY_B), [B_MAKE, B_BREAK]);
    let m = model(&mut bus);
    assert!(m.split_log.is_empty(), "high speed needs no split");
    assert!(
        m.periodic_transactions > 0,
        "the report came by the frame list"
    );
    assert!(m.handed_to_companion.is_empty());
    assert_eq!(m.usbintr(), 0, "polled: no interrupts");
    assert_clean(m);
}

/// Checks every split the model ran for the device at `address`: the
/// translator's hub and port, the speed, and the masks by schedule.
fn assert_splits(m: &EhciModel, address: u8, hub_address: u8, hub_port: u8, eps: u8) {
    let splits: Vec<SplitRecord> = m
        .split_log
        .iter()
        .copied()
        .filter(|s| s.address == address)
        .collect();
    assert!(
        splits.iter().any(|s| !s.periodic),
        "control transfers split"
    );
    assert!(splits.iter().any(|s| s.periodic), "reports split");
    for s in splits {
        assert_eq!(s.hub_address, hub_address, "Hub Addr: {s:?}");
        assert_eq!(s.hub_port, hub_port, "Port Number: {s:?}");
        assert_eq!(s.eps, eps, "EPS: {s:?}");
        if s.periodic {
            assert_eq!((s.endpoint, s.control), (1, false), "{s:?}");
            let start = s.s_mask.trailing_zeros();
            assert!(s.s_mask.count_ones() == 1 && start <= 3, "S-mask: {s:?}");
            assert_eq!(s.c_mask, 0b111 << (start + 2), "C-mask: {s:?}");
        } else {
            assert_eq!((s.endpoint, s.control), (0, true), "{s:?}");
            assert_eq!((s.s_mask, s.c_mask), (0, 0), "async masks: {s:?}");
        }
    }
}

#[test]
fn keyboards_behind_a_high_speed_hub_go_through_its_translator() {
    let mut m = EhciModel::new(4);
    let hub = m.tree.plug(
        &[3],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 4,
            multi_tt: false,
        },
    );
    let full = m.tree.plug(&[3, 2], UsbDevice::Keyboard(Speed::Full));
    let low = m.tree.plug(&[3, 4], UsbDevice::Keyboard(Speed::Low));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(keyboards, 2, "{:#?}", model(&mut bus).log);
    assert_eq!(type_key(&mut bus, full, KEY_A), [A_MAKE, A_BREAK]);
    assert_eq!(type_key(&mut bus, low, KEY_B), [B_MAKE, B_BREAK]);
    let m = model(&mut bus);
    let hub_address = m.tree.keyboard_state(hub).2;
    let full_address = m.tree.keyboard_state(full).2;
    let low_address = m.tree.keyboard_state(low).2;
    assert_splits(m, full_address, hub_address, 2, 0);
    assert_splits(m, low_address, hub_address, 4, 1);
    assert!(
        m.split_log.iter().all(|s| s.address != hub_address),
        "the hub itself is high speed"
    );
    // And the devices saw the same translator fields (at address 0,
    // before SET_ADDRESS, either keyboard's).
    for (split, packet) in m.tree.splits() {
        let ports: &[u8] = match packet.address {
            0 => &[2, 4],
            a if a == full_address => &[2],
            _ => &[4],
        };
        assert_eq!(split.hub_address, hub_address, "{packet:?}");
        assert!(ports.contains(&split.hub_port), "{split:?} {packet:?}");
    }
    assert!(m
        .tree
        .splits()
        .iter()
        .any(|(_, p)| p.address == low_address));
    assert!(m.handed_to_companion.is_empty());
    assert_clean(m);
}

#[test]
fn with_no_companion_the_integrated_hub_carries_full_and_low_speed() {
    let mut m = EhciModel::new(2);
    m.companions = 0;
    // Intel's rate-matching hub sits on each root port.
    let hub = m.tree.plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 8,
            multi_tt: true,
        },
    );
    let full = m.tree.plug(&[1, 5], UsbDevice::Keyboard(Speed::Full));
    let low = m.tree.plug(&[1, 7], UsbDevice::Keyboard(Speed::Low));
    // A full-speed device straight on a root port has nowhere to go.
    m.tree.plug(&[2], UsbDevice::Keyboard(Speed::Full));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(bus.controller().companions(), 0);
    assert_eq!(keyboards, 2, "{:#?}", model(&mut bus).log);
    assert_eq!(type_key(&mut bus, full, KEY_A), [A_MAKE, A_BREAK]);
    assert_eq!(type_key(&mut bus, low, KEY_B), [B_MAKE, B_BREAK]);
    let m = model(&mut bus);
    let hub_address = m.tree.keyboard_state(hub).2;
    assert_splits(m, m.tree.keyboard_state(full).2, hub_address, 5, 0);
    assert_splits(m, m.tree.keyboard_state(low).2, hub_address, 7, 1);
    assert!(m.handed_to_companion.is_empty(), "no companion to hand to");
    assert!(logged(m, "port 2: a full-speed device and no companion"));
    assert_clean(m);
}

#[test]
fn full_and_low_speed_keyboards_on_root_ports_go_to_the_companion() {
    let mut m = EhciModel::new(4);
    m.tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
    m.tree.plug(&[4], UsbDevice::Keyboard(Speed::Low));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(keyboards, 0);
    let m = model(&mut bus);
    let mut handed = m.handed_to_companion.clone();
    handed.sort_unstable();
    assert_eq!(handed, [1, 4]);
    assert!(logged(
        m,
        "port 1: full-speed device, handed to the companion"
    ));
    // Low speed shows as a K state before any reset, and goes at once.
    assert!(logged(
        m,
        "port 4: low-speed device, handed to the companion"
    ));
    assert!(!m.port_resets.contains(&4), "no reset for low speed");
    assert!(m.port_resets.contains(&1), "full speed shows by its reset");
    assert_clean(m);

    // The port comes back when the device goes; a high-speed one is ours.
    m.tree.unplug(&[1]);
    run(&mut bus, 1_000);
    let keyboard = model(&mut bus)
        .tree
        .plug(&[1], UsbDevice::Keyboard(Speed::High));
    run(&mut bus, 1_000_000);
    assert_eq!(bus.keyboards().count(), 1, "{:#?}", model(&mut bus).log);
    assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
    assert_clean(model(&mut bus));
}

#[test]
fn the_firmware_that_lets_go_is_waited_for_and_its_smis_turned_off() {
    let mut m = EhciModel::new(2).left_running();
    m.firmware_releases_after = Some(30_000);
    let mut ehci = Ehci::new(m, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    let Handoff::Released { micros } = ehci.take_ownership() else {
        panic!("not released");
    };
    assert!((30_000..31_000).contains(&micros), "{micros}");
    let (support, control) = ehci.hardware().legacy_registers();
    assert_eq!(support & (1 << 16 | 1 << 24), 1 << 24, "OS-owned only");
    assert_eq!(control, 0, "SMIs off, their status cleared");
    ehci.reset_and_start().unwrap();
    assert_clean(ehci.hardware());
}

#[test]
fn a_firmware_that_never_lets_go_keeps_the_controller_untouched() {
    let mut m = EhciModel::new(2);
    m.firmware_releases_after = None;
    m.tree.plug(&[1], UsbDevice::Keyboard(Speed::High));
    let mut ehci = Ehci::new(m, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    let start = ehci.hardware().now;
    assert_eq!(ehci.take_ownership(), Handoff::NeverReleased);
    let waited = ehci.hardware().now - start;
    assert!(
        (HANDOFF_MICROS..HANDOFF_MICROS + 1_000).contains(&waited),
        "{waited}"
    );
    assert_eq!(ehci.reset_and_start(), Err(EhciError::FirmwareOwns));
    assert!(ehci.halt(), "halted as the firmware left it");
    assert_eq!(
        ehci.device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::High,
            root_port: 1,
            translator: None,
        }),
        Err(HostError::ControllerGone)
    );
    let m = ehci.hardware();
    assert_eq!(m.mmio_writes, 0, "not one register written");
    let (support, control) = m.legacy_registers();
    assert_eq!(support & (1 << 16 | 1 << 24), 1 << 16, "request withdrawn");
    assert_eq!(
        control, 0x2000_E03F,
        "the firmware's SMIs left as they were"
    );
    assert!(logged(m, "the firmware kept the controller for 1000 ms"));
    assert_clean(m);
}

#[test]
fn a_looping_capability_list_is_walked_a_bounded_number_of_times() {
    let mut m = EhciModel::new(2).firmware_not_owning();
    m.eecp_loop = true;
    let mut ehci = Ehci::new(m, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    let start = ehci.hardware().now;
    assert_eq!(ehci.take_ownership(), Handoff::NotOwned);
    assert!(ehci.hardware().now - start < 1_000);
    assert!(logged(
        ehci.hardware(),
        "extended capabilities loop at 0x60"
    ));
}

#[test]
fn registers_and_memory_out_of_bounds_are_refused() {
    let new =
        |bar: u32, base: u64, bytes: u64| Ehci::new(EhciModel::new(4), bar, base, bytes).err();
    // 4 ports end at 0x20 + 0x44 + 16.
    assert_eq!(
        new(0x70, DMA_BASE, DMA_BYTES),
        Some(EhciError::RegistersOutsideBar)
    );
    assert_eq!(new(0x74, DMA_BASE, DMA_BYTES), None);
    assert_eq!(
        new(0x08, DMA_BASE, DMA_BYTES),
        Some(EhciError::RegistersOutsideBar)
    );
    assert_eq!(
        new(BAR_BYTES, DMA_BASE + 0x800, DMA_BYTES),
        Some(EhciError::DmaUnaligned)
    );
    assert_eq!(
        new(BAR_BYTES, DMA_BASE, DMA_BYTES_USED - 1),
        Some(EhciError::DmaTooSmall)
    );
    assert_eq!(
        new(BAR_BYTES, (1 << 32) - 0x1000, DMA_BYTES),
        Some(EhciError::DmaAbove4GiB)
    );
}

#[test]
fn a_reset_or_halt_that_never_ends_costs_bounded_time() {
    let mut m = EhciModel::new(2).firmware_not_owning();
    m.reset_stuck = true;
    let mut ehci = Ehci::new(m, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    let start = ehci.hardware().now;
    assert_eq!(ehci.reset_and_start(), Err(EhciError::ResetStuck));
    let waited = ehci.hardware().now - start;
    assert!(
        (RESET_MICROS..RESET_MICROS + 1_000).contains(&waited),
        "{waited}"
    );

    let mut ehci = started(EhciModel::new(2).firmware_not_owning());
    ehci.hardware().halt_stuck = true;
    let start = ehci.hardware().now;
    assert!(!ehci.halt());
    assert!(ehci.hardware().now - start < HALT_MICROS + 1_000);
    assert_eq!(ehci.hardware().configflag(), 0, "ports handed back anyway");
}

/// The SeaBIOS case: the firmware left the controller running, so starting
/// waits for the halt, the reset and both schedules. Each wait reads its
/// register once per `POLL_INTERVAL_MICROS`: a wait that read without a
/// pause kept QEMU's global lock from the thread that runs the controller's
/// frames, and on a loaded host the schedules "did not start".
#[test]
fn waits_read_their_register_once_per_poll_interval() {
    let mut m = EhciModel::new(2).left_running();
    m.firmware_releases_after = Some(0);
    let mut ehci = Ehci::new(m, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    assert!(matches!(ehci.take_ownership(), Handoff::Released { .. }));
    let (start, reads_before) = (ehci.hardware().now, ehci.hardware().mmio_reads);
    ehci.reset_and_start().unwrap();
    let waited = ehci.hardware().now - start;
    let reads = ehci.hardware().mmio_reads - reads_before;
    // Three waits (halt, reset, start), each with a read at its start and
    // at its end, and a few reads outside any wait.
    let most = waited / POLL_INTERVAL_MICROS + 3 * 2 + 8;
    assert!(
        u64::from(reads) <= most,
        "{reads} register reads in {waited} us (at most {most})"
    );
    assert!(waited >= 300, "the model's 300 us reset was waited for");
    assert_clean(ehci.hardware());
}

#[test]
fn halt_stops_the_controller_and_gives_every_port_to_the_companions() {
    let mut m = EhciModel::new(4);
    m.tree.plug(&[2], UsbDevice::Keyboard(Speed::High));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(keyboards, 1);
    assert_eq!(model(&mut bus).configflag(), 1);
    assert!(bus.shut_down());
    let ehci = bus.controller();
    for port in 1..=4 {
        assert!(ehci.port_status(port) == PortStatus::default());
        let portsc = ehci
            .hardware()
            .mmio_read(0x20 + 0x44 + 4 * (u32::from(port) - 1));
        assert_ne!(
            portsc & PORT_OWNER,
            0,
            "port {port} routed to the companion"
        );
    }
    let m = ehci.hardware();
    assert!(m.halted());
    assert_eq!(m.configflag(), 0);
    assert_clean(m);
}

#[test]
fn port_change_bits_stay_until_acknowledged() {
    let mut ehci = started(EhciModel::new(2));
    ehci.hardware()
        .tree
        .plug(&[1], UsbDevice::Keyboard(Speed::High));
    ehci.hardware().advance(1_000);
    let status = ehci.port_status(1);
    assert!(status.connected && status.connect_changed && !status.enabled);
    assert!(!status.low_speed);
    ehci.port_reset_begin(1);
    assert!(ehci.port_status(1).connect_changed, "the reset kept CSC");
    assert_eq!(
        reset_polled(&mut ehci, 1),
        ResetOutcome::Enabled(Speed::High)
    );
    let status = ehci.port_status(1);
    assert!(status.enabled && status.connect_changed, "{status:?}");
    ehci.clear_port_change(1);
    let status = ehci.port_status(1);
    assert!(status.enabled && !status.connect_changed, "{status:?}");
    ehci.port_disable(1);
    let status = ehci.port_status(1);
    assert!(status.connected && !status.enabled && !status.connect_changed);
    assert_clean(ehci.hardware());
}

#[test]
fn anything_happened_is_one_register_read() {
    let mut ehci = started(EhciModel::new(2));
    // The ports' first connections have been seen (or not): start idle.
    ehci.hardware().advance(1_000);
    while ehci.anything_happened() {}
    let now = ehci.hardware().now;
    assert!(!ehci.anything_happened());
    assert_eq!(ehci.hardware().now - now, 5, "one read of USBSTS");
    ehci.hardware()
        .tree
        .plug(&[2], UsbDevice::Keyboard(Speed::High));
    ehci.hardware().advance(200);
    assert!(ehci.anything_happened(), "a port change");
    assert!(!ehci.anything_happened(), "and it was acknowledged");
}

#[test]
fn a_lying_keyboard_is_refused_and_its_memory_reused() {
    let mut m = EhciModel::new(2);
    // At high speed it says endpoint 0 is 8 bytes; at full speed, behind a
    // translator, its configuration's lengths lie.
    m.tree.plug(&[1], UsbDevice::LyingKeyboard(Speed::High));
    m.tree.plug(
        &[2],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 4,
            multi_tt: false,
        },
    );
    m.tree.plug(&[2, 1], UsbDevice::LyingKeyboard(Speed::Full));
    let (mut bus, keyboards) = enumerated(m);
    assert_eq!(keyboards, 0, "{:#?}", model(&mut bus).log);
    let m = model(&mut bus);
    assert!(logged(m, "port 1: endpoint 0 packet size 8 is impossible"));
    assert!(logged(m, "port 2.1: 34 bytes came of the 64 asked for"));
    assert_clean(m);
    // Only the hub and its status pipe hold driver memory.
    assert_eq!(
        bus.controller().free_slots(),
        (MAX_DEVICES - 1, MAX_PIPES - 1)
    );
    // Whatever the device layer kept of it, the driver refuses what no
    // device may have: a high-speed endpoint 0 of 8 bytes, interrupt
    // packets past 64 bytes, endpoints past 15.
    let ehci = bus.controller();
    let device = ehci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::High,
            root_port: 2,
            translator: None,
        })
        .unwrap();
    assert_eq!(
        ehci.device_set_max_packet(device, 8),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.device_set_max_packet(device, 512),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.interrupt_open(device, 1, 65, 1),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.interrupt_open(device, 1, 0, 1),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.interrupt_open(device, 16, 8, 1),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.interrupt_open(device, 0, 8, 1),
        Err(HostError::Invalid)
    );
    let too_long = Setup {
        request_type: 0x80,
        request: 6,
        value: 0x0200,
        index: 0,
        length: MAX_CONTROL_DATA as u16 + 1,
    };
    assert_eq!(
        ehci.control_begin(device, too_long, &[]),
        Err(HostError::Invalid)
    );
    let short_out = Setup {
        request_type: 0x21,
        request: 9,
        value: 0x0200,
        index: 0,
        length: 4,
    };
    assert_eq!(
        ehci.control_begin(device, short_out, &[1]),
        Err(HostError::Invalid)
    );
    // Full speed only behind a translator; a translator only for it.
    let full = DeviceInfo {
        route: Some(0),
        speed: Speed::Full,
        root_port: 1,
        translator: None,
    };
    assert_eq!(ehci.device_new(full), Err(HostError::Invalid));
    let tt = Some(TransactionTranslator {
        hub_address: 0,
        hub_port: 1,
    });
    assert_eq!(
        ehci.device_new(DeviceInfo {
            route: Some(0),
            translator: tt,
            ..full
        }),
        Err(HostError::Invalid)
    );
    assert_eq!(
        ehci.device_new(DeviceInfo {
            route: Some(0),
            root_port: 3,
            ..full
        }),
        Err(HostError::Invalid)
    );
    ehci.device_remove(device);
    assert_eq!(
        ehci.device_set_address(device, 5),
        Err(HostError::UnknownHandle)
    );
    assert_clean(ehci.hardware());
}

#[test]
fn a_repeated_report_is_dropped_and_a_stall_recovered() {
    for translated in [false, true] {
        let mut m = EhciModel::new(2);
        let keyboard = if translated {
            m.tree.plug(
                &[1],
                UsbDevice::Hub {
                    speed: Speed::High,
                    ports: 4,
                    multi_tt: false,
                },
            );
            m.tree.plug(&[1, 1], UsbDevice::Keyboard(Speed::Full))
        } else {
            m.tree.plug(&[1], UsbDevice::Keyboard(Speed::High))
        };
        let (mut bus, keyboards) = enumerated(m);
        assert_eq!(keyboards, 1);
        assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
        // The release comes again with the old toggle: dropped, so the
        // next press is not taken for a repeat either.
        model(&mut bus).tree.repeat_next_toggle(keyboard);
        assert_eq!(type_key(&mut bus, keyboard, KEY_B), [B_MAKE, B_BREAK]);
        // An odd number of reports, so the host's toggle is DATA1...
        let m = model(&mut bus);
        assert!(m.tree.send_report(keyboard, KEY_A));
        assert!(m.tree.send_report(keyboard, NO_KEYS));
        assert!(m.tree.send_report(keyboard, NO_KEYS));
        assert_eq!(run(&mut bus, 20_000), [A_MAKE, A_BREAK]);
        // ...when a stall comes: the device layer clears it, which puts
        // the device's toggle back to DATA0, and so must the driver.
        model(&mut bus).tree.stall_interrupt(keyboard);
        run(&mut bus, 100_000);
        for _ in 0..3 {
            assert_eq!(
                type_key(&mut bus, keyboard, KEY_A),
                [A_MAKE, A_BREAK],
                "translated {translated}: {:#?}",
                model(&mut bus).log
            );
        }
        assert_clean(model(&mut bus));
    }
}

#[test]
fn six_keyboards_one_with_its_data_buffer_across_a_page() {
    // Device slot 5's data buffer starts 32 bytes before a page boundary:
    // its configuration descriptor (34 bytes) and report descriptor are
    // read through the second buffer pointer.
    let layout = Layout::new(DMA_BASE);
    assert_eq!(layout.device_data(5) % 0x1000, 0xFE0);
    let mut m = EhciModel::new(6);
    let keyboards: Vec<usize> = (1..=6)
        .map(|port| m.tree.plug(&[port], UsbDevice::Keyboard(Speed::High)))
        .collect();
    let (mut bus, found) = enumerated(m);
    assert_eq!(found, 6, "{:#?}", model(&mut bus).log);
    for keyboard in keyboards {
        assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
    }
    assert_clean(model(&mut bus));
}

#[test]
fn sixty_four_bit_controllers_get_the_long_layout_with_high_dwords_zero() {
    for sixty_four_bit in [false, true] {
        let mut m = EhciModel::new(2);
        m.sixty_four_bit = sixty_four_bit;
        // Junk everywhere: what the driver does not write stays junk.
        for word in (0..DMA_BYTES).step_by(4) {
            m.mem_write(DMA_BASE + word, 0xDEAD_BEEF);
        }
        let keyboard = m.tree.plug(&[1], UsbDevice::Keyboard(Speed::High));
        let (mut bus, keyboards) = enumerated(m);
        assert_eq!(
            keyboards,
            1,
            "64-bit {sixty_four_bit}: {:#?}",
            model(&mut bus).log
        );
        assert!(bus.controller().sixty_four_bit() == sixty_four_bit);
        assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
        let layout = Layout::new(DMA_BASE);
        let m = model(&mut bus);
        let high_dwords = [
            layout.pipe_qtd(0) + 0x20,
            layout.pipe_qh(0) + 0x30,
            layout.device_qh(0) + 0x30,
            layout.device_qtd(0, Stage::Setup) + 0x20,
        ];
        for address in high_dwords {
            for i in 0..5 {
                let word = m.peek(address + 4 * i);
                let expected = if sixty_four_bit { 0 } else { 0xDEAD_BEEF };
                assert_eq!(
                    word, expected,
                    "64-bit {sixty_four_bit}: {address:#x} + {i}"
                );
            }
        }
        assert_clean(m);
    }
}

#[test]
fn a_thousand_plug_cycles_never_run_the_pools_dry() {
    let mut m = EhciModel::new(2);
    let hub = UsbDevice::Hub {
        speed: Speed::High,
        ports: 4,
        multi_tt: false,
    };
    m.tree.plug(&[2], hub);
    let (mut bus, _) = enumerated(m);
    for cycle in 0..1_000 {
        // A high-speed keyboard on the root port, and a full-speed one
        // behind the hub, in turns.
        let path: &[u8] = if cycle % 2 == 0 { &[1] } else { &[2, 3] };
        let speed = if cycle % 2 == 0 {
            Speed::High
        } else {
            Speed::Full
        };
        let keyboard = model(&mut bus).tree.plug(path, UsbDevice::Keyboard(speed));
        let mut waited = 0;
        while bus.keyboards().count() == 0 {
            run(&mut bus, 10_000);
            waited += 1;
            assert!(waited < 100, "cycle {cycle}: {:#?}", model(&mut bus).log);
        }
        assert_eq!(
            type_key(&mut bus, keyboard, KEY_A),
            [A_MAKE, A_BREAK],
            "cycle {cycle}"
        );
        model(&mut bus).tree.unplug(path);
        let mut waited = 0;
        while bus.keyboards().count() != 0 {
            run(&mut bus, 10_000);
            waited += 1;
            assert!(waited < 100, "cycle {cycle}: not gone");
        }
        assert!(
            model(&mut bus).errors.is_empty(),
            "cycle {cycle}: {:#?}",
            model(&mut bus).errors
        );
    }
    // Only the hub (and its status pipe) remain.
    assert_eq!(
        bus.controller().free_slots(),
        (MAX_DEVICES - 1, MAX_PIPES - 1)
    );
    assert_clean(model(&mut bus));
}

/// A high-speed keyboard on root `port`, reset, addressed at `address`
/// and configured, through [`HostController`] alone.
fn addressed_keyboard(ehci: &mut Ehci<EhciModel>, port: u8, address: u8) -> DeviceId {
    ehci.hardware().advance(1_000);
    assert_eq!(
        reset_root_port(ehci, port),
        ResetOutcome::Enabled(Speed::High)
    );
    let device = ehci
        .device_new(DeviceInfo {
            route: Some(0),
            speed: Speed::High,
            root_port: port,
            translator: None,
        })
        .unwrap();
    let set_address = Setup {
        request_type: 0,
        request: 5,
        value: u16::from(address),
        index: 0,
        length: 0,
    };
    assert_eq!(control(ehci, device, set_address).0, Transfer::Complete(0));
    ehci.device_set_address(device, address).unwrap();
    let set_configuration = Setup {
        request_type: 0,
        request: 9,
        value: 1,
        index: 0,
        length: 0,
    };
    assert_eq!(
        control(ehci, device, set_configuration).0,
        Transfer::Complete(0)
    );
    device
}

/// Runs a control transfer to its end; what it ended in, and the bytes.
fn control(ehci: &mut Ehci<EhciModel>, device: DeviceId, setup: Setup) -> (Transfer, Vec<u8>) {
    ehci.control_begin(device, setup, &[]).unwrap();
    let mut bytes = std::vec![0u8; usize::from(setup.length)];
    for _ in 0..1_000 {
        match ehci.control_poll(device, &mut bytes) {
            Transfer::Pending => ehci.hardware().advance(100),
            done => return (done, bytes),
        }
    }
    panic!("the transfer never ended");
}

const GET_DEVICE_DESCRIPTOR: Setup = Setup {
    request_type: 0x80,
    request: 6,
    value: 0x0100,
    index: 0,
    length: 18,
};

#[test]
fn a_control_transfer_cancelled_leaves_the_device_usable() {
    let mut ehci = started(EhciModel::new(2));
    ehci.hardware()
        .tree
        .plug(&[1], UsbDevice::Keyboard(Speed::High));
    let device = addressed_keyboard(&mut ehci, 1, 7);
    let advances = ehci.hardware().async_advances;
    ehci.control_begin(device, GET_DEVICE_DESCRIPTOR, &[])
        .unwrap();
    ehci.control_cancel(device);
    assert_eq!(
        ehci.hardware().async_advances,
        advances + 1,
        "off the ring first"
    );
    let (done, bytes) = control(&mut ehci, device, GET_DEVICE_DESCRIPTOR);
    assert_eq!(done, Transfer::Complete(18));
    assert_eq!(&bytes[..2], [18, 1]);
    // A request the device does not know stalls.
    let unknown = Setup {
        value: 0x0F00,
        ..GET_DEVICE_DESCRIPTOR
    };
    assert_eq!(control(&mut ehci, device, unknown).0, Transfer::Stalled);
    // A report longer than the pipe's packet size is babble.
    let keyboard = ehci.hardware().tree.handle_at(&[1]).unwrap();
    let pipe = ehci.interrupt_open(device, 1, 4, 1).unwrap();
    assert!(ehci.hardware().tree.send_report(keyboard, KEY_A));
    ehci.hardware().advance(2_000);
    let mut report = [0u8; 8];
    assert_eq!(
        ehci.interrupt_poll(pipe, &mut report),
        Transfer::Failed(TransferError::Babble)
    );
    assert_eq!(ehci.interrupt_poll(pipe, &mut report), Transfer::Pending);
    ehci.interrupt_close(pipe);
    // The device's toggle moved on: CLEAR_FEATURE(ENDPOINT_HALT) puts it
    // back to DATA0, where a new pipe starts.
    let clear_halt = Setup {
        request_type: 0x02,
        request: 1,
        value: 0,
        index: 0x81,
        length: 0,
    };
    assert_eq!(
        control(&mut ehci, device, clear_halt).0,
        Transfer::Complete(0)
    );
    let pipe = ehci.interrupt_open(device, 1, 8, 1).unwrap();
    assert!(ehci.hardware().tree.send_report(keyboard, KEY_B));
    ehci.hardware().advance(2_000);
    assert_eq!(
        ehci.interrupt_poll(pipe, &mut report),
        Transfer::Complete(8)
    );
    assert_eq!(report, KEY_B);
    // A transfer to a device that answers nothing fails after three tries.
    ehci.hardware().tree.unplug(&[1]);
    let (done, _) = control(&mut ehci, device, GET_DEVICE_DESCRIPTOR);
    assert_eq!(done, Transfer::Failed(TransferError::NoResponse));
    assert_clean(ehci.hardware());
}

#[test]
fn a_pipe_closed_and_opened_again_at_once_waits_for_the_frames() {
    let mut ehci = started(EhciModel::new(2));
    ehci.hardware()
        .tree
        .plug(&[1], UsbDevice::Keyboard(Speed::High));
    ehci.hardware()
        .tree
        .plug(&[2], UsbDevice::Keyboard(Speed::High));
    let first = addressed_keyboard(&mut ehci, 1, 1);
    let second = addressed_keyboard(&mut ehci, 2, 2);
    let pipe = ehci.interrupt_open(first, 1, 8, 8).unwrap();
    // Every 8 frames, the other every frame (10 rounds down to 8).
    let other = ehci.interrupt_open(second, 1, 8, 10).unwrap();
    ehci.interrupt_close(other);
    let other = ehci.interrupt_open(second, 1, 8, 1).unwrap();
    let polls = ehci.hardware().polls;
    ehci.hardware().advance(64_000);
    let m = ehci.hardware();
    assert!(
        (7..=9).contains(&(m.polls[1] - polls[1])),
        "{}",
        m.polls[1] - polls[1]
    );
    assert!(
        (63..=65).contains(&(m.polls[2] - polls[2])),
        "{}",
        m.polls[2] - polls[2]
    );
    ehci.interrupt_close(other);
    let before = ehci.hardware().now;
    ehci.interrupt_close(pipe);
    assert!(
        ehci.hardware().now - before >= 1_000,
        "a whole frame passed"
    );
    // The same slot, another device: the queue head is rewritten only now.
    let again = ehci.interrupt_open(second, 1, 8, 1).unwrap();
    assert_eq!(again, pipe);
    ehci.hardware().advance(20_000);
    ehci.device_remove(first);
    ehci.device_remove(second);
    assert_eq!(ehci.free_slots(), (MAX_DEVICES, MAX_PIPES));
    assert_clean(ehci.hardware());
}

// The periodic schedule's budget (`ehci/budget.rs`).

/// Keyboards of `speed` on ports 1..=`count` of a high-speed hub on root
/// port 1 (one translator, or one per port); the model and the handles.
fn keyboards_behind_a_hub(count: u8, speed: Speed, multi_tt: bool) -> (EhciModel, Vec<usize>) {
    let mut m = EhciModel::new(2);
    m.tree.plug(
        &[1],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 8,
            multi_tt,
        },
    );
    let keyboards = (1..=count)
        .map(|port| m.tree.plug(&[1, port], UsbDevice::Keyboard(speed)))
        .collect();
    (m, keyboards)
}

/// How many interrupt pipes start (transaction or start-split) in each
/// micro-frame, as the queue heads the controller ran say.
fn starts_by_micro_frame(m: &EhciModel, addresses: &[u8]) -> [usize; 8] {
    let mut starts = [0; 8];
    for &address in addresses {
        let masks: std::collections::BTreeSet<(u8, u8)> = m
            .split_log
            .iter()
            .filter(|s| s.periodic && s.address == address)
            .map(|s| (s.s_mask, s.c_mask))
            .collect();
        assert_eq!(masks.len(), 1, "address {address}: {masks:?}");
        let (s_mask, _) = masks.into_iter().next().unwrap();
        starts[s_mask.trailing_zeros() as usize] += 1;
    }
    starts
}

/// Every keyboard types, and gives its address.
fn type_on_each(bus: &mut Bus<Ehci<EhciModel>>, keyboards: &[usize]) -> Vec<u8> {
    keyboards
        .iter()
        .map(|&keyboard| {
            assert_eq!(type_key(bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
            model(bus).tree.keyboard_state(keyboard).2
        })
        .collect()
}

/// Eight full-speed keyboards behind a high-speed hub, each typing: two
/// start-splits in each of micro-frames 0-3, none later (their
/// complete-splits in N+2..N+4 end in micro-frame 7). Gives the bus and
/// the hub's address.
fn eight_keyboards_spread(multi_tt: bool) -> (Bus<Ehci<EhciModel>>, u8) {
    let (m, keyboards) = keyboards_behind_a_hub(8, Speed::Full, multi_tt);
    let (mut bus, found) = enumerated(m);
    assert_eq!(found, 8, "{:#?}", model(&mut bus).log);
    let addresses = type_on_each(&mut bus, &keyboards);
    let m = model(&mut bus);
    assert_eq!(
        starts_by_micro_frame(m, &addresses),
        [2, 2, 2, 2, 0, 0, 0, 0]
    );
    assert_clean(m);
    let hub = m.tree.handle_at(&[1]).unwrap();
    let hub_address = m.tree.keyboard_state(hub).2;
    (bus, hub_address)
}

#[test]
fn eight_full_speed_keyboards_share_one_translator_spread_over_micro_frames() {
    let (mut bus, hub_address) = eight_keyboards_spread(false);
    // One translator, 20 us a keyboard (USB 2.0 5.11.3 and think time).
    let load = model(&mut bus).periodic_load.clone();
    assert_eq!(
        load.translators.into_iter().collect::<Vec<_>>(),
        [((hub_address, 0), 160)]
    );
    // High speed: each start-split 1 us, each complete-split 3 us (two
    // keyboards' in each of N+2..N+4), the hub's own poll 1 us (in one
    // frame of 32).
    assert_eq!(load.micro_frames, [3, 2, 8, 14, 18, 18, 12, 6]);
}

#[test]
fn eight_keyboards_behind_a_multi_tt_hub_each_get_their_own_translator() {
    let (mut bus, hub_address) = eight_keyboards_spread(true);
    let translators: Vec<((u8, u8), u32)> = model(&mut bus)
        .periodic_load
        .translators
        .clone()
        .into_iter()
        .collect();
    let each: Vec<((u8, u8), u32)> = (1..=8).map(|port| ((hub_address, port), 20)).collect();
    assert_eq!(translators, each);
}

#[test]
fn a_seventh_low_speed_keyboard_on_a_full_translator_is_refused() {
    // 121 us each: six fit in the 750 us the start-splits in micro-frames
    // 0-3 can carry, a seventh does not.
    let (m, keyboards) = keyboards_behind_a_hub(7, Speed::Low, false);
    let (mut bus, found) = enumerated(m);
    assert_eq!(found, 6, "{:#?}", model(&mut bus).log);
    let refused = model(&mut bus)
        .log
        .iter()
        .filter(|line| line.contains("ehci: no room in the periodic schedule for endpoint 1"))
        .count();
    assert_eq!(refused, 1, "{:#?}", model(&mut bus).log);
    assert!(logged(
        model(&mut bus),
        "(Low speed, 8 bytes every 1 frames, through hub 1's translator): pipe refused"
    ));
    let working: Vec<usize> = keyboards
        .into_iter()
        .filter(|&k| model(&mut bus).tree.keyboard_state(k).1 != 0)
        .collect();
    let addresses = type_on_each(&mut bus, &working[..6]);
    let m = model(&mut bus);
    assert_eq!(
        starts_by_micro_frame(m, &addresses),
        [1, 2, 2, 1, 0, 0, 0, 0]
    );
    assert_eq!(
        m.periodic_load
            .translators
            .values()
            .copied()
            .collect::<Vec<_>>(),
        [726]
    );
    assert_clean(m);
}

#[test]
fn a_thousand_plug_cycles_on_a_full_translator_give_its_time_back() {
    // Six low-speed keyboards leave 24 us of the translator's 750: a
    // keyboard's 121 us not given back would refuse the next one.
    let (m, keyboards) = keyboards_behind_a_hub(6, Speed::Low, false);
    let (mut bus, found) = enumerated(m);
    assert_eq!(found, 6, "{:#?}", model(&mut bus).log);
    run(&mut bus, 2_000);
    let full = model(&mut bus).periodic_load.clone();
    let booked: Vec<_> = bus.controller().bookings().collect();
    let mut last = keyboards[5];
    for cycle in 0..1_000 {
        model(&mut bus).tree.unplug(&[1, 6]);
        let mut waited = 0;
        // The hub and five keyboards.
        while bus.devices() != 6 {
            run(&mut bus, 10_000);
            waited += 1;
            assert!(waited < 100, "cycle {cycle}: not gone");
        }
        last = model(&mut bus)
            .tree
            .plug(&[1, 6], UsbDevice::Keyboard(Speed::Low));
        let mut waited = 0;
        while bus.keyboards().count() != 6 {
            run(&mut bus, 10_000);
            waited += 1;
            assert!(waited < 100, "cycle {cycle}: {:#?}", model(&mut bus).log);
        }
    }
    assert_eq!(type_key(&mut bus, last, KEY_B), [B_MAKE, B_BREAK]);
    assert_eq!(model(&mut bus).periodic_load, full);
    let mut again: Vec<_> = bus.controller().bookings().collect();
    let mut before = booked.clone();
    let key = |b: &Booking| (b.phase, b.s_mask, b.translator_micros);
    again.sort_by_key(key);
    before.sort_by_key(key);
    assert_eq!(again, before);
    // Every keyboard gone: only the hub's own poll is left.
    for port in 1..=6 {
        model(&mut bus).tree.unplug(&[1, port]);
    }
    run(&mut bus, 200_000);
    assert_eq!(bus.keyboards().count(), 0);
    assert_eq!(bus.controller().bookings().count(), 1);
    let m = model(&mut bus);
    assert!(m.periodic_load.translators.is_empty());
    assert_eq!(m.periodic_load.micro_frames, [1, 0, 0, 0, 0, 0, 0, 0]);
    assert_clean(m);
}

#[test]
fn pipes_polled_every_eight_frames_go_to_eight_different_frames() {
    let mut ehci = started(EhciModel::new(9));
    let mut devices = Vec::new();
    for port in 1..=9u8 {
        ehci.hardware()
            .tree
            .plug(&[port], UsbDevice::Keyboard(Speed::High));
        devices.push(addressed_keyboard(&mut ehci, port, port));
    }
    let pipes: Vec<PipeId> = devices[..8]
        .iter()
        .map(|&d| ehci.interrupt_open(d, 1, 8, 8).unwrap())
        .collect();
    let mut phases: Vec<(u16, u8)> = ehci.bookings().map(|b| (b.phase, b.s_mask)).collect();
    phases.sort();
    assert_eq!(phases, (0..8).map(|phase| (phase, 1)).collect::<Vec<_>>());
    // As the controller runs it: each frame polls exactly one of them.
    let polls = ehci.hardware().polls;
    ehci.hardware().advance(64_000);
    let m = ehci.hardware();
    for address in 1..=8 {
        let polled = m.polls[address] - polls[address];
        assert!((7..=9).contains(&polled), "address {address}: {polled}");
    }
    assert_eq!(m.periodic_load.micro_frames, [2, 0, 0, 0, 0, 0, 0, 0]);
    // A ninth every frame goes where the others are not: micro-frame 1.
    let ninth = ehci.interrupt_open(devices[8], 1, 8, 1);
    assert!(ninth.is_ok());
    ehci.hardware().advance(2_000);
    assert_eq!(
        ehci.hardware().periodic_load.micro_frames,
        [2, 2, 0, 0, 0, 0, 0, 0]
    );
    for pipe in pipes {
        ehci.interrupt_close(pipe);
    }
    ehci.interrupt_close(ninth.unwrap());
    ehci.hardware().advance(2_000);
    assert_eq!(ehci.bookings().count(), 0);
    assert_eq!(ehci.hardware().periodic_load, Default::default());
    assert_clean(ehci.hardware());
}

#[test]
fn a_twenty_byte_report_in_eight_byte_packets_is_put_back_together() {
    use crate::model::devices::rollover_report;
    // Split through a hub's translator: three packets, three polls.
    let (mut m, _) = keyboards_behind_a_hub(0, Speed::Full, false);
    let keyboard = m
        .tree
        .plug(&[1, 2], UsbDevice::RolloverKeyboard(Speed::Full));
    let (mut bus, found) = enumerated(m);
    assert_eq!(found, 1, "{:#?}", model(&mut bus).log);
    assert!(logged(model(&mut bus), "(2 key fields, 20-byte reports)"));
    let a_and_b = rollover_report(&[0x04, 0x05]);
    assert!(model(&mut bus).tree.send_packets(keyboard, &a_and_b, false));
    assert_eq!(run(&mut bus, 20_000), [A_MAKE, B_MAKE]);
    // Cut short after 10 bytes: dropped, and the next report is whole.
    assert!(model(&mut bus)
        .tree
        .send_packets(keyboard, &a_and_b[..10], false));
    let released = rollover_report(&[]);
    assert!(model(&mut bus)
        .tree
        .send_packets(keyboard, &released, false));
    assert_eq!(run(&mut bus, 20_000), [A_BREAK, B_BREAK]);
    assert!(logged(
        model(&mut bus),
        "keyboard: 1 unreadable reports dropped (the last 10 bytes)"
    ));
    assert_eq!(bus.dropped_reports(), 1);
    assert_clean(model(&mut bus));
}

#[test]
fn the_model_refuses_a_schedule_over_budget_or_with_bad_split_masks() {
    let mut ehci = started(EhciModel::new(1));
    let frame_list = Layout::new(DMA_BASE).frame_list();
    let m = ehci.hardware();
    // Queue heads the driver never wrote, past its memory: five
    // high-speed polls of 1,024 bytes (21 us each) in micro-frame 0; two
    // low-speed ones of 64 bytes (475 us each) and a full-speed one (20 us)
    // through one translator, the full-speed one started in micro-frame 4
    // with complete-splits that would run past the frame. Each split's
    // start-split adds 1 us of high speed.
    let high_speed = 2 << 12 | 1024 << 16 | 1 << 8;
    let low_speed = 1 << 12 | 64 << 16 | 1 << 8;
    let full_speed = 8 << 16 | 1 << 8 | 5;
    let split = |s_mask: u32, c_mask: u32| 1 << 30 | 1 << 23 | 1 << 16 | c_mask << 8 | s_mask;
    let heads = [
        (high_speed | 1, 1 << 30 | 1),
        (high_speed | 2, 1 << 30 | 1),
        (high_speed | 3, 1 << 30 | 1),
        (high_speed | 4, 1 << 30 | 1),
        (high_speed | 5, 1 << 30 | 1),
        (low_speed | 6, split(0x01, 0x1C)),
        (low_speed | 7, split(0x01, 0x1C)),
        (full_speed, split(0x10, 0xC0)),
    ];
    let base = DMA_BASE + 0x2_0000;
    for (i, &(characteristics, capabilities)) in heads.iter().enumerate() {
        let qh = base + 0x80 * i as u64;
        let next = if i + 1 < heads.len() {
            (qh + 0x80) as u32 | 2
        } else {
            1
        };
        let qtd = base + 0x1000 + 0x40 * i as u64;
        for (offset, word) in [(0, next), (4, characteristics), (8, capabilities)] {
            m.poke(qh + offset, word);
        }
        for offset in [0x10, 0x14] {
            m.poke(qh + offset, 1);
        }
        // The split's qTD is active, so it runs (and its masks are seen).
        let active = i + 1 == heads.len();
        m.poke(qh + 0x18, 0);
        m.poke(qtd, 1);
        m.poke(qtd + 4, 1);
        m.poke(qtd + 8, 1 << 7 | 1 << 8 | 3 << 10 | 8 << 16);
        m.poke(qtd + 12, (base + 0x2000) as u32);
        if active {
            m.poke(qh + 0x10, qtd as u32);
        }
    }
    m.poke(frame_list, base as u32 | 2);
    m.advance(1_000);
    let expected = [
        "micro-frame 0 has 107 us of high-speed periodic time (at most 100)",
        "translator (1, 0) has 970 us of full- and low-speed time (at most 900)",
        "translator (1, 0) ends a split started in micro-frame 0 at 600 us",
        "S-mask 0x10 with C-mask 0xc0",
    ];
    for text in expected {
        assert!(
            m.errors.iter().any(|e| e.contains(text)),
            "{text}: {:#?}",
            m.errors
        );
    }
}

/// Through the real driver: keyboards that stall their device descriptor
/// twice (a high-speed one on a root port, a full-speed one behind a
/// high-speed hub's translator) are found on their third try, the old
/// scheme's first, after the new scheme's 64-byte reads failed.
#[test]
fn keyboards_that_fail_their_first_two_enumerations_are_found_on_the_third() {
    let mut m = EhciModel::new(4);
    m.port_power_control = true;
    let keyboard = m.tree.plug(&[1], UsbDevice::Keyboard(Speed::High));
    m.tree.plug(
        &[2],
        UsbDevice::Hub {
            speed: Speed::High,
            ports: 4,
            multi_tt: false,
        },
    );
    let behind = m.tree.plug(&[2, 1], UsbDevice::Keyboard(Speed::Full));
    m.tree.stall_device_descriptor(keyboard, 2);
    m.tree.stall_device_descriptor(behind, 2);
    let (mut bus, _) = enumerated(m);
    run(&mut bus, 2_000_000);
    assert_eq!(bus.keyboards().count(), 2, "{:#?}", model(&mut bus).log);
    let m = model(&mut bus);
    for at in ["1", "2.1"] {
        assert!(
            logged(m, &std::format!("port {at}: request stalled while reading the device descriptor's first 8 bytes, try 2 of 4")),
            "{:#?}",
            m.log
        );
    }
    assert_eq!(type_key(&mut bus, keyboard, KEY_A), [A_MAKE, A_BREAK]);
    assert_eq!(type_key(&mut bus, behind, KEY_B), [B_MAKE, B_BREAK]);
    assert_clean(model(&mut bus));
}
