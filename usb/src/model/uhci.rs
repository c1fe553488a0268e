//! A register model of a UHCI controller (PIIX3-like: I/O registers, LEGSUP
//! in PCI configuration space) over a simulated clock, for the host tests.
//! Every register read and clock read moves the clock on a little; each
//! time it passes a millisecond the model runs a frame: it reads the frame
//! list entry, walks the queue heads and executes their TDs against the
//! shared device tree ([`UsbTree::transact`]), writing status and ActLen
//! back as the hardware does (depth or breadth first, short packet detect,
//! three strikes for errors, NAK keeps a TD active, IN toggle mismatches
//! ACKed and dropped). It checks what the driver gives it — pointers inside
//! DMA memory, reserved bits, terminate bits, MaxLen, SETUP and control
//! stage toggles, the LS bit for low-speed devices, reset timings, LEGSUP
//! and PORTSC writes — and records every violation in `errors`. Knobs make
//! it misbehave: a BIOS that owns LEGSUP (and one that never lets go), a
//! controller that never halts or never ends its reset, port registers
//! that read nonsense, ports that refuse their first enables.

use super::devices::{Packet, Pid, Reply, UsbDevice, UsbTree};
use crate::host::Speed;
use crate::{Hardware, Memory, PciHardware, Platform};
use std::collections::BTreeMap;
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// Where the tests put the driver's DMA memory.
pub const DMA_BASE: u64 = 0x20_0000;
/// The 256 KiB the kernel gives each controller.
pub const DMA_BYTES: u64 = 256 * 1024;
/// What a register read or a clock read costs.
pub const MICROS_PER_READ: u64 = 2;
/// A frame.
pub const MICROS_PER_USB_FRAME: u64 = 1_000;
/// HCRESET takes this long to clear itself.
const HOST_RESET_TAKES: u64 = 20;
/// Where the BIOS's own frame list is (outside the driver's memory).
const BIOS_FRAME_LIST: u32 = 0x000F_0000;

const CMD_RUN: u16 = 1;
const CMD_HOST_RESET: u16 = 2;
const CMD_GLOBAL_RESET: u16 = 4;
const CMD_SOFTWARE_DEBUG: u16 = 1 << 5;
const STS_INTERRUPT: u16 = 1;
const STS_ERROR: u16 = 2;
const STS_HOST_SYSTEM_ERROR: u16 = 8;
const STS_PROCESS_ERROR: u16 = 0x10;
const STS_HALTED: u16 = 0x20;
const PORT_CONNECTED: u16 = 1;
const PORT_CONNECT_CHANGE: u16 = 2;
const PORT_ENABLED: u16 = 4;
const PORT_ENABLE_CHANGE: u16 = 8;
const PORT_D_PLUS: u16 = 0x10;
const PORT_D_MINUS: u16 = 0x20;
const PORT_ALWAYS_ONE: u16 = 0x80;
const PORT_LOW_SPEED: u16 = 0x100;
const PORT_RESET: u16 = 0x200;
const PORT_OVER_CURRENT_CHANGE: u16 = 0x800;
const PORT_STORED: u16 = PORT_CONNECT_CHANGE | PORT_ENABLED | PORT_ENABLE_CHANGE | PORT_RESET;

const LEGSUP_CLEAR: u16 = 0x8F00;
const LEGSUP_READ_ONLY: u16 = 0x5040;
const LEGSUP_WRITABLE: u16 = !(LEGSUP_CLEAR | LEGSUP_READ_ONLY);
/// The SMI enables a BIOS with keyboard emulation sets.
pub const BIOS_LEGSUP: u16 = 0x20BF | 0x0100;

const LINK_TERMINATE: u32 = 1;
const LINK_QH: u32 = 2;
const LINK_DEPTH: u32 = 4;
const TD_SPD: u32 = 1 << 29;
const TD_LOW_SPEED: u32 = 1 << 26;
const TD_ISOCHRONOUS: u32 = 1 << 25;
const TD_IOC: u32 = 1 << 24;
const TD_ACTIVE: u32 = 1 << 23;
const TD_STALLED: u32 = 1 << 22;
const TD_BABBLE: u32 = 1 << 20;
const TD_NAK: u32 = 1 << 19;
const TD_CRC_TIMEOUT: u32 = 1 << 18;

/// What one TD's transaction did to its queue.
enum Outcome {
    /// Done: the queue moves on to the TD's link.
    Advance,
    /// The queue stays on this TD (NAK, retry, error, short packet).
    Stop,
}

/// A control transfer's stages as the model saw them, per device address.
#[derive(Clone, Copy, Debug)]
struct ControlCheck {
    data_in: bool,
    /// wLength was not 0.
    had_data: bool,
    /// Data stage bytes not yet moved.
    remaining: usize,
    /// The toggle the next data packet must have.
    toggle: bool,
}

/// The model.
#[derive(Debug)]
pub struct UhciModel {
    /// The simulated clock, in microseconds (tests may move it on).
    pub now: u64,
    memory: Vec<u32>,
    /// The devices on the root ports.
    pub tree: UsbTree,
    ports: u8,

    // Knobs.
    /// The BIOS's SMM puts its SMI enables back whatever is written.
    pub bios_keeps_legsup: bool,
    /// HCHalted never comes, whatever Run/Stop says.
    pub never_halts: bool,
    /// HCRESET never clears.
    pub host_reset_stuck: bool,
    /// Frames run this many microseconds late (an emulator whose timer
    /// thread a busy host has not scheduled), until the clock passes it.
    pub frames_late_until: u64,
    /// Every port register reads this.
    pub port_nonsense: Option<u16>,
    /// The first this many Port Enabled writes after a port reset are
    /// ignored.
    pub port_enable_refusals: u32,
    /// Setting Port Reset on a connected port sets Connect Status Change,
    /// as Bochs 2.7's UHCI does (its reset reconnects the device, in
    /// uhci_core.cc); Linux's uhci_check_ports clears such changes when it
    /// ends the reset.
    pub reset_sets_connect_change: bool,

    // Registers.
    usbcmd: u16,
    usbsts: u16,
    usbintr: u16,
    frnum: u16,
    frbaseadd: u32,
    sofmod: u8,
    portsc: Vec<u16>,
    legsup: u16,
    legsup_above: u16,
    global_reset_since: Option<u64>,
    host_reset_until: Option<u64>,
    port_reset_since: Vec<Option<u64>>,
    refusals_left: Vec<u32>,
    next_frame_at: u64,
    /// The BIOS's schedule runs (until the driver resets the controller).
    bios_schedule: bool,
    control: BTreeMap<u8, ControlCheck>,

    // What happened.
    /// Every violation seen; a test asserts it is empty.
    pub errors: Vec<String>,
    /// The driver's log.
    pub log: Vec<String>,
    /// Frames the controller ran its schedule in.
    pub frames: u64,
    /// Register reads (I/O, FRBASEADD) by the driver.
    pub register_reads: u64,
    /// Register writes by the driver.
    pub register_writes: u64,
    /// DMA words the driver read.
    pub dma_reads: u64,
    /// Transactions put on the bus.
    pub transactions: u64,
    /// IN transactions on endpoints other than 0, by address and endpoint.
    pub interrupt_polls: BTreeMap<(u8, u8), u64>,
    /// IN packets dropped for a wrong data toggle (ACKed, TD kept active).
    pub toggle_mismatches: u32,
    /// Every LEGSUP value written (the low 16 bits).
    pub legsup_writes: Vec<u16>,
    /// The highest DMA address the driver touched, plus 4.
    pub dma_high_water: u64,
}

impl UhciModel {
    /// A controller with `ports` root ports (bit 7 reads 1 on each), as
    /// the firmware leaves it when it does not use it: halted, LEGSUP's
    /// PIRQ enable set.
    pub fn new(ports: u8) -> UhciModel {
        let ports_usize = usize::from(ports);
        UhciModel {
            now: 0,
            memory: vec![0; (DMA_BYTES / 4) as usize],
            tree: UsbTree::new(ports),
            ports,
            bios_keeps_legsup: false,
            never_halts: false,
            host_reset_stuck: false,
            frames_late_until: 0,
            port_nonsense: None,
            port_enable_refusals: 0,
            reset_sets_connect_change: false,
            usbcmd: 0,
            usbsts: STS_HALTED,
            usbintr: 0,
            frnum: 0,
            frbaseadd: 0,
            sofmod: 64,
            portsc: vec![0; ports_usize],
            legsup: 0x2000,
            legsup_above: 0,
            global_reset_since: None,
            host_reset_until: None,
            port_reset_since: vec![None; ports_usize],
            refusals_left: vec![0; ports_usize],
            next_frame_at: MICROS_PER_USB_FRAME,
            bios_schedule: false,
            control: BTreeMap::new(),
            errors: Vec::new(),
            log: Vec::new(),
            frames: 0,
            register_reads: 0,
            register_writes: 0,
            dma_reads: 0,
            transactions: 0,
            interrupt_polls: BTreeMap::new(),
            toggle_mismatches: 0,
            legsup_writes: Vec::new(),
            dma_high_water: 0,
        }
    }

    /// As a BIOS with USB keyboard emulation leaves it: SMI enables and a
    /// trap status bit set in LEGSUP, the controller running the BIOS's
    /// own frame list with interrupts enabled.
    pub fn owned_by_bios(ports: u8) -> UhciModel {
        let mut model = UhciModel::new(ports);
        model.legsup = BIOS_LEGSUP;
        model.usbcmd = CMD_RUN | 0x40 | 0x80;
        model.usbsts = 0;
        model.usbintr = 0xF;
        model.frbaseadd = BIOS_FRAME_LIST;
        model.bios_schedule = true;
        model
    }

    /// Plugs `device` at `path` (a root port's connect change if it is
    /// one); the tree's handle for it.
    pub fn plug(&mut self, path: &[u8], device: UsbDevice) -> usize {
        let handle = self.tree.plug(path, device);
        if let [port] = path {
            self.connect_changed(*port);
        }
        handle
    }

    /// Pulls out what is at `path` (a root port's connect change if it is
    /// one; the port is disabled).
    pub fn unplug(&mut self, path: &[u8]) {
        self.tree.unplug(path);
        if let [port] = path {
            self.connect_changed(*port);
        }
    }

    fn connect_changed(&mut self, port: u8) {
        let index = usize::from(port - 1);
        let stored = &mut self.portsc[index];
        *stored |= PORT_CONNECT_CHANGE;
        if *stored & PORT_ENABLED != 0 {
            *stored &= !PORT_ENABLED;
            *stored |= PORT_ENABLE_CHANGE;
        }
    }

    /// The controller hits a host system error (a PCI master abort): it
    /// halts, as the hardware does.
    pub fn host_system_error(&mut self) {
        self.usbsts |= STS_HOST_SYSTEM_ERROR | STS_HALTED;
        self.usbcmd &= !CMD_RUN;
    }

    /// USBCMD as the driver left it.
    pub fn usbcmd(&self) -> u16 {
        self.usbcmd
    }

    /// USBSTS.
    pub fn usbsts(&self) -> u16 {
        self.usbsts
    }

    /// USBINTR.
    pub fn usbintr(&self) -> u16 {
        self.usbintr
    }

    /// LEGSUP (the low 16 bits of the dword at 0xC0).
    pub fn legsup(&self) -> u16 {
        self.legsup_value()
    }

    /// SOFMOD.
    pub fn sofmod(&self) -> u8 {
        self.sofmod
    }

    /// FRBASEADD.
    pub fn frame_list(&self) -> u32 {
        self.frbaseadd
    }

    /// Whether the BIOS's schedule still runs.
    pub fn bios_schedule_runs(&self) -> bool {
        self.bios_schedule
    }

    fn error(&mut self, message: String) {
        if self.errors.len() < 100 {
            self.errors.push(message);
        }
    }

    /// A schedule the controller cannot follow: the hardware halts with
    /// a host controller process error.
    fn fault(&mut self, message: String) {
        self.error(message);
        self.usbsts |= STS_PROCESS_ERROR | STS_HALTED;
        self.usbcmd &= !CMD_RUN;
    }

    fn in_dma(address: u64, bytes: u64) -> bool {
        address >= DMA_BASE && address + bytes <= DMA_BASE + DMA_BYTES
    }

    fn word(&self, address: u64) -> usize {
        assert!(
            Self::in_dma(address, 4) && address % 4 == 0,
            "DMA access at {address:#x}, outside the driver's memory or unaligned"
        );
        ((address - DMA_BASE) / 4) as usize
    }

    /// The controller's own DMA (not counted as the driver's).
    fn hc_read(&self, address: u32) -> u32 {
        self.memory[self.word(u64::from(address))]
    }

    fn hc_write(&mut self, address: u32, value: u32) {
        let word = self.word(u64::from(address));
        self.memory[word] = value;
    }

    fn read_byte(&self, address: u32) -> u8 {
        let word = self.hc_read(address & !3);
        word.to_le_bytes()[(address & 3) as usize]
    }

    fn write_byte(&mut self, address: u32, byte: u8) {
        let mut word = self.hc_read(address & !3).to_le_bytes();
        word[(address & 3) as usize] = byte;
        self.hc_write(address & !3, u32::from_le_bytes(word));
    }

    /// Moves the clock on, running the frames it passes.
    fn tick(&mut self, micros: u64) {
        self.now += micros;
        self.catch_up();
    }

    /// Runs what the controller did while the clock moved on (a test may
    /// move it by hand): HCRESET's end, the frames passed.
    fn catch_up(&mut self) {
        if let Some(until) = self.host_reset_until {
            if self.now >= until {
                self.host_reset_until = None;
                self.usbcmd &= !CMD_HOST_RESET;
            }
        }
        while self.now >= self.next_frame_at.max(self.frames_late_until) {
            self.next_frame_at += MICROS_PER_USB_FRAME;
            self.frame();
        }
    }

    /// Everything a host controller reset (or the end of a global reset)
    /// puts back: registers to their defaults, every port disabled, a
    /// connected device seen as newly connected.
    fn reset_registers(&mut self) {
        self.usbcmd &= CMD_HOST_RESET | CMD_GLOBAL_RESET;
        self.usbsts = STS_HALTED;
        self.usbintr = 0;
        self.frnum = 0;
        self.frbaseadd = 0;
        self.sofmod = 64;
        self.bios_schedule = false;
        self.control.clear();
        for port in 1..=self.ports {
            let connected = self.tree.root_device(port).is_some();
            let index = usize::from(port - 1);
            self.portsc[index] = if connected { PORT_CONNECT_CHANGE } else { 0 };
            self.port_reset_since[index] = None;
        }
    }

    fn frame(&mut self) {
        if self.global_reset_since.is_some() || self.host_reset_until.is_some() {
            return;
        }
        let running = self.usbcmd & CMD_RUN != 0;
        if !running {
            if !self.never_halts {
                self.usbsts |= STS_HALTED;
            }
            return;
        }
        if self.usbsts & (STS_HOST_SYSTEM_ERROR | STS_PROCESS_ERROR) != 0 {
            return;
        }
        self.usbsts &= !STS_HALTED;
        if self.bios_schedule {
            self.frnum = (self.frnum + 1) & 0x7FF;
            return;
        }
        let list = self.frbaseadd;
        if list & 0xFFF != 0 || !Self::in_dma(u64::from(list), 4096) {
            self.fault(format!("running with FRBASEADD {list:#x}"));
            return;
        }
        self.frames += 1;
        let entry = list + 4 * u32::from(self.frnum & 0x3FF);
        let mut link = self.hc_read(entry);
        let mut visited: Vec<u32> = Vec::new();
        while link & LINK_TERMINATE == 0 {
            let Some(qh) = self.follow(link, "frame list or QH link") else {
                return;
            };
            if link & LINK_QH == 0 {
                self.fault(format!("a TD {qh:#x} where the driver keeps queue heads"));
                return;
            }
            if link & LINK_DEPTH != 0 {
                self.error(format!("QH link {link:#x} sets the TD-only depth bit"));
            }
            if visited.contains(&qh) {
                self.fault(format!("the schedule loops through QH {qh:#x}"));
                return;
            }
            if visited.len() > 200 {
                self.fault("the schedule never ends".into());
                return;
            }
            visited.push(qh);
            self.run_queue(qh);
            if self.usbcmd & CMD_RUN == 0 {
                return;
            }
            link = self.hc_read(qh);
        }
        self.frnum = (self.frnum + 1) & 0x7FF;
    }

    /// Checks a link pointer (T clear) and gives the address it names.
    fn follow(&mut self, link: u32, what: &str) -> Option<u32> {
        let address = link & !0xF;
        if link & 0x8 != 0 {
            self.fault(format!("{what} {link:#x} sets reserved bit 3"));
            return None;
        }
        if !Self::in_dma(u64::from(address), 16) {
            self.fault(format!("{what} {link:#x} points outside DMA memory"));
            return None;
        }
        Some(address)
    }

    /// Runs a queue head's TDs: depth first while the links say so.
    fn run_queue(&mut self, qh: u32) {
        let mut element = self.hc_read(qh + 4);
        for _ in 0..300 {
            if element & LINK_TERMINATE != 0 {
                return;
            }
            let Some(address) = self.follow(element, "QH element") else {
                return;
            };
            if element & LINK_QH != 0 {
                self.fault(format!("QH {qh:#x} holds a queue head {address:#x}"));
                return;
            }
            let control = self.hc_read(address + 4);
            if control & TD_ACTIVE == 0 {
                return;
            }
            match self.execute(address, control) {
                Outcome::Stop => return,
                Outcome::Advance => {
                    let next = self.hc_read(address);
                    self.hc_write(qh + 4, next);
                    if next & LINK_DEPTH == 0 {
                        return;
                    }
                    element = next;
                }
            }
        }
        self.fault(format!("QH {qh:#x}: a chain of TDs that never ends"));
    }

    /// One TD's transaction.
    fn execute(&mut self, td: u32, mut control: u32) -> Outcome {
        let token = self.hc_read(td + 8);
        let buffer = self.hc_read(td + 12);
        let pid = match token & 0xFF {
            0x2D => Pid::Setup,
            0x69 => Pid::In,
            0xE1 => Pid::Out,
            other => {
                self.fault(format!("TD {td:#x}: PID {other:#x}"));
                return Outcome::Stop;
            }
        };
        let length_field = token >> 21;
        let length = match length_field {
            0x7FF => 0,
            0..=0x4FF => length_field as usize + 1,
            _ => {
                self.fault(format!("TD {td:#x}: MaxLen {length_field:#x}"));
                return Outcome::Stop;
            }
        };
        if token & 1 << 20 != 0 {
            self.error(format!("TD {td:#x}: reserved token bit 20 set"));
        }
        let address = ((token >> 8) & 0x7F) as u8;
        let endpoint = ((token >> 15) & 0xF) as u8;
        let toggle = token & 1 << 19 != 0;
        let errors_left = (control >> 27) & 3;
        if errors_left == 0 {
            self.error(format!("TD {td:#x}: C_ERR 0 retries errors forever"));
        }
        if control & TD_ISOCHRONOUS != 0 {
            self.error(format!("TD {td:#x}: isochronous"));
        }
        if length > 0 && !Self::in_dma(u64::from(buffer), length as u64) {
            self.fault(format!(
                "TD {td:#x}: buffer {buffer:#x}+{length} outside DMA"
            ));
            return Outcome::Stop;
        }
        if pid == Pid::Setup && (length != 8 || toggle) {
            self.error(format!(
                "TD {td:#x}: SETUP of {length} bytes with DATA{}",
                toggle as u8
            ));
        }
        let data: Vec<u8> = match pid {
            Pid::In => Vec::new(),
            _ => (0..length as u32)
                .map(|i| self.read_byte(buffer + i))
                .collect(),
        };
        if endpoint == 0 {
            self.check_control(td, address, pid, toggle, &data, length);
        }
        let speed = if control & TD_LOW_SPEED != 0 {
            Speed::Low
        } else {
            Speed::Full
        };
        let packet = Packet {
            address,
            endpoint,
            pid,
            toggle,
            data,
            max_packet: length,
            speed,
        };
        self.transactions += 1;
        if endpoint != 0 && pid == Pid::In {
            *self.interrupt_polls.entry((address, endpoint)).or_default() += 1;
        }
        let reply = self.broadcast(&packet);
        let moved = match (pid, reply) {
            (_, Reply::Nak) => {
                self.hc_write(td + 4, control | TD_NAK);
                return Outcome::Stop;
            }
            (_, Reply::Stall) => {
                self.retire(td, control | TD_STALLED, true);
                return Outcome::Stop;
            }
            (_, Reply::Timeout) => {
                let left = errors_left.saturating_sub(1);
                control = (control & !(3 << 27)) | left << 27;
                if left == 0 {
                    self.retire(td, control | TD_CRC_TIMEOUT | TD_STALLED, true);
                } else {
                    self.hc_write(td + 4, control);
                }
                return Outcome::Stop;
            }
            (Pid::Setup | Pid::Out, Reply::Ack) => length,
            (
                Pid::In,
                Reply::Data {
                    bytes,
                    toggle: sent,
                },
            ) => {
                if bytes.len() > length {
                    self.retire(td, control | TD_BABBLE | TD_STALLED, true);
                    return Outcome::Stop;
                }
                if sent != toggle {
                    // The host ACKs and drops it; the TD stays active.
                    self.toggle_mismatches += 1;
                    return Outcome::Stop;
                }
                for (i, byte) in bytes.iter().enumerate() {
                    self.write_byte(buffer + i as u32, *byte);
                }
                bytes.len()
            }
            (pid, reply) => {
                self.error(format!("TD {td:#x}: {pid:?} answered {reply:?}"));
                self.retire(td, control | TD_STALLED, true);
                return Outcome::Stop;
            }
        };
        if endpoint == 0 {
            self.control_moved(address, pid, moved, length);
        }
        let actual = (moved as u32).wrapping_sub(1) & 0x7FF;
        control = (control & !(TD_ACTIVE | TD_NAK | 0x7FF)) | actual;
        self.hc_write(td + 4, control);
        if control & TD_IOC != 0 {
            self.usbsts |= STS_INTERRUPT;
        }
        if pid == Pid::In && moved < length && control & TD_SPD != 0 {
            // Short packet detect: the queue stays on this TD.
            self.usbsts |= STS_INTERRUPT;
            return Outcome::Stop;
        }
        Outcome::Advance
    }

    /// A TD ends in an error: inactive, the error interrupt raised.
    fn retire(&mut self, td: u32, control: u32, error: bool) {
        let control = control & !TD_ACTIVE;
        self.hc_write(td + 4, control);
        if error {
            self.usbsts |= STS_ERROR;
        }
        if control & TD_IOC != 0 {
            self.usbsts |= STS_INTERRUPT;
        }
    }

    /// The packet goes out on every enabled root port; the device that
    /// answers, answers. A low-speed device on a root port hears only
    /// low-speed packets (the tree checks every device's speed).
    fn broadcast(&mut self, packet: &Packet) -> Reply {
        for port in 1..=self.ports {
            if self.portsc[usize::from(port - 1)] & PORT_ENABLED == 0 {
                continue;
            }
            let reply = self.tree.transact(port, packet, None);
            if reply != Reply::Timeout {
                return reply;
            }
        }
        Reply::Timeout
    }

    /// Checks a transaction on endpoint 0 against its control transfer:
    /// SETUP first, data stage toggles from DATA1, a zero-length DATA1
    /// status stage in the other direction (IN when there is no data).
    fn check_control(
        &mut self,
        td: u32,
        address: u8,
        pid: Pid,
        toggle: bool,
        data: &[u8],
        length: usize,
    ) {
        if pid == Pid::Setup {
            if data.len() == 8 {
                let asked = usize::from(u16::from_le_bytes([data[6], data[7]]));
                self.control.insert(
                    address,
                    ControlCheck {
                        data_in: data[0] & 0x80 != 0,
                        had_data: asked > 0,
                        remaining: asked,
                        toggle: true,
                    },
                );
            }
            return;
        }
        let Some(check) = self.control.get(&address).copied() else {
            self.error(format!(
                "TD {td:#x}: {pid:?} on endpoint 0 of {address} with no SETUP"
            ));
            return;
        };
        let is_in = pid == Pid::In;
        if check.remaining > 0 && is_in == check.data_in {
            if toggle != check.toggle {
                self.error(format!(
                    "TD {td:#x}: control data {pid:?} with DATA{} where DATA{} is due",
                    toggle as u8, check.toggle as u8
                ));
            }
            return;
        }
        let status_in = !(check.data_in && check.had_data);
        if is_in != status_in || !toggle || length != 0 {
            self.error(format!(
                "TD {td:#x}: status stage {pid:?} DATA{} of {length} bytes after {} data",
                toggle as u8,
                if check.data_in { "IN" } else { "OUT" }
            ));
        }
    }

    /// Moves a control transfer's check on after a transaction went
    /// through: a data packet flips the toggle (a short one ends the data
    /// stage), the status stage ends the transfer.
    fn control_moved(&mut self, address: u8, pid: Pid, moved: usize, length: usize) {
        if pid == Pid::Setup {
            return;
        }
        let Some(check) = self.control.get_mut(&address) else {
            return;
        };
        let is_in = pid == Pid::In;
        if check.remaining > 0 && is_in == check.data_in {
            check.toggle = !check.toggle;
            check.remaining = if moved < length {
                0
            } else {
                check.remaining.saturating_sub(moved)
            };
        } else {
            self.control.remove(&address);
        }
    }

    fn legsup_value(&self) -> u16 {
        if self.bios_keeps_legsup {
            self.legsup | (BIOS_LEGSUP & LEGSUP_WRITABLE)
        } else {
            self.legsup
        }
    }

    fn port_value(&self, index: usize) -> u16 {
        if let Some(nonsense) = self.port_nonsense {
            return nonsense;
        }
        let port = index as u8 + 1;
        let mut value = self.portsc[index] | PORT_ALWAYS_ONE;
        match self.tree.root_device(port) {
            Some(Speed::Low) => value |= PORT_CONNECTED | PORT_LOW_SPEED | PORT_D_MINUS,
            Some(_) => value |= PORT_CONNECTED | PORT_D_PLUS,
            None => {}
        }
        if value & PORT_RESET != 0 {
            value &= !(PORT_D_PLUS | PORT_D_MINUS);
        }
        value
    }

    fn port_write(&mut self, index: usize, value: u16) {
        let port = index as u8 + 1;
        if value & 0xE000 != 0 {
            self.error(format!("PORTSC{port}: reserved bits written {value:#06x}"));
        }
        if value & PORT_OVER_CURRENT_CHANGE != 0 {
            self.error(format!(
                "PORTSC{port}: over-current change written 1 {value:#06x}"
            ));
        }
        let connected = self.tree.root_device(port).is_some();
        let mut stored = self.portsc[index];
        stored &= !(value & (PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE));
        let was_reset = stored & PORT_RESET != 0;
        let reset = value & PORT_RESET != 0;
        if reset && !was_reset {
            stored = (stored | PORT_RESET) & !PORT_ENABLED;
            if connected && self.reset_sets_connect_change {
                stored |= PORT_CONNECT_CHANGE;
            }
            self.port_reset_since[index] = Some(self.now);
        } else if !reset && was_reset {
            stored &= !PORT_RESET;
            let held = self.port_reset_since[index]
                .take()
                .map_or(0, |since| self.now - since);
            if held < 10_000 {
                self.error(format!("PORTSC{port}: reset held only {held} us"));
            }
            if connected {
                self.tree.reset_root_port(port);
            }
            self.refusals_left[index] = self.port_enable_refusals;
        }
        if value & PORT_ENABLED != 0 {
            if stored & PORT_ENABLED == 0 {
                if !connected || stored & PORT_RESET != 0 {
                    // The hardware does not enable it.
                } else if self.refusals_left[index] > 0 {
                    self.refusals_left[index] -= 1;
                } else {
                    stored |= PORT_ENABLED;
                }
            }
        } else {
            stored &= !PORT_ENABLED;
        }
        self.portsc[index] = stored & PORT_STORED;
    }

    fn command_write(&mut self, value: u16) {
        let old = self.usbcmd;
        if value & CMD_SOFTWARE_DEBUG != 0 {
            self.error(format!("USBCMD {value:#06x}: software debug mode"));
        }
        if value & CMD_GLOBAL_RESET != 0 {
            if old & CMD_GLOBAL_RESET == 0 {
                self.global_reset_since = Some(self.now);
            }
            self.usbcmd = value;
            return;
        }
        if old & CMD_GLOBAL_RESET != 0 {
            let held = self
                .global_reset_since
                .take()
                .map_or(0, |since| self.now - since);
            if held < 10_000 {
                self.error(format!("global reset held only {held} us"));
            }
            self.usbcmd = 0;
            self.reset_registers();
            for port in 1..=self.ports {
                if self.tree.root_device(port).is_some() {
                    self.tree.reset_root_port(port);
                }
            }
        }
        if value & CMD_HOST_RESET != 0 {
            self.usbcmd = CMD_HOST_RESET;
            self.reset_registers();
            self.host_reset_until = if self.host_reset_stuck {
                Some(u64::MAX)
            } else {
                Some(self.now + HOST_RESET_TAKES)
            };
            return;
        }
        if self.host_reset_until.is_some() {
            self.error(format!("USBCMD {value:#06x} written during HCRESET"));
        }
        if value & CMD_RUN != 0 && old & CMD_RUN == 0 && self.usbsts & STS_HALTED != 0 {
            let list = self.frbaseadd;
            if list & 0xFFF != 0 || !Self::in_dma(u64::from(list), 4096) {
                self.error(format!("Run/Stop set with FRBASEADD {list:#x}"));
            }
        }
        self.usbcmd = value;
    }
}

impl Memory for UhciModel {
    fn mem_read(&mut self, address: u64) -> u32 {
        self.catch_up();
        self.dma_reads += 1;
        self.dma_high_water = self.dma_high_water.max(address + 4);
        self.memory[self.word(address)]
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        self.catch_up();
        self.dma_high_water = self.dma_high_water.max(address + 4);
        let word = self.word(address);
        self.memory[word] = value;
    }
}

impl Hardware for UhciModel {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        self.register_reads += 1;
        self.tick(MICROS_PER_READ);
        if offset != 0x08 {
            self.error(format!("32-bit read at {offset:#x}: only FRBASEADD is"));
            return 0;
        }
        self.frbaseadd
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        self.register_writes += 1;
        if offset != 0x08 {
            self.error(format!("32-bit write at {offset:#x}: only FRBASEADD is"));
            return;
        }
        if self.usbsts & STS_HALTED == 0 {
            self.error(format!("FRBASEADD written while running: {value:#x}"));
        }
        if value & 0xFFF != 0 {
            self.error(format!("FRBASEADD {value:#x} not 4 KiB aligned"));
        }
        self.frbaseadd = value & !0xFFF;
        self.bios_schedule = false;
    }
}

impl Platform for UhciModel {
    fn now_micros(&mut self) -> u64 {
        self.tick(MICROS_PER_READ);
        self.now
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.log.push(format!("{message}"));
    }
}

impl PciHardware for UhciModel {
    fn read16(&mut self, offset: u32) -> u16 {
        self.register_reads += 1;
        self.tick(MICROS_PER_READ);
        if offset % 2 != 0 || offset >= 0x20 {
            self.error(format!("16-bit read at {offset:#x}"));
            return 0xFFFF;
        }
        match offset {
            0x00 => self.usbcmd,
            0x02 => self.usbsts,
            0x04 => self.usbintr,
            0x06 => self.frnum,
            0x08 | 0x0A => {
                self.error("FRBASEADD read 16 bits at a time".into());
                0
            }
            0x0C => u16::from(self.sofmod),
            o if o >= 0x10 => {
                let index = ((o - 0x10) / 2) as usize;
                if index < usize::from(self.ports) {
                    self.port_value(index)
                } else {
                    0
                }
            }
            _ => 0,
        }
    }

    fn write16(&mut self, offset: u32, value: u16) {
        self.register_writes += 1;
        if offset % 2 != 0 || offset >= 0x20 {
            self.error(format!("16-bit write at {offset:#x}"));
            return;
        }
        match offset {
            0x00 => self.command_write(value),
            0x02 => self.usbsts &= !(value & 0x1F),
            0x04 => self.usbintr = value & 0xF,
            0x06 => {
                if self.usbsts & STS_HALTED == 0 {
                    self.error("FRNUM written while running".into());
                }
                self.frnum = value & 0x7FF;
            }
            0x08 | 0x0A => self.error("FRBASEADD written 16 bits at a time".into()),
            0x0C => self.error(format!("SOFMOD written: {value:#x}")),
            o if o >= 0x10 => {
                let index = ((o - 0x10) / 2) as usize;
                if index < usize::from(self.ports) {
                    self.port_write(index, value);
                } else {
                    self.error(format!("write to port register {o:#x}: no such port"));
                }
            }
            o => self.error(format!("write to reserved register {o:#x}")),
        }
    }

    fn pci_config_read(&mut self, offset: u8) -> u32 {
        match offset {
            0x00 => 0x7020_8086,
            0x08 => 0x0C03_0001,
            0x60 => 0x10,
            0xC0 => u32::from(self.legsup_above) << 16 | u32::from(self.legsup_value()),
            _ => 0,
        }
    }

    fn pci_config_write(&mut self, offset: u8, value: u32) {
        if offset != 0xC0 {
            self.error(format!("PCI configuration write at {offset:#x}"));
            return;
        }
        if (value >> 16) as u16 != self.legsup_above {
            self.error(format!("LEGSUP's dword: upper half changed: {value:#x}"));
        }
        let low = value as u16;
        self.legsup_writes.push(low);
        let mut legsup = self.legsup;
        legsup &= !(low & LEGSUP_CLEAR);
        legsup = (legsup & !LEGSUP_WRITABLE) | (low & LEGSUP_WRITABLE);
        self.legsup = legsup;
    }
}
