//! The xHCI driver under the device layer against the register model:
//! ownership, reset, scratchpads, context sizes, ring wrap, a keyboard end
//! to end, hubs, hot-plug and misbehaviour.

use super::bus::{Bus, Location};
use super::host::{Handoff, HostController};
use super::model::xhci::{OnRootPort2, XhciModel, BAR_BYTES, DMA_BASE, DMA_BYTES, SUPERSPEED_HALF};
use super::xhci::{Capabilities, Xhci, XhciError, HANDOFF_MICROS, PAGE_BYTES, RESET_MICROS};
use super::Hardware;
use std::vec::Vec;

/// The driver under the device layer, with the driver's own start-up
/// calls beside the device layer's.
struct Tested<H: Hardware>(Bus<Xhci<H>>);

impl<H: Hardware> core::ops::Deref for Tested<H> {
    type Target = Bus<Xhci<H>>;
    fn deref(&self) -> &Bus<Xhci<H>> {
        &self.0
    }
}

impl<H: Hardware> core::ops::DerefMut for Tested<H> {
    fn deref_mut(&mut self) -> &mut Bus<Xhci<H>> {
        &mut self.0
    }
}

impl<H: Hardware> Tested<H> {
    fn new(hardware: H) -> Tested<H> {
        Tested(Bus::new(
            Xhci::new(hardware, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap(),
        ))
    }
    fn hardware(&mut self) -> &mut H {
        self.0.controller().hardware()
    }
    fn capabilities(&mut self) -> Capabilities {
        self.0.controller().capabilities()
    }
    fn take_ownership(&mut self) -> Handoff {
        self.0.controller().take_ownership()
    }
    fn reset_and_start(&mut self) -> Result<(), XhciError> {
        self.0.controller().reset_and_start()
    }
    fn no_op(&mut self) -> Result<(), XhciError> {
        self.0.controller().no_op()
    }
}

/// Where a device hangs, by root port and route string (a hub port a
/// nibble, the first tier lowest), as the xHCI slot context names it.
fn location(root_port: u8, route: u32) -> Location {
    let mut at = Location::root(root_port);
    let mut route = route;
    while route & 0xF != 0 {
        at = at.below((route & 0xF) as u8).unwrap();
        route >>= 4;
    }
    at
}

/// A controller whose endpoint 0 halts on a stall, as on real hardware.
fn controller(mut model: XhciModel) -> Tested<XhciModel> {
    model.ep0_halts = true;
    Tested::new(model)
}

/// A controller taken, reset and started, its keyboard set up.
fn with_keyboard(model: XhciModel) -> Tested<XhciModel> {
    let mut xhci = controller(model);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 1, "{:?}", xhci.hardware().log);
    // The pipe's Configure Endpoint completes after the enumeration's
    // last step; the next poll queues its transfers.
    assert_eq!(poll(&mut xhci), []);
    xhci
}

fn poll(xhci: &mut Tested<XhciModel>) -> Vec<u8> {
    let mut bytes = Vec::new();
    xhci.poll(&mut |b| bytes.push(b));
    bytes
}

/// Model time a poll may take: a step's own work, never a wait.
const POLL_MICROS_BOUND: u64 = 1_000;

/// Polls a frame (1 ms of model time) apart, at least once and then until
/// nothing is left to enumerate, each poll within [`POLL_MICROS_BOUND`];
/// gives the bytes typed meanwhile and the polls it took.
fn settle(xhci: &mut Tested<XhciModel>) -> (Vec<u8>, u32) {
    let mut bytes = Vec::new();
    let mut polls = 0;
    while polls == 0 || !xhci.enumeration_idle() {
        polls += 1;
        assert!(
            polls < 20_000,
            "enumeration never ends: {:?}",
            xhci.hardware().log
        );
        let before = xhci.hardware().now;
        xhci.poll(&mut |b| bytes.push(b));
        let took = xhci.hardware().now - before;
        assert!(
            took <= POLL_MICROS_BOUND,
            "a poll took {took} us of model time"
        );
        xhci.hardware().now += 1_000;
    }
    // The last pipe's Configure Endpoint completes after the enumeration's
    // last step; this poll queues its transfers.
    xhci.poll(&mut |b| bytes.push(b));
    (bytes, polls)
}

#[test]
fn the_firmware_that_lets_go_is_waited_for_and_its_smis_turned_off() {
    let mut model = XhciModel::new();
    model.firmware_releases_after = Some(3_000);
    let mut xhci = controller(model);
    let handoff = xhci.take_ownership();
    let Handoff::Released { micros } = handoff else {
        panic!("{handoff:?}");
    };
    assert!((3_000..4_000).contains(&micros), "{micros}");
    let (legacy, control) = xhci.hardware().legacy_registers();
    assert_eq!(
        legacy & (1 << 24 | 1 << 16),
        1 << 24,
        "OS-owned, not BIOS-owned"
    );
    assert_eq!(
        control, 0,
        "SMI enables off and their status cleared: {control:#x}"
    );
}

#[test]
fn a_firmware_that_never_lets_go_is_overruled_after_a_second() {
    let mut model = XhciModel::new();
    model.firmware_releases_after = None;
    let mut xhci = controller(model);
    let start = xhci.hardware().now;
    assert_eq!(xhci.take_ownership(), Handoff::Forced);
    let waited = xhci.hardware().now - start;
    assert!(
        (HANDOFF_MICROS..HANDOFF_MICROS + 10_000).contains(&waited),
        "{waited} us"
    );
    let (legacy, control) = xhci.hardware().legacy_registers();
    assert_eq!(legacy & (1 << 24 | 1 << 16), 1 << 24);
    assert_eq!(control & 0xE011, 0);
    // And the rest goes on as usual.
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 1);
}

#[test]
fn controller_not_ready_stuck_fails_the_reset_in_bounded_time() {
    let mut model = XhciModel::new();
    model.cnr_stuck = true;
    let mut xhci = controller(model);
    xhci.take_ownership();
    let start = xhci.hardware().now;
    assert_eq!(xhci.reset_and_start(), Err(XhciError::NotReady));
    let waited = xhci.hardware().now - start;
    assert!(waited <= RESET_MICROS + 100_000, "{waited} us");
    assert!(
        xhci.hardware().errors.is_empty(),
        "{:?}",
        xhci.hardware().errors
    );
}

#[test]
fn scratchpads_asked_for_are_given_page_by_page() {
    let mut model = XhciModel::new();
    model.scratchpads = 37; // the high and low fields of HCSPARAMS2 both used
    let mut xhci = controller(model);
    assert_eq!(xhci.capabilities().scratchpads, 37);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    let model = xhci.hardware();
    let array = model.scratchpad_array();
    assert!(array != 0 && array.is_multiple_of(PAGE_BYTES));
    let mut pages: Vec<u64> = (0..37).map(|i| model.read_u64(array + 8 * i)).collect();
    assert!(pages.iter().all(|&p| p.is_multiple_of(PAGE_BYTES)
        && p >= DMA_BASE
        && p + PAGE_BYTES <= DMA_BASE + DMA_BYTES));
    pages.sort_unstable();
    pages.dedup();
    assert_eq!(pages.len(), 37, "every scratchpad a page of its own");
    assert_eq!(model.read_u64(array + 8 * 37), 0);
}

#[test]
fn without_scratchpads_the_dcbaa_has_no_array() {
    let mut xhci = controller(XhciModel::new());
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.hardware().scratchpad_array(), 0);
}

#[test]
fn a_keyboard_is_set_up_with_32_and_with_64_byte_contexts() {
    for csz in [false, true] {
        let mut model = XhciModel::new();
        model.csz = csz;
        let mut xhci = with_keyboard(model);
        assert_eq!(
            xhci.capabilities().layout.context_bytes,
            if csz { 64 } else { 32 }
        );
        let model = xhci.hardware();
        assert!(model.errors.is_empty(), "csz {csz}: {:?}", model.errors);
        assert_eq!(model.keyboard.configuration, Some(1));
        // Its report descriptor describes it: kept in the report protocol.
        assert_eq!(model.keyboard.protocol, 1);
        assert!(model.keyboard.idle_set);
        assert_eq!(model.keyboard_slot_state(), 3, "configured");
        assert!(model
            .log
            .iter()
            .any(|l| l
                == "keyboard: USB keyboard, read by its report descriptor (2 key fields, 8-byte reports), on xhci port 1"));
        assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [location(1, 0)]);
    }
}

#[test]
fn reports_become_scancodes_and_a_held_key_repeats() {
    let mut xhci = with_keyboard(XhciModel::new());
    assert_eq!(poll(&mut xhci), []);
    assert!(xhci.hardware().send_report([0, 0, 0x50, 0, 0, 0, 0, 0])); // Left
    assert_eq!(poll(&mut xhci), [0xE0, 0x4B]);
    // Held: repeats after 500 ms by the controller's clock.
    xhci.hardware().now += 550_000;
    assert_eq!(poll(&mut xhci), [0xE0, 0x4B]);
    assert!(xhci.hardware().send_report([0; 8]));
    assert_eq!(poll(&mut xhci), [0xE0, 0xCB]);
    xhci.hardware().now += 600_000;
    assert_eq!(poll(&mut xhci), []);
}

#[test]
fn normal_trbs_stay_queued_through_many_reports_and_the_rings_wrap() {
    let mut xhci = with_keyboard(XhciModel::new());
    // 300 presses and releases: the 64-TRB interrupt ring wraps many times,
    // the 256-TRB event ring more than twice.
    for i in 0..300u32 {
        let usage = 0x04 + (i % 26) as u8;
        assert!(
            xhci.hardware().send_report([0, 0, usage, 0, 0, 0, 0, 0]),
            "report {i}"
        );
        assert!(xhci.hardware().send_report([0; 8]), "release {i}");
        let bytes = poll(&mut xhci);
        assert_eq!(bytes.len(), 2, "key {i}: {bytes:x?}");
        assert_eq!(bytes[0] | 0x80, bytes[1]);
    }
    let model = xhci.hardware();
    assert_eq!(model.events_dropped, 0);
    assert!(model.errors.is_empty(), "{:?}", model.errors);
}

#[test]
fn the_event_ring_wraps_with_its_cycle_bit_over_many_commands() {
    let mut xhci = controller(XhciModel::new());
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    // 700 No Ops after the start's: both the command ring (255 usable
    // TRBs) and the event ring (256) go round more than twice; each
    // completion must be found.
    for i in 0..700 {
        xhci.no_op().unwrap_or_else(|e| panic!("no-op {i}: {e}"));
    }
    let model = xhci.hardware();
    assert_eq!(model.events_posted, 701);
    assert_eq!(model.events_dropped, 0);
}

#[test]
fn a_controller_that_never_answers_commands_costs_bounded_time() {
    let mut model = XhciModel::new();
    model.commands_answered = false;
    let mut xhci = controller(model);
    xhci.take_ownership();
    let start = xhci.hardware().now;
    // The start's No Op is not answered (the kernel leaves such a
    // controller); the device layer over it is bounded anyway.
    assert!(matches!(
        xhci.reset_and_start(),
        Err(XhciError::CommandTimeout(_))
    ));
    // Enable Slot gets Linux's 5 s; boot does not wait that long.
    assert_eq!(xhci.enumerate(), 0);
    let waited = xhci.hardware().now - start;
    assert!(waited < 2_500_000, "{waited} us");
    assert!(
        xhci.hardware().log.iter().any(|l| l.starts_with(
            "usb: xhci: boot enumeration cut short after 2000 ms, port 1 still reading the device descriptor's first 8 bytes"
        )),
        "{:?}",
        xhci.hardware().log
    );
    settle(&mut xhci);
    let waited = xhci.hardware().now - start;
    assert!((5_000_000..6_000_000).contains(&waited), "{waited} us");
    let model = xhci.hardware();
    assert!(
        model.log.iter().any(|l| l
            .starts_with("usb: xhci: a command for device 0 not completed in 5000 ms; aborted")),
        "{:?}",
        model.log
    );
    assert_eq!(model.commands_aborted, 1, "the command stuck is aborted");
}

#[test]
fn nonsense_descriptors_are_refused_and_survived() {
    let cases: [(&str, Vec<u8>, Vec<u8>); 4] = [
        (
            "device length 0",
            std::vec![0; 18],
            super::model::devices::KEYBOARD_CONFIGURATION.to_vec(),
        ),
        ("no descriptor at all", Vec::new(), Vec::new()),
        (
            "configuration with a zero-length descriptor",
            super::model::devices::KEYBOARD_DEVICE.to_vec(),
            {
                let mut c = super::model::devices::KEYBOARD_CONFIGURATION.to_vec();
                c[9] = 0;
                c
            },
        ),
        (
            "endpoint past the end",
            super::model::devices::KEYBOARD_DEVICE.to_vec(),
            {
                let mut c = super::model::devices::KEYBOARD_CONFIGURATION.to_vec();
                c[27] = 200;
                c
            },
        ),
    ];
    for (what, device, configuration) in cases {
        let mut model = XhciModel::new();
        model.device_descriptor = device;
        model.configuration = configuration;
        let mut xhci = controller(model);
        xhci.take_ownership();
        xhci.reset_and_start().unwrap();
        assert_eq!(xhci.enumerate(), 0, "{what}");
        assert!(
            xhci.hardware()
                .log
                .iter()
                .any(|l| l.starts_with("usb: xhci port 1: ")),
            "{what}: {:?}",
            xhci.hardware().log
        );
        // Polling afterwards is harmless.
        assert_eq!(poll(&mut xhci), []);
    }
}

#[test]
fn registers_outside_the_bar_are_refused() {
    assert_eq!(
        Xhci::new(XhciModel::new(), 0x100, DMA_BASE, DMA_BYTES).err(),
        Some(XhciError::RegistersOutsideBar)
    );
}

#[test]
fn too_little_dma_memory_for_the_scratchpads_is_an_error() {
    let mut model = XhciModel::new();
    model.scratchpads = 200;
    let mut xhci = Xhci::new(model, BAR_BYTES, DMA_BASE, 64 * PAGE_BYTES).unwrap();
    xhci.take_ownership();
    assert_eq!(xhci.reset_and_start(), Err(XhciError::OutOfDmaMemory));
}

#[test]
fn a_keyboard_behind_a_hub_is_reached_through_its_route_string() {
    let mut model = XhciModel::new();
    model.hub = true;
    let mut xhci = with_keyboard(model);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [location(1, 2)]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert!(model.hub_states[0].configured && model.hub_states[0].marked);
    assert_eq!(model.hub_states[0].powered, [true; 4]);
    assert_eq!(
        model.keyboard_port_status_after_reset(),
        0b11,
        "connected, enabled, change cleared"
    );
    assert!(model.log.iter().any(|l| l
        .starts_with("keyboard: USB keyboard, read by its report descriptor")
        && l.ends_with(" on xhci port 1.2")));
    assert!(model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
    assert_eq!(poll(&mut xhci), [0x01]);
}

/// A keyboard whose configuration announces `report_descriptor` (its HID
/// descriptor's length fixed to match).
fn keyboard_described_by(report_descriptor: &[u8]) -> XhciModel {
    let mut model = XhciModel::new();
    let length = (report_descriptor.len() as u16).to_le_bytes();
    model.configuration[25..27].copy_from_slice(&length);
    model.report_descriptor = Some(report_descriptor.to_vec());
    // The whole report in one packet: a report over several packets is the
    // device layer's to put together (issue 46, periodic scheduling).
    model.configuration[31] = 32;
    model
}

#[test]
fn an_nkro_keyboard_that_ignores_set_protocol_is_read_through_its_descriptor() {
    use super::hid::tests::NKRO;
    let mut model = keyboard_described_by(&NKRO);
    model.ignores_set_protocol = true;
    let mut xhci = with_keyboard(model);
    let bitmap = |usages: &[u8]| {
        let mut report = [0u8; 21];
        report[0] = 1;
        for &usage in usages {
            match usage {
                0xE0.. => report[1] |= 1 << (usage - 0xE0),
                _ => report[2 + usize::from(usage / 8)] |= 1 << (usage % 8),
            }
        }
        report
    };
    assert!(xhci.hardware().log.iter().any(|l| l.contains(
        "read by its report descriptor (2 key fields, 21-byte reports, numbered), on xhci port 1"
    )));
    // Left Shift and A, then Left too: eight bytes of a boot decoder would
    // have read the bitmap as phantom usages.
    assert!(xhci.hardware().send_bytes(&bitmap(&[0xE1, 0x04])));
    assert_eq!(poll(&mut xhci), [0x2A, 0x1E]);
    assert!(xhci.hardware().send_bytes(&bitmap(&[0xE1, 0x04, 0x50])));
    assert_eq!(poll(&mut xhci), [0xE0, 0x4B]);
    // Seven letters at once (past the boot report's six) all act.
    let letters = [0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0A];
    assert!(xhci.hardware().send_bytes(&bitmap(&letters)));
    assert_eq!(
        poll(&mut xhci),
        [0xAA, 0xE0, 0xCB, 0x30, 0x2E, 0x20, 0x12, 0x21, 0x22]
    );
    // A report it cannot read (a boot report, a report cut short) is
    // dropped and counted, and changes nothing.
    assert!(xhci.hardware().send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    assert!(xhci.hardware().send_bytes(&bitmap(&[])[..12]));
    assert_eq!(poll(&mut xhci), []);
    assert_eq!(xhci.dropped_reports(), 2);
    assert!(xhci.hardware().send_bytes(&bitmap(&[])));
    assert_eq!(poll(&mut xhci), [0x9E, 0xB0, 0xAE, 0xA0, 0x92, 0xA1, 0xA2]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(model.keyboard.protocol, 1);
}

#[test]
fn a_keyboard_with_report_ids_is_kept_in_the_report_protocol() {
    use super::hid::tests::NUMBERED;
    let mut xhci = with_keyboard(keyboard_described_by(&NUMBERED));
    assert_eq!(xhci.hardware().keyboard.protocol, 1, "report protocol");
    assert_eq!(xhci.hardware().keyboard.set_protocols, 1);
    // Esc in report 1; a media key in report 2 types nothing; an unknown
    // report ID is dropped.
    assert!(xhci.hardware().send_bytes(&[1, 0, 0, 0x29, 0, 0, 0, 0, 0]));
    assert!(xhci.hardware().send_bytes(&[2, 0xE9, 0x00]));
    assert!(xhci.hardware().send_bytes(&[9, 0, 0, 0x04, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x01]);
    assert_eq!(xhci.dropped_reports(), 1);
    assert!(xhci.hardware().send_bytes(&[1, 0, 0, 0, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x81]);
}

#[test]
fn a_boot_keyboard_without_a_report_descriptor_is_put_in_the_boot_protocol() {
    let mut model = XhciModel::new();
    model.report_descriptor = None;
    let mut xhci = with_keyboard(model);
    assert_eq!(xhci.hardware().keyboard.protocol, 0, "boot protocol");
    assert!(xhci
        .hardware()
        .log
        .iter()
        .any(|l| l == "keyboard: USB keyboard, boot protocol, on xhci port 1"));
    assert!(xhci.hardware().send_report([0, 0, 0x15, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x13]);
    // Only eight bytes are a boot report.
    assert!(xhci.hardware().send_bytes(&[0, 0, 0x16, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), []);
    assert_eq!(xhci.dropped_reports(), 1);
}

#[test]
fn a_lying_report_descriptor_refuses_the_device_and_a_tablet_is_left_alone() {
    use super::hid::tests::{BOOT, TABLET};
    for (what, descriptor, line) in [
        (
            "unclosed",
            BOOT[..BOOT.len() - 1].to_vec(),
            "usb: xhci port 1: report descriptor refused (1 collections never closed); device left alone",
        ),
        (
            "tablet",
            TABLET.to_vec(),
            "usb: xhci port 1: device 0627:0001 is a HID device without keys; left alone",
        ),
    ] {
        let mut model = keyboard_described_by(&descriptor);
        if what == "tablet" {
            model.configuration[15] = 0; // no boot subclass
            model.configuration[16] = 0;
        }
        let mut xhci = controller(model);
        xhci.take_ownership();
        xhci.reset_and_start().unwrap();
        assert_eq!(xhci.enumerate(), 0, "{what}");
        let model = xhci.hardware();
        assert!(model.log.iter().any(|l| l == line), "{what}: {:?}", model.log);
        assert!(!model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0]), "{what}: no endpoint");
        assert_eq!(poll(&mut xhci), [], "{what}");
    }
}

#[test]
fn a_stall_mid_run_is_recovered_and_the_keyboard_comes_back_by_itself() {
    let mut xhci = with_keyboard(XhciModel::new());
    assert!(xhci.hardware().send_report([0x02, 0, 0x04, 0, 0, 0, 0, 0])); // Shift+A
    assert_eq!(poll(&mut xhci), [0x2A, 0x1E]);
    // The keyboard stalls: what was held is let go (its releases may be
    // lost), and the recovery runs a step per event.
    assert!(xhci.hardware().fail_transfer(6));
    assert_eq!(poll(&mut xhci), [0xAA, 0x9E]);
    for _ in 0..4 {
        poll(&mut xhci);
    }
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(
        model.keyboard.halts_cleared, 1,
        "CLEAR_FEATURE(ENDPOINT_HALT)"
    );
    assert!(
        model
            .log
            .iter()
            .any(|l| l == "usb: xhci port 1: halt cleared; recovered"),
        "{:?}",
        model.log
    );
    // Keys act again, the one still held among them.
    assert!(xhci.hardware().send_report([0, 0, 0x04, 0x05, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x1E, 0x30]);
    assert!(xhci.hardware().send_report([0; 8]));
    assert_eq!(poll(&mut xhci), [0x9E, 0xB0]);
    // A transaction error (no stall on the device's side): recovered
    // without CLEAR_FEATURE, and again many times over.
    for round in 0..20 {
        assert!(xhci.hardware().fail_transfer(4), "round {round}");
        // Reset Endpoint, Set TR Dequeue Pointer, the transfers queued
        // again: a command a poll.
        for _ in 0..4 {
            poll(&mut xhci);
        }
        assert!(
            xhci.hardware().send_report([0, 0, 0x29, 0, 0, 0, 0, 0]),
            "round {round}"
        );
        assert!(xhci.hardware().send_report([0; 8]));
        assert_eq!(poll(&mut xhci), [0x01, 0x81], "round {round}");
    }
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(model.keyboard.halts_cleared, 1);
    assert_eq!(xhci.keyboards().count(), 1);
}

#[test]
fn a_keyboard_that_fails_every_transfer_is_given_up_in_bounded_time() {
    let mut xhci = with_keyboard(XhciModel::new());
    let (mut rounds, mut failures) = (0, 0);
    while xhci.keyboards().count() == 1 {
        rounds += 1;
        assert!(rounds <= 40, "never given up");
        // Fails the transfer queued, once the restart has queued one.
        if xhci.hardware().fail_transfer(4) {
            failures += 1;
        }
        poll(&mut xhci);
    }
    assert_eq!(failures, 9, "eight recoveries, then given up");
    assert!(xhci
        .hardware()
        .log
        .iter()
        .any(|l| l.ends_with("keyboard given up")));
}

#[test]
fn a_recovery_the_controller_never_answers_gives_the_keyboard_up() {
    let mut xhci = with_keyboard(XhciModel::new());
    xhci.hardware().commands_answered = false;
    assert!(xhci.hardware().fail_transfer(4));
    let start = xhci.hardware().now;
    while xhci.keyboards().count() == 1 {
        let before = xhci.hardware().now;
        poll(&mut xhci);
        // A poll never waits for the controller.
        assert!(xhci.hardware().now - before < 1_000);
        xhci.hardware().now += 10_000;
        // The Reset Endpoint is aborted after Linux's 5 s for a command
        // (the driver's own recovery gave 300 ms).
        assert!(
            xhci.hardware().now - start < 6_000_000,
            "never given up: {:?}",
            xhci.hardware().log
        );
    }
}

#[test]
fn a_full_speed_device_that_needs_the_two_step_address_is_set_up() {
    let mut model = XhciModel::new();
    model.needs_two_step = true;
    model.device_descriptor[7] = 64; // endpoint 0 takes 64-byte packets
    let mut xhci = with_keyboard(model);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(model.keyboard_slot_state(), 3, "configured");
    assert!(model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x01]);
}

/// The model, with the driver's register and DMA accesses counted.
struct Counting {
    model: XhciModel,
    mmio: u64,
    dma: u64,
}

impl super::Memory for Counting {
    fn mem_read(&mut self, address: u64) -> u32 {
        self.dma += 1;
        self.model.mem_read(address)
    }
    fn mem_write(&mut self, address: u64, value: u32) {
        self.dma += 1;
        self.model.mem_write(address, value)
    }
}

impl super::Hardware for Counting {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        self.mmio += 1;
        self.model.mmio_read(offset)
    }
    fn mmio_write(&mut self, offset: u32, value: u32) {
        self.mmio += 1;
        self.model.mmio_write(offset, value)
    }
}

impl super::Platform for Counting {
    fn now_micros(&mut self) -> u64 {
        self.model.now_micros()
    }
    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.model.log(message)
    }
}

/// Polls with no key changing: the cost the frame loop pays every frame.
const IDLE_POLLS: u64 = 100_000;

#[test]
fn an_idle_poll_reads_one_event_word_and_touches_no_register() {
    let counting = Counting {
        model: XhciModel::new(),
        mmio: 0,
        dma: 0,
    };
    let mut xhci = Tested::new(counting);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 1);
    // The pipe's Configure Endpoint completes after the enumeration.
    xhci.poll(&mut |_| {});
    // A key held (repeat due later) is the usual state mid-spin too.
    assert!(xhci
        .hardware()
        .model
        .send_report([0, 0, 0x50, 0, 0, 0, 0, 0]));
    let mut bytes = Vec::new();
    xhci.poll(&mut |b| bytes.push(b));
    let (mmio, dma) = (xhci.hardware().mmio, xhci.hardware().dma);
    for _ in 0..IDLE_POLLS {
        xhci.poll(&mut |b| bytes.push(b));
        xhci.hardware().model.now = 1_000; // no repeat falls due
    }
    let hardware = xhci.hardware();
    assert_eq!(hardware.mmio - mmio, 0, "register accesses");
    assert_eq!(hardware.dma - dma, IDLE_POLLS, "one event ring word a poll");
}

#[test]
fn shut_down_switches_the_ports_off_then_halts_and_resets() {
    let mut xhci = with_keyboard(XhciModel::new());
    assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
    poll(&mut xhci);
    assert_eq!(
        xhci.hardware().shut_down_state(),
        (false, true, std::vec![true, true])
    );
    let start = xhci.hardware().now;
    assert!(xhci.shut_down());
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(
        model.shut_down_state(),
        (true, true, std::vec![false, false]),
        "halted, reset, every port unpowered"
    );
    assert!(model.now - start < 100_000);
    // Nothing of the old controller is touched afterwards.
    assert_eq!(poll(&mut xhci), []);
    assert_eq!(xhci.keyboards().count(), 0);
}

#[test]
fn a_keyboard_pulled_out_lets_go_of_its_keys_and_its_slot() {
    for hub in [false, true] {
        let mut model = XhciModel::new();
        model.hub = hub;
        let mut xhci = with_keyboard(model);
        assert!(xhci.hardware().send_report([0x02, 0, 0x04, 0, 0, 0, 0, 0])); // Shift+A
        assert_eq!(poll(&mut xhci), [0x2A, 0x1E]);
        xhci.hardware().unplug();
        // The held keys are released at once, nothing repeats afterwards.
        assert_eq!(poll(&mut xhci), [0xAA, 0x9E], "hub {hub}");
        xhci.hardware().now += 2_000_000;
        assert_eq!(poll(&mut xhci), []);
        assert_eq!(xhci.keyboards().count(), 0);
        let model = xhci.hardware();
        assert!(model.errors.is_empty(), "{:?}", model.errors);
        let disabled = if hub { 2 } else { 1 };
        assert_eq!(model.slots_disabled.len(), disabled, "hub {hub}");
        assert_eq!(model.root_port_changes(), 0, "changes acknowledged");
        assert!(!model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    }
}

#[test]
fn a_keyboard_plugged_in_after_start_is_found_and_found_again_after_an_unplug() {
    for hub in [false, true] {
        let mut model = XhciModel::new();
        model.hub = hub;
        model.empty_at_start = true;
        let mut xhci = controller(model);
        xhci.take_ownership();
        xhci.reset_and_start().unwrap();
        assert_eq!(xhci.enumerate(), 0);
        for round in 0..3 {
            xhci.hardware().plug();
            // The connection settles first: nothing is asked of the device
            // on the poll that sees the change.
            assert_eq!(poll(&mut xhci), []);
            assert_eq!(xhci.keyboards().count(), 0, "hub {hub} round {round}");
            xhci.hardware().now += 100_000;
            assert_eq!(settle(&mut xhci).0, []);
            assert_eq!(xhci.keyboards().count(), 1, "hub {hub} round {round}");
            assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0])); // A
            assert_eq!(poll(&mut xhci), [0x1E], "hub {hub} round {round}");
            assert!(xhci.hardware().send_report([0; 8]));
            assert_eq!(poll(&mut xhci), [0x9E]);
            xhci.hardware().unplug();
            assert_eq!(poll(&mut xhci), []);
            assert_eq!(xhci.keyboards().count(), 0);
            xhci.hardware().now += 1_000_000;
            assert_eq!(poll(&mut xhci), []);
            assert_eq!(xhci.keyboards().count(), 0);
        }
        let model = xhci.hardware();
        assert!(model.errors.is_empty(), "hub {hub}: {:?}", model.errors);
        assert_eq!(model.root_port_changes(), 0, "changes acknowledged");
        let devices = if hub { 6 } else { 3 };
        assert_eq!(model.slots_disabled.len(), devices, "hub {hub}");
    }
}

#[test]
fn a_keyboard_behind_three_and_five_tiers_of_hubs_is_reached() {
    for (tiers, route, name) in [(3, 0x222, "1.2.2.2"), (5, 0x2_2222, "1.2.2.2.2.2")] {
        let mut model = XhciModel::new();
        model.hub = true;
        model.hub_tiers = tiers;
        let mut xhci = with_keyboard(model);
        assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [location(1, route)]);
        assert_eq!(std::format!("{}", xhci.keyboards().next().unwrap()), name);
        let model = xhci.hardware();
        assert!(model.errors.is_empty(), "{:?}", model.errors);
        for (tier, hub) in model.hub_states[..tiers].iter().enumerate() {
            assert!(hub.configured && hub.marked, "tier {tier}: {hub:?}");
            assert_eq!(hub.powered, [true; 4], "tier {tier}");
        }
        assert_eq!(model.keyboard_port_status_after_reset(), 0b11);
        assert!(model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
        assert_eq!(poll(&mut xhci), [0x01], "{tiers} tiers");
    }
}

#[test]
fn a_sixth_tier_of_hubs_is_left_alone() {
    let mut model = XhciModel::new();
    model.hub = true;
    model.hub_tiers = 6;
    let mut xhci = controller(model);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 0);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert!(
        model
            .log
            .iter()
            .any(|l| l
                == "usb: xhci port 1.2.2.2.2.2: hub past the 5 hub tiers USB allows; left alone"),
        "{:?}",
        model.log
    );
    assert!(model.hub_states[..5].iter().all(|hub| hub.configured));
    assert!(!model.hub_states[5].configured, "the sixth hub is not used");
}

#[test]
fn a_keyboard_switched_back_and_forth_a_thousand_times_still_types() {
    let mut model = XhciModel::new();
    model.hub = true;
    model.empty_at_start = true;
    let mut xhci = controller(model);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 0);
    // Each plug takes 10 pages (a hub and a keyboard); 1,000 of them are
    // far more than the model's 1 MiB of DMA memory holds.
    for round in 0..1000 {
        xhci.hardware().plug();
        assert_eq!(poll(&mut xhci), []);
        xhci.hardware().now += 100_000;
        assert_eq!(settle(&mut xhci).0, []);
        assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0])); // A
        assert_eq!(poll(&mut xhci), [0x1E], "round {round}");
        xhci.hardware().unplug();
        assert_eq!(poll(&mut xhci), [0x9E], "round {round}");
    }
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
}

/// A controller taken, reset and started, its ports to be enumerated by
/// the polls that follow.
fn started(model: XhciModel) -> Tested<XhciModel> {
    let mut xhci = controller(model);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    xhci.start_enumeration();
    xhci
}

#[test]
fn a_device_that_never_answers_costs_its_timeouts_and_never_a_frame() {
    let mut model = XhciModel::new();
    model.port_2 = Some(OnRootPort2::Dead);
    let mut xhci = started(model);
    let start = xhci.hardware().now;
    let mut typed = Vec::new();
    let mut typed_while_probing = 0;
    let mut polls = 0u32;
    while !xhci.enumeration_idle() {
        polls += 1;
        assert!(polls < 20_000, "{:?}", xhci.hardware().log);
        // A frame: a key pressed and let go on the good keyboard once it
        // is there, then the poll.
        let probing = xhci.keyboards().count() == 1;
        if probing && polls.is_multiple_of(100) {
            assert!(xhci.hardware().send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
            assert!(xhci.hardware().send_report([0; 8]));
        }
        let before = xhci.hardware().now;
        let bytes = poll(&mut xhci);
        let took = xhci.hardware().now - before;
        assert!(took <= POLL_MICROS_BOUND, "poll {polls} took {took} us");
        if probing && !bytes.is_empty() {
            assert_eq!(bytes, [0x01, 0x81]);
            typed_while_probing += 1;
        }
        typed.extend(bytes);
        xhci.hardware().now += 1_000;
    }
    let waited = xhci.hardware().now - start;
    // Linux's 5 s for the control transfer, then given up.
    assert!((5_000_000..5_600_000).contains(&waited), "{waited} us");
    assert!(
        typed_while_probing >= 40,
        "{typed_while_probing} keys typed"
    );
    let model = xhci.hardware();
    assert!(
        model.log.iter().any(|l| l.starts_with(
            "usb: xhci port 2: control transfer not completed in 5000 ms while reading the device descriptor's first 8 bytes; port disabled, left until it changes again"
        )),
        "{:?}",
        model.log
    );
    assert_eq!(model.slots_disabled, [2], "the dead device's slot");
    assert_eq!(model.ports_disabled, [2], "and its port, as Linux does");
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(xhci.keyboards().count(), 1);
}

#[test]
fn a_keyboard_plugged_in_while_a_dead_device_is_probed_waits_its_turn_then_types() {
    let mut model = XhciModel::new();
    model.port_2 = Some(OnRootPort2::Dead);
    model.empty_at_start = true;
    let mut xhci = started(model);
    // The dead device's probe starts.
    for _ in 0..400 {
        poll(&mut xhci);
        xhci.hardware().now += 1_000;
    }
    assert!(!xhci.enumeration_idle());
    xhci.hardware().plug();
    let start = xhci.hardware().now;
    let (bytes, _) = settle(&mut xhci);
    assert_eq!(bytes, []);
    let waited = xhci.hardware().now - start;
    assert!(waited < 5_000_000, "{waited} us");
    assert_eq!(xhci.keyboards().count(), 1, "{:?}", xhci.hardware().log);
    assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut xhci), [0x1E]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert!(model
        .log
        .iter()
        .any(|l| l.starts_with("usb: xhci port 2: control transfer not completed")));
}

#[test]
fn two_keyboards_at_boot_are_both_set_up_and_both_type() {
    let mut model = XhciModel::new();
    model.port_2 = Some(OnRootPort2::Keyboard);
    let mut xhci = controller(model);
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    assert_eq!(xhci.enumerate(), 2, "{:?}", xhci.hardware().log);
    assert!(xhci.enumeration_idle());
    // The last pipe's Configure Endpoint completes after the enumeration.
    assert_eq!(poll(&mut xhci), []);
    let at = |root_port| location(root_port, 0);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [at(1), at(2)]);
    assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0])); // A
    assert!(xhci.hardware().send_report_2([0, 0, 0x05, 0, 0, 0, 0, 0])); // B
    assert_eq!(poll(&mut xhci), [0x1E, 0x30]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(model.keyboard.configuration, Some(1));
    assert_eq!(model.keyboard2.configuration, Some(1));
    assert!(model.keyboard2.idle_set);
}

#[test]
fn a_keyboard_behind_one_and_three_hubs_is_plugged_and_pulled_many_times() {
    for tiers in [1, 3] {
        let mut model = XhciModel::new();
        model.hub = true;
        model.hub_tiers = tiers;
        let mut xhci = with_keyboard(model);
        let last = tiers - 1;
        // 100 rounds of a keyboard's 6 pages are more than the model's
        // 256 pages of DMA memory: pages must be reused.
        for round in 0..100 {
            assert!(xhci.hardware().send_report([0x02, 0, 0x04, 0, 0, 0, 0, 0]));
            assert_eq!(poll(&mut xhci), [0x2A, 0x1E], "{tiers} tiers round {round}");
            xhci.hardware().unplug_behind_hub(last);
            // Held keys released once the hub's port says it is gone.
            let (bytes, _) = settle(&mut xhci);
            assert_eq!(
                bytes,
                [0xAA, 0x9E],
                "{tiers} tiers round {round}: {:?}",
                xhci.hardware().log
            );
            assert_eq!(xhci.keyboards().count(), 0);
            xhci.hardware().plug_behind_hub(last);
            assert_eq!(settle(&mut xhci).0, []);
            assert_eq!(
                xhci.keyboards().count(),
                1,
                "{tiers} tiers round {round}: {:?}",
                xhci.hardware().log
            );
        }
        let model = xhci.hardware();
        assert!(model.errors.is_empty(), "{:?}", model.errors);
        assert_eq!(model.slots_disabled.len(), 100);
        assert_eq!(model.keyboard_port_status_after_reset(), 0b11);
        let gone = std::format!("usb: xhci port 1{}: keyboard gone", ".2".repeat(tiers));
        assert_eq!(
            model.log.iter().filter(|l| l.starts_with(&gone)).count(),
            100
        );
        assert!(model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
        assert_eq!(poll(&mut xhci), [0x01]);
    }
}

#[test]
fn a_hub_pulled_out_takes_the_keyboard_behind_it() {
    let mut model = XhciModel::new();
    model.hub = true;
    model.hub_tiers = 2;
    let mut xhci = with_keyboard(model);
    assert!(xhci.hardware().send_report([0, 0, 0x50, 0, 0, 0, 0, 0])); // Left
    assert_eq!(poll(&mut xhci), [0xE0, 0x4B]);
    // The second hub, with the keyboard on it, is pulled from the first.
    xhci.hardware().unplug_behind_hub(0);
    let (bytes, _) = settle(&mut xhci);
    assert_eq!(bytes, [0xE0, 0xCB], "the held key released");
    xhci.hardware().now += 2_000_000;
    assert_eq!(poll(&mut xhci), [], "and never repeated");
    assert_eq!(xhci.keyboards().count(), 0);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    assert_eq!(model.slots_disabled.len(), 2, "the hub and the keyboard");
    for (at, what) in [("1.2", "hub"), ("1.2.2", "keyboard")] {
        let line = std::format!("usb: xhci port {at}: {what} gone");
        assert!(model.log.iter().any(|l| l.starts_with(&line)), "{at}");
    }
    // Plugged back: the hub and then its keyboard are enumerated again.
    model.plug_behind_hub(0);
    settle(&mut xhci);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [location(1, 0x22)]);
    assert!(xhci.hardware().send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
    assert_eq!(poll(&mut xhci), [0x01]);
    assert!(xhci.hardware().errors.is_empty());
}

#[test]
fn a_keyboard_behind_two_usb_3_hubs_is_reached_and_found_again_after_an_unplug() {
    let mut model = XhciModel::new();
    model.usb3 = true;
    model.hub = true;
    model.hub_tiers = 2;
    // A SuperSpeed keyboard: endpoint 0 takes 2^9 = 512-byte packets.
    model.device_descriptor[2..4].copy_from_slice(&0x0300u16.to_le_bytes());
    model.device_descriptor[7] = 9;
    let mut xhci = with_keyboard(model);
    let behind = location(1, 0x22);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [behind]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    for (tier, hub) in model.hub_states[..2].iter().enumerate() {
        assert!(hub.configured && hub.marked, "tier {tier}: {hub:?}");
        assert_eq!(hub.depth, Some(tier as u16), "SET_HUB_DEPTH, tier {tier}");
    }
    assert_eq!(model.keyboard_port_status_after_reset(), 0b11);
    assert!(model.send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
    assert_eq!(poll(&mut xhci), [0x01]);
    // Pulled out of the second hub and plugged back.
    xhci.hardware().unplug_behind_hub(1);
    settle(&mut xhci);
    assert_eq!(xhci.keyboards().count(), 0);
    xhci.hardware().plug_behind_hub(1);
    settle(&mut xhci);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [behind]);
    assert!(xhci.hardware().send_report([0, 0, 0x04, 0, 0, 0, 0, 0])); // A
    assert_eq!(poll(&mut xhci), [0x1E]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
}

/// A USB 3 hub is two hubs in one box: its SuperSpeed half on a USB 3
/// root port, its USB 2 half (a high-speed hub with a transaction
/// translator) on a USB 2 root port, each enumerated on its own. A
/// full-speed keyboard behind the USB 2 half types.
#[test]
fn a_superspeed_hub_with_a_keyboard_behind_its_usb_2_half() {
    let mut model = XhciModel::new();
    // The USB 2 half on root port 1 (USB 2), the keyboard on its port 2.
    model.hub = true;
    model.high_speed_hub = true;
    // The SuperSpeed half on root port 2 (USB 3), nothing behind it.
    model.port_2 = Some(OnRootPort2::SuperSpeedHalf);
    let mut xhci = with_keyboard(model);
    assert_eq!(xhci.keyboards().collect::<Vec<_>>(), [location(1, 0x2)]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
    let usb_2_half = &model.hub_states[0];
    assert!(usb_2_half.configured && usb_2_half.marked, "{usb_2_half:?}");
    assert_eq!(usb_2_half.depth, None, "no SET_HUB_DEPTH for USB 2");
    let superspeed_half = &model.hub_states[SUPERSPEED_HALF];
    assert!(
        superspeed_half.configured && superspeed_half.marked,
        "the SuperSpeed half enumerated too: {superspeed_half:?}"
    );
    assert_eq!(superspeed_half.depth, Some(0), "SET_HUB_DEPTH on port 2");
    assert_eq!(superspeed_half.powered, [true; 4]);
    assert!(model.send_report([0, 0, 0x04, 0, 0, 0, 0, 0])); // A
    assert_eq!(poll(&mut xhci), [0x1E]);
    assert!(xhci.hardware().send_report([0; 8]));
    assert_eq!(poll(&mut xhci), [0x9E]);
    let model = xhci.hardware();
    assert!(model.errors.is_empty(), "{:?}", model.errors);
}

#[test]
fn a_keyboard_pulled_out_while_it_is_enumerated_is_let_go_of_and_found_again() {
    // Pulled after each number of steps until enumeration would have ended.
    let mut stopped = 0;
    for steps in 1..40 {
        let mut model = XhciModel::new();
        model.empty_at_start = true;
        let mut xhci = controller(model);
        xhci.take_ownership();
        xhci.reset_and_start().unwrap();
        assert_eq!(xhci.enumerate(), 0);
        xhci.hardware().plug();
        poll(&mut xhci);
        xhci.hardware().now += 100_000;
        for _ in 0..steps {
            poll(&mut xhci);
            xhci.hardware().now += 1_000;
        }
        let finished = xhci.enumeration_idle();
        xhci.hardware().unplug();
        settle(&mut xhci);
        assert_eq!(xhci.keyboards().count(), 0, "after {steps} steps");
        let log = xhci.hardware().log.join("\n");
        // Said either way: stopped mid-way, or gone once set up.
        let said = if finished {
            "keyboard gone; its keys released"
        } else {
            stopped += 1;
            "the device went away while"
        };
        assert!(log.contains(said), "after {steps} steps:\n{log}");
        xhci.hardware().plug();
        poll(&mut xhci);
        xhci.hardware().now += 100_000;
        settle(&mut xhci);
        assert_eq!(xhci.keyboards().count(), 1, "after {steps} steps:\n{log}");
        let model = xhci.hardware();
        assert!(
            model.errors.is_empty(),
            "after {steps} steps: {:?}",
            model.errors
        );
    }
    assert!(stopped > 10, "pulled mid-way only {stopped} times");
}
