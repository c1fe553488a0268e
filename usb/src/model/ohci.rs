//! A register model of an OHCI 1.0a controller for the host tests: the
//! operational registers and root hub of chapter 7, a frame every 1 ms of
//! a simulated clock (every register read and clock read advances it),
//! and in each frame the periodic list of the HCCA's interrupt table and
//! the control list run against the shared device tree ([`UsbTree`]),
//! with the write-backs a controller does: ConditionCode, ErrorCount,
//! CurrentBufferPointer and the data toggle into the TD; HeadP, the
//! toggle carry and Halted into the ED; the done queue into HcDoneHead
//! and, at the frame's end, the HCCA (WDH).
//!
//! It checks what the driver gives it as hardware would need it (pointer
//! alignment and bounds, TailP reachable from HeadP, list loops, the HCCA's
//! alignment, FrameInterval and PeriodicStart before UsbOperational, the
//! 2 ms after a software reset, HcControlCurrentED written only with CLE
//! clear) and notes every breach in [`OhciModel::errors`]. Knobs: SMM owns
//! it (InterruptRouting) and lets go after a while or never; the root hub
//! reports a nonsense port count; HcControl never leaves UsbOperational;
//! the software reset never ends; the power switching mode and POTPGT.

use super::devices::{Packet, Pid, Reply, UsbTree};
use crate::host::Speed;
use crate::{Hardware, Memory, PciHardware, Platform};
use std::collections::{BTreeMap, BTreeSet};
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// Where the tests' DMA region starts.
pub const DMA_BASE: u64 = 0x20_0000;
/// How long it is (what the kernel gives each controller).
pub const DMA_BYTES: u64 = 256 * 1024;
/// BAR0's size.
pub const BAR_BYTES: u32 = 0x1000;

const MICROS_PER_REGISTER_READ: u64 = 1;
const MICROS_PER_CLOCK_READ: u64 = 5;
const MICROS_PER_USB_FRAME: u64 = 1_000;
/// How long the root hub drives a port reset (OHCI: about 10 ms).
const RESET_PULSE_MICROS: u64 = 10_000;
/// How long HostControllerReset takes.
const SOFTWARE_RESET_MICROS: u64 = 10;
/// After a software reset the controller must be operational within 2 ms.
const SUSPEND_LIMIT_MICROS: u64 = 2_000;
/// Transactions per ED per frame on the control list.
const CONTROL_TRANSACTIONS_PER_FRAME: usize = 32;
/// EDs on one list before the model calls it a loop.
const MAX_LIST_EDS: usize = 256;
/// TDs from HeadP before TailP must have come.
const MAX_QUEUE_TDS: usize = 64;

// HcControl.
const CONTROL_PLE: u32 = 1 << 2;
const CONTROL_IE: u32 = 1 << 3;
const CONTROL_CLE: u32 = 1 << 4;
const CONTROL_BLE: u32 = 1 << 5;
const HCFS: u32 = 3 << 6;
const HCFS_RESET: u32 = 0;
const HCFS_RESUME: u32 = 1 << 6;
const HCFS_OPERATIONAL: u32 = 2 << 6;
const HCFS_SUSPEND: u32 = 3 << 6;
const CONTROL_IR: u32 = 1 << 8;
const CONTROL_RWC: u32 = 1 << 9;
// HcCommandStatus.
const HCR: u32 = 1 << 0;
const CLF: u32 = 1 << 1;
const BLF: u32 = 1 << 2;
const OCR: u32 = 1 << 3;
// HcInterruptStatus.
const WDH: u32 = 1 << 1;
const SF: u32 = 1 << 2;
const RHSC: u32 = 1 << 6;
const OC: u32 = 1 << 30;
const INTERRUPT_SOURCES: u32 = 0x7F | OC;
// HcRhDescriptorA.
const PSM: u32 = 1 << 8;
const NPS: u32 = 1 << 9;
// HcRhPortStatus (reads; the same bits written mean other things).
const CCS: u32 = 1 << 0;
const PES: u32 = 1 << 1;
const PSS: u32 = 1 << 2;
const PRS: u32 = 1 << 4;
const PPS: u32 = 1 << 8;
const LSDA: u32 = 1 << 9;
const CSC: u32 = 1 << 16;
const PESC: u32 = 1 << 17;
const PSSC: u32 = 1 << 18;
const OCIC: u32 = 1 << 19;
const PRSC: u32 = 1 << 20;
const CLEAR_PORT_ENABLE: u32 = 1 << 0;
const SET_PORT_ENABLE: u32 = 1 << 1;
const SET_PORT_SUSPEND: u32 = 1 << 2;
const CLEAR_SUSPEND_STATUS: u32 = 1 << 3;
const SET_PORT_RESET: u32 = 1 << 4;
const SET_PORT_POWER: u32 = 1 << 8;
const CLEAR_PORT_POWER: u32 = 1 << 9;
// ED and TD bits.
const ED_SKIP: u32 = 1 << 14;
const ED_ISO: u32 = 1 << 15;
const ED_LOW_SPEED: u32 = 1 << 13;
const ED_HALTED: u32 = 1 << 0;
const ED_CARRY: u32 = 1 << 1;
const TD_ROUNDING: u32 = 1 << 18;
const CC_NO_ERROR: u32 = 0x0;
const CC_DATA_TOGGLE_MISMATCH: u32 = 0x3;
const CC_STALL: u32 = 0x4;
const CC_DEVICE_NOT_RESPONDING: u32 = 0x5;
const CC_DATA_OVERRUN: u32 = 0x8;
const CC_DATA_UNDERRUN: u32 = 0x9;
/// HcFmInterval after a reset: FI 11,999, FSMPS 0 (the driver must set it).
const FM_INTERVAL_DEFAULT: u32 = 11_999;

/// How the root ports get power (HcRhDescriptorA NPS/PSM).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PowerSwitching {
    /// Always powered (NPS).
    None,
    /// All together by SetGlobalPower.
    Ganged,
    /// Each by SetPortPower (PSM, every port in PortPowerControlMask).
    PerPort,
}

#[derive(Clone, Copy, Debug, Default)]
struct Port {
    powered_at: Option<u64>,
    enabled: bool,
    suspended: bool,
    reset_until: Option<u64>,
    /// Whether the connection was last seen (CCS).
    connected: bool,
    changes: u32,
}

/// What a transaction did to its TD.
enum Step {
    /// More packets to go on this TD.
    Continue,
    /// Retired: the queue moved on.
    Retired,
    /// Nothing more on this ED this frame (NAK, an error retried, halted).
    Stop,
}

/// The controller, the DMA memory it shares with the driver, and the
/// devices on its root ports.
#[derive(Debug)]
pub struct OhciModel {
    /// The simulated clock, in microseconds.
    pub now: u64,
    memory: Vec<u32>,
    /// The devices.
    pub tree: UsbTree,
    // Knobs.
    /// HcRhDescriptorA.NDP as reported (a nonsense value on purpose).
    pub reported_ports: u8,
    /// How the ports are powered.
    pub power_switching: PowerSwitching,
    /// HcRhDescriptorA.POTPGT, in 2 ms units.
    pub power_on_to_good: u8,
    /// SMM lets go this long after the ownership change request (None:
    /// never). Only with [`OhciModel::smm_owns`].
    pub smm_releases_after: Option<u64>,
    /// HcControl never leaves UsbOperational.
    pub never_halts: bool,
    /// HostControllerReset never clears.
    pub reset_stuck: bool,
    /// FrameInterval (FI) as the firmware left it.
    pub firmware_frame_interval: u32,
    // Registers.
    control: u32,
    command_status: u32,
    interrupt_status: u32,
    interrupt_enable: u32,
    hcca: u32,
    control_head: u32,
    control_current: u32,
    bulk_head: u32,
    done_head: u32,
    fm_interval: u32,
    frame_number: u16,
    periodic_start: u32,
    ports: Vec<Port>,
    // Timers.
    ocr_at: Option<u64>,
    reset_until: Option<u64>,
    suspended_at: Option<u64>,
    next_frame: u64,
    done_counter: u32,
    smm_owned: bool,
    /// The firmware's own schedule runs (until the software reset): its
    /// frames touch nothing the driver gave.
    firmware_schedule: bool,
    /// At the end of the last frame: every ED on a list, and whether it
    /// was halted or skipped then (only then may the driver write HeadP).
    listed_eds: BTreeMap<u64, bool>,
    /// At the end of the last frame: the TDs queued on live EDs (HeadP up
    /// to TailP), which the driver must not write.
    queued_tds: BTreeSet<u64>,
    // Records.
    /// Record every periodic ED serviced, for [`OhciModel::visits`].
    pub record_visits: bool,
    /// (frame number, function address, endpoint) of each periodic ED
    /// serviced while `record_visits` is on.
    pub visits: Vec<(u16, u8, u8)>,
    /// Data toggle mismatches seen (a repeated packet dropped).
    pub toggle_mismatches: u32,
    /// Register reads by the driver.
    pub register_reads: u64,
    /// DMA word reads by the driver.
    pub memory_reads: u64,
    /// Frames run.
    pub frames: u64,
    /// Packets sent to the devices.
    pub packets: u64,
    /// Software resets done.
    pub software_resets: u32,
    /// When each software reset was asked for.
    pub software_resets_at: Vec<u64>,
    /// Each SetPortReset written (a reset pulse): the port and when.
    pub port_resets_at: Vec<(u8, u64)>,
    /// Every HcControl write: when, and the value.
    pub control_writes: Vec<(u64, u32)>,
    /// Done queue heads written to the HCCA.
    pub done_queue_writes: u32,
    /// Register writes while SMM owned the controller (offset, value),
    /// apart from the ownership change request itself.
    pub writes_while_owned: Vec<(u32, u32)>,
    /// Times HcControl was asked to leave UsbOperational.
    pub halts_requested: u32,
    /// What the driver logged.
    pub log: Vec<String>,
    /// What the driver did that the hardware would not take.
    pub errors: Vec<String>,
}

impl OhciModel {
    /// A controller with `ports` root ports, nothing plugged in, left by
    /// the firmware in UsbReset.
    pub fn new(ports: u8) -> OhciModel {
        OhciModel {
            now: 0,
            memory: vec![0; (DMA_BYTES / 4) as usize],
            tree: UsbTree::new(ports),
            reported_ports: ports,
            power_switching: PowerSwitching::PerPort,
            power_on_to_good: 50,
            smm_releases_after: None,
            never_halts: false,
            reset_stuck: false,
            firmware_frame_interval: FM_INTERVAL_DEFAULT,
            control: HCFS_RESET,
            command_status: 0,
            interrupt_status: 0,
            interrupt_enable: 0,
            hcca: 0,
            control_head: 0,
            control_current: 0,
            bulk_head: 0,
            done_head: 0,
            fm_interval: FM_INTERVAL_DEFAULT,
            frame_number: 0,
            periodic_start: 0,
            ports: vec![Port::default(); usize::from(ports)],
            ocr_at: None,
            reset_until: None,
            suspended_at: None,
            next_frame: 0,
            done_counter: 7,
            smm_owned: false,
            firmware_schedule: false,
            listed_eds: BTreeMap::new(),
            queued_tds: BTreeSet::new(),
            record_visits: false,
            visits: Vec::new(),
            toggle_mismatches: 0,
            register_reads: 0,
            memory_reads: 0,
            frames: 0,
            packets: 0,
            software_resets: 0,
            software_resets_at: Vec::new(),
            port_resets_at: Vec::new(),
            control_writes: Vec::new(),
            done_queue_writes: 0,
            writes_while_owned: Vec::new(),
            halts_requested: 0,
            log: Vec::new(),
            errors: Vec::new(),
        }
    }

    /// SMM runs the controller (for its legacy keyboard): InterruptRouting
    /// set, UsbOperational; it lets go `releases_after` microseconds after
    /// an ownership change request, or never.
    pub fn smm_owns(&mut self, releases_after: Option<u64>) {
        self.smm_owned = true;
        self.firmware_schedule = true;
        self.smm_releases_after = releases_after;
        self.control = CONTROL_IR | HCFS_OPERATIONAL | CONTROL_CLE | CONTROL_PLE;
        self.fm_interval = self.firmware_frame_interval | 0x2778 << 16;
        self.next_frame = self.now + MICROS_PER_USB_FRAME;
    }

    /// The firmware left the controller running (UsbOperational) without
    /// SMM.
    pub fn firmware_left_running(&mut self) {
        self.firmware_schedule = true;
        self.control = HCFS_OPERATIONAL;
        self.fm_interval = self.firmware_frame_interval | 0x2778 << 16;
        self.next_frame = self.now + MICROS_PER_USB_FRAME;
    }

    /// The firmware left the controller suspended (UsbSuspend), its
    /// schedule set up, without SMM.
    pub fn firmware_left_suspended(&mut self) {
        self.firmware_schedule = true;
        self.control = HCFS_SUSPEND;
        self.fm_interval = self.firmware_frame_interval | 0x2778 << 16;
    }

    /// HcControl.HCFS: 0 reset, 1 resume, 2 operational, 3 suspend.
    pub fn functional_state(&self) -> u32 {
        (self.control & HCFS) >> 6
    }

    /// Whether SMM still holds InterruptRouting.
    pub fn interrupt_routing(&self) -> bool {
        self.control & CONTROL_IR != 0
    }

    /// Whether root port `port` is powered.
    pub fn port_powered(&self, port: u8) -> bool {
        self.power_switching == PowerSwitching::None
            || self.ports[usize::from(port) - 1].powered_at.is_some()
    }

    /// Every error of the model and of the device tree.
    pub fn all_errors(&self) -> Vec<String> {
        let mut all = self.errors.clone();
        all.extend(self.tree.errors().iter().cloned());
        all
    }

    fn error(&mut self, message: String) {
        if self.errors.len() < 100 {
            self.errors.push(message);
        }
    }

    // -----------------------------------------------------------------------
    // Memory as the controller reaches it: a bad pointer is the driver's
    // error, not a crash.

    fn in_memory(address: u64, bytes: u64) -> bool {
        address >= DMA_BASE && address + bytes <= DMA_BASE + DMA_BYTES
    }

    fn peek(&mut self, address: u64) -> u32 {
        if !Self::in_memory(address, 4) || address % 4 != 0 {
            self.error(format!("the controller was sent to read {address:#x}"));
            return 0;
        }
        self.memory[((address - DMA_BASE) / 4) as usize]
    }

    fn poke(&mut self, address: u64, value: u32) {
        if !Self::in_memory(address, 4) || address % 4 != 0 {
            self.error(format!("the controller was sent to write {address:#x}"));
            return;
        }
        self.memory[((address - DMA_BASE) / 4) as usize] = value;
    }

    fn peek_byte(&mut self, address: u64) -> u8 {
        let word = self.peek(address & !3);
        (word >> ((address & 3) * 8)) as u8
    }

    fn poke_byte(&mut self, address: u64, value: u8) {
        let shift = (address & 3) * 8;
        let word = self.peek(address & !3);
        self.poke(
            address & !3,
            word & !(0xFF << shift) | u32::from(value) << shift,
        );
    }

    /// Checks an ED or TD pointer (16-byte aligned, inside the region).
    fn check_descriptor(&mut self, what: &str, address: u32) -> bool {
        let ok = address % 16 == 0 && Self::in_memory(u64::from(address), 16);
        if !ok {
            self.error(format!(
                "{what} pointer {address:#x} is misaligned or outside memory"
            ));
        }
        ok
    }

    // -----------------------------------------------------------------------
    // Time.

    fn operational(&self) -> bool {
        self.control & HCFS == HCFS_OPERATIONAL
    }

    fn catch_up(&mut self) {
        if let Some(until) = self.reset_until {
            if self.now >= until && !self.reset_stuck {
                self.reset_until = None;
                self.command_status &= !HCR;
                self.control = self.control & (CONTROL_IR | CONTROL_RWC) | HCFS_SUSPEND;
                self.suspended_at = Some(self.now);
            }
        }
        if let Some(at) = self.suspended_at {
            if self.control & HCFS == HCFS_SUSPEND && self.now > at + SUSPEND_LIMIT_MICROS {
                self.error("not operational within 2 ms of the software reset".into());
                self.suspended_at = None;
                self.control = self.control & !HCFS | HCFS_RESUME;
            }
        }
        if let (Some(asked), Some(after)) = (self.ocr_at, self.smm_releases_after) {
            if self.now >= asked + after && self.control & CONTROL_IR != 0 {
                self.control &= !CONTROL_IR;
                self.smm_owned = false;
                self.command_status &= !OCR;
                self.interrupt_status |= OC;
            }
        }
        self.sync_ports();
        while self.operational() && self.now >= self.next_frame {
            self.next_frame += MICROS_PER_USB_FRAME;
            self.run_frame();
        }
    }

    fn port_power_good(&self, index: usize) -> bool {
        if self.power_switching == PowerSwitching::None {
            // Powered since the machine was.
            return true;
        }
        let good = u64::from(self.power_on_to_good) * 2_000;
        self.ports[index]
            .powered_at
            .is_some_and(|at| self.now >= at + good)
    }

    /// Connections, disconnections and ends of resets, as the root hub
    /// sees them now.
    fn sync_ports(&mut self) {
        for index in 0..self.ports.len() {
            let port = index as u8 + 1;
            let connected = self.port_power_good(index) && self.tree.root_device(port).is_some();
            let mut changes = 0;
            let state = &mut self.ports[index];
            if connected != state.connected {
                state.connected = connected;
                changes |= CSC;
                if !connected {
                    if state.enabled {
                        changes |= PESC;
                    }
                    state.enabled = false;
                    state.reset_until = None;
                }
            }
            if let Some(until) = state.reset_until {
                if self.now >= until {
                    state.reset_until = None;
                    state.enabled = true;
                    changes |= PRSC;
                    self.tree.reset_root_port(port);
                }
            }
            self.raise_port_change(index, changes);
        }
    }

    fn raise_port_change(&mut self, index: usize, changes: u32) {
        if changes & !self.ports[index].changes != 0 {
            self.interrupt_status |= RHSC;
        }
        self.ports[index].changes |= changes;
    }

    fn power_port(&mut self, index: usize, on: bool) {
        let state = &mut self.ports[index];
        match (on, state.powered_at) {
            (true, None) => state.powered_at = Some(self.now),
            (false, Some(_)) => {
                *state = Port {
                    connected: state.connected,
                    changes: state.changes,
                    ..Port::default()
                };
            }
            _ => {}
        }
    }

    // -----------------------------------------------------------------------
    // Frames.

    fn run_frame(&mut self) {
        self.frames += 1;
        self.frame_number = self.frame_number.wrapping_add(1);
        self.interrupt_status |= SF;
        if self.firmware_schedule {
            return;
        }
        let hcca = u64::from(self.hcca);
        if hcca == 0 {
            self.error("a frame with no HCCA".into());
            return;
        }
        // The end of the last frame: the done queue goes out when its
        // interrupt delay has run down and the driver took the last one.
        if self.done_counter == 0 && self.interrupt_status & WDH == 0 {
            let head = self.done_head;
            self.poke(hcca + 0x84, head);
            self.done_head = 0;
            self.done_counter = 7;
            self.done_queue_writes += 1;
            self.interrupt_status |= WDH;
        } else if self.done_counter != 7 && self.done_counter != 0 {
            self.done_counter -= 1;
        }
        self.poke(hcca + 0x80, u32::from(self.frame_number));
        if self.control & CONTROL_PLE != 0 {
            let entry = hcca + u64::from(self.frame_number % 32) * 4;
            let head = self.peek(entry);
            self.run_periodic(head);
        }
        if self.control & CONTROL_CLE != 0 {
            self.run_control_list();
        }
        if self.control & (CONTROL_BLE | CONTROL_IE) != 0 || self.command_status & BLF != 0 {
            self.error("the bulk list or isochronous transfers were enabled".into());
        }
        self.snapshot_lists(hcca);
    }

    /// Notes what the controller may be working on until the next frame
    /// ends: every ED on the lists and the TDs queued on the live ones.
    fn snapshot_lists(&mut self, hcca: u64) {
        self.listed_eds.clear();
        self.queued_tds.clear();
        let mut heads: Vec<u32> = (0..32).map(|entry| self.peek(hcca + entry * 4)).collect();
        heads.push(self.control_head);
        for head in heads {
            let mut ed = head;
            for _ in 0..MAX_LIST_EDS {
                if ed == 0 || ed % 16 != 0 || !Self::in_memory(u64::from(ed), 16) {
                    break;
                }
                let address = u64::from(ed);
                if self.listed_eds.contains_key(&address) {
                    break;
                }
                let flags = self.peek(address);
                let tail = self.peek(address + 4) & !0xF;
                let head_word = self.peek(address + 8);
                let protected = flags & ED_SKIP != 0 || head_word & ED_HALTED != 0;
                self.listed_eds.insert(address, protected);
                if !protected {
                    let mut td = head_word & !0xF;
                    for _ in 0..MAX_QUEUE_TDS {
                        if td == tail || td % 16 != 0 || !Self::in_memory(u64::from(td), 16) {
                            break;
                        }
                        self.queued_tds.insert(u64::from(td));
                        td = self.peek(u64::from(td) + 8) & !0xF;
                    }
                }
                ed = self.peek(address + 12) & !0xF;
            }
        }
    }

    /// A driver write the controller could be reading at the same time.
    fn check_driver_write(&mut self, address: u64) {
        let descriptor = address & !0xF;
        if self.queued_tds.contains(&descriptor) {
            self.error(format!(
                "the driver wrote {address:#x} of a TD the controller owns"
            ));
        }
        if address & 0xF == 8 && self.listed_eds.get(&descriptor) == Some(&false) {
            self.error(format!(
                "the driver wrote HeadP of ED {descriptor:#x}, neither halted nor skipped for a frame"
            ));
        }
    }

    fn run_periodic(&mut self, head: u32) {
        let mut address = head;
        for _ in 0..MAX_LIST_EDS {
            if address == 0 {
                return;
            }
            if !self.check_descriptor("periodic ED", address) {
                return;
            }
            if self.record_visits {
                let flags = self.peek(u64::from(address));
                if flags & ED_SKIP == 0 {
                    let visit = (
                        self.frame_number,
                        (flags & 0x7F) as u8,
                        ((flags >> 7) & 0xF) as u8,
                    );
                    self.visits.push(visit);
                }
            }
            self.service_ed(address, 1);
            address = self.peek(u64::from(address) + 12) & !0xF;
        }
        self.error(format!("the periodic list from {head:#x} loops"));
    }

    fn run_control_list(&mut self) {
        if self.control_current == 0 {
            if self.command_status & CLF == 0 {
                return;
            }
            self.command_status &= !CLF;
            self.control_current = self.control_head;
        }
        let mut found = false;
        for _ in 0..MAX_LIST_EDS {
            let address = self.control_current;
            if address == 0 {
                break;
            }
            if !self.check_descriptor("control ED", address) {
                self.control_current = 0;
                break;
            }
            found |= self.service_ed(address, CONTROL_TRANSACTIONS_PER_FRAME);
            self.control_current = self.peek(u64::from(address) + 12) & !0xF;
        }
        if self.control_current != 0 {
            self.error("the control list loops".into());
            self.control_current = 0;
        }
        if found {
            self.command_status |= CLF;
        }
    }

    /// Runs up to `transactions` transactions of the ED's queue; says
    /// whether it had a TD.
    fn service_ed(&mut self, ed: u32, transactions: usize) -> bool {
        let ed = u64::from(ed);
        let flags = self.peek(ed);
        if flags & ED_SKIP != 0 {
            return false;
        }
        let mut found = false;
        for _ in 0..transactions {
            let tail = self.peek(ed + 4) & !0xF;
            let head_word = self.peek(ed + 8);
            if head_word & ED_HALTED != 0 {
                return found;
            }
            let head = head_word & !0xF;
            if head == tail {
                return found;
            }
            found = true;
            if flags & ED_ISO != 0 {
                self.error(format!("ED {ed:#x} is isochronous"));
                return found;
            }
            if !self.check_descriptor("TailP", tail) || !self.check_descriptor("HeadP", head) {
                return found;
            }
            if !self.tail_reachable(head, tail) {
                self.error(format!(
                    "ED {ed:#x}: TailP {tail:#x} not reached from HeadP {head:#x}"
                ));
                return found;
            }
            match self.transaction(ed, flags, head_word, u64::from(head)) {
                Step::Continue | Step::Retired => {}
                Step::Stop => return found,
            }
        }
        found
    }

    fn tail_reachable(&mut self, head: u32, tail: u32) -> bool {
        let mut td = head;
        for _ in 0..MAX_QUEUE_TDS {
            if td == tail {
                return true;
            }
            if td % 16 != 0 || !Self::in_memory(u64::from(td), 16) {
                return false;
            }
            td = self.peek(u64::from(td) + 8) & !0xF;
        }
        false
    }

    /// The bytes from CurrentBufferPointer to BufferEnd (crossing at most
    /// one 4 KiB page, to BufferEnd's), and the address of byte `k` of them.
    fn buffer_length(&mut self, td: u64, start: u32, end: u32) -> Option<u32> {
        if start == 0 {
            return Some(0);
        }
        let length = if start & !0xFFF == end & !0xFFF {
            if end < start {
                self.error(format!(
                    "TD {td:#x}: BufferEnd {end:#x} before CBP {start:#x}"
                ));
                return None;
            }
            end - start + 1
        } else {
            (0x1000 - (start & 0xFFF)) + (end & 0xFFF) + 1
        };
        if length > 8192 {
            self.error(format!("TD {td:#x}: a buffer of {length} bytes"));
            return None;
        }
        Some(length)
    }

    fn buffer_address(start: u32, end: u32, offset: u32) -> u64 {
        let in_page = (start & 0xFFF) + offset;
        if in_page < 0x1000 {
            u64::from(start + offset)
        } else {
            u64::from((end & !0xFFF) + in_page - 0x1000)
        }
    }

    /// One transaction of the TD at the head of the ED's queue.
    fn transaction(&mut self, ed: u64, flags: u32, head_word: u32, td: u64) -> Step {
        let control = self.peek(td);
        let start = self.peek(td + 4);
        let end = self.peek(td + 12);
        let Some(length) = self.buffer_length(td, start, end) else {
            return self.retire(
                ed,
                head_word,
                td,
                control,
                start,
                CC_DATA_OVERRUN,
                None,
                true,
            );
        };
        if length > 0 && !Self::in_memory(u64::from(start), 1) {
            self.error(format!("TD {td:#x}: buffer {start:#x} outside memory"));
        }
        let max_packet = (flags >> 16) & 0x7FF;
        if max_packet == 0 {
            self.error(format!("ED {ed:#x}: MaximumPacketSize 0"));
            return Step::Stop;
        }
        let pid = match (flags >> 11) & 3 {
            1 => Pid::Out,
            2 => Pid::In,
            _ => match (control >> 19) & 3 {
                0 => Pid::Setup,
                1 => Pid::Out,
                2 => Pid::In,
                _ => {
                    self.error(format!("TD {td:#x}: reserved Direction/PID"));
                    return Step::Stop;
                }
            },
        };
        let toggle_field = (control >> 24) & 3;
        let toggle = if toggle_field & 2 != 0 {
            toggle_field & 1 != 0
        } else {
            head_word & ED_CARRY != 0
        };
        let size = length.min(max_packet);
        if pid == Pid::Setup && size != 8 {
            self.error(format!("TD {td:#x}: a SETUP of {size} bytes"));
        }
        let mut data = Vec::new();
        if pid != Pid::In {
            for k in 0..size {
                let address = Self::buffer_address(start, end, k);
                data.push(self.peek_byte(address));
            }
        }
        let packet = Packet {
            address: (flags & 0x7F) as u8,
            endpoint: ((flags >> 7) & 0xF) as u8,
            pid,
            toggle,
            data,
            max_packet: max_packet as usize,
            speed: if flags & ED_LOW_SPEED != 0 {
                Speed::Low
            } else {
                Speed::Full
            },
        };
        let reply = self.send(&packet);
        let errors = (control >> 26) & 3;
        // CurrentBufferPointer after `moved` bytes: 0 once all are.
        let advance = |moved: u32| -> (u32, bool) {
            if moved >= length {
                (0, true)
            } else {
                (Self::buffer_address(start, end, moved) as u32, false)
            }
        };
        match reply {
            Reply::Nak => Step::Stop,
            Reply::Stall => self.retire(
                ed,
                head_word,
                td,
                control,
                start,
                CC_STALL,
                Some(toggle),
                true,
            ),
            Reply::Timeout => self.count_error(
                ed,
                head_word,
                td,
                control,
                start,
                errors,
                CC_DEVICE_NOT_RESPONDING,
                toggle,
            ),
            Reply::Ack if pid != Pid::In => {
                let (pointer, done) = advance(size);
                let control = with_toggle(control, !toggle) & !(3 << 26);
                if done {
                    self.retire(
                        ed,
                        head_word,
                        td,
                        control,
                        pointer,
                        CC_NO_ERROR,
                        Some(!toggle),
                        false,
                    )
                } else {
                    self.poke(td, control);
                    self.poke(td + 4, pointer);
                    Step::Continue
                }
            }
            Reply::Data {
                bytes,
                toggle: sent,
            } if pid == Pid::In => {
                if sent != toggle {
                    // A repeat of a packet already taken: ACKed, dropped,
                    // and counted as an error (OHCI 4.3.1.3.5.2).
                    self.toggle_mismatches += 1;
                    return self.count_error(
                        ed,
                        head_word,
                        td,
                        control,
                        start,
                        errors,
                        CC_DATA_TOGGLE_MISMATCH,
                        toggle,
                    );
                }
                let got = bytes.len() as u32;
                if got > max_packet || got > length {
                    return self.retire(
                        ed,
                        head_word,
                        td,
                        control,
                        start,
                        CC_DATA_OVERRUN,
                        Some(toggle),
                        true,
                    );
                }
                for (k, &byte) in bytes.iter().enumerate() {
                    let address = Self::buffer_address(start, end, k as u32);
                    self.poke_byte(address, byte);
                }
                let (pointer, done) = advance(got);
                let control = with_toggle(control, !toggle) & !(3 << 26);
                if done {
                    self.retire(
                        ed,
                        head_word,
                        td,
                        control,
                        pointer,
                        CC_NO_ERROR,
                        Some(!toggle),
                        false,
                    )
                } else if got < max_packet {
                    if control & TD_ROUNDING != 0 {
                        self.retire(
                            ed,
                            head_word,
                            td,
                            control,
                            pointer,
                            CC_NO_ERROR,
                            Some(!toggle),
                            false,
                        )
                    } else {
                        self.retire(
                            ed,
                            head_word,
                            td,
                            control,
                            pointer,
                            CC_DATA_UNDERRUN,
                            Some(!toggle),
                            true,
                        )
                    }
                } else {
                    self.poke(td, control);
                    self.poke(td + 4, pointer);
                    Step::Continue
                }
            }
            other => {
                self.error(format!("TD {td:#x}: {pid:?} answered {other:?}"));
                self.retire(
                    ed,
                    head_word,
                    td,
                    control,
                    start,
                    CC_DEVICE_NOT_RESPONDING,
                    Some(toggle),
                    true,
                )
            }
        }
    }

    /// A transmission error: ErrorCount goes up, and at 3 the TD retires
    /// with `code` and the ED halts; before that it is tried again next
    /// time, with the code already written.
    #[allow(clippy::too_many_arguments)]
    fn count_error(
        &mut self,
        ed: u64,
        head_word: u32,
        td: u64,
        control: u32,
        pointer: u32,
        errors: u32,
        code: u32,
        toggle: bool,
    ) -> Step {
        let errors = errors + 1;
        let control = control & !(3 << 26) | (errors.min(3)) << 26;
        if errors >= 3 {
            self.retire(
                ed,
                head_word,
                td,
                control,
                pointer,
                code,
                Some(toggle),
                true,
            )
        } else {
            self.poke(td, control & !(0xF << 28) | code << 28);
            Step::Stop
        }
    }

    /// Retires the TD onto the done queue with `code`; the ED's HeadP moves
    /// to the next TD, with the toggle carry and, on an error, Halted.
    #[allow(clippy::too_many_arguments)]
    fn retire(
        &mut self,
        ed: u64,
        head_word: u32,
        td: u64,
        control: u32,
        pointer: u32,
        code: u32,
        toggle: Option<bool>,
        halt: bool,
    ) -> Step {
        let next = self.peek(td + 8) & !0xF;
        self.poke(td, control & !(0xF << 28) | code << 28);
        self.poke(td + 4, pointer);
        self.poke(td + 8, self.done_head);
        self.done_head = td as u32;
        let carry = match toggle {
            Some(true) => ED_CARRY,
            Some(false) => 0,
            None => head_word & ED_CARRY,
        };
        self.poke(ed + 8, next | carry | if halt { ED_HALTED } else { 0 });
        let delay = (control >> 21) & 7;
        if delay != 7 {
            self.done_counter = self.done_counter.min(delay);
        }
        if halt {
            Step::Stop
        } else {
            Step::Retired
        }
    }

    /// Sends the packet down every enabled root port: the one device at
    /// its address answers.
    fn send(&mut self, packet: &Packet) -> Reply {
        self.packets += 1;
        let mut answer = Reply::Timeout;
        for index in 0..self.ports.len() {
            let state = self.ports[index];
            if !state.enabled || state.suspended || !state.connected {
                continue;
            }
            let reply = self.tree.transact(index as u8 + 1, packet, None);
            if reply != Reply::Timeout {
                if answer != Reply::Timeout {
                    self.error(format!("two root ports answered {packet:?}"));
                }
                answer = reply;
            }
        }
        answer
    }

    // -----------------------------------------------------------------------
    // Registers.

    fn port_index(&self, offset: u32) -> Option<usize> {
        let index = (offset.checked_sub(0x54)? / 4) as usize;
        (index < self.ports.len()).then_some(index)
    }

    fn port_read(&self, index: usize) -> u32 {
        let state = self.ports[index];
        let low_speed =
            state.connected && self.tree.root_device(index as u8 + 1) == Some(Speed::Low);
        let powered = self.power_switching == PowerSwitching::None || state.powered_at.is_some();
        let bit = |on: bool, bit: u32| if on { bit } else { 0 };
        bit(state.connected, CCS)
            | bit(state.enabled, PES)
            | bit(state.suspended, PSS)
            | bit(state.reset_until.is_some(), PRS)
            | bit(powered, PPS)
            | bit(low_speed, LSDA)
            | state.changes
    }

    fn port_write(&mut self, index: usize, value: u32) {
        let connected = self.ports[index].connected;
        // Writes to a port with nothing attached set CSC instead (7.4.4).
        let attempt = |model: &mut OhciModel| {
            if !connected {
                model.raise_port_change(index, CSC);
            }
            connected
        };
        if value & CLEAR_PORT_ENABLE != 0 {
            self.ports[index].enabled = false;
        }
        if value & SET_PORT_ENABLE != 0 && attempt(self) {
            self.ports[index].enabled = true;
        }
        if value & SET_PORT_SUSPEND != 0 && attempt(self) {
            self.ports[index].suspended = true;
        }
        if value & CLEAR_SUSPEND_STATUS != 0 {
            self.ports[index].suspended = false;
        }
        if value & SET_PORT_RESET != 0 {
            self.port_resets_at.push((index as u8 + 1, self.now));
            if self.ports[index].reset_until.is_some() {
                self.error(format!("port {}: SetPortReset during a reset", index + 1));
            }
        }
        if value & SET_PORT_RESET != 0 && attempt(self) {
            self.ports[index].reset_until = Some(self.now + RESET_PULSE_MICROS);
            self.ports[index].enabled = false;
        }
        if value & SET_PORT_POWER != 0 && self.power_switching == PowerSwitching::PerPort {
            self.power_port(index, true);
        }
        if value & CLEAR_PORT_POWER != 0 && self.power_switching == PowerSwitching::PerPort {
            self.power_port(index, false);
        }
        self.ports[index].changes &= !(value & (CSC | PESC | PSSC | OCIC | PRSC));
        self.sync_ports();
    }

    fn write_control(&mut self, value: u32) {
        self.control_writes.push((self.now, value));
        let old = self.control;
        let mut new = value & 0x7FF;
        if old & HCFS == HCFS_OPERATIONAL && new & HCFS != HCFS_OPERATIONAL {
            self.halts_requested += 1;
            if self.never_halts {
                new = new & !HCFS | HCFS_OPERATIONAL;
            }
        }
        if new & HCFS == HCFS_OPERATIONAL && old & HCFS != HCFS_OPERATIONAL {
            let largest = (self.fm_interval >> 16) & 0x7FFF;
            if largest == 0 || self.periodic_start == 0 {
                self.error(format!(
                    "operational with HcFmInterval {:#x}, HcPeriodicStart {:#x}",
                    self.fm_interval, self.periodic_start
                ));
            }
            if self.hcca == 0 {
                self.error("operational with no HCCA".into());
            }
            self.next_frame = self.now + MICROS_PER_USB_FRAME;
            self.suspended_at = None;
        }
        if new & HCFS == HCFS_RESET && old & HCFS != HCFS_RESET {
            // UsbReset: the bus is reset, every port disabled.
            for index in 0..self.ports.len() {
                self.ports[index].enabled = false;
                self.ports[index].reset_until = None;
                if self.ports[index].connected {
                    self.tree.reset_root_port(index as u8 + 1);
                }
            }
        }
        self.control = new;
    }

    fn software_reset(&mut self) {
        self.software_resets += 1;
        self.software_resets_at.push(self.now);
        self.firmware_schedule = false;
        self.command_status = HCR;
        self.reset_until = Some(self.now + SOFTWARE_RESET_MICROS);
        // Every register but InterruptRouting, RemoteWakeupConnected and
        // the root hub's goes back to its reset value.
        self.control &= CONTROL_IR | CONTROL_RWC;
        self.interrupt_status = 0;
        self.interrupt_enable = 0;
        self.hcca = 0;
        self.control_head = 0;
        self.control_current = 0;
        self.bulk_head = 0;
        self.done_head = 0;
        self.done_counter = 7;
        self.fm_interval = FM_INTERVAL_DEFAULT;
        self.frame_number = 0;
        self.periodic_start = 0;
    }

    fn register_read(&mut self, offset: u32) -> u32 {
        match offset {
            0x00 => 0x10 | if self.smm_owned { 1 << 8 } else { 0 },
            0x04 => self.control,
            0x08 => self.command_status,
            0x0C => self.interrupt_status,
            0x10 | 0x14 => self.interrupt_enable,
            0x18 => self.hcca,
            0x1C => 0,
            0x20 => self.control_head,
            0x24 => self.control_current,
            0x28 => self.bulk_head,
            0x2C => 0,
            0x30 => self.done_head,
            0x34 => self.fm_interval,
            0x38 => {
                let left =
                    (self.next_frame.saturating_sub(self.now)).min(MICROS_PER_USB_FRAME) as u32;
                left * 12
            }
            0x3C => u32::from(self.frame_number),
            0x40 => self.periodic_start,
            0x44 => 0x628,
            0x48 => {
                let switching = match self.power_switching {
                    PowerSwitching::None => NPS,
                    PowerSwitching::Ganged => 0,
                    PowerSwitching::PerPort => PSM,
                };
                u32::from(self.reported_ports) | switching | u32::from(self.power_on_to_good) << 24
            }
            0x4C => match self.power_switching {
                PowerSwitching::PerPort => 0xFFFE << 16,
                _ => 0,
            },
            0x50 => 0,
            _ => match self.port_index(offset) {
                Some(index) => self.port_read(index),
                None => 0,
            },
        }
    }

    fn register_write(&mut self, offset: u32, value: u32) {
        if self.control & CONTROL_IR != 0 {
            let asks = (offset == 0x08 && value == OCR) || (offset == 0x10 && value == OC);
            if !asks {
                self.writes_while_owned.push((offset, value));
                // SMM would not notice: the write goes nowhere useful.
                return;
            }
        }
        match offset {
            0x04 => self.write_control(value),
            0x08 => {
                if value & HCR != 0 {
                    self.software_reset();
                }
                if value & OCR != 0 && self.control & CONTROL_IR != 0 {
                    self.ocr_at = Some(self.now);
                    self.command_status |= OCR;
                }
                self.command_status |= value & (CLF | BLF);
            }
            0x0C => self.interrupt_status &= !(value & INTERRUPT_SOURCES),
            0x10 => self.interrupt_enable |= value,
            0x14 => self.interrupt_enable &= !value,
            0x18 => {
                if value & 0xFF != 0 || !Self::in_memory(u64::from(value), 256) {
                    self.error(format!("HcHCCA {value:#x}: not 256-byte aligned in memory"));
                }
                self.hcca = value & !0xFF;
            }
            0x20 => {
                if value != 0 {
                    self.check_descriptor("HcControlHeadED", value);
                }
                self.control_head = value & !0xF;
            }
            0x24 => {
                if self.control & CONTROL_CLE != 0 {
                    self.error("HcControlCurrentED written with CLE set".into());
                }
                self.control_current = value & !0xF;
            }
            0x28 => self.bulk_head = value & !0xF,
            0x34 => {
                if (value ^ self.fm_interval) & (1 << 31) == 0 {
                    self.error("HcFmInterval written without toggling FIT".into());
                }
                self.fm_interval = value & 0xFFFF_3FFF;
            }
            0x40 => self.periodic_start = value & 0x3FFF,
            0x48 | 0x4C => self.error(format!("the driver rewrote HcRhDescriptor at {offset:#x}")),
            0x50 => {
                // SetGlobalPower and ClearGlobalPower reach ganged ports
                // only (every port is in PortPowerControlMask with PSM).
                if value & (1 << 16) != 0 && self.power_switching == PowerSwitching::Ganged {
                    for index in 0..self.ports.len() {
                        self.power_port(index, true);
                    }
                }
                if value & 1 != 0 && self.power_switching == PowerSwitching::Ganged {
                    for index in 0..self.ports.len() {
                        self.power_port(index, false);
                    }
                }
            }
            _ => {
                if let Some(index) = self.port_index(offset) {
                    self.port_write(index, value);
                }
            }
        }
    }
}

/// TD dword 0 after a packet: the toggle for the next one is the TD's
/// own from now on (T = 1x), whether it came from the TD or the ED.
fn with_toggle(control: u32, toggle: bool) -> u32 {
    control & !(3 << 24) | (2 | u32::from(toggle)) << 24
}

impl Memory for OhciModel {
    fn mem_read(&mut self, address: u64) -> u32 {
        assert!(
            Self::in_memory(address, 4) && address % 4 == 0,
            "the driver read {address:#x}, outside its DMA memory"
        );
        self.memory_reads += 1;
        self.memory[((address - DMA_BASE) / 4) as usize]
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        assert!(
            Self::in_memory(address, 4) && address % 4 == 0,
            "the driver wrote {address:#x}, outside its DMA memory"
        );
        self.check_driver_write(address);
        self.memory[((address - DMA_BASE) / 4) as usize] = value;
        // An ED the driver un-halts or un-skips is live again at once.
        let descriptor = address & !0xF;
        if address & 0xF != 4 && self.listed_eds.get(&descriptor) == Some(&true) {
            let flags = self.memory[((descriptor - DMA_BASE) / 4) as usize];
            let head = self.memory[((descriptor + 8 - DMA_BASE) / 4) as usize];
            if flags & ED_SKIP == 0 && head & ED_HALTED == 0 {
                self.listed_eds.insert(descriptor, false);
            }
        }
    }
}

impl Hardware for OhciModel {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        assert!(
            offset + 4 <= BAR_BYTES && offset % 4 == 0,
            "read outside the BAR: {offset:#x}"
        );
        self.now += MICROS_PER_REGISTER_READ;
        self.register_reads += 1;
        self.catch_up();
        self.register_read(offset)
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        assert!(
            offset + 4 <= BAR_BYTES && offset % 4 == 0,
            "write outside the BAR: {offset:#x}"
        );
        self.catch_up();
        self.register_write(offset, value);
    }
}

impl Platform for OhciModel {
    fn now_micros(&mut self) -> u64 {
        self.now += MICROS_PER_CLOCK_READ;
        self.catch_up();
        self.now
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.log.push(format!("{message}"));
    }
}

impl PciHardware for OhciModel {
    fn read16(&mut self, offset: u32) -> u16 {
        self.error(format!(
            "an I/O read at {offset:#x}: OHCI has no I/O registers"
        ));
        0xFFFF
    }

    fn write16(&mut self, offset: u32, _value: u16) {
        self.error(format!(
            "an I/O write at {offset:#x}: OHCI has no I/O registers"
        ));
    }

    fn pci_config_read(&mut self, offset: u8) -> u32 {
        match offset {
            // Class 0C03, prog-if 10h.
            0x08 => 0x0C03_1000,
            _ => 0,
        }
    }

    fn pci_config_write(&mut self, offset: u8, value: u32) {
        self.error(format!("PCI config write {value:#x} at {offset:#x}"));
    }
}
