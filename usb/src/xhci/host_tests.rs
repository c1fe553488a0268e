//! xHCI under the device layer (`Bus<Xhci<XhciModel>>`) against the register
//! model: the keyboard on a root port typing the bytes the driver's own
//! enumeration typed before it was deleted, behind hubs (route strings), plugged and pulled a
//! thousand times (slots and pages reused), stalls on its report endpoint
//! and on endpoint 0 recovered, a device that never answers, and what an
//! idle poll costs.

use crate::bus::Bus;
use crate::host::{HostController, ResetOutcome};
use crate::model::xhci::{OnRootPort2, XhciModel, BAR_BYTES, DMA_BASE, DMA_BYTES};
use crate::xhci::host::ROOT_RESET_BOUND_MICROS;
use crate::xhci::Xhci;
use crate::{Hardware, Memory, Platform};
use std::format;
use std::string::String;
use std::vec::Vec;

/// Model time one poll may take: its own work, never a wait.
const POLL_MICROS_BOUND: u64 = 1_000;

/// A controller taken, reset and started; endpoint 0 halts on a stall,
/// as on real hardware.
fn started(mut model: XhciModel) -> Xhci<XhciModel> {
    model.ep0_halts = true;
    let mut xhci = Xhci::new(model, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    xhci
}

fn bus(model: XhciModel) -> Bus<Xhci<XhciModel>> {
    Bus::new(started(model))
}

/// A bus whose boot enumeration found `keyboards`.
fn with_keyboards(model: XhciModel, keyboards: usize) -> Bus<Xhci<XhciModel>> {
    let mut bus = bus(model);
    assert_eq!(bus.enumerate(), keyboards, "{:#?}", log(&mut bus));
    // The pipes' Configure Endpoint completes after the enumeration's last
    // step; the next poll queues their transfers.
    assert_eq!(poll(&mut bus), []);
    bus
}

fn hw(bus: &mut Bus<Xhci<XhciModel>>) -> &mut XhciModel {
    bus.controller().hardware()
}

fn log(bus: &mut Bus<Xhci<XhciModel>>) -> Vec<String> {
    hw(bus).log.clone()
}

fn logged(bus: &mut Bus<Xhci<XhciModel>>, text: &str) -> bool {
    hw(bus).log.iter().any(|line| line.contains(text))
}

fn poll(bus: &mut Bus<Xhci<XhciModel>>) -> Vec<u8> {
    let mut bytes = Vec::new();
    bus.poll(&mut |b| bytes.push(b));
    bytes
}

/// Polls a frame (1 ms of model time) apart, at least once and then until
/// nothing is left to enumerate, each poll within [`POLL_MICROS_BOUND`];
/// gives the bytes typed meanwhile.
fn settle(bus: &mut Bus<Xhci<XhciModel>>) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut polls = 0;
    while polls == 0 || !bus.enumeration_idle() {
        polls += 1;
        assert!(polls < 20_000, "enumeration never ends: {:#?}", log(bus));
        let before = hw(bus).now;
        bus.poll(&mut |b| bytes.push(b));
        let took = hw(bus).now - before;
        assert!(took <= POLL_MICROS_BOUND, "a poll took {took} us");
        hw(bus).now += 1_000;
    }
    bytes
}

/// Nothing the model checks went wrong.
fn assert_clean(bus: &mut Bus<Xhci<XhciModel>>) {
    let errors = hw(bus).errors.clone();
    assert!(errors.is_empty(), "{errors:?}\n{:#?}", log(bus));
}

fn locations(bus: &Bus<Xhci<XhciModel>>) -> Vec<String> {
    bus.keyboards().map(|l| format!("{l}")).collect()
}

/// Reports a keyboard sends, time passing after each (a held key's
/// repeat), and the set-1 bytes each step types at once and after that
/// time: the bytes the driver's own enumeration typed for the same
/// session, before it was deleted.
type Step = ([u8; 8], u64, &'static [u8], &'static [u8]);
const SESSION: [Step; 8] = [
    ([0x02, 0, 0x04, 0, 0, 0, 0, 0], 0, &[0x2A, 0x1E], &[]), // Shift+A
    ([0x02, 0, 0x04, 0x05, 0, 0, 0, 0], 0, &[0x30], &[]),    // and B
    ([0, 0, 0, 0, 0, 0, 0, 0], 0, &[0xAA, 0x9E, 0xB0], &[]), // all up
    // Left, held to repeat.
    (
        [0, 0, 0x50, 0, 0, 0, 0, 0],
        550_000,
        &[0xE0, 0x4B],
        &[0xE0, 0x4B],
    ),
    ([0, 0, 0x50, 0x4F, 0, 0, 0, 0], 40_000, &[0xE0, 0x4D], &[]), // and Right
    // Left GUI alone.
    (
        [0x08, 0, 0, 0, 0, 0, 0, 0],
        0,
        &[0xE0, 0xCD, 0xE0, 0xCB, 0xE0, 0x5B],
        &[],
    ),
    ([0, 0, 0x29, 0, 0, 0, 0, 0], 0, &[0xE0, 0xDB, 0x01], &[]), // Esc
    ([0; 8], 600_000, &[0x81], &[]),                            // up; nothing repeats
];

#[test]
fn a_keyboard_on_a_root_port_types_what_the_drivers_own_enumeration_typed() {
    for csz in [false, true] {
        let mut model = XhciModel::new();
        model.csz = csz;
        let mut bus = with_keyboards(model, 1);
        assert_eq!(locations(&bus), ["1"]);
        {
            let model = hw(&mut bus);
            assert_eq!(model.keyboard.configuration, Some(1));
            assert_eq!(model.keyboard.protocol, 1, "read by its report descriptor");
            assert!(model.keyboard.idle_set);
            assert_eq!(model.keyboard_slot_state(), 3, "configured");
        }
        assert!(logged(
            &mut bus,
            "keyboard: USB keyboard, read by its report descriptor (2 key fields, 8-byte reports), on xhci port 1"
        ));
        for (step, (report, later, now_bytes, later_bytes)) in SESSION.into_iter().enumerate() {
            assert!(hw(&mut bus).send_report(report), "step {step}");
            assert_eq!(poll(&mut bus), now_bytes, "csz {csz} step {step}");
            hw(&mut bus).now += later;
            assert_eq!(poll(&mut bus), later_bytes, "csz {csz} step {step}, later");
        }
        assert_clean(&mut bus);
    }
}

/// A chipset's xHCI: 26 root ports, its USB 2 ports listed after its USB
/// 3 ones, the keyboard on USB 2 port 24, past the first 15: it is heard.
#[test]
fn a_keyboard_on_root_port_24_of_26_usb_2_ports_last_types() {
    let mut model = XhciModel::new();
    model.wide_ports(26, 24);
    let mut bus = with_keyboards(model, 1);
    assert_eq!(locations(&bus), ["24"]);
    assert!(!logged(&mut bus, "are used"), "{:#?}", log(&mut bus));
    assert!(hw(&mut bus).send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut bus), [0x1E]);
    assert!(hw(&mut bus).send_report([0; 8]));
    assert_eq!(poll(&mut bus), [0x9E]);
    assert_clean(&mut bus);
}

#[test]
fn a_keyboard_behind_one_and_three_hubs_is_reached_through_its_route_string() {
    for (tiers, at) in [(1, "1.2"), (3, "1.2.2.2")] {
        let mut model = XhciModel::new();
        model.hub = true;
        model.hub_tiers = tiers;
        let mut bus = with_keyboards(model, 1);
        assert_eq!(locations(&bus), [at]);
        // The model accepts an Address Device only with the route string
        // of the device it names: clean means every route was right.
        assert_clean(&mut bus);
        for tier in 0..tiers {
            let hub = &hw(&mut bus).hub_states[tier];
            assert!(hub.configured && hub.marked, "tier {tier}: {hub:?}");
            assert_eq!(hub.powered, [true; 4]);
        }
        assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
        assert_eq!(poll(&mut bus), [0x01]);
        assert!(hw(&mut bus).send_report([0; 8]));
        assert_eq!(poll(&mut bus), [0x81]);
    }
}

#[test]
fn a_keyboard_pulled_out_and_plugged_in_a_thousand_times_still_types() {
    for hub in [false, true] {
        let mut model = XhciModel::new();
        model.hub = hub;
        let mut bus = with_keyboards(model, 1);
        let rounds = if hub { 200 } else { 1_000 };
        for round in 0..rounds {
            assert!(hw(&mut bus).send_report([0x02, 0, 0x04, 0, 0, 0, 0, 0]));
            assert_eq!(poll(&mut bus), [0x2A, 0x1E], "hub {hub} round {round}");
            hw(&mut bus).unplug();
            // Held keys are let go at once.
            assert_eq!(poll(&mut bus), [0xAA, 0x9E], "hub {hub} round {round}");
            assert_eq!(bus.keyboards().count(), 0);
            hw(&mut bus).now += 200_000;
            assert_eq!(settle(&mut bus), []);
            hw(&mut bus).plug();
            hw(&mut bus).now += 1_000;
            assert_eq!(settle(&mut bus), []);
            assert_eq!(poll(&mut bus), []);
            assert_eq!(
                bus.keyboards().count(),
                1,
                "hub {hub} round {round}: {:#?}",
                log(&mut bus)
            );
        }
        assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
        assert_eq!(poll(&mut bus), [0x01]);
        assert_clean(&mut bus);
        let devices = if hub { 2 } else { 1 };
        assert_eq!(hw(&mut bus).slots_disabled.len(), rounds * devices);
        assert_eq!(hw(&mut bus).root_port_changes(), 0, "changes acknowledged");
    }
}

#[test]
fn a_keyboard_behind_a_hub_pulled_and_plugged_again_is_found_by_the_hubs_report() {
    let mut model = XhciModel::new();
    model.hub = true;
    let mut bus = with_keyboards(model, 1);
    for round in 0..20 {
        assert!(hw(&mut bus).send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
        assert_eq!(poll(&mut bus), [0x1E], "round {round}");
        hw(&mut bus).unplug_behind_hub(0);
        hw(&mut bus).now += 1_000;
        let bytes = settle(&mut bus);
        assert_eq!(bytes, [0x9E], "round {round}: {:#?}", log(&mut bus));
        assert_eq!(bus.keyboards().count(), 0, "round {round}");
        hw(&mut bus).plug_behind_hub(0);
        hw(&mut bus).now += 1_000;
        assert_eq!(settle(&mut bus), []);
        assert_eq!(poll(&mut bus), []);
        assert_eq!(
            locations(&bus),
            ["1.2"],
            "round {round}: {:#?}",
            log(&mut bus)
        );
    }
    assert_clean(&mut bus);
    assert_eq!(
        hw(&mut bus).slots_disabled.len(),
        20,
        "the keyboard's slot each time"
    );
}

#[test]
fn a_stall_and_transaction_errors_on_the_report_endpoint_are_recovered() {
    let mut bus = with_keyboards(XhciModel::new(), 1);
    assert!(hw(&mut bus).send_report([0x02, 0, 0x04, 0, 0, 0, 0, 0])); // Shift+A
    assert_eq!(poll(&mut bus), [0x2A, 0x1E]);
    // A stall: the keys are let go, the halt cleared on the device, the
    // endpoint reset in the controller (its toggle too), the reports queued.
    assert!(hw(&mut bus).fail_transfer(6));
    assert_eq!(poll(&mut bus), [0xAA, 0x9E]);
    for _ in 0..10 {
        poll(&mut bus);
        hw(&mut bus).now += 1_000;
    }
    assert_eq!(hw(&mut bus).keyboard.halts_cleared, 1);
    assert!(
        logged(&mut bus, "halt cleared; recovered"),
        "{:#?}",
        log(&mut bus)
    );
    assert!(hw(&mut bus).send_report([0, 0, 0x04, 0x05, 0, 0, 0, 0]));
    assert_eq!(poll(&mut bus), [0x1E, 0x30]);
    assert!(hw(&mut bus).send_report([0; 8]));
    assert_eq!(poll(&mut bus), [0x9E, 0xB0]);
    // Transaction errors: restarted without CLEAR_FEATURE, many times.
    for round in 0..20 {
        assert!(hw(&mut bus).fail_transfer(4), "round {round}");
        poll(&mut bus);
        poll(&mut bus);
        assert!(
            hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0]),
            "round {round}: {:#?}",
            log(&mut bus)
        );
        assert!(hw(&mut bus).send_report([0; 8]));
        assert_eq!(poll(&mut bus), [0x01, 0x81], "round {round}");
    }
    assert_eq!(hw(&mut bus).keyboard.halts_cleared, 1);
    assert_eq!(bus.keyboards().count(), 1);
    assert_clean(&mut bus);
}

#[test]
fn a_keyboard_that_fails_every_transfer_is_given_up() {
    let mut bus = with_keyboards(XhciModel::new(), 1);
    let mut rounds = 0;
    while bus.keyboards().count() == 1 {
        rounds += 1;
        assert!(rounds < 20, "{:#?}", log(&mut bus));
        assert!(hw(&mut bus).fail_transfer(4));
        poll(&mut bus);
        poll(&mut bus);
    }
    assert_eq!(rounds, 9, "eight recoveries, then given up");
    assert!(logged(&mut bus, "keyboard given up"));
    assert_clean(&mut bus);
}

#[test]
fn a_stall_on_endpoint_0_is_cleared_in_the_controller_before_the_next_request() {
    // No report descriptor: its request stalls, and a real controller
    // halts endpoint 0 until Reset Endpoint. The boot protocol follows.
    let mut model = XhciModel::new();
    model.report_descriptor = None;
    let mut bus = with_keyboards(model, 1);
    assert_eq!(hw(&mut bus).keyboard.protocol, 0, "boot protocol");
    assert!(hw(&mut bus).keyboard.idle_set);
    assert!(
        logged(
            &mut bus,
            "keyboard: no report descriptor (request stalled); boot protocol"
        ),
        "{:#?}",
        log(&mut bus)
    );
    assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut bus), [0x01]);
    assert_clean(&mut bus);
}

#[test]
fn endpoint_0_of_64_bytes_is_evaluated_and_the_two_step_device_addressed() {
    let mut model = XhciModel::new();
    model.needs_two_step = true;
    model.device_descriptor[7] = 64;
    let mut bus = with_keyboards(model, 1);
    assert_eq!(hw(&mut bus).keyboard_slot_state(), 3, "configured");
    assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    assert_eq!(poll(&mut bus), [0x01]);
    assert_clean(&mut bus);
}

#[test]
fn two_keyboards_both_type() {
    let mut model = XhciModel::new();
    model.port_2 = Some(OnRootPort2::Keyboard);
    let mut bus = with_keyboards(model, 2);
    let mut at = locations(&bus);
    at.sort();
    assert_eq!(at, ["1", "2"]);
    assert!(hw(&mut bus).send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
    assert!(hw(&mut bus).send_report_2([0, 0, 0x05, 0, 0, 0, 0, 0]));
    let mut bytes = poll(&mut bus);
    bytes.sort();
    assert_eq!(bytes, [0x1E, 0x30]);
    assert_clean(&mut bus);
}

#[test]
fn a_device_that_never_answers_is_given_up_after_its_timeout_and_the_keyboard_types() {
    let mut model = XhciModel::new();
    model.port_2 = Some(OnRootPort2::Dead);
    let mut bus = bus(model);
    bus.enumerate();
    let start = hw(&mut bus).now;
    let mut typed = 0;
    let mut polls = 0u32;
    while !bus.enumeration_idle() {
        polls += 1;
        assert!(polls < 20_000, "{:#?}", log(&mut bus));
        if bus.keyboards().count() == 1 && polls.is_multiple_of(100) {
            assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
            assert!(hw(&mut bus).send_report([0; 8]));
        }
        let before = hw(&mut bus).now;
        let bytes = poll(&mut bus);
        assert!(hw(&mut bus).now - before <= POLL_MICROS_BOUND);
        if !bytes.is_empty() {
            assert_eq!(bytes, [0x01, 0x81]);
            typed += 1;
        }
        hw(&mut bus).now += 1_000;
    }
    let waited = hw(&mut bus).now - start;
    assert!(waited < 6_000_000, "{waited} us");
    assert!(typed >= 20, "{typed} keys typed meanwhile");
    assert!(
        logged(
            &mut bus,
            "port 2: control transfer not completed in 5000 ms"
        ),
        "{:#?}",
        log(&mut bus)
    );
    assert_eq!(bus.keyboards().count(), 1);
    assert_eq!(
        hw(&mut bus).slots_disabled.len(),
        1,
        "the dead device's slot"
    );
    // The port given up is disabled, as Linux does.
    assert_eq!(hw(&mut bus).ports_disabled, [2]);
    assert_clean(&mut bus);
}

#[test]
fn a_superspeed_device_on_a_usb_3_port_is_enumerated_with_512_byte_packets() {
    let mut model = XhciModel::new();
    model.usb3 = true;
    // bcdUSB 3.0, bMaxPacketSize0 9: 2^9 = 512 bytes.
    model.device_descriptor[2..4].copy_from_slice(&0x0300u16.to_le_bytes());
    model.device_descriptor[7] = 9;
    let mut bus = with_keyboards(model, 1);
    assert_eq!(hw(&mut bus).keyboard_slot_state(), 3, "configured");
    assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
    assert_eq!(poll(&mut bus), [0x01]);
    assert_clean(&mut bus);
    // A SuperSpeed device that says 8 bytes is refused at its port.
    let mut model = XhciModel::new();
    model.usb3 = true;
    let mut bus = self::bus(model);
    assert_eq!(bus.enumerate(), 0);
    assert!(
        logged(
            &mut bus,
            "endpoint 0 packet size 8 is impossible at its speed"
        ),
        "{:#?}",
        log(&mut bus)
    );
}

#[test]
fn a_root_port_reset_that_never_ends_fails_at_its_bound_and_no_call_blocks() {
    let mut model = XhciModel::new();
    model.port_reset_stuck = true;
    let mut bus = bus(model);
    // Each poll within its bound: settle checks it.
    bus.start_enumeration();
    settle(&mut bus);
    assert!(
        logged(&mut bus, "port 1: the reset did not end in 200 ms"),
        "{:#?}",
        log(&mut bus)
    );
    assert!(
        logged(&mut bus, "port reset failed"),
        "{:#?}",
        log(&mut bus)
    );
    assert_eq!(bus.keyboards().count(), 0);
    // Called by hand, the driver says the same at the same bound.
    let xhci = bus.controller();
    xhci.port_reset_begin(1);
    let began = xhci.hardware().now_micros();
    loop {
        let before = xhci.hardware().now_micros();
        let outcome = xhci.port_reset_poll(1);
        let now = xhci.hardware().now_micros();
        assert!(
            now - before <= POLL_MICROS_BOUND,
            "a poll took {} us",
            now - before
        );
        if let Some(outcome) = outcome {
            assert_eq!(outcome, ResetOutcome::Failed);
            assert!(now - began >= ROOT_RESET_BOUND_MICROS);
            assert!(now - began < ROOT_RESET_BOUND_MICROS + POLL_MICROS_BOUND);
            break;
        }
        assert!(now - began < 2 * ROOT_RESET_BOUND_MICROS, "never given up");
        xhci.hardware().now += 100;
    }
}

#[test]
fn a_usb_3_link_still_training_at_the_reset_gets_the_reset_s_50_ms() {
    let mut model = XhciModel::new();
    model.usb3 = true;
    model.device_descriptor[2..4].copy_from_slice(&0x0300u16.to_le_bytes());
    model.device_descriptor[7] = 9;
    // Connected when the device layer first looks (200 ms after the
    // start), enabled 40 ms later.
    model.usb3_link_micros = 240_000;
    let mut bus = with_keyboards(model, 1);
    assert!(
        !logged(&mut bus, "port reset failed"),
        "{:#?}",
        log(&mut bus)
    );
    assert_clean(&mut bus);
}

/// A USB 3 link that fell into SS.Inactive after the controller's reset
/// (and would stay there), or that has not reached U0 by the end of the
/// reset's 50 ms, is warm-reset (PORTSC WPR) and its keyboard set up.
#[test]
fn a_usb_3_link_stuck_in_ss_inactive_or_short_of_u0_is_warm_reset() {
    for (stuck, said) in [(true, "link state 6"), (false, "link state 0")] {
        let mut model = XhciModel::new();
        model.usb3 = true;
        model.device_descriptor[2..4].copy_from_slice(&0x0300u16.to_le_bytes());
        model.device_descriptor[7] = 9;
        if stuck {
            model.usb3_link_stuck = true;
        } else {
            // Never trained by itself.
            model.usb3_link_micros = 1_000_000_000;
        }
        let mut bus = with_keyboards(model, 1);
        assert_eq!(hw(&mut bus).warm_resets, 1);
        assert!(
            logged(
                &mut bus,
                &format!("port 1: USB 3 link stuck ({said}); warm reset")
            ),
            "{:#?}",
            log(&mut bus)
        );
        assert!(!logged(&mut bus, "port reset failed"));
        assert!(hw(&mut bus).send_report([0, 0, 0x04, 0, 0, 0, 0, 0]));
        assert_eq!(poll(&mut bus), [0x1E]);
        assert_clean(&mut bus);
    }
}

#[test]
fn halt_switches_the_ports_off_then_halts_and_resets() {
    let mut bus = with_keyboards(XhciModel::new(), 1);
    assert!(bus.shut_down());
    let (halted, reset_done, powered) = hw(&mut bus).shut_down_state();
    assert!(halted && reset_done);
    assert_eq!(powered, [false, false]);
}

/// The model, with the driver's register and DMA accesses counted.
struct Counting {
    model: XhciModel,
    mmio: u64,
    dma: u64,
}

impl Memory for Counting {
    fn mem_read(&mut self, address: u64) -> u32 {
        self.dma += 1;
        self.model.mem_read(address)
    }
    fn mem_write(&mut self, address: u64, value: u32) {
        self.dma += 1;
        self.model.mem_write(address, value)
    }
}

impl Hardware for Counting {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        self.mmio += 1;
        self.model.mmio_read(offset)
    }
    fn mmio_write(&mut self, offset: u32, value: u32) {
        self.mmio += 1;
        self.model.mmio_write(offset, value)
    }
}

impl Platform for Counting {
    fn now_micros(&mut self) -> u64 {
        self.model.now_micros()
    }
    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.model.log(message)
    }
}

#[test]
fn an_idle_poll_reads_one_event_word_and_touches_no_register() {
    let mut model = XhciModel::new();
    model.ep0_halts = true;
    let counting = Counting {
        model,
        mmio: 0,
        dma: 0,
    };
    let mut xhci = Xhci::new(counting, BAR_BYTES, DMA_BASE, DMA_BYTES).unwrap();
    xhci.take_ownership();
    xhci.reset_and_start().unwrap();
    let mut bus = Bus::new(xhci);
    assert_eq!(bus.enumerate(), 1);
    let mut bytes = Vec::new();
    bus.poll(&mut |b| bytes.push(b));
    let (mmio, dma) = {
        let hw = bus.controller().hardware();
        (hw.mmio, hw.dma)
    };
    const IDLE_POLLS: u64 = 10_000;
    for _ in 0..IDLE_POLLS {
        bus.poll(&mut |b| bytes.push(b));
    }
    let hw = bus.controller().hardware();
    assert_eq!(hw.mmio - mmio, 0, "register accesses");
    assert_eq!(hw.dma - dma, IDLE_POLLS, "one event ring word a poll");
    assert!(bytes.is_empty());
    // And a report is still seen by the next poll.
    assert!(bus
        .controller()
        .hardware()
        .model
        .send_report([0, 0, 0x29, 0, 0, 0, 0, 0]));
    bus.poll(&mut |b| bytes.push(b));
    assert_eq!(bytes, [0x01]);
    assert_eq!(bus.controller().kind(), crate::host::ControllerKind::Xhci);
}

#[test]
fn a_data_stage_shorter_than_asked_says_how_many_bytes_came() {
    // The configuration says it is 40 bytes long and sends its 34: the
    // data stage's event says 6 did not come, and the device layer
    // refuses a device that sends less than it announces.
    let mut model = XhciModel::new();
    let announced = model.configuration.len() as u16 + 6;
    model.configuration[2..4].copy_from_slice(&announced.to_le_bytes());
    let mut bus = with_keyboards(model, 0);
    assert!(
        logged(&mut bus, "34 bytes came of the 40 asked for"),
        "{:#?}",
        log(&mut bus)
    );
    assert_eq!(hw(&mut bus).slots_disabled.len(), 1);
}

#[test]
fn a_full_speed_keyboard_behind_high_speed_hubs_names_the_last_ones_translator() {
    for tiers in [1, 2] {
        let mut model = XhciModel::new();
        model.hub = true;
        model.hub_tiers = tiers;
        model.high_speed_hub = true;
        let mut bus = with_keyboards(model, 1);
        // The model refuses an Address Device without the translator's
        // slot and port: clean means they were right.
        assert_clean(&mut bus);
        assert!(hw(&mut bus).hub_states[tiers - 1].marked);
        assert!(hw(&mut bus).send_report([0, 0, 0x29, 0, 0, 0, 0, 0])); // Esc
        assert_eq!(poll(&mut bus), [0x01], "tiers {tiers}");
    }
}

#[test]
fn a_twenty_byte_report_in_eight_byte_packets_is_put_back_together() {
    use crate::model::devices::{rollover_report, ROLLOVER_REPORT_DESCRIPTOR};
    let mut model = XhciModel::new();
    model.report_descriptor = Some(ROLLOVER_REPORT_DESCRIPTOR.to_vec());
    // The HID descriptor's wDescriptorLength of the report descriptor.
    model.configuration[25] = ROLLOVER_REPORT_DESCRIPTOR.len() as u8;
    let mut bus = with_keyboards(model, 1);
    assert!(logged(&mut bus, "(2 key fields, 20-byte reports)"));
    // A packet a transfer, as the endpoint's 8 bytes allow.
    let send = |bus: &mut Bus<Xhci<XhciModel>>, report: &[u8]| {
        let mut bytes = Vec::new();
        for packet in report.chunks(8) {
            assert!(hw(bus).send_bytes(packet));
            bytes.extend(poll(bus));
        }
        bytes
    };
    let a_and_b = rollover_report(&[0x04, 0x05]);
    assert_eq!(send(&mut bus, &a_and_b), [0x1E, 0x30]);
    // Cut short after 10 bytes: dropped, and the next report is whole.
    assert_eq!(send(&mut bus, &a_and_b[..10]), []);
    assert_eq!(send(&mut bus, &rollover_report(&[])), [0x9E, 0xB0]);
    assert!(logged(
        &mut bus,
        "keyboard: 1 unreadable reports dropped (the last 10 bytes)"
    ));
    assert_clean(&mut bus);
}
