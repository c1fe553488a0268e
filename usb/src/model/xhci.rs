//! A register model of an xHCI controller with one full-speed boot keyboard
//! on root port 1 (or behind up to six hubs there, USB 2 or USB 3; and a
//! second keyboard, or a device that never answers, on root port 2), for
//! the host tests: enough of the specification to run
//! the driver end to end (ownership hand-off, reset and Controller Not Ready,
//! scratchpads, 32- or 64-byte contexts, the command, transfer and event
//! rings with their cycle bits), and knobs to make it misbehave. It checks
//! what the driver gives it (context layouts, ring ownership, memory
//! bounds) and fails commands that get it wrong, as hardware would.

use crate::xhci::ring::{trb_type, Trb, CYCLE, TOGGLE_CYCLE};
use crate::{Hardware, Memory, Platform};
use std::string::String;
use std::vec;
use std::vec::Vec;

const DISABLE_SLOT: u32 = 10;
const RESET_ENDPOINT: u32 = 14;
const SET_TR_DEQUEUE: u32 = 16;
const STOP_ENDPOINT: u32 = 15;

pub const DMA_BASE: u64 = 0x10_0000;
pub const DMA_BYTES: u64 = 1 << 20;
pub const BAR_BYTES: u32 = 0x2000;
const OPERATIONAL: u32 = 0x20;
const RUNTIME: u32 = 0x600;
const DOORBELLS: u32 = 0x800;
const EXTENDED: u32 = 0x1000;
/// Root ports unless [`XhciModel::wide_ports`] says otherwise.
const PORTS: u8 = 2;
const MICROS_PER_CLOCK_READ: u64 = 5;

/// The descriptors the xHCI model's devices give, shared with the tree
/// of devices the other controllers' models use.
pub use super::devices::{
    HUB_CONFIGURATION, HUB_DESCRIPTOR, HUB_DEVICE, KEYBOARD_CONFIGURATION, KEYBOARD_DEVICE,
    KEYBOARD_REPORT_DESCRIPTOR,
};
/// A SuperSpeed hub's descriptor: 4 ports, 100 ms to power good.
pub const SUPERSPEED_HUB_DESCRIPTOR: [u8; 12] = [12, 0x2A, 4, 0, 0, 50, 0, 0, 0, 0, 0, 0];

/// A consumer's place on a producer ring.
#[derive(Clone, Copy, Debug, Default)]
struct Cursor {
    dequeue: u64,
    cycle: bool,
}

#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
enum Kind {
    #[default]
    Keyboard,
    Hub,
    /// The keyboard on root port 2.
    Keyboard2,
    /// The SuperSpeed half of a USB 3 hub, on root port 2.
    SuperSpeedHalf,
    /// A device on root port 2 that answers no control transfer.
    Dead,
}

/// What hangs on root port 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnRootPort2 {
    /// A second keyboard (its state is `keyboard2`).
    Keyboard,
    /// A device whose control transfers never complete.
    Dead,
    /// The SuperSpeed half of the USB 3 hub whose USB 2 half is the hub on
    /// root port 1 (`hub` with `high_speed_hub`): root port 2 is then a USB 3
    /// port (its own Supported Protocol range) and port 1 a USB 2 one. (Which
    /// range comes first is the controller's choice: QEMU's qemu-xhci puts
    /// its USB 3 ports first.) Nothing hangs on this half.
    SuperSpeedHalf,
}

/// Where in [`XhciModel::hub_states`] the SuperSpeed half of a USB 3 hub
/// keeps its state (after the six tiers of hubs on root port 1).
pub const SUPERSPEED_HALF: usize = 6;

/// Every hub's state after power-on: nothing behind the SuperSpeed half.
fn fresh_hub_states() -> Vec<HubState> {
    let mut states = vec![HubState::default(); SUPERSPEED_HALF + 1];
    states[SUPERSPEED_HALF].port_2_empty = true;
    states
}

#[derive(Clone, Debug, Default)]
struct Slot {
    kind: Kind,
    /// A hub's tier (0: on the root port).
    tier: usize,
    enabled: bool,
    output: u64,
    ep0: Cursor,
    interrupt: Option<(u8, Cursor)>,
    /// The controller halted the interrupt endpoint after an error.
    interrupt_halted: bool,
    /// Address Device with BSR=1 done: the device is at the default address.
    default_address: bool,
    /// Endpoint 0's packet size in the device's context (8 until evaluated).
    ep0_max_packet: u16,
    /// The device descriptor was read (at whatever address).
    descriptor_read: bool,
    /// A transfer on endpoint 0 babbled (a packet larger than its size).
    babble: bool,
    /// Endpoint 0 halted after a stall or babble (with `ep0_halts`), until
    /// Reset Endpoint.
    ep0_halted: bool,
    /// Endpoint 0 stopped (Reset Endpoint or Stop Endpoint), until Set TR
    /// Dequeue Pointer or its doorbell.
    ep0_stopped: bool,
}

/// What the keyboard was told.
#[derive(Clone, Debug, Default)]
pub struct KeyboardState {
    pub configuration: Option<u8>,
    /// The protocol the keyboard is in: 1 (report) after a reset, 0 (boot)
    /// once told, unless it ignores SET_PROTOCOL.
    pub protocol: u16,
    /// SET_PROTOCOL requests received.
    pub set_protocols: u32,
    pub idle_set: bool,
    /// The keyboard's own endpoint is halted (after a stall) until
    /// CLEAR_FEATURE(ENDPOINT_HALT).
    pub device_halted: bool,
    pub halts_cleared: u32,
    pub slot: u8,
}

/// What a hub was told, and its port 2 (where the keyboard, or the next
/// hub, is).
#[derive(Clone, Debug, Default)]
pub struct HubState {
    pub slot: u8,
    pub configured: bool,
    /// The controller was told it is a hub, with its 4 ports.
    pub marked: bool,
    pub powered: [bool; 4],
    pub keyboard_port_status: u32,
    /// Nothing is plugged into port 2.
    pub port_2_empty: bool,
    /// What SET_HUB_DEPTH said (SuperSpeed hubs).
    pub depth: Option<u16>,
    /// A port change waits for a transfer on the status change endpoint.
    pub change_pending: bool,
}

/// The xHCI register model.
#[derive(Debug)]
pub struct XhciModel {
    pub now: u64,
    memory: Vec<u32>,
    // Knobs.
    pub csz: bool,
    pub scratchpads: u32,
    /// When the firmware clears BIOS-owned after the OS asks (None: never).
    pub firmware_releases_after: Option<u64>,
    pub cnr_stuck: bool,
    pub commands_answered: bool,
    pub device_descriptor: Vec<u8>,
    pub configuration: Vec<u8>,
    /// The report descriptor (None: the request stalls).
    pub report_descriptor: Option<Vec<u8>>,
    /// The keyboard stays in the report protocol whatever it is told.
    pub ignores_set_protocol: bool,
    /// The keyboard answers SET_ADDRESS only once its device descriptor
    /// has been read (the two-step address).
    pub needs_two_step: bool,
    /// Endpoint 0 halts in the controller after a stall or babble, as on
    /// real hardware, and takes no transfer until Reset Endpoint and Set TR
    /// Dequeue Pointer (the driver's own enumeration never resets it: off
    /// by default).
    pub ep0_halts: bool,
    /// With `hub`: the hubs are high speed with one transaction translator
    /// each, and the full-speed keyboard is reached through the last one's
    /// (its slot and port 2 in the keyboard's slot context).
    pub high_speed_hub: bool,
    /// A full-speed hub on root port 1, the keyboard on its port 2.
    pub hub: bool,
    /// With `hub`: this many hubs chained, each on port 2 of the one
    /// above, the keyboard on the last one's port 2.
    pub hub_tiers: usize,
    /// Root port 1 is empty after the controller's reset (plugged later).
    pub empty_at_start: bool,
    /// What hangs on root port 2 (None: nothing).
    pub port_2: Option<OnRootPort2>,
    /// The root ports are USB 3 and the hubs SuperSpeed (the keyboard
    /// behind them too).
    pub usb3: bool,
    /// A USB 2 port's reset never ends: PR stays set.
    pub port_reset_stuck: bool,
    /// With `usb3`: root port 1's link trains this long after the
    /// controller's reset (connected at once, enabled then; 0: at once).
    pub usb3_link_micros: u64,
    /// When root port 1's USB 3 link is trained and the port enabled.
    usb3_enabled_at: Option<u64>,
    /// With `usb3`: root port 1's link falls into SS.Inactive after the
    /// controller's reset and stays there until a warm reset (WPR).
    pub usb3_link_stuck: bool,
    /// Warm resets (WPR) the driver asked for.
    pub warm_resets: u32,
    /// Root ports (MaxPorts); see [`XhciModel::wide_ports`].
    ports: u8,
    /// The port the model's "root port 1" (the keyboard, or the hubs) is.
    keyboard_port: u8,
    /// The keyboard on root port 2.
    pub keyboard2: KeyboardState,
    /// Command Aborts the driver asked for (CRCR's CA).
    pub commands_aborted: u32,
    /// The keyboard's interrupt endpoint was reset and awaits its dequeue pointer.
    endpoint_stopped: bool,
    // Registers.
    legacy: u32,
    legacy_control: u32,
    os_asked_at: Option<u64>,
    usbcmd: u32,
    usbsts: u32,
    config: u32,
    dcbaap: u64,
    crcr: Cursor,
    portsc: Vec<u32>,
    erstsz: u32,
    erstba: u64,
    erdp: u64,
    event_base: u64,
    event_size: u64,
    event_enqueue: u64,
    event_cycle: bool,
    slots: [Slot; 9],
    next_slot: u8,
    // What happened.
    pub keyboard: KeyboardState,
    /// Each hub tier's state, the one on the root port first.
    pub hub_states: Vec<HubState>,
    pub events_dropped: u32,
    /// Slots the driver disabled, in order.
    pub slots_disabled: Vec<u8>,
    /// Root ports (1-based) the driver disabled (PED written), in order.
    pub ports_disabled: Vec<u8>,
    pub events_posted: u32,
    pub log: Vec<String>,
    pub errors: Vec<String>,
}

impl XhciModel {
    pub fn new() -> XhciModel {
        XhciModel {
            now: 0,
            memory: vec![0; (DMA_BYTES / 4) as usize],
            csz: false,
            scratchpads: 0,
            firmware_releases_after: Some(2_000),
            cnr_stuck: false,
            commands_answered: true,
            device_descriptor: KEYBOARD_DEVICE.to_vec(),
            configuration: KEYBOARD_CONFIGURATION.to_vec(),
            report_descriptor: Some(KEYBOARD_REPORT_DESCRIPTOR.to_vec()),
            ignores_set_protocol: false,
            needs_two_step: false,
            ep0_halts: false,
            high_speed_hub: false,
            hub: false,
            hub_tiers: 1,
            empty_at_start: false,
            port_2: None,
            usb3: false,
            port_reset_stuck: false,
            usb3_link_micros: 0,
            usb3_enabled_at: None,
            usb3_link_stuck: false,
            warm_resets: 0,
            keyboard2: KeyboardState {
                protocol: 1,
                ..KeyboardState::default()
            },
            commands_aborted: 0,
            endpoint_stopped: false,
            legacy: 1 << 16,
            legacy_control: 0xE000_E011,
            os_asked_at: None,
            usbcmd: 0,
            usbsts: 1,
            config: 0,
            dcbaap: 0,
            crcr: Cursor::default(),
            portsc: vec![0; usize::from(PORTS)],
            ports: PORTS,
            keyboard_port: 1,
            erstsz: 0,
            erstba: 0,
            erdp: 0,
            event_base: 0,
            event_size: 0,
            event_enqueue: 0,
            event_cycle: true,
            slots: Default::default(),
            next_slot: 1,
            keyboard: KeyboardState {
                protocol: 1,
                ..KeyboardState::default()
            },
            hub_states: fresh_hub_states(),
            events_dropped: 0,
            slots_disabled: Vec::new(),
            ports_disabled: Vec::new(),
            events_posted: 0,
            log: Vec::new(),
            errors: Vec::new(),
        }
    }

    fn context_bytes(&self) -> u64 {
        if self.csz {
            64
        } else {
            32
        }
    }

    fn word(&self, address: u64) -> usize {
        assert!(
            address >= DMA_BASE && address + 4 <= DMA_BASE + DMA_BYTES && address % 4 == 0,
            "the driver touched {address:#x}, outside its DMA memory"
        );
        ((address - DMA_BASE) / 4) as usize
    }

    fn read64(&mut self, address: u64) -> u64 {
        u64::from(self.mem_read(address)) | u64::from(self.mem_read(address + 4)) << 32
    }

    fn read_trb(&mut self, address: u64) -> Trb {
        Trb([
            self.mem_read(address),
            self.mem_read(address + 4),
            self.mem_read(address + 8),
            self.mem_read(address + 12),
        ])
    }

    /// The next TRB the producer has handed over, following Link TRBs.
    fn next_trb(&mut self, cursor: &mut Cursor) -> Option<(u64, Trb)> {
        for _ in 0..4 {
            let trb = self.read_trb(cursor.dequeue);
            if (trb.0[3] & CYCLE != 0) != cursor.cycle {
                return None;
            }
            if trb.kind() == trb_type::LINK {
                if trb.0[3] & TOGGLE_CYCLE != 0 {
                    cursor.cycle = !cursor.cycle;
                }
                cursor.dequeue = trb.parameter() & !0xF;
                continue;
            }
            let address = cursor.dequeue;
            cursor.dequeue += 16;
            return Some((address, trb));
        }
        self.errors.push("a loop of Link TRBs".into());
        None
    }

    fn post_event(&mut self, trb: Trb) {
        if self.event_size == 0 {
            self.errors.push("an event with no event ring".into());
            return;
        }
        let next = (self.event_enqueue + 1) % self.event_size;
        let dequeue_index = (self.erdp - self.event_base) / 16;
        if next == dequeue_index {
            self.events_dropped += 1;
            return;
        }
        let address = self.event_base + self.event_enqueue * 16;
        self.mem_write(address, trb.0[0]);
        self.mem_write(address + 4, trb.0[1]);
        self.mem_write(address + 8, trb.0[2]);
        self.mem_write(
            address + 12,
            (trb.0[3] & !CYCLE) | u32::from(self.event_cycle),
        );
        self.event_enqueue = next;
        if next == 0 {
            self.event_cycle = !self.event_cycle;
        }
        self.events_posted += 1;
    }

    fn complete_command(&mut self, address: u64, code: u8, slot: u8) {
        if self.commands_answered {
            self.post_event(Trb([
                address as u32,
                (address >> 32) as u32,
                u32::from(code) << 24,
                trb_type::COMMAND_COMPLETION << 10 | u32::from(slot) << 24,
            ]));
        }
    }

    fn transfer_event(&mut self, address: u64, code: u8, residual: u32, slot: u8, dci: u8) {
        self.post_event(Trb([
            address as u32,
            (address >> 32) as u32,
            u32::from(code) << 24 | residual,
            trb_type::TRANSFER_EVENT << 10 | u32::from(slot) << 24 | u32::from(dci) << 16,
        ]));
    }

    fn output_context(&mut self, slot: u8) -> u64 {
        self.read64(self.dcbaap + 8 * u64::from(slot))
    }

    fn run_commands(&mut self) {
        let mut cursor = self.crcr;
        while let Some((address, trb)) = self.next_trb(&mut cursor) {
            let slot = trb.slot();
            let ctx = self.context_bytes();
            match trb.kind() {
                trb_type::NO_OP_COMMAND => self.complete_command(address, 1, 0),
                DISABLE_SLOT => {
                    let state = &mut self.slots[usize::from(slot)];
                    if !state.enabled {
                        self.errors
                            .push(std::format!("Disable Slot {slot}: not enabled"));
                    }
                    *state = Slot::default();
                    self.slots_disabled.push(slot);
                    self.complete_command(address, 1, slot);
                }
                trb_type::ENABLE_SLOT => {
                    // The lowest slot free, as a controller hands them out
                    // again once disabled.
                    let Some(slot) = (1..self.slots.len()).find(|&s| !self.slots[s].enabled) else {
                        self.complete_command(address, 9, 0); // No Slots Available
                        continue;
                    };
                    let slot = slot as u8;
                    self.next_slot = self.next_slot.max(slot + 1);
                    self.slots[usize::from(slot)].enabled = true;
                    self.complete_command(address, 1, slot);
                }
                trb_type::ADDRESS_DEVICE => {
                    let input = trb.parameter();
                    let add = self.mem_read(input + 4);
                    let slot_dw0 = self.mem_read(input + ctx);
                    let root_port = (self.mem_read(input + ctx + 4) >> 16) & 0xFF;
                    let ep0_dw1 = self.mem_read(input + 2 * ctx + 4);
                    let ep0_dequeue = self.read64(input + 2 * ctx + 8);
                    let route = slot_dw0 & 0xF_FFFF;
                    let tiers = if self.hub { self.hub_tiers } else { 0 };
                    // Each tier's hub on port 2 of the one above.
                    let route_of = |tier: usize| (0..tier).fold(0, |r, t| r | 2 << (4 * t));
                    let hub_tier = (0..tiers).find(|&t| route == route_of(t));
                    let kind = if root_port == 2 {
                        match (route, self.port_2) {
                            (0, Some(OnRootPort2::Keyboard)) => Some(Kind::Keyboard2),
                            (0, Some(OnRootPort2::Dead)) => Some(Kind::Dead),
                            (0, Some(OnRootPort2::SuperSpeedHalf)) => Some(Kind::SuperSpeedHalf),
                            _ => None,
                        }
                    } else if route == route_of(tiers) {
                        Some(Kind::Keyboard)
                    } else {
                        hub_tier.map(|_| Kind::Hub)
                    };
                    // SuperSpeed: speed 4, 512-byte packets on endpoint 0,
                    // and no transaction translator anywhere.
                    let high_speed = self.high_speed_hub && kind == Some(Kind::Hub);
                    let superspeed = self.usb3 || kind == Some(Kind::SuperSpeedHalf);
                    let (speed, ep0_packet) = if superspeed {
                        (4, 512)
                    } else if high_speed {
                        (3, 64)
                    } else {
                        (1, self.slots[usize::from(slot)].ep0_max_packet.max(8))
                    };
                    let translator = self.mem_read(input + ctx + 8) & 0xFFFF;
                    // Behind high-speed hubs the keyboard names the last
                    // one's translator: its slot, port 2.
                    let expected_translator = match kind {
                        Some(Kind::Keyboard) if self.high_speed_hub && tiers > 0 => {
                            u32::from(self.hub_states[tiers - 1].slot) | 2 << 8
                        }
                        _ => 0,
                    };
                    let valid = add == 0b11
                        && kind.is_some()
                        && (slot_dw0 >> 20) & 0xF == speed
                        && slot_dw0 >> 27 == 1
                        && (root_port == u32::from(self.keyboard_port) || root_port == 2)
                        && (ep0_dw1 >> 3) & 7 == 4
                        && (ep0_dw1 >> 16 == u32::from(ep0_packet)
                            || (speed == 1 && matches!(ep0_dw1 >> 16, 8 | 16 | 32 | 64)))
                        && !(superspeed && translator != 0)
                        && (!self.high_speed_hub || translator == expected_translator)
                        && ep0_dequeue != 0
                        && self.slots[usize::from(slot)].enabled;
                    let block_set_address = trb.0[3] & (1 << 9) != 0;
                    if !valid {
                        self.errors.push(std::format!(
                            "Address Device: input context wrong (add {add:#x}, slot {slot_dw0:#x}, port {root_port}, ep0 {ep0_dw1:#x})"
                        ));
                        self.complete_command(address, 17, slot);
                        continue;
                    }
                    let kind_now = kind.unwrap_or_default();
                    let state = &self.slots[usize::from(slot)];
                    if !block_set_address
                        && kind_now == Kind::Keyboard
                        && self.needs_two_step
                        && !state.descriptor_read
                    {
                        // SET_ADDRESS before its descriptor was read: this
                        // device does not answer it.
                        self.complete_command(address, 4, slot);
                        continue;
                    }
                    let new_ep0 = Cursor {
                        dequeue: ep0_dequeue & !0xF,
                        cycle: ep0_dequeue & 1 != 0,
                    };
                    // The ring may have been padded (with No Ops), never rewound.
                    if state.default_address
                        && (new_ep0.dequeue < state.ep0.dequeue || new_ep0.cycle != state.ep0.cycle)
                    {
                        self.errors.push(std::format!(
                            "second Address Device: endpoint 0 dequeue {ep0_dequeue:#x} is not where the ring stands"
                        ));
                    }
                    if speed == 1 {
                        // A full-speed endpoint 0 is the host's guess
                        // until evaluated (Linux's xHCI driver guesses 64).
                        self.slots[usize::from(slot)].ep0_max_packet = (ep0_dw1 >> 16) as u16;
                    }
                    let output = self.output_context(slot);
                    let slot_state = if block_set_address { 1 } else { 2 };
                    self.mem_write(output + 12, slot_state << 27 | u32::from(slot));
                    let state = &mut self.slots[usize::from(slot)];
                    state.kind = kind_now;
                    state.tier = match kind {
                        Some(Kind::SuperSpeedHalf) => SUPERSPEED_HALF,
                        _ => hub_tier.unwrap_or(0),
                    };
                    state.output = output;
                    state.default_address = block_set_address;
                    state.ep0 = new_ep0;
                    match kind {
                        Some(Kind::Hub) => self.hub_states[hub_tier.unwrap_or(0)].slot = slot,
                        Some(Kind::SuperSpeedHalf) => self.hub_states[SUPERSPEED_HALF].slot = slot,
                        Some(Kind::Keyboard2) => self.keyboard2.slot = slot,
                        Some(Kind::Dead) => {}
                        _ => self.keyboard.slot = slot,
                    }
                    self.complete_command(address, 1, slot);
                }
                trb_type::EVALUATE_CONTEXT => {
                    let input = trb.parameter();
                    let add = self.mem_read(input + 4);
                    if add & 0b10 != 0 {
                        let ep0_dw1 = self.mem_read(input + 2 * ctx + 4);
                        self.slots[usize::from(slot)].ep0_max_packet = (ep0_dw1 >> 16) as u16;
                    }
                    self.complete_command(address, 1, slot)
                }
                RESET_ENDPOINT | SET_TR_DEQUEUE | STOP_ENDPOINT if (trb.0[3] >> 16) & 0x1F == 1 => {
                    // Endpoint 0: Reset Endpoint takes Halted to Stopped,
                    // Stop Endpoint a running one to Stopped, Set TR
                    // Dequeue Pointer moves a stopped one's ring.
                    let state = &mut self.slots[usize::from(slot)];
                    let code = match trb.kind() {
                        RESET_ENDPOINT if state.ep0_halted => {
                            state.ep0_halted = false;
                            state.ep0_stopped = true;
                            1
                        }
                        STOP_ENDPOINT if !state.ep0_halted && state.enabled => {
                            state.ep0_stopped = true;
                            1
                        }
                        SET_TR_DEQUEUE if state.ep0_stopped => {
                            state.ep0 = Cursor {
                                dequeue: trb.parameter() & !0xF,
                                cycle: trb.parameter() & 1 != 0,
                            };
                            state.ep0_stopped = false;
                            1
                        }
                        SET_TR_DEQUEUE => {
                            self.errors
                                .push("Set TR Dequeue Pointer on endpoint 0 not stopped".into());
                            19
                        }
                        _ => 19,
                    };
                    self.complete_command(address, code, slot);
                }
                RESET_ENDPOINT | SET_TR_DEQUEUE => {
                    let dci = ((trb.0[3] >> 16) & 0x1F) as u8;
                    let state = &mut self.slots[usize::from(slot)];
                    let Some((endpoint, cursor)) = state.interrupt.as_mut() else {
                        self.complete_command(address, 19, slot);
                        continue;
                    };
                    if *endpoint != dci {
                        self.errors.push(std::format!("command for endpoint {dci}"));
                        self.complete_command(address, 19, slot);
                        continue;
                    }
                    // Reset Endpoint: Halted -> Stopped; Set TR Dequeue
                    // Pointer: only while Stopped.
                    let code = if trb.kind() == RESET_ENDPOINT {
                        if state.interrupt_halted {
                            state.interrupt_halted = false;
                            self.endpoint_stopped = true;
                            1
                        } else {
                            19
                        }
                    } else if state.interrupt_halted || !self.endpoint_stopped {
                        19
                    } else {
                        *cursor = Cursor {
                            dequeue: trb.parameter() & !0xF,
                            cycle: trb.parameter() & 1 != 0,
                        };
                        self.endpoint_stopped = false;
                        1
                    };
                    if code != 1 {
                        self.errors.push(std::format!(
                            "command {} in the wrong endpoint state",
                            trb.kind()
                        ));
                    }
                    self.complete_command(address, code, slot);
                }
                trb_type::CONFIGURE_ENDPOINT => {
                    let input = trb.parameter();
                    let add = self.mem_read(input + 4);
                    let mut ok = add & 1 != 0 && add & 0b10 == 0;
                    if self.is_hub(slot) {
                        let slot_dw0 = self.mem_read(input + ctx);
                        let ports = self.mem_read(input + ctx + 4) >> 24;
                        let tier = self.slots[usize::from(slot)].tier;
                        self.hub_states[tier].marked =
                            add & !(1 << 3) == 1 && slot_dw0 & (1 << 26) != 0 && ports == 4;
                    }
                    for dci in 2..32u8 {
                        if add & (1 << dci) == 0 {
                            continue;
                        }
                        let dw1 = self.mem_read(input + (1 + u64::from(dci)) * ctx + 4);
                        let dequeue = self.read64(input + (1 + u64::from(dci)) * ctx + 8);
                        if (dw1 >> 3) & 7 != 7 || dequeue == 0 || dw1 >> 16 == 0 {
                            ok = false;
                            continue;
                        }
                        self.slots[usize::from(slot)].interrupt = Some((
                            dci,
                            Cursor {
                                dequeue: dequeue & !0xF,
                                cycle: dequeue & 1 != 0,
                            },
                        ));
                    }
                    if !ok {
                        self.errors
                            .push(std::format!("Configure Endpoint: add flags {add:#x} wrong"));
                        self.complete_command(address, 17, slot);
                        continue;
                    }
                    let output = self.slots[usize::from(slot)].output;
                    self.mem_write(output + 12, 3 << 27 | u32::from(slot));
                    self.complete_command(address, 1, slot);
                }
                other => {
                    self.errors.push(std::format!("unknown command {other}"));
                    self.complete_command(address, 5, slot);
                }
            }
        }
        self.crcr = cursor;
    }

    fn run_control(&mut self, slot: u8) {
        if self.slots[usize::from(slot)].kind == Kind::Dead {
            // It never answers: the TRBs stay where they are.
            return;
        }
        if self.slots[usize::from(slot)].kind == Kind::Keyboard2 {
            // The second keyboard answers as the first does, with its own state.
            std::mem::swap(&mut self.keyboard, &mut self.keyboard2);
            self.slots[usize::from(slot)].kind = Kind::Keyboard;
            self.run_control(slot);
            self.slots[usize::from(slot)].kind = Kind::Keyboard2;
            std::mem::swap(&mut self.keyboard, &mut self.keyboard2);
            return;
        }
        if self.slots[usize::from(slot)].ep0_halted {
            // A halted endpoint takes nothing until it is reset.
            return;
        }
        // A stopped endpoint runs again when its doorbell rings.
        self.slots[usize::from(slot)].ep0_stopped = false;
        let mut cursor = self.slots[usize::from(slot)].ep0;
        let mut setup = 0u64;
        while let Some((address, trb)) = self.next_trb(&mut cursor) {
            match trb.kind() {
                trb_type::SETUP => setup = trb.parameter(),
                trb_type::DATA => {
                    let (request_type, request) = (setup as u8, (setup >> 8) as u8);
                    let value = (setup >> 16) as u16;
                    let length = (setup >> 48) as usize;
                    let hub = self.is_hub(slot);
                    let superspeed = self.superspeed(slot);
                    let reply = match (hub, request_type, request, value >> 8) {
                        (false, 0x80, 6, 1) => {
                            let announced =
                                usize::from(self.device_descriptor.get(7).copied().unwrap_or(8));
                            // SuperSpeed gives the packet size as a power of two.
                            let (packet, device_packet) = if self.usb3 {
                                (512, 1 << announced.min(9))
                            } else {
                                (
                                    usize::from(
                                        self.slots[usize::from(slot)].ep0_max_packet.max(8),
                                    ),
                                    announced,
                                )
                            };
                            // A reply longer than one packet of the wrong
                            // size babbles.
                            if length > packet && packet != device_packet {
                                self.slots[usize::from(slot)].babble = true;
                            }
                            self.slots[usize::from(slot)].descriptor_read = true;
                            self.device_descriptor.clone()
                        }
                        (false, 0x80, 6, 2) => self.configuration.clone(),
                        (false, 0x81, 6, 0x22) => {
                            self.report_descriptor.clone().unwrap_or_default()
                        }
                        (true, 0x80, 6, 1) if self.high_speed_hub && !superspeed => {
                            super::devices::HIGH_SPEED_HUB_DEVICE.to_vec()
                        }
                        (true, 0x80, 6, 1) => {
                            let mut device = HUB_DEVICE;
                            if superspeed {
                                device[2..4].copy_from_slice(&0x0300u16.to_le_bytes());
                                device[7] = 9; // 2^9 = 512 bytes
                            }
                            device.to_vec()
                        }
                        (true, 0x80, 6, 2) => HUB_CONFIGURATION.to_vec(),
                        (true, 0xA0, 6, 0x29) if !superspeed => HUB_DESCRIPTOR.to_vec(),
                        (true, 0xA0, 6, 0x2A) if superspeed => SUPERSPEED_HUB_DESCRIPTOR.to_vec(),
                        (true, 0xA3, 0, _) => {
                            let port = (setup >> 32) as u16;
                            let status = if port == 2 {
                                self.hub_states[self.slots[usize::from(slot)].tier]
                                    .keyboard_port_status
                            } else {
                                0
                            };
                            status.to_le_bytes().to_vec()
                        }
                        _ => Vec::new(),
                    };
                    let buffer = trb.parameter();
                    let mut bytes = reply;
                    bytes.truncate(length.min(trb.0[2] as usize));
                    // An event for the data stage when asked for (IOC), or
                    // when short and asked for that (ISP).
                    let asked = trb.0[2] & 0x1_FFFF;
                    let residual = asked.saturating_sub(bytes.len() as u32);
                    let (ioc, isp) = (trb.0[3] & 1 << 5 != 0, trb.0[3] & 1 << 2 != 0);
                    if ioc || (isp && residual > 0) {
                        let code = if residual > 0 { 13 } else { 1 };
                        self.transfer_event(address, code, residual, slot, 1);
                    }
                    bytes.resize(bytes.len().div_ceil(4) * 4, 0);
                    for (i, chunk) in bytes.chunks(4).enumerate() {
                        let word = u32::from_le_bytes([chunk[0], chunk[1], chunk[2], chunk[3]]);
                        self.mem_write(buffer + 4 * i as u64, word);
                    }
                }
                trb_type::STATUS => {
                    let (request_type, request) = (setup as u8, (setup >> 8) as u8);
                    let value = (setup >> 16) as u16;
                    if self.is_hub(slot) {
                        let tier = self.slots[usize::from(slot)].tier;
                        let known = self.hub_request(tier, setup);
                        self.transfer_event(address, if known { 1 } else { 6 }, 0, slot, 1);
                        if !known && self.halt_ep0(slot, cursor) {
                            return;
                        }
                        continue;
                    }
                    if std::mem::take(&mut self.slots[usize::from(slot)].babble) {
                        self.transfer_event(address, 3, 0, slot, 1);
                        if self.halt_ep0(slot, cursor) {
                            return;
                        }
                        continue;
                    }
                    let known = match (request_type, request) {
                        (0x80, 6) => true,
                        (0x81, 6) => self.report_descriptor.is_some(),
                        (0x00, 9) => {
                            self.keyboard.configuration = Some(value as u8);
                            true
                        }
                        (0x21, 0x0B) => {
                            self.keyboard.set_protocols += 1;
                            if !self.ignores_set_protocol {
                                self.keyboard.protocol = value;
                            }
                            true
                        }
                        (0x02, 1) if value == 0 && (setup >> 32) as u16 == 0x81 => {
                            self.keyboard.device_halted = false;
                            self.keyboard.halts_cleared += 1;
                            true
                        }
                        (0x21, 0x0A) => {
                            self.keyboard.idle_set = true;
                            true
                        }
                        _ => false,
                    };
                    self.transfer_event(address, if known { 1 } else { 6 }, 0, slot, 1);
                    if !known && self.halt_ep0(slot, cursor) {
                        return;
                    }
                }
                trb_type::NO_OP_TRANSFER => {}
                other => self.errors.push(std::format!("TRB type {other} on EP0")),
            }
        }
        self.slots[usize::from(slot)].ep0 = cursor;
    }

    /// With `ep0_halts`, endpoint 0 halts after a failed transfer, its ring
    /// left at `cursor`; gives whether it did.
    fn halt_ep0(&mut self, slot: u8, cursor: Cursor) -> bool {
        if !self.ep0_halts {
            return false;
        }
        let state = &mut self.slots[usize::from(slot)];
        state.ep0_halted = true;
        state.ep0 = cursor;
        true
    }

    /// Whether `slot` is a hub (a tier on root port 1, or a SuperSpeed half).
    fn is_hub(&self, slot: u8) -> bool {
        matches!(
            self.slots[usize::from(slot)].kind,
            Kind::Hub | Kind::SuperSpeedHalf
        )
    }

    /// Whether `slot`'s device is SuperSpeed.
    fn superspeed(&self, slot: u8) -> bool {
        self.usb3 || self.slots[usize::from(slot)].kind == Kind::SuperSpeedHalf
    }

    /// Root port 2 is a USB 3 port and port 1 a USB 2 one.
    fn split_protocols(&self) -> bool {
        self.port_2 == Some(OnRootPort2::SuperSpeedHalf)
    }

    /// The Supported Protocol ranges, (major, first port, count): every
    /// port USB 2 or USB 3; with a SuperSpeed half on port 2, port 1 USB 2
    /// and port 2 USB 3; with [`XhciModel::wide_ports`], the USB 3 half
    /// first and the USB 2 half last.
    fn protocols(&self) -> Vec<(u32, u32, u32)> {
        let ports = u32::from(self.ports);
        if self.ports > PORTS {
            vec![(3, 1, ports / 2), (2, ports / 2 + 1, ports - ports / 2)]
        } else if self.split_protocols() {
            vec![(2, 1, 1), (3, 2, 1)]
        } else if self.usb3 {
            vec![(3, 1, ports)]
        } else {
            vec![(2, 1, ports)]
        }
    }

    /// `ports` root ports (MaxPorts), the USB 3 half first and the USB 2
    /// half last (as Bochs's Renesas model and chipsets put them), the
    /// keyboard (or the hubs) on USB 2 port `keyboard_port` instead of
    /// port 1; port 2 keeps what `port_2` puts there.
    pub fn wide_ports(&mut self, ports: u8, keyboard_port: u8) {
        assert!(OPERATIONAL + 0x400 + 0x10 * u32::from(ports) <= RUNTIME);
        assert!(keyboard_port > ports / 2 && keyboard_port <= ports && !self.usb3);
        self.ports = ports;
        self.keyboard_port = keyboard_port;
        self.portsc = vec![0; usize::from(ports)];
    }

    /// The index in `portsc` of the keyboard's port.
    fn kb(&self) -> usize {
        usize::from(self.keyboard_port) - 1
    }

    /// Root port 1's speed ID: full speed, or high with `high_speed_hub`.
    fn port_1_speed(&self) -> u32 {
        if self.hub && self.high_speed_hub {
            3 << 10
        } else {
            1 << 10
        }
    }

    /// PORT_HIGH_SPEED for port 2 of hub `tier` when a high-speed hub hangs there.
    fn high_speed_below(&self, tier: usize) -> u32 {
        if self.high_speed_hub && tier + 1 < self.hub_tiers {
            1 << 10
        } else {
            0
        }
    }

    /// A hub class (or standard) request's effect; whether the hub knows it.
    fn hub_request(&mut self, tier: usize, setup: u64) -> bool {
        const CONNECTED: u32 = 1;
        const ENABLED: u32 = 1 << 1;
        const POWERED: u32 = 1 << 8;
        const RESET_CHANGE: u32 = 1 << 20;
        const CONNECTION_CHANGE: u32 = 1 << 16;
        // A SuperSpeed hub's power bit is bit 9 (bit 9 is low speed in USB 2.0).
        let superspeed = self.usb3 || tier == SUPERSPEED_HALF;
        let powered = if superspeed { 1 << 9 } else { POWERED };
        let (request_type, request) = (setup as u8, (setup >> 8) as u8);
        let value = (setup >> 16) as u16;
        let port = (setup >> 32) as u16;
        let port_index = usize::from(port).wrapping_sub(1);
        match (request_type, request, value) {
            (0x80 | 0xA0 | 0xA3, 6 | 0, _) => true,
            (0x00, 9, _) => {
                self.hub_states[tier].configured = true;
                true
            }
            (0x20, 12, depth) if superspeed => {
                self.hub_states[tier].depth = Some(depth);
                true
            }
            (0x23, 3, 8) if port_index < 4 => {
                self.hub_states[tier].powered[port_index] = true;
                if port == 2 && !self.hub_states[tier].port_2_empty {
                    // A device found at power-on is a connection change.
                    self.hub_states[tier].keyboard_port_status =
                        CONNECTED | powered | CONNECTION_CHANGE | self.high_speed_below(tier);
                }
                true
            }
            (0x23, 3, 4) if port == 2 => {
                if self.hub_states[tier].keyboard_port_status & CONNECTED != 0 {
                    self.hub_states[tier].keyboard_port_status |= ENABLED | RESET_CHANGE;
                }
                true
            }
            (0x23, 1, 16..=20) if port == 2 => {
                self.hub_states[tier].keyboard_port_status &= !(1 << value);
                true
            }
            _ => {
                self.errors.push(std::format!("hub request {setup:#018x}"));
                false
            }
        }
    }

    /// The keyboard sends a report (if a Normal TRB waits for one); returns
    /// whether it could.
    pub fn send_report(&mut self, report: [u8; 8]) -> bool {
        self.send_bytes(&report)
    }

    /// The keyboard sends a report of any length (at most the TRB's: a
    /// longer one is cut, as a babble would be).
    pub fn send_bytes(&mut self, report: &[u8]) -> bool {
        if self.keyboard.device_halted {
            // Still halted on the device's side: the next try stalls again.
            self.fail_transfer(6);
            return false;
        }
        let slot = self.keyboard.slot;
        let Some((dci, mut cursor)) = self.slots[usize::from(slot)].interrupt else {
            return false;
        };
        if self.slots[usize::from(slot)].interrupt_halted || self.endpoint_stopped {
            return false;
        }
        let Some((address, trb)) = self.next_trb(&mut cursor) else {
            return false;
        };
        self.slots[usize::from(slot)].interrupt = Some((dci, cursor));
        let buffer = trb.parameter();
        let length = report.len().min(trb.0[2] as usize & 0x1_FFFF);
        for (i, chunk) in report[..length].chunks(4).enumerate() {
            let mut word = [0u8; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.mem_write(buffer + 4 * i as u64, u32::from_le_bytes(word));
        }
        let residual = trb.0[2].saturating_sub(length as u32);
        self.transfer_event(
            address,
            if residual > 0 { 13 } else { 1 },
            residual,
            slot,
            dci,
        );
        true
    }

    /// The device on root port 1 is pulled out: the port loses its
    /// connection and the controller says so with a Port Status Change event.
    pub fn unplug(&mut self) {
        const CONNECT_CHANGE: u32 = 1 << 17;
        const ENABLE_CHANGE: u32 = 1 << 18;
        let kb = self.kb();
        self.portsc[kb] &= !0b11;
        self.portsc[kb] |= CONNECT_CHANGE | ENABLE_CHANGE;
        self.post_event(Trb([
            u32::from(self.keyboard_port) << 24,
            0,
            1 << 24,
            trb_type::PORT_STATUS_CHANGE << 10,
        ]));
    }

    /// A keyboard (or the hub, with `hub`) is plugged into root port 1, in
    /// the state a device has after power-on: the port connects and the
    /// controller says so with a Port Status Change event.
    pub fn plug(&mut self) {
        const CONNECT_CHANGE: u32 = 1 << 17;
        self.keyboard = KeyboardState {
            protocol: 1,
            ..KeyboardState::default()
        };
        self.hub_states = fresh_hub_states();
        self.endpoint_stopped = false;
        let kb = self.kb();
        self.portsc[kb] = 1 | 1 << 9 | self.port_1_speed() | CONNECT_CHANGE;
        self.post_event(Trb([
            u32::from(self.keyboard_port) << 24,
            0,
            1 << 24,
            trb_type::PORT_STATUS_CHANGE << 10,
        ]));
    }

    /// The device on port 2 of hub `tier` (the next hub, or the keyboard)
    /// is pulled out: the hub says so on its status change endpoint.
    pub fn unplug_behind_hub(&mut self, tier: usize) {
        let hub = &mut self.hub_states[tier];
        hub.port_2_empty = true;
        hub.keyboard_port_status &= !0b11;
        hub.keyboard_port_status |= 1 << 16;
        self.notify_hub_change(tier);
    }

    /// A device (the next hub, or the keyboard) in its power-on state is
    /// plugged into port 2 of hub `tier`.
    pub fn plug_behind_hub(&mut self, tier: usize) {
        for below in &mut self.hub_states[tier + 1..SUPERSPEED_HALF] {
            *below = HubState::default();
        }
        self.keyboard = KeyboardState {
            protocol: 1,
            ..KeyboardState::default()
        };
        self.endpoint_stopped = false;
        self.hub_states[tier].port_2_empty = false;
        let powered = if self.usb3 { 1 << 9 } else { 1 << 8 };
        let high_speed = self.high_speed_below(tier);
        let hub = &mut self.hub_states[tier];
        hub.keyboard_port_status = 1 | powered | 1 << 16 | high_speed;
        self.notify_hub_change(tier);
    }

    /// Hub `tier` reports port 2's change on its status change endpoint,
    /// now if a transfer waits there, else when one is queued.
    fn notify_hub_change(&mut self, tier: usize) {
        let slot = self.hub_states[tier].slot;
        let Some((dci, mut cursor)) = self.slots[usize::from(slot)].interrupt else {
            self.hub_states[tier].change_pending = true;
            return;
        };
        let Some((address, trb)) = self.next_trb(&mut cursor) else {
            self.hub_states[tier].change_pending = true;
            return;
        };
        self.slots[usize::from(slot)].interrupt = Some((dci, cursor));
        self.hub_states[tier].change_pending = false;
        let length = trb.0[2] & 0x1_FFFF;
        if length == 0 {
            self.errors.push("a hub status transfer of no bytes".into());
            return;
        }
        self.mem_write(trb.parameter(), 1 << 2);
        let code = if length > 1 { 13 } else { 1 };
        self.transfer_event(address, code, length - 1, slot, dci);
    }

    /// The keyboard on root port 2 sends a report.
    pub fn send_report_2(&mut self, report: [u8; 8]) -> bool {
        std::mem::swap(&mut self.keyboard, &mut self.keyboard2);
        let sent = self.send_bytes(&report);
        std::mem::swap(&mut self.keyboard, &mut self.keyboard2);
        sent
    }

    /// The root port's status change bits still set.
    pub fn root_port_changes(&self) -> u32 {
        self.portsc[self.kb()] & (0x7F << 17)
    }

    /// The keyboard's next report transfer fails with `code` (6: a stall,
    /// which halts the device's endpoint too; 4: a transaction error) and
    /// the controller halts the endpoint; returns whether a TRB was there.
    pub fn fail_transfer(&mut self, code: u8) -> bool {
        let slot = self.keyboard.slot;
        let Some((dci, mut cursor)) = self.slots[usize::from(slot)].interrupt else {
            return false;
        };
        if self.slots[usize::from(slot)].interrupt_halted || self.endpoint_stopped {
            return false;
        }
        let Some((address, trb)) = self.next_trb(&mut cursor) else {
            return false;
        };
        self.slots[usize::from(slot)].interrupt = Some((dci, cursor));
        self.slots[usize::from(slot)].interrupt_halted = true;
        if code == 6 {
            self.keyboard.device_halted = true;
        }
        self.transfer_event(address, code, trb.0[2] & 0x1_FFFF, slot, dci);
        true
    }

    /// The slot context state the driver's output context holds for the keyboard.
    pub fn keyboard_slot_state(&mut self) -> u32 {
        let output = self.slots[usize::from(self.keyboard.slot)].output;
        self.mem_read(output + 12) >> 27
    }

    /// The hub's port 2 status bits that matter: connected and enabled, and
    /// the reset change (bit 20) once cleared.
    pub fn keyboard_port_status_after_reset(&self) -> u32 {
        let last = if self.hub { self.hub_tiers - 1 } else { 0 };
        self.hub_states[last].keyboard_port_status & (0b11 | 1 << 20)
    }

    /// The DCBAA's entry 0: the scratchpad array.
    pub fn scratchpad_array(&mut self) -> u64 {
        self.read64(self.dcbaap)
    }

    pub fn read_u64(&mut self, address: u64) -> u64 {
        self.read64(address)
    }

    /// Whether the controller is halted and its reset done, and each root
    /// port's power.
    pub fn shut_down_state(&self) -> (bool, bool, Vec<bool>) {
        (
            self.usbsts & 1 != 0,
            self.usbcmd & 2 == 0,
            self.portsc.iter().map(|p| p & (1 << 9) != 0).collect(),
        )
    }

    pub fn legacy_registers(&self) -> (u32, u32) {
        (self.legacy, self.legacy_control)
    }
}

impl Memory for XhciModel {
    fn mem_read(&mut self, address: u64) -> u32 {
        let word = self.word(address);
        self.memory[word]
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        let word = self.word(address);
        self.memory[word] = value;
    }
}

impl Hardware for XhciModel {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        assert!(offset + 4 <= BAR_BYTES, "read outside the BAR: {offset:#x}");
        match offset {
            0x00 => 0x0100_0000 | OPERATIONAL,
            0x04 => u32::from(self.ports) << 24 | 1 << 8 | 8,
            0x08 => ((self.scratchpads >> 5) & 0x1F) << 21 | (self.scratchpads & 0x1F) << 27,
            0x10 => (EXTENDED / 4) << 16 | u32::from(self.csz) << 2 | 1,
            0x14 => DOORBELLS,
            0x18 => RUNTIME,
            o if o == OPERATIONAL => self.usbcmd,
            o if o == OPERATIONAL + 0x04 => self.usbsts,
            o if o == OPERATIONAL + 0x08 => 1,
            o if o == OPERATIONAL + 0x38 => self.config,
            o if (OPERATIONAL + 0x400..OPERATIONAL + 0x400 + 0x10 * u32::from(self.ports))
                .contains(&o) =>
            {
                let port = ((o - OPERATIONAL - 0x400) / 0x10) as usize;
                if port == self.kb() && self.usb3_enabled_at.is_some_and(|at| self.now >= at) {
                    self.usb3_enabled_at = None;
                    let kb = self.kb();
                    self.portsc[kb] |= 1 << 1;
                }
                if (o - OPERATIONAL - 0x400) % 0x10 == 0 {
                    self.portsc[port]
                } else {
                    0
                }
            }
            o if o == RUNTIME + 0x28 => self.erstsz,
            o if o == EXTENDED => {
                if let (Some(asked), Some(after)) = (self.os_asked_at, self.firmware_releases_after)
                {
                    if self.now >= asked + after {
                        self.legacy &= !(1 << 16);
                    }
                }
                self.legacy | 4 << 8 | 1
            }
            o if o == EXTENDED + 4 => self.legacy_control,
            // Supported Protocol: one capability, or two, the first
            // pointing at the second.
            o if (EXTENDED + 0x10..EXTENDED + 0x30).contains(&o) => {
                let protocols = self.protocols();
                let index = ((o - EXTENDED - 0x10) / 0x10) as usize;
                let Some(&(major, first, count)) = protocols.get(index) else {
                    return 0;
                };
                let next = if index + 1 < protocols.len() { 4 } else { 0 };
                match (o - EXTENDED) % 0x10 {
                    0 => major << 24 | next << 8 | 2,
                    4 => 0x2042_5355,
                    8 => count << 8 | first,
                    _ => 0,
                }
            }
            _ => 0,
        }
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        assert!(
            offset + 4 <= BAR_BYTES,
            "write outside the BAR: {offset:#x}"
        );
        let set_low = |old: u64, v: u32| (old & !0xFFFF_FFFF) | u64::from(v);
        let set_high = |old: u64, v: u32| (old & 0xFFFF_FFFF) | u64::from(v) << 32;
        match offset {
            o if o == OPERATIONAL => {
                if value & 2 != 0 {
                    if self.usbsts & 1 == 0 {
                        self.errors.push("reset while running".into());
                    }
                    self.usbcmd = 0;
                    self.usbsts = 1 | if self.cnr_stuck { 1 << 11 } else { 0 };
                    self.portsc = vec![1 << 9; usize::from(self.ports)];
                    let kb = self.kb();
                    self.portsc[kb] = if self.empty_at_start {
                        1 << 9
                    } else if self.usb3 && self.usb3_link_stuck {
                        // Connected, its link in SS.Inactive.
                        self.usb3_enabled_at = None;
                        1 | 6 << 5 | 1 << 9 | 4 << 10
                    } else if self.usb3 {
                        // A USB 3 port trains and enables by itself.
                        self.usb3_enabled_at = Some(self.now + self.usb3_link_micros);
                        1 | 1 << 9 | 4 << 10
                    } else {
                        1 | 1 << 9 | self.port_1_speed() // connected, powered
                    };
                    self.portsc[1] = if self.split_protocols() {
                        // A USB 3 port trains and enables by itself.
                        1 | 1 << 1 | 1 << 9 | 4 << 10
                    } else if self.port_2.is_some() {
                        1 | 1 << 9 | 1 << 10
                    } else {
                        1 << 9
                    };
                } else {
                    self.usbcmd = value;
                    if value & 1 != 0 {
                        if self.erstsz == 0 || self.dcbaap == 0 {
                            self.errors.push("run without rings".into());
                        }
                        self.usbsts &= !1;
                    } else {
                        self.usbsts |= 1;
                    }
                }
            }
            o if o == OPERATIONAL + 0x18 && value & (1 << 2) != 0 => {
                // Command Abort: the ring stops; what was consumed stays consumed.
                self.commands_aborted += 1;
            }
            o if o == OPERATIONAL + 0x18 => {
                self.crcr = Cursor {
                    dequeue: u64::from(value & !0x3F),
                    cycle: value & 1 != 0,
                }
            }
            o if o == OPERATIONAL + 0x1C => self.crcr.dequeue = set_high(self.crcr.dequeue, value),
            o if o == OPERATIONAL + 0x30 => self.dcbaap = set_low(self.dcbaap, value),
            o if o == OPERATIONAL + 0x34 => self.dcbaap = set_high(self.dcbaap, value),
            o if o == OPERATIONAL + 0x38 => self.config = value,
            o if (OPERATIONAL + 0x400..OPERATIONAL + 0x400 + 0x10 * u32::from(self.ports))
                .contains(&o) =>
            {
                let port = ((o - OPERATIONAL - 0x400) / 0x10) as usize;
                if value & 0b10 != 0 {
                    self.ports_disabled.push(port as u8 + 1);
                }
                let status = &mut self.portsc[port];
                *status &= !(value & (0x7F << 17));
                if value & (1 << 9) == 0 {
                    // Port power off: the device is gone from the port.
                    *status &= !(1 << 9 | 0b11);
                }
                if value & (1 << 31) != 0 && *status & 1 != 0 {
                    // A warm reset: the link trains to U0, the port enables,
                    // WRC and PRC say it is over.
                    self.warm_resets += 1;
                    *status = (*status & !(0xF << 5)) | 1 << 1 | 1 << 19 | 1 << 21;
                }
                if value & (1 << 4) != 0 && *status & 1 != 0 {
                    *status |= if self.port_reset_stuck {
                        1 << 4
                    } else {
                        1 << 21 | 0b10
                    };
                }
            }
            o if o == RUNTIME + 0x28 => self.erstsz = value,
            o if o == RUNTIME + 0x30 => self.erstba = set_low(self.erstba, value),
            o if o == RUNTIME + 0x34 => {
                self.erstba = set_high(self.erstba, value);
                self.event_base = self.read64(self.erstba);
                self.event_size = u64::from(self.mem_read(self.erstba + 8) & 0xFFFF);
                self.event_enqueue = 0;
                self.event_cycle = true;
            }
            o if o == RUNTIME + 0x38 => self.erdp = set_low(self.erdp, value & !0xF),
            o if o == RUNTIME + 0x3C => self.erdp = set_high(self.erdp, value),
            o if o == DOORBELLS => {
                if self.usbsts & 1 != 0 {
                    self.errors.push("command doorbell while halted".into());
                } else {
                    self.run_commands();
                }
            }
            o if (DOORBELLS + 4..DOORBELLS + 4 * 9).contains(&o) => {
                let slot = ((o - DOORBELLS) / 4) as u8;
                if value == 1 {
                    self.run_control(slot);
                } else if let Some(tier) = self
                    .hub_states
                    .iter()
                    .position(|h| h.slot == slot && h.change_pending)
                {
                    self.notify_hub_change(tier);
                }
                // Interrupt endpoints are served when the keyboard has a report.
            }
            o if o == EXTENDED => {
                if value & (1 << 24) != 0 && self.os_asked_at.is_none() {
                    self.os_asked_at = Some(self.now);
                }
                self.legacy = (self.legacy & (1 << 16)) | (value & (1 << 24));
                if value & (1 << 16) == 0 && self.legacy & (1 << 16) != 0 {
                    // The OS clears BIOS-owned itself (forcing).
                    self.legacy &= !(1 << 16);
                }
            }
            o if o == EXTENDED + 4 => {
                // SMI enables are read-write, the SMI status bits write-1-to-clear.
                self.legacy_control =
                    (value & 0xE011) | (self.legacy_control & 0xE000_0000 & !value);
            }
            _ => {}
        }
    }
}

impl Platform for XhciModel {
    fn now_micros(&mut self) -> u64 {
        self.now += MICROS_PER_CLOCK_READ;
        self.now
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.log.push(std::format!("{message}"));
    }
}
