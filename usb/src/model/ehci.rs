//! A register model of an EHCI controller (EHCI 1.0) for the host tests:
//! BAR0's capability and operational registers, PCI configuration space
//! with an EECP chain ending in USBLEGSUP, root ports with the companion
//! hand-over (PORT_OWNER, CONFIGFLAG), and both schedules run against the
//! device tree ([`UsbTree`]) on a simulated clock: every register read
//! and clock read advances it 5 us, and the schedules run once per
//! micro-frame (125 us, 8 per ms of model time).
//!
//! It checks what the driver gives it as the hardware would, and notes in
//! [`EhciModel::errors`] what real hardware would do something undefined with:
//! bad alignment, fields the spec reserves, H bits, S-/C-masks, a queue
//! head rewritten before the controller let go of it (the Interrupt on
//! Async Advance doorbell, two frame boundaries on the periodic side),
//! writes while the firmware owns the controller, and more. Each time the
//! periodic schedule changes, every frame's list is priced with USB 2.0
//! 5.11.3's bus times: a micro-frame with more than 100 us of high-speed
//! periodic time, a translator with more than 900 us of full- and
//! low-speed time in a frame, or one that cannot end a split's
//! transaction before its last complete-split, is an error
//! ([`EhciModel::periodic_load`] keeps the peaks).
//!
//! Knobs: the firmware's hand-off, 64-bit addressing, the number of
//! companion controllers (0: an integrated rate-matching hub, which the
//! test plugs into the tree as a high-speed hub), port power switching, a
//! looping EECP chain, a halt or reset that never ends.

use super::devices::{Packet, Pid, Reply, Split, UsbTree};
use crate::ehci::budget::{
    high_speed_micros, translator_micros, MICRO_FRAME_BUDGET_MICROS, TT_FRAME_BUDGET_MICROS,
    TT_MICRO_FRAME_MICROS,
};
use crate::host::Speed;
use crate::{Hardware, Memory, PciHardware, Platform};
use std::collections::{BTreeMap, BTreeSet};
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// The DMA region the tests give the driver (as the kernel: 256 KiB).
pub const DMA_BASE: u64 = 0x10_0000;
/// Its size.
pub const DMA_BYTES: u64 = 256 * 1024;
/// BAR0's size (Intel's EHCI: 1 KiB).
pub const BAR_BYTES: u32 = 0x400;
const CAPLENGTH: u32 = 0x20;
const MICROS_PER_READ: u64 = 5;
const MICRO_FRAME_MICROS: u64 = 125;
/// How long HCRESET takes.
const RESET_MICROS: u64 = 300;
/// How long a port takes to end its reset after PR is written 0.
const PORT_RESET_END_MICROS: u64 = 200;
/// USB 2.0 7.1.7.5: a reset is held at least 10 ms (TDRST; root ports 50).
const PORT_RESET_MIN_MICROS: u64 = 10_000;
/// Transactions the asynchronous schedule runs per micro-frame at most.
const ASYNC_TRANSACTIONS: usize = 24;
/// Queue heads followed in one walk before the model calls it a loop.
const WALK_LIMIT: usize = 80;

/// Where the first extended capability is (a vendor one), and USBLEGSUP.
const EECP_FIRST: u8 = 0x60;
const EECP_LEGACY: u8 = 0x68;

// Register bits (EHCI 2.3), the model's own copy.
const CMD_RUN: u32 = 1 << 0;
const CMD_HCRESET: u32 = 1 << 1;
const CMD_FRAME_LIST_SIZE: u32 = 3 << 2;
const CMD_PSE: u32 = 1 << 4;
const CMD_ASE: u32 = 1 << 5;
const CMD_IAAD: u32 = 1 << 6;
const STS_USBINT: u32 = 1 << 0;
const STS_ERROR: u32 = 1 << 1;
const STS_PCD: u32 = 1 << 2;
const STS_IAA: u32 = 1 << 5;
const STS_W1C: u32 = 0x3F;
const STS_HALTED: u32 = 1 << 12;
const STS_PSS: u32 = 1 << 14;
const STS_ASS: u32 = 1 << 15;

const PORT_CCS: u32 = 1 << 0;
const PORT_CSC: u32 = 1 << 1;
const PORT_PE: u32 = 1 << 2;
const PORT_PEC: u32 = 1 << 3;
const PORT_PR: u32 = 1 << 8;
const PORT_PP: u32 = 1 << 12;
const PORT_PO: u32 = 1 << 13;

const TOKEN_ACTIVE: u32 = 1 << 7;
const TOKEN_HALTED: u32 = 1 << 6;
const TOKEN_DATA_BUFFER: u32 = 1 << 5;
const TOKEN_BABBLE: u32 = 1 << 4;
const TOKEN_XACT: u32 = 1 << 3;
const TOKEN_IOC: u32 = 1 << 15;
const TOKEN_TOGGLE: u32 = 1 << 31;

/// One root port's state.
#[derive(Clone, Copy, Debug, Default)]
struct Port {
    /// PORT_OWNER: the companion controller has the port.
    companion: bool,
    powered: bool,
    connected: bool,
    enabled: bool,
    connect_change: bool,
    enable_change: bool,
    /// PR is 1: the reset started at this time.
    reset_since: Option<u64>,
    /// PR was written 0: the reset ends at this time.
    reset_ends: Option<u64>,
}

/// A split transaction the model ran, with its queue head's fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SplitRecord {
    /// The device address.
    pub address: u8,
    /// The endpoint.
    pub endpoint: u8,
    /// EPS: 0 full speed, 1 low speed.
    pub eps: u8,
    /// The QH's Hub Addr.
    pub hub_address: u8,
    /// The QH's Port Number.
    pub hub_port: u8,
    /// The S-mask (0 on the asynchronous schedule).
    pub s_mask: u8,
    /// The C-mask (0 on the asynchronous schedule).
    pub c_mask: u8,
    /// The Control Endpoint flag.
    pub control: bool,
    /// From the periodic schedule.
    pub periodic: bool,
}

/// What the periodic schedule, as last linked, asks of the bus: the
/// peaks over every frame.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PeriodicLoad {
    /// High-speed time in each micro-frame (us), the most any frame has.
    pub micro_frames: [u32; 8],
    /// Each translator's (hub address, port; port 0 for a hub with one
    /// translator) full- and low-speed time in its busiest frame (us).
    pub translators: BTreeMap<(u8, u8), u32>,
}

/// A split's work on its translator in one frame: the start-split's
/// micro-frame, the C-mask, and its full- or low-speed time (us).
type SplitWork = (u32, u8, u32);

/// The EHCI register model.
#[derive(Debug)]
pub struct EhciModel {
    /// The clock, in microseconds.
    pub now: u64,
    memory: Vec<u32>,
    /// The devices on the root ports.
    pub tree: UsbTree,
    // Knobs.
    /// Root ports (1-15).
    pub ports: u8,
    /// N_CC: companion controllers (0: an integrated rate-matching hub).
    pub companions: u8,
    /// PPC: ports are powered by the driver.
    pub port_power_control: bool,
    /// HCCPARAMS bit 0.
    pub sixty_four_bit: bool,
    /// When the firmware clears BIOS-owned after the OS asks (None: never).
    pub firmware_releases_after: Option<u64>,
    /// The first extended capability points at itself.
    pub eecp_loop: bool,
    /// RS written 0 never halts the controller.
    pub halt_stuck: bool,
    /// HCRESET never ends.
    pub reset_stuck: bool,
    // Registers.
    legacy: u32,
    legacy_control: u32,
    os_asked_at: Option<u64>,
    usbcmd: u32,
    usbsts: u32,
    usbintr: u32,
    frindex: u32,
    ctrldssegment: u32,
    periodic_base: u32,
    async_base: u32,
    configflag: u32,
    port: [Port; 15],
    reset_ends: Option<u64>,
    next_micro_frame: u64,
    iaa_pending: bool,
    // What the controller holds (see the module doc).
    async_live: BTreeMap<u64, (u32, u32)>,
    async_unlinked: BTreeSet<u64>,
    async_dirty: bool,
    periodic_live: BTreeMap<u64, (u32, u32)>,
    /// Unlinked periodic queue heads, with FRINDEX when that was seen.
    periodic_unlinked: BTreeMap<u64, u32>,
    periodic_dirty: bool,
    /// The root port each address answered on last.
    routes: [Option<u8>; 128],
    // What happened.
    /// Register reads (BAR0).
    pub mmio_reads: u32,
    /// Register writes (BAR0).
    pub mmio_writes: u32,
    /// Root ports handed to the companion, in order.
    pub handed_to_companion: Vec<u8>,
    /// Root ports reset (PR written 1), in order.
    pub port_resets: Vec<u8>,
    /// Every split transaction run, with its queue head's fields.
    pub split_log: Vec<SplitRecord>,
    /// Interrupt-in transactions run on the periodic schedule.
    pub periodic_transactions: u64,
    /// The same, by device address.
    pub polls: [u64; 128],
    /// Times the async advance doorbell was answered.
    pub async_advances: u32,
    /// The periodic schedule's bus time, as last linked.
    pub periodic_load: PeriodicLoad,
    /// The driver's log.
    pub log: Vec<String>,
    /// What real hardware would not have taken.
    pub errors: Vec<String>,
}

impl EhciModel {
    /// A controller with `ports` root ports, four companions, no port power
    /// switching, 32-bit, and a firmware that owns it and lets go after 3 ms.
    pub fn new(ports: u8) -> EhciModel {
        assert!((1..=15).contains(&ports));
        EhciModel {
            now: 0,
            memory: vec![0; (DMA_BYTES / 4) as usize],
            tree: UsbTree::new(ports),
            ports,
            companions: 4.min(ports),
            port_power_control: false,
            sixty_four_bit: false,
            firmware_releases_after: Some(3_000),
            eecp_loop: false,
            halt_stuck: false,
            reset_stuck: false,
            legacy: 1 << 16 | 1,
            legacy_control: 0x2000_E03F,
            os_asked_at: None,
            usbcmd: 0x0008_0000,
            usbsts: STS_HALTED,
            usbintr: 0,
            frindex: 0,
            ctrldssegment: 0,
            periodic_base: 0,
            async_base: 0,
            configflag: 0,
            port: [Port::default(); 15],
            reset_ends: None,
            next_micro_frame: MICRO_FRAME_MICROS,
            iaa_pending: false,
            async_live: BTreeMap::new(),
            async_unlinked: BTreeSet::new(),
            async_dirty: true,
            periodic_live: BTreeMap::new(),
            periodic_unlinked: BTreeMap::new(),
            periodic_dirty: true,
            routes: [None; 128],
            mmio_reads: 0,
            mmio_writes: 0,
            handed_to_companion: Vec::new(),
            port_resets: Vec::new(),
            split_log: Vec::new(),
            periodic_transactions: 0,
            polls: [0; 128],
            async_advances: 0,
            periodic_load: PeriodicLoad::default(),
            log: Vec::new(),
            errors: Vec::new(),
        }
    }

    /// The firmware does not own the controller at all.
    pub fn firmware_not_owning(mut self) -> EhciModel {
        self.legacy &= !(1 << 16);
        self
    }

    /// The firmware left the controller running, its schedules on and
    /// every port routed to it (its keyboard emulation).
    pub fn left_running(mut self) -> EhciModel {
        self.usbcmd = 0x0008_0000 | CMD_RUN | CMD_ASE | CMD_PSE;
        self.usbsts = STS_ASS | STS_PSS;
        self.configflag = 1;
        // The firmware's own schedules, in the last two pages of memory:
        // an empty frame list and a head queue head on its own.
        let frame_list = DMA_BASE + DMA_BYTES - 0x2000;
        let head = DMA_BASE + DMA_BYTES - 0x1000;
        for entry in 0..1024 {
            self.hc_write(frame_list + 4 * entry, 1);
        }
        self.hc_write(head, head as u32 | 2);
        self.hc_write(head + 4, 1 << 15 | 2 << 12 | 64 << 16 | 1 << 14);
        self.hc_write(head + 8, 1 << 30);
        self.hc_write(head + 0x10, 1);
        self.hc_write(head + 0x14, 1);
        self.hc_write(head + 0x18, TOKEN_HALTED);
        self.periodic_base = frame_list as u32;
        self.async_base = head as u32;
        self
    }

    /// CONFIGFLAG as the driver left it.
    pub fn configflag(&self) -> u32 {
        self.configflag
    }

    /// USBLEGSUP and USBLEGCTLSTS as they stand.
    pub fn legacy_registers(&self) -> (u32, u32) {
        (self.legacy, self.legacy_control)
    }

    /// USBINTR as the driver left it.
    pub fn usbintr(&self) -> u32 {
        self.usbintr
    }

    /// Whether the controller is halted.
    pub fn halted(&self) -> bool {
        self.usbsts & STS_HALTED != 0
    }

    fn error(&mut self, message: String) {
        if self.errors.len() < 100 {
            self.errors.push(message);
        }
    }

    // The clock.

    /// Lets `micros` pass, running each micro-frame that ends in them.
    pub fn advance(&mut self, micros: u64) {
        self.now += micros;
        while self.now >= self.next_micro_frame {
            self.next_micro_frame += MICRO_FRAME_MICROS;
            self.micro_frame();
        }
    }

    fn micro_frame(&mut self) {
        if let Some(at) = self.reset_ends {
            if self.now >= at {
                self.reset_ends = None;
                self.controller_reset();
            }
        }
        for port in 1..=self.ports {
            self.sync_port(port);
        }
        let run = self.usbcmd & CMD_RUN != 0;
        if !run {
            if !self.halt_stuck {
                self.usbsts |= STS_HALTED;
                self.usbsts &= !(STS_ASS | STS_PSS);
            }
            return;
        }
        self.usbsts &= !STS_HALTED;
        // The schedule status bits follow their enables a micro-frame later.
        if self.usbcmd & CMD_ASE != 0 {
            if self.usbsts & STS_ASS == 0 {
                self.async_dirty = true;
            }
            self.usbsts |= STS_ASS;
        } else {
            self.usbsts &= !STS_ASS;
        }
        if self.usbcmd & CMD_PSE != 0 {
            self.usbsts |= STS_PSS;
        } else {
            self.usbsts &= !STS_PSS;
        }
        self.frindex = (self.frindex + 1) & 0x3FFF;
        if self.usbsts & STS_PSS != 0 {
            if self.periodic_dirty {
                self.periodic_reachable();
            }
            self.run_periodic();
        }
        if self.usbsts & STS_ASS != 0 {
            if self.async_dirty {
                self.async_reachable();
            }
            self.run_async();
            if self.iaa_pending {
                // Past a whole pass: nothing unlinked before is held.
                self.iaa_pending = false;
                self.usbcmd &= !CMD_IAAD;
                self.usbsts |= STS_IAA;
                self.async_unlinked.clear();
                self.async_advances += 1;
            }
        }
    }

    // Memory as the controller sees it.

    fn index(&self, address: u64) -> Option<usize> {
        if address % 4 == 0 && address >= DMA_BASE && address + 4 <= DMA_BASE + DMA_BYTES {
            Some(((address - DMA_BASE) / 4) as usize)
        } else {
            None
        }
    }

    /// A 32-bit pointer the driver wrote, made whole with CTRLDSSEGMENT.
    fn pointer(&self, low: u32) -> u64 {
        if self.sixty_four_bit {
            u64::from(self.ctrldssegment) << 32 | u64::from(low)
        } else {
            u64::from(low)
        }
    }

    fn hc_read(&mut self, address: u64) -> u32 {
        match self.index(address) {
            Some(i) => self.memory[i],
            None => {
                self.error(format!("the controller was sent to read {address:#x}"));
                0
            }
        }
    }

    fn hc_write(&mut self, address: u64, value: u32) {
        match self.index(address) {
            Some(i) => self.memory[i] = value,
            None => self.error(format!("the controller was sent to write {address:#x}")),
        }
    }

    /// Writes word `address` behind the driver's back, unchecked, as a
    /// test building a schedule the driver never would does; the
    /// periodic schedule is looked at again.
    pub fn poke(&mut self, address: u64, value: u32) {
        self.hc_write(address, value);
        self.periodic_dirty = true;
    }

    /// Reads word `address` as the test sees it.
    pub fn peek(&self, address: u64) -> u32 {
        self.index(address).map_or(0, |i| self.memory[i])
    }

    // Ports.

    fn sync_port(&mut self, port: u8) {
        let present = self.tree.root_device(port).is_some();
        let configured = self.configflag & 1 != 0;
        let port_power_control = self.port_power_control;
        let p = &mut self.port[usize::from(port) - 1];
        if p.companion {
            // Ownership comes back when the device goes (EHCI 4.2.2).
            if !present && configured {
                p.companion = false;
            } else {
                return;
            }
        }
        let visible = present && configured && (p.powered || !port_power_control);
        if visible != p.connected {
            p.connected = visible;
            p.connect_change = true;
            self.usbsts |= STS_PCD;
            if !visible {
                p.enabled = false;
                p.reset_since = None;
                p.reset_ends = None;
            }
        }
        if let Some(at) = p.reset_ends {
            if self.now >= at {
                p.reset_ends = None;
                p.reset_since = None;
                // Only a high-speed device chirps: the port enables.
                p.enabled = p.connected && self.tree.root_device(port) == Some(Speed::High);
            }
        }
    }

    fn portsc(&mut self, port: u8) -> u32 {
        self.sync_port(port);
        let p = self.port[usize::from(port) - 1];
        let bit = |on: bool, bit: u32| if on { bit } else { 0 };
        let powered = p.powered || !self.port_power_control;
        if p.companion || self.configflag & 1 == 0 {
            // Routed to the companion: nothing of it shows here.
            return PORT_PO | bit(powered, PORT_PP);
        }
        let line = if p.connected && !p.enabled && p.reset_since.is_none() {
            match self.tree.root_device(port) {
                Some(Speed::Low) => 1 << 10,
                Some(_) => 2 << 10,
                None => 0,
            }
        } else {
            0
        };
        bit(p.connected, PORT_CCS)
            | bit(p.connect_change, PORT_CSC)
            | bit(p.enabled, PORT_PE)
            | bit(p.enable_change, PORT_PEC)
            | bit(p.reset_since.is_some(), PORT_PR)
            | bit(powered, PORT_PP)
            | line
    }

    fn write_portsc(&mut self, port: u8, value: u32) {
        self.sync_port(port);
        if self.configflag & 1 == 0 {
            self.error(format!("port {port}: PORTSC written while CONFIGFLAG is 0"));
            return;
        }
        let index = usize::from(port) - 1;
        let halted = self.usbsts & STS_HALTED != 0;
        let companions = self.companions;
        let now = self.now;
        let mut p = self.port[index];
        if self.port_power_control {
            p.powered = value & PORT_PP != 0;
        }
        if p.companion {
            if value & PORT_PO == 0 {
                self.error(format!(
                    "port {port}: PORT_OWNER taken back from the companion"
                ));
            }
            self.port[index] = p;
            return;
        }
        if value & PORT_PO != 0 {
            if companions == 0 {
                self.error(format!(
                    "port {port}: PORT_OWNER set with no companion controller"
                ));
            } else {
                p = Port {
                    companion: true,
                    powered: p.powered,
                    ..Port::default()
                };
                self.handed_to_companion.push(port);
                self.port[index] = p;
                return;
            }
        }
        if value & PORT_CSC != 0 {
            p.connect_change = false;
        }
        if value & PORT_PEC != 0 {
            p.enable_change = false;
        }
        if value & PORT_PE == 0 {
            p.enabled = false;
        }
        match (value & PORT_PR != 0, p.reset_since) {
            (true, None) => {
                if halted {
                    self.error(format!("port {port}: reset while the controller is halted"));
                }
                if value & PORT_PE != 0 {
                    self.error(format!("port {port}: PR written with PE 1"));
                }
                p.enabled = false;
                p.reset_since = Some(now);
                p.reset_ends = None;
                self.port_resets.push(port);
                self.tree.reset_root_port(port);
            }
            (false, Some(since)) if p.reset_ends.is_none() => {
                if now - since < PORT_RESET_MIN_MICROS {
                    self.error(format!("port {port}: reset held {} us only", now - since));
                }
                p.reset_ends = Some(now + PORT_RESET_END_MICROS);
            }
            _ => {}
        }
        self.port[index] = p;
        // A device can come or go with the power.
        self.sync_port(port);
    }

    // Registers.

    /// HCRESET: everything back to its power-on value (EHCI 2.3.1).
    fn controller_reset(&mut self) {
        self.usbcmd = 0x0008_0000;
        self.usbsts = STS_HALTED;
        self.usbintr = 0;
        self.frindex = 0;
        self.ctrldssegment = 0;
        self.configflag = 0;
        self.iaa_pending = false;
        for p in self.port.iter_mut() {
            *p = Port::default();
        }
        self.async_live.clear();
        self.async_unlinked.clear();
        self.periodic_live.clear();
        self.periodic_unlinked.clear();
        self.async_dirty = true;
        self.periodic_dirty = true;
    }

    fn write_usbcmd(&mut self, value: u32) {
        if self.reset_ends.is_some() || (self.reset_stuck && self.usbcmd & CMD_HCRESET != 0) {
            self.error("USBCMD written during HCRESET".into());
            return;
        }
        if value & CMD_HCRESET != 0 {
            if self.usbsts & STS_HALTED == 0 {
                self.error("HCRESET while running".into());
            }
            self.usbcmd |= CMD_HCRESET;
            if !self.reset_stuck {
                self.reset_ends = Some(self.now + RESET_MICROS);
            }
            return;
        }
        if value & CMD_FRAME_LIST_SIZE != 0 {
            self.error(format!("frame list size {} asked for", value >> 2 & 3));
        }
        let status = self.usbsts;
        let running = status & STS_HALTED == 0;
        if running || value & CMD_RUN != 0 {
            // EHCI 4.8.1: an enable changes only when its status matches.
            if (value & CMD_ASE != 0) != (self.usbcmd & CMD_ASE != 0)
                && (self.usbcmd & CMD_ASE != 0) != (status & STS_ASS != 0)
            {
                self.error("ASE changed before ASS followed".into());
            }
            if (value & CMD_PSE != 0) != (self.usbcmd & CMD_PSE != 0)
                && (self.usbcmd & CMD_PSE != 0) != (status & STS_PSS != 0)
            {
                self.error("PSE changed before PSS followed".into());
            }
        }
        if value & CMD_RUN != 0 {
            if value & CMD_ASE != 0 && self.async_base == 0 {
                self.error("the async schedule enabled with no ASYNCLISTADDR".into());
            }
            if value & CMD_PSE != 0 && self.periodic_base == 0 {
                self.error("the periodic schedule enabled with no PERIODICLISTBASE".into());
            }
        }
        if value & CMD_IAAD != 0 {
            if status & STS_ASS == 0 || value & CMD_ASE == 0 {
                self.error("async advance doorbell with the async schedule off".into());
            } else {
                self.iaa_pending = true;
            }
        }
        self.usbcmd =
            value & !(CMD_HCRESET | CMD_IAAD) | if self.iaa_pending { CMD_IAAD } else { 0 };
    }

    fn write_configflag(&mut self, value: u32) {
        let was = self.configflag & 1;
        self.configflag = value & 1;
        if was == 0 && value & 1 == 1 {
            // Every port comes to this controller (EHCI 4.2.1).
            for port in 1..=self.ports {
                let p = &mut self.port[usize::from(port) - 1];
                p.companion = false;
                p.connected = false;
                self.sync_port(port);
            }
        } else if was == 1 && value & 1 == 0 {
            for p in self.port.iter_mut() {
                *p = Port {
                    companion: true,
                    powered: p.powered,
                    ..Port::default()
                };
            }
        }
    }

    // The asynchronous schedule.

    /// Walks the ring from ASYNCLISTADDR, checking its shape; notes what
    /// left it since the last walk.
    fn async_reachable(&mut self) {
        self.async_dirty = false;
        let start = self.pointer(self.async_base);
        let mut seen = BTreeMap::new();
        let mut heads = 0;
        let mut qh = start;
        for _ in 0..WALK_LIMIT {
            if seen.contains_key(&qh) {
                break;
            }
            let link = self.hc_read(qh);
            let characteristics = self.hc_read(qh + 4);
            let capabilities = self.hc_read(qh + 8);
            if characteristics & 1 << 15 != 0 {
                heads += 1;
            }
            seen.insert(qh, (characteristics, capabilities));
            if link & 1 != 0 || link >> 1 & 3 != 1 {
                self.error(format!(
                    "async QH {qh:#x}: horizontal link {link:#x} not a QH"
                ));
                break;
            }
            qh = self.pointer(link & !0x1F);
        }
        if qh != start {
            self.error(format!("the async ring does not come back to {start:#x}"));
        }
        if heads != 1 || seen.get(&start).is_none_or(|&(c, _)| c & 1 << 15 == 0) {
            self.error(format!(
                "{heads} H bits on the async ring (the head must have the one)"
            ));
        }
        for &qh in self.async_live.keys() {
            if !seen.contains_key(&qh) {
                self.async_unlinked.insert(qh);
            }
        }
        self.async_live = seen;
    }

    fn run_async(&mut self) {
        let head = self.pointer(self.async_base);
        let mut transactions = 0;
        // Passes over the ring until one does nothing (the reclamation
        // bit, EHCI 4.8.3) or the micro-frame's budget is spent.
        for _ in 0..4 {
            let mut progress = false;
            let mut qh = head;
            for _ in 0..WALK_LIMIT {
                if self.service_qh(qh, false) {
                    progress = true;
                    transactions += 1;
                    if transactions >= ASYNC_TRANSACTIONS {
                        return;
                    }
                }
                let link = self.hc_read(qh);
                if link & 1 != 0 {
                    return;
                }
                qh = self.pointer(link & !0x1F);
                if qh == head {
                    break;
                }
            }
            if !progress {
                return;
            }
        }
    }

    // The periodic schedule.

    /// The queue heads reachable from any frame list entry.
    fn periodic_reachable(&mut self) {
        self.periodic_dirty = false;
        let base = self.pointer(self.periodic_base);
        let mut entries = BTreeSet::new();
        for frame in 0..1024 {
            let entry = self.hc_read(base + 4 * frame);
            entries.insert(entry);
        }
        self.price_periodic(&entries);
        let mut seen = BTreeMap::new();
        for entry in entries {
            let mut link = entry;
            for _ in 0..WALK_LIMIT {
                if link & 1 != 0 {
                    break;
                }
                if link >> 1 & 3 != 1 {
                    self.error(format!("periodic link {link:#x}: not a QH"));
                    break;
                }
                let qh = self.pointer(link & !0x1F);
                if seen.contains_key(&qh) {
                    break;
                }
                let value = (self.hc_read(qh + 4), self.hc_read(qh + 8));
                seen.insert(qh, value);
                link = self.hc_read(qh);
            }
        }
        for &qh in self.periodic_live.keys() {
            if !seen.contains_key(&qh) {
                self.periodic_unlinked.insert(qh, self.frindex);
            }
        }
        self.periodic_live = seen;
    }

    /// Prices each frame's list (`entries`: the distinct frame list
    /// entries) in bus time, as the spec budgets it; notes what is over.
    fn price_periodic(&mut self, entries: &BTreeSet<u32>) {
        let mut load = PeriodicLoad::default();
        for &entry in entries {
            let mut high_speed = [0u32; 8];
            let mut splits: BTreeMap<(u8, u8), Vec<SplitWork>> = BTreeMap::new();
            let mut link = entry;
            let mut seen = BTreeSet::new();
            while link & 1 == 0 && link >> 1 & 3 == 1 && seen.len() < WALK_LIMIT {
                let qh = self.pointer(link & !0x1F);
                if !seen.insert(qh) {
                    break;
                }
                let characteristics = self.hc_read(qh + 4);
                let capabilities = self.hc_read(qh + 8);
                link = self.hc_read(qh);
                let max_packet = (characteristics >> 16 & 0x7FF) as u16;
                let speed = match characteristics >> 12 & 3 {
                    0 => Speed::Full,
                    1 => Speed::Low,
                    _ => Speed::High,
                };
                let s_mask = (capabilities & 0xFF) as u8;
                let c_mask = (capabilities >> 8 & 0xFF) as u8;
                let (start, complete) = high_speed_micros(speed, max_packet);
                for (micro_frame, time) in high_speed.iter_mut().enumerate() {
                    if s_mask & 1 << micro_frame != 0 {
                        *time += start;
                    }
                    if c_mask & 1 << micro_frame != 0 {
                        *time += complete;
                    }
                }
                if speed != Speed::High {
                    let hub = (capabilities >> 16 & 0x7F) as u8;
                    let port = if self.tree.translator_per_port(hub) {
                        (capabilities >> 23 & 0x7F) as u8
                    } else {
                        0
                    };
                    splits.entry((hub, port)).or_default().push((
                        s_mask.trailing_zeros(),
                        c_mask,
                        translator_micros(speed, max_packet),
                    ));
                }
            }
            for (micro_frame, &time) in high_speed.iter().enumerate() {
                if time > MICRO_FRAME_BUDGET_MICROS {
                    self.error(format!(
                        "frame list entry {entry:#x}: micro-frame {micro_frame} has {time} us of high-speed periodic time (at most {MICRO_FRAME_BUDGET_MICROS})"
                    ));
                }
                load.micro_frames[micro_frame] = load.micro_frames[micro_frame].max(time);
            }
            for (translator, mut work) in splits {
                let total: u32 = work.iter().map(|&(_, _, time)| time).sum();
                if total > TT_FRAME_BUDGET_MICROS {
                    self.error(format!(
                        "frame list entry {entry:#x}: translator {translator:?} has {total} us of full- and low-speed time (at most {TT_FRAME_BUDGET_MICROS})"
                    ));
                }
                let peak = load.translators.entry(translator).or_default();
                *peak = (*peak).max(total);
                // The translator runs them in turn, each from the
                // micro-frame after its start-split; each must end before
                // the micro-frame of its last complete-split.
                work.sort_by_key(|&(start, _, _)| start);
                let mut busy_until = 0;
                for (start, c_mask, time) in work {
                    busy_until = busy_until.max(TT_MICRO_FRAME_MICROS * (start + 1)) + time;
                    let last_complete = 7u32.saturating_sub(c_mask.leading_zeros());
                    if c_mask == 0 || busy_until > TT_MICRO_FRAME_MICROS * last_complete {
                        self.error(format!(
                            "frame list entry {entry:#x}: translator {translator:?} ends a split started in micro-frame {start} at {busy_until} us, after its last complete-split (C-mask {c_mask:#x})"
                        ));
                    }
                }
            }
        }
        self.periodic_load = load;
    }

    fn run_periodic(&mut self) {
        let frame = u64::from(self.frindex >> 3 & 0x3FF);
        let micro_frame = self.frindex & 7;
        let base = self.pointer(self.periodic_base);
        let mut link = self.hc_read(base + 4 * frame);
        let mut seen = BTreeSet::new();
        for _ in 0..WALK_LIMIT {
            if link & 1 != 0 || link >> 1 & 3 != 1 {
                return;
            }
            let qh = self.pointer(link & !0x1F);
            if !seen.insert(qh) {
                self.error(format!("the periodic schedule loops at {qh:#x}"));
                return;
            }
            let s_mask = self.hc_read(qh + 8) & 0xFF;
            if s_mask & 1 << micro_frame != 0 {
                self.service_qh(qh, true);
            }
            link = self.hc_read(qh);
        }
        self.error("the periodic schedule is too long".into());
    }

    // One queue head.

    /// Runs one transaction on `qh` if it has one to run; says whether it did.
    fn service_qh(&mut self, qh: u64, periodic: bool) -> bool {
        let characteristics = self.hc_read(qh + 4);
        let capabilities = self.hc_read(qh + 8);
        let mut token = self.hc_read(qh + 0x18);
        if characteristics & 1 << 15 != 0 && !periodic {
            // The reclamation head: the driver keeps it halted.
            if token & TOKEN_ACTIVE != 0 {
                self.error("the async head QH has an active overlay".into());
            }
            return false;
        }
        if token & TOKEN_HALTED != 0 {
            return false;
        }
        if token & TOKEN_ACTIVE == 0 {
            // Fetch the next qTD into the overlay (EHCI 4.10.2).
            let next = self.hc_read(qh + 0x10);
            if next & 1 != 0 {
                return false;
            }
            if next & 0x1E != 0 {
                self.error(format!(
                    "QH {qh:#x}: next qTD {next:#x} not 32-byte aligned"
                ));
            }
            let qtd = self.pointer(next & !0x1F);
            let words = if self.sixty_four_bit { 13 } else { 8 };
            let mut copy = [0u32; 13];
            for (i, word) in copy.iter_mut().enumerate().take(words) {
                *word = self.hc_read(qtd + 4 * i as u64);
            }
            let data_toggle_control = characteristics & 1 << 14 != 0;
            let mut new_token = copy[2];
            if !data_toggle_control {
                new_token = new_token & !TOKEN_TOGGLE | token & TOKEN_TOGGLE;
            }
            self.hc_write(qh + 0x0C, next & !0x1F);
            self.hc_write(qh + 0x10, copy[0]);
            self.hc_write(qh + 0x14, copy[1]);
            for i in 0..5 {
                self.hc_write(qh + 0x1C + 4 * i as u64, copy[3 + i]);
                if self.sixty_four_bit {
                    self.hc_write(qh + 0x30 + 4 * i as u64, copy[8 + i]);
                }
            }
            self.hc_write(qh + 0x18, new_token);
            token = new_token;
            if token & TOKEN_ACTIVE == 0 {
                return false;
            }
        }
        if !self.check_qh(qh, characteristics, capabilities, periodic) {
            return false;
        }
        self.transaction(qh, characteristics, capabilities, token, periodic)
    }

    /// What the spec leaves undefined, checked once per transaction.
    fn check_qh(
        &mut self,
        qh: u64,
        characteristics: u32,
        capabilities: u32,
        periodic: bool,
    ) -> bool {
        let endpoint = characteristics >> 8 & 0xF;
        let eps = characteristics >> 12 & 3;
        let dtc = characteristics & 1 << 14 != 0;
        let max_packet = characteristics >> 16 & 0x7FF;
        let control_flag = characteristics & 1 << 27 != 0;
        let nak_reload = characteristics >> 28;
        let s_mask = capabilities & 0xFF;
        let c_mask = capabilities >> 8 & 0xFF;
        let mult = capabilities >> 30;
        let mut problems = Vec::new();
        if eps == 3 {
            problems.push("EPS 11b is reserved".into());
        }
        if mult == 0 {
            problems.push("Mult 0".into());
        }
        let split = eps != 2;
        if endpoint == 0 {
            if !dtc {
                problems.push("a control endpoint without DTC".into());
            }
            if control_flag != split {
                problems.push(format!("C bit {} at EPS {eps}", u8::from(control_flag)));
            }
        } else {
            if dtc {
                problems.push("an interrupt endpoint with DTC".into());
            }
            if control_flag {
                problems.push("the C bit on an interrupt endpoint".into());
            }
        }
        let largest = match (eps, endpoint) {
            (1, _) => 8,
            (0, _) => 64,
            (_, 0) => 64,
            _ => 1024,
        };
        if max_packet == 0
            || max_packet > largest
            || (eps == 2 && endpoint == 0 && max_packet != 64)
        {
            problems.push(format!("maximum packet {max_packet} at EPS {eps}"));
        }
        if periodic {
            if nak_reload != 0 {
                problems.push("a NAK reload on the periodic schedule".into());
            }
            if !split && c_mask != 0 {
                problems.push(format!("C-mask {c_mask:#x} at high speed"));
            }
            if split {
                // One start-split in N, complete-splits in N+2, N+3 and
                // N+4 (USB 2.0 11.18.4, EHCI 4.12.2.1), all inside the
                // frame: past micro-frame 7 they would need an FSTN.
                let start = s_mask.trailing_zeros();
                if s_mask.count_ones() != 1 || start > 3 || c_mask != 0b111 << (start + 2) {
                    problems.push(format!(
                        "S-mask {s_mask:#x} with C-mask {c_mask:#x} (complete-splits belong in the start's micro-frame + 2, 3 and 4)"
                    ));
                }
            }
        } else if s_mask != 0 {
            problems.push(format!("S-mask {s_mask:#x} on the async schedule"));
        }
        if problems.is_empty() {
            return true;
        }
        for problem in problems {
            self.error(format!("QH {qh:#x}: {problem}"));
        }
        // Undefined: the model halts the endpoint.
        let token = self.hc_read(qh + 0x18);
        self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED, false);
        false
    }

    /// Which root port a packet to `address` goes out on: the one it
    /// answered on last, then every enabled port.
    fn deliver(&mut self, packet: &Packet, split: Option<Split>) -> Reply {
        let learned = self.routes[usize::from(packet.address & 0x7F)];
        let mut order: Vec<u8> = learned.into_iter().collect();
        order.extend((1..=self.ports).filter(|&p| Some(p) != learned));
        for port in order {
            let p = self.port[usize::from(port) - 1];
            if p.companion || !p.enabled {
                continue;
            }
            let reply = self.tree.transact(port, packet, split);
            if reply != Reply::Timeout {
                self.routes[usize::from(packet.address & 0x7F)] = Some(port);
                return reply;
            }
        }
        Reply::Timeout
    }

    /// The address of byte `position` of the overlay's buffer, counted
    /// from the start of the first buffer page (C_Page 4096 + offset).
    fn buffer_address(&mut self, qh: u64, position: u32) -> Option<u64> {
        let page = position / 4096;
        let offset = position % 4096;
        if page > 4 {
            self.error(format!("QH {qh:#x}: the buffer runs past its fifth page"));
            return None;
        }
        let low = self.hc_read(qh + 0x1C + 4 * u64::from(page)) & !0xFFF;
        let high = if self.sixty_four_bit {
            self.hc_read(qh + 0x30 + 4 * u64::from(page))
        } else {
            0
        };
        if low == 0 && high == 0 {
            self.error(format!("QH {qh:#x}: buffer page {page} is 0"));
            return None;
        }
        Some(u64::from(high) << 32 | u64::from(low) | u64::from(offset))
    }

    /// Reads `count` bytes of the buffer from `position`, or writes `write`.
    fn buffer_bytes(
        &mut self,
        qh: u64,
        position: u32,
        count: usize,
        write: Option<&[u8]>,
    ) -> Option<Vec<u8>> {
        let mut out = Vec::new();
        for i in 0..count {
            let address = self.buffer_address(qh, position + i as u32)?;
            let word_address = address & !3;
            let shift = 8 * (address & 3);
            let word = self.hc_read(word_address);
            match write {
                Some(bytes) => {
                    let word = word & !(0xFF << shift) | u32::from(bytes[i]) << shift;
                    self.hc_write(word_address, word);
                }
                None => out.push((word >> shift) as u8),
            }
        }
        Some(out)
    }

    fn transaction(
        &mut self,
        qh: u64,
        characteristics: u32,
        capabilities: u32,
        token: u32,
        periodic: bool,
    ) -> bool {
        let address = (characteristics & 0x7F) as u8;
        let endpoint = (characteristics >> 8 & 0xF) as u8;
        let eps = characteristics >> 12 & 3;
        let max_packet = (characteristics >> 16 & 0x7FF) as usize;
        let speed = match eps {
            0 => Speed::Full,
            1 => Speed::Low,
            _ => Speed::High,
        };
        let total = (token >> 16 & 0x7FFF) as usize;
        let toggle = token & TOKEN_TOGGLE != 0;
        let pid = match token >> 8 & 3 {
            0 => Pid::Out,
            1 => Pid::In,
            2 => Pid::Setup,
            _ => {
                self.error(format!("QH {qh:#x}: PID code 3"));
                self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED, false);
                return false;
            }
        };
        // Where the buffer stands: the overlay's first pointer's offset and
        // the current page (bits 11:0 of the first pointer, C_Page).
        let position = (token >> 12 & 7) * 4096 + (self.hc_read(qh + 0x1C) & 0xFFF);
        let out_bytes = match pid {
            Pid::Setup if total != 8 => {
                self.error(format!("QH {qh:#x}: a SETUP qTD of {total} bytes"));
                self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED, false);
                return false;
            }
            Pid::Setup | Pid::Out => {
                let n = total.min(max_packet);
                match self.buffer_bytes(qh, position, n, None) {
                    Some(bytes) => bytes,
                    None => {
                        self.retire(
                            qh,
                            token & !TOKEN_ACTIVE | TOKEN_HALTED | TOKEN_DATA_BUFFER,
                            false,
                        );
                        return true;
                    }
                }
            }
            Pid::In => Vec::new(),
        };
        let split = (eps != 2).then_some(Split {
            hub_address: (capabilities >> 16 & 0x7F) as u8,
            hub_port: (capabilities >> 23 & 0x7F) as u8,
        });
        if let Some(s) = split {
            self.split_log.push(SplitRecord {
                address,
                endpoint,
                eps: eps as u8,
                hub_address: s.hub_address,
                hub_port: s.hub_port,
                s_mask: (capabilities & 0xFF) as u8,
                c_mask: (capabilities >> 8 & 0xFF) as u8,
                control: characteristics & 1 << 27 != 0,
                periodic,
            });
        }
        let packet = Packet {
            address,
            endpoint,
            pid,
            toggle,
            data: out_bytes.clone(),
            max_packet,
            speed,
        };
        if periodic {
            self.periodic_transactions += 1;
            self.polls[usize::from(address)] += 1;
        }
        let reply = self.deliver(&packet, split);
        let ioc = token & TOKEN_IOC != 0;
        match (pid, reply) {
            (
                Pid::In,
                Reply::Data {
                    bytes,
                    toggle: sent,
                },
            ) => {
                if sent != toggle {
                    // A repeat whose ACK was lost: ACKed and dropped.
                    return true;
                }
                if bytes.len() > max_packet.min(total) {
                    self.retire(
                        qh,
                        token & !TOKEN_ACTIVE | TOKEN_HALTED | TOKEN_BABBLE,
                        false,
                    );
                    return true;
                }
                if self
                    .buffer_bytes(qh, position, bytes.len(), Some(&bytes))
                    .is_none()
                {
                    self.retire(
                        qh,
                        token & !TOKEN_ACTIVE | TOKEN_HALTED | TOKEN_DATA_BUFFER,
                        false,
                    );
                    return true;
                }
                let short = bytes.len() < max_packet;
                self.advance_overlay(qh, token, position, bytes.len(), short, ioc);
            }
            (Pid::Setup | Pid::Out, Reply::Ack) => {
                let n = out_bytes.len();
                self.advance_overlay(qh, token, position, n, false, ioc);
            }
            (_, Reply::Nak) => {}
            (_, Reply::Stall) => {
                self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED, false);
            }
            (_, Reply::Timeout) => {
                // CERR 0 counts nothing: the transaction is tried for ever.
                let errors = token >> 10 & 3;
                if errors == 0 {
                    self.hc_write(qh + 0x18, token | TOKEN_XACT);
                    return true;
                }
                let token = token & !(3 << 10) | TOKEN_XACT;
                if errors == 1 {
                    self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED, false);
                } else {
                    let token = token | (errors - 1) << 10;
                    self.hc_write(qh + 0x18, token);
                }
            }
            (pid, reply) => {
                self.error(format!("QH {qh:#x}: {pid:?} answered with {reply:?}"));
                self.retire(qh, token & !TOKEN_ACTIVE | TOKEN_HALTED | TOKEN_XACT, false);
            }
        }
        true
    }

    /// `moved` bytes went: the total, the offset, the page and the toggle
    /// move on; the qTD retires when its bytes are done or a packet is short.
    fn advance_overlay(
        &mut self,
        qh: u64,
        token: u32,
        position: u32,
        moved: usize,
        short: bool,
        ioc: bool,
    ) {
        let total = (token >> 16 & 0x7FFF) as usize - moved;
        let position = position + moved as u32;
        let token = token & !(0x7FFF << 16 | 7 << 12 | TOKEN_TOGGLE)
            | (total as u32) << 16
            | (position >> 12).min(7) << 12
            | if token & TOKEN_TOGGLE == 0 {
                TOKEN_TOGGLE
            } else {
                0
            };
        let first = self.hc_read(qh + 0x1C);
        self.hc_write(qh + 0x1C, first & !0xFFF | position & 0xFFF);
        if total == 0 || short {
            self.retire(qh, token & !TOKEN_ACTIVE, short && total > 0);
            if ioc {
                self.usbsts |= STS_USBINT;
            }
        } else {
            self.hc_write(qh + 0x18, token);
        }
    }

    /// The overlay's qTD is done (or halted): its token is written back to
    /// the qTD, and on a short packet the alternate next qTD is next.
    fn retire(&mut self, qh: u64, token: u32, short: bool) {
        self.hc_write(qh + 0x18, token);
        let current = self.hc_read(qh + 0x0C);
        let qtd = self.pointer(current & !0x1F);
        self.hc_write(qtd + 8, token);
        if token & TOKEN_HALTED != 0 {
            self.usbsts |= STS_ERROR;
        }
        if short {
            let alternate = self.hc_read(qh + 0x14);
            if alternate & 1 == 0 {
                self.hc_write(qh + 0x10, alternate);
            }
        }
    }

    /// A driver write into DMA memory: is it one the controller could
    /// trip over?
    fn check_driver_write(&mut self, address: u64, value: u32) {
        let qh = address & !0x1F;
        let offset = address & 0x1F;
        if offset == 0 {
            if self.async_live.contains_key(&qh) {
                self.async_dirty = true;
            }
            if self.periodic_live.contains_key(&qh) {
                self.periodic_dirty = true;
            }
        }
        let base = self.pointer(self.periodic_base);
        if self.periodic_base != 0 && (base..base + 4096).contains(&address) {
            self.periodic_dirty = true;
        }
        if offset > 8 {
            return;
        }
        if self.async_unlinked.contains(&qh) {
            self.error(format!(
                "QH {qh:#x} rewritten after its unlink, before the async advance doorbell"
            ));
        }
        if let Some(&since) = self.periodic_unlinked.get(&qh) {
            if self.frindex.wrapping_sub(since) & 0x3FFF < 8 {
                self.error(format!(
                    "periodic QH {qh:#x} rewritten within a frame of its unlink"
                ));
            } else {
                self.periodic_unlinked.remove(&qh);
            }
        }
        if offset == 0 {
            return;
        }
        let overlay_active = self.peek(qh + 0x18) & TOKEN_ACTIVE != 0;
        if let Some(&(characteristics, capabilities)) = self.async_live.get(&qh) {
            let (old, changeable) = if offset == 4 {
                // The address and packet size of an idle QH may change.
                (characteristics, 0x7F | 0x7FF << 16)
            } else {
                (capabilities, 0)
            };
            if (value ^ old) & !changeable != 0 || (value != old && overlay_active) {
                self.error(format!(
                    "async QH {qh:#x} dword {} rewritten from {old:#x} to {value:#x} while linked",
                    offset / 4
                ));
            }
            let entry = self.async_live.get_mut(&qh).expect("there");
            if offset == 4 {
                entry.0 = value;
            } else {
                entry.1 = value;
            }
        }
        if let Some(&(characteristics, capabilities)) = self.periodic_live.get(&qh) {
            let old = if offset == 4 {
                characteristics
            } else {
                capabilities
            };
            if value != old {
                self.error(format!(
                    "periodic QH {qh:#x} dword {} rewritten from {old:#x} to {value:#x} while linked",
                    offset / 4
                ));
            }
        }
    }
}

impl Memory for EhciModel {
    fn mem_read(&mut self, address: u64) -> u32 {
        let i = self
            .index(address)
            .unwrap_or_else(|| panic!("the driver read {address:#x}, outside its DMA memory"));
        self.memory[i]
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        let i = self
            .index(address)
            .unwrap_or_else(|| panic!("the driver wrote {address:#x}, outside its DMA memory"));
        self.check_driver_write(address, value);
        self.memory[i] = value;
    }
}

impl Hardware for EhciModel {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        assert!(
            offset % 4 == 0 && offset + 4 <= BAR_BYTES,
            "read outside the BAR: {offset:#x}"
        );
        self.advance(MICROS_PER_READ);
        self.mmio_reads += 1;
        let operational = CAPLENGTH;
        match offset {
            0x00 => 0x0100_0000 | CAPLENGTH,
            0x04 => {
                let per_companion = if self.companions == 0 {
                    0
                } else {
                    u32::from(self.ports.div_ceil(self.companions))
                };
                u32::from(self.ports)
                    | u32::from(self.port_power_control) << 4
                    | per_companion << 8
                    | u32::from(self.companions) << 12
            }
            0x08 => u32::from(EECP_FIRST) << 8 | u32::from(self.sixty_four_bit),
            o if o == operational => self.usbcmd,
            o if o == operational + 0x04 => self.usbsts,
            o if o == operational + 0x08 => self.usbintr,
            o if o == operational + 0x0C => self.frindex,
            o if o == operational + 0x10 => self.ctrldssegment,
            o if o == operational + 0x14 => self.periodic_base,
            o if o == operational + 0x18 => self.async_base,
            o if o == operational + 0x40 => self.configflag,
            o if (operational + 0x44..operational + 0x44 + 4 * u32::from(self.ports))
                .contains(&o) =>
            {
                let port = ((o - operational - 0x44) / 4 + 1) as u8;
                self.portsc(port)
            }
            _ => 0,
        }
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        assert!(
            offset % 4 == 0 && offset + 4 <= BAR_BYTES,
            "write outside the BAR: {offset:#x}"
        );
        self.mmio_writes += 1;
        if self.legacy & 1 << 16 != 0 {
            self.error(format!(
                "register {offset:#x} written while the firmware owns the controller"
            ));
        }
        let operational = CAPLENGTH;
        match offset {
            o if o == operational => self.write_usbcmd(value),
            o if o == operational + 0x04 => {
                self.usbsts &= !(value & STS_W1C);
            }
            o if o == operational + 0x08 => self.usbintr = value & 0x3F,
            o if o == operational + 0x0C => {
                if self.usbsts & STS_HALTED == 0 {
                    self.error("FRINDEX written while running".into());
                }
                self.frindex = value & 0x3FFF;
            }
            o if o == operational + 0x10 => {
                if !self.sixty_four_bit {
                    self.error("CTRLDSSEGMENT written without 64-bit addressing".into());
                }
                self.ctrldssegment = value;
            }
            o if o == operational + 0x14 => {
                if value & 0xFFF != 0 {
                    self.error(format!("PERIODICLISTBASE {value:#x} not 4 KiB aligned"));
                }
                self.periodic_base = value & !0xFFF;
                self.periodic_dirty = true;
            }
            o if o == operational + 0x18 => {
                if value & 0x1F != 0 {
                    self.error(format!("ASYNCLISTADDR {value:#x} not 32-byte aligned"));
                }
                self.async_base = value & !0x1F;
                self.async_dirty = true;
            }
            o if o == operational + 0x40 => self.write_configflag(value),
            o if (operational + 0x44..operational + 0x44 + 4 * u32::from(self.ports))
                .contains(&o) =>
            {
                let port = ((o - operational - 0x44) / 4 + 1) as u8;
                self.write_portsc(port, value);
            }
            o => self.error(format!("write to {o:#x}, no register there")),
        }
    }
}

impl Platform for EhciModel {
    fn now_micros(&mut self) -> u64 {
        self.advance(MICROS_PER_READ);
        self.now
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.log.push(format!("{message}"));
    }
}

impl PciHardware for EhciModel {
    fn read16(&mut self, offset: u32) -> u16 {
        self.error(format!("read16({offset:#x}): EHCI has no I/O registers"));
        0
    }

    fn write16(&mut self, offset: u32, _value: u16) {
        self.error(format!("write16({offset:#x}): EHCI has no I/O registers"));
    }

    fn pci_config_read(&mut self, offset: u8) -> u32 {
        assert!(offset % 4 == 0, "config read at {offset:#x}");
        self.advance(MICROS_PER_READ);
        match offset {
            0x00 => 0x293A_8086, // ICH9's EHCI
            0x08 => 0x0C03_2003,
            o if o == EECP_FIRST => {
                let next = if self.eecp_loop {
                    EECP_FIRST
                } else {
                    EECP_LEGACY
                };
                u32::from(next) << 8 | 0x0A
            }
            o if o == EECP_LEGACY => {
                if let (Some(asked), Some(after)) = (self.os_asked_at, self.firmware_releases_after)
                {
                    if self.now >= asked + after {
                        self.legacy &= !(1 << 16);
                    }
                }
                self.legacy
            }
            o if o == EECP_LEGACY + 4 => self.legacy_control,
            _ => 0,
        }
    }

    fn pci_config_write(&mut self, offset: u8, value: u32) {
        match offset {
            o if o == EECP_LEGACY => {
                let os = value & 1 << 24;
                if os != 0 && self.legacy & 1 << 24 == 0 {
                    self.os_asked_at = Some(self.now);
                }
                if os == 0 {
                    self.os_asked_at = None;
                }
                if value & 1 << 16 == 0 && self.legacy & 1 << 16 != 0 {
                    self.error("the driver cleared BIOS-owned itself".into());
                }
                if value & 1 << 16 != 0 && self.legacy & 1 << 16 == 0 {
                    self.error("the driver set BIOS-owned".into());
                }
                self.legacy = self.legacy & !(1 << 24) | os;
            }
            o if o == EECP_LEGACY + 4 => {
                // The SMI enables are read-write, the status bits W1C.
                self.legacy_control = value & 0xE03F | self.legacy_control & 0xE000_0000 & !value;
            }
            o => self.error(format!("PCI configuration {o:#x} written")),
        }
    }
}
