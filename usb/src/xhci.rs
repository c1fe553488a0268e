//! The xHCI controller, polled: no interrupts, MSI or IOAPIC routing. The
//! kernel calls [`Xhci::poll`] from its loops; every wait in here is bounded
//! by the clock, every index the controller or a device gives is checked,
//! and every failure is an [`XhciError`] the caller logs and survives.

use super::context::{
    endpoint_type, interrupt_interval, speed, ContextLayout, EndpointContext, SlotContext,
};
use super::descriptor::{self, Function, InterruptIn};
use super::hid::{self, Decoded, KeySet, KeyboardLayout};
use super::report::{self, BootKeyboard};
use super::ring::{trb_type, EventRing, ProducerRing, Trb};
use super::Hardware;
// TRBs are built with the `xhci` crate's layouts; the rings here own the
// cycle bit.
use xhci::ring::trb::{command, transfer};

mod enumeration;
mod host;
#[cfg(test)]
mod host_tests;
pub use enumeration::BOOT_ENUMERATION_MICROS;
pub use host::HOST_DEVICES;

/// Bytes in a page: DMA memory is handed out a page at a time.
pub const PAGE_BYTES: u64 = 4096;
/// TRBs in the command and event rings (one page each).
const RING_TRBS: u16 = 256;
/// TRBs in a keyboard's interrupt ring, each with a 64-byte report buffer
/// (together one page).
const INTERRUPT_RING_TRBS: u16 = 64;
const REPORT_BUFFER_BYTES: u64 = 64;
/// Normal TRBs kept queued on a keyboard's interrupt endpoint.
const QUEUED_REPORTS: u16 = 16;
/// Keyboards are polled every 2^3 x 125 us = 1 ms, however slowly they
/// ask to be: a host may poll an interrupt endpoint more often than its
/// bInterval (USB 2.0 5.7.4), and keys then wait at most 1 ms, not 8-10.
const KEYBOARD_INTERVAL: u8 = 3;
/// Devices (slots) this driver keeps: a hub and keyboards.
pub const MAX_DEVICES: usize = 8;
/// Slots enabled in CONFIG (the DCBAA has this many entries plus one).
const MAX_SLOTS: u8 = 16;
/// Events handled in one poll, so a controller that floods cannot stall the loop.
const EVENTS_PER_POLL: u32 = 64;
/// The largest configuration descriptor read.
const CONFIGURATION_BYTES: u16 = 1024;

/// How long the firmware gets to let go of the controller.
pub const HANDOFF_MICROS: u64 = 1_000_000;
const HALT_MICROS: u64 = 50_000;
/// How long Controller Not Ready and the reset may take.
pub const RESET_MICROS: u64 = 500_000;
/// How long the No Op at start may take (a check that the rings work).
const NO_OP_MICROS: u64 = 300_000;
/// How long each command of a keyboard's recovery may take.
const RECOVERY_MICROS: u64 = 300_000;

// Capability registers.
const CAPLENGTH: u32 = 0x00;
const HCSPARAMS1: u32 = 0x04;
const HCSPARAMS2: u32 = 0x08;
const HCCPARAMS1: u32 = 0x10;
const DBOFF: u32 = 0x14;
const RTSOFF: u32 = 0x18;
// Operational registers, from the operational base.
const USBCMD: u32 = 0x00;
const USBSTS: u32 = 0x04;
const PAGESIZE: u32 = 0x08;
const CRCR: u32 = 0x18;
const DCBAAP: u32 = 0x30;
const CONFIG: u32 = 0x38;
const PORTSC: u32 = 0x400;
// Interrupter 0, from the runtime base.
const ERSTSZ: u32 = 0x28;
const ERSTBA: u32 = 0x30;
const ERDP: u32 = 0x38;

const CMD_RUN: u32 = 1 << 0;
const CMD_RESET: u32 = 1 << 1;
const STS_HALTED: u32 = 1 << 0;
const STS_NOT_READY: u32 = 1 << 11;
const ERDP_BUSY: u32 = 1 << 3;
/// CRCR's Command Abort bit.
const CRCR_COMMAND_ABORT: u32 = 1 << 2;

const PORT_CONNECTED: u32 = 1 << 0;
const PORT_ENABLED: u32 = 1 << 1;
const PORT_RESET: u32 = 1 << 4;
const PORT_POWER: u32 = 1 << 9;
const PORT_RESET_CHANGE: u32 = 1 << 21;
const PORT_CONNECT_CHANGE: u32 = 1 << 17;
/// The write-1-to-clear change bits (CSC, PEC, WRC, OCC, PRC, PLC, CEC).
const PORT_CHANGES: u32 = 0x7F << 17;

/// The USB Legacy Support extended capability.
const CAP_LEGACY: u32 = 1;
/// The Supported Protocol extended capability.
const CAP_PROTOCOL: u32 = 2;
const LEGACY_BIOS_OWNED: u32 = 1 << 16;
const LEGACY_OS_OWNED: u32 = 1 << 24;
/// USBLEGCTLSTS: the SMI enables (USB, host system error, OS ownership
/// change, PCI command, BAR) and the write-1-to-clear SMI status bits.
const LEGACY_SMI_ENABLES: u32 = (1 << 0) | (1 << 4) | (1 << 13) | (1 << 14) | (1 << 15);
const LEGACY_SMI_STATUS: u32 = (1 << 29) | (1 << 30) | (1 << 31);

const COMPLETION_SUCCESS: u8 = 1;
const COMPLETION_SHORT_PACKET: u8 = 13;
const COMPLETION_STALL: u8 = 6;
const COMPLETION_CONTEXT_STATE: u8 = 19;
const COMPLETION_COMMAND_RING_STOPPED: u8 = 24;

/// Why a step failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum XhciError {
    /// A register offset the capabilities give lies outside BAR0.
    RegistersOutsideBar,
    /// The controller does not do 4 KiB pages.
    PageSize(u32),
    /// The DMA region is used up (scratchpads, or too many devices).
    OutOfDmaMemory,
    /// The controller did not halt.
    NotHalted,
    /// HCRST or Controller Not Ready never cleared.
    NotReady,
    /// The controller did not start running.
    NotRunning,
    /// A command got no completion in time.
    CommandTimeout(u32),
    /// A command completed with an error code.
    CommandFailed(u32, u8),
    /// A control transfer got no completion in time.
    TransferTimeout,
    /// A transfer completed with an error code (6 is a stall).
    TransferFailed(u8),
    /// A descriptor that makes no sense.
    Descriptor(descriptor::DescriptorError),
    /// The controller gave a slot ID outside what was enabled.
    BadSlot(u8),
    /// More devices than this driver keeps.
    TooManyDevices,
    /// The device being enumerated was let go of in the meantime (pulled
    /// out, or its hub was).
    Gone,
    /// A port reset did not finish, or left the port disabled.
    PortReset,
}

impl core::fmt::Display for XhciError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            XhciError::RegistersOutsideBar => write!(f, "registers lie outside BAR0"),
            XhciError::PageSize(p) => write!(f, "no 4 KiB pages (PAGESIZE {p:#x})"),
            XhciError::OutOfDmaMemory => write!(f, "out of DMA memory"),
            XhciError::NotHalted => write!(f, "the controller did not halt"),
            XhciError::NotReady => {
                write!(f, "the controller stayed not ready (CNR) after its reset")
            }
            XhciError::NotRunning => write!(f, "the controller did not start"),
            XhciError::CommandTimeout(t) => write!(f, "command (TRB type {t}) not completed"),
            XhciError::CommandFailed(t, c) => {
                write!(f, "command (TRB type {t}) failed with completion code {c}")
            }
            XhciError::TransferTimeout => write!(f, "control transfer not completed"),
            XhciError::TransferFailed(c) => {
                write!(f, "transfer failed with completion code {c}")
            }
            XhciError::Descriptor(e) => write!(f, "{e}"),
            XhciError::BadSlot(s) => write!(f, "the controller gave slot {s}"),
            XhciError::TooManyDevices => write!(f, "too many devices"),
            XhciError::Gone => write!(f, "the device went away during its enumeration"),
            XhciError::PortReset => write!(f, "port reset failed"),
        }
    }
}

impl From<descriptor::DescriptorError> for XhciError {
    fn from(e: descriptor::DescriptorError) -> Self {
        XhciError::Descriptor(e)
    }
}

type Result<T> = core::result::Result<T, XhciError>;

/// How the firmware let go of the controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handoff {
    /// No USB Legacy Support capability: the firmware never had it.
    NoLegacyCapability,
    /// BIOS-owned was already clear.
    NotOwned,
    /// The firmware cleared BIOS-owned after this many microseconds.
    Released(u64),
    /// The firmware never let go within [`HANDOFF_MICROS`]: BIOS-owned was
    /// cleared by the driver.
    Forced,
}

/// Where a device hangs: a root port, and the hub ports on the way down.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    /// The root hub port, 1-based.
    pub root_port: u8,
    /// The route string: the port on each hub tier below the root port,
    /// four bits a tier, the first tier lowest (0: the root port itself).
    pub route: u32,
}

/// Hub tiers below the root hub a route string can name (USB 2.0 and
/// xHCI: five, four bits each).
pub const MAX_HUB_TIERS: u32 = 5;

impl Location {
    /// The hub tiers between the root port and the device.
    pub fn depth(&self) -> u32 {
        (0..MAX_HUB_TIERS)
            .take_while(|tier| (self.route >> (4 * tier)) & 0xF != 0)
            .count() as u32
    }

    /// Port `port` of the hub at this location.
    fn below(&self, port: u8) -> Location {
        Location {
            root_port: self.root_port,
            route: self.route | u32::from(port & 0xF) << (4 * self.depth()),
        }
    }
}

impl core::fmt::Display for Location {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}", self.root_port)?;
        for tier in 0..self.depth() {
            write!(f, ".{}", (self.route >> (4 * tier)) & 0xF)?;
        }
        Ok(())
    }
}

/// A device with a slot.
#[derive(Clone, Debug)]
struct Device {
    slot: u8,
    location: Location,
    speed: u32,
    output: u64,
    input: u64,
    buffer: u64,
    ep0: ProducerRing,
    slot_context: SlotContext,
    keyboard: Option<Keyboard>,
    hub: Option<Hub>,
}

/// A configured hub's status change endpoint.
#[derive(Clone, Debug)]
struct Hub {
    ports: u8,
    /// The endpoint's device context index (0: none, nothing plugged in
    /// later is seen).
    dci: u8,
    ring: ProducerRing,
    /// The page its reports land in.
    buffer: u64,
}

/// How a keyboard's reports are read.
// The layout lives in the keyboard itself: the driver has no allocator to
// box it in, and a keyboard is a few of these at most.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
enum ReportFormat {
    /// The boot report, exactly 8 bytes (the keyboard was put in the boot
    /// protocol because its report descriptor could not be read).
    Boot,
    /// As its report descriptor lays them out (report protocol).
    Described(KeyboardLayout),
}

/// Where a keyboard's report endpoint stands: running, or a step of its
/// recovery after a failed transfer (each with the TRB whose event ends the
/// step, and when it began).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Recovery {
    Running,
    ResettingEndpoint {
        command: u64,
        since: u64,
        stalled: bool,
    },
    SettingDequeue {
        command: u64,
        since: u64,
        stalled: bool,
    },
    ClearingHalt {
        status: u64,
        since: u64,
    },
}

impl Recovery {
    fn command(&self) -> Option<u64> {
        match *self {
            Recovery::ResettingEndpoint { command, .. }
            | Recovery::SettingDequeue { command, .. } => Some(command),
            _ => None,
        }
    }

    fn since(&self) -> Option<u64> {
        match *self {
            Recovery::Running => None,
            Recovery::ResettingEndpoint { since, .. }
            | Recovery::SettingDequeue { since, .. }
            | Recovery::ClearingHalt { since, .. } => Some(since),
        }
    }
}

/// Failed reports in a row after which a keyboard is given up (a device
/// that fails every transfer is gone or broken; hot-plug finds it again).
const MAX_RECOVERIES: u32 = 8;

/// Report IDs whose keys are kept apart (a keyboard may split its keys over
/// several numbered reports; the keys down are the union).
const KEY_REPORTS: usize = 4;

/// A configured keyboard's interrupt endpoint.
#[derive(Clone, Debug)]
struct Keyboard {
    dci: u8,
    ring: ProducerRing,
    reports: u64,
    report_bytes: u32,
    format: ReportFormat,
    /// The keys each report ID last said are down.
    keys_by_report: [(u8, KeySet); KEY_REPORTS],
    state: BootKeyboard,
    /// Reports that could not be read, dropped.
    dropped: u32,
    recovery: Recovery,
    /// Failed transfers since the last good report.
    failures_in_a_row: u32,
    failed: bool,
}

impl Keyboard {
    /// Takes one report: gives the keys now down, or why it changes nothing.
    fn keys(&mut self, report: &[u8]) -> core::result::Result<KeySet, Decoded> {
        match &self.format {
            ReportFormat::Boot if report.len() == report::REPORT_BYTES => {
                report::boot_report_keys(report).ok_or(Decoded::Rollover)
            }
            ReportFormat::Boot => Err(Decoded::Unreadable),
            ReportFormat::Described(layout) => match layout.decode(report) {
                Decoded::Keys { report_id, keys } => {
                    let slot = match self
                        .keys_by_report
                        .iter()
                        .position(|&(id, _)| id == report_id)
                    {
                        Some(slot) => slot,
                        None => self
                            .keys_by_report
                            .iter()
                            .position(|&(id, _)| id == u8::MAX)
                            .ok_or(Decoded::Unreadable)?,
                    };
                    self.keys_by_report[slot] = (report_id, keys);
                    Ok(self
                        .keys_by_report
                        .iter()
                        .filter(|&&(id, _)| id != u8::MAX)
                        .fold(KeySet::default(), |all, (_, keys)| all.union(keys)))
                }
                other => Err(other),
            },
        }
    }
}

/// A bump allocator of zeroed pages in the DMA region, with the pages of
/// devices pulled out kept for the next ones (a KVM switched back and
/// forth all day must not run the region dry).
#[derive(Clone, Copy, Debug)]
struct Pages {
    next: u64,
    end: u64,
    freed: [u64; FREED_PAGES],
    freed_count: usize,
}

/// Pages of departed devices kept for reuse: a hub tree's worth.
const FREED_PAGES: usize = 64;

/// What the capability registers say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capabilities {
    /// Root hub ports.
    pub ports: u8,
    /// Device slots.
    pub slots: u8,
    /// Scratchpad pages the controller wants.
    pub scratchpads: u32,
    /// 64-bit addressing (AC64).
    pub addressing_64: bool,
    /// The context layout (CSZ).
    pub layout: ContextLayout,
}

/// Ranges of root ports by USB major revision (Supported Protocol capabilities).
#[derive(Clone, Copy, Debug, Default)]
struct PortProtocols {
    ranges: [(u8, u8, u8); 4],
    count: usize,
}

impl PortProtocols {
    fn major(&self, port: u8) -> Option<u8> {
        self.ranges[..self.count]
            .iter()
            .find(|&&(_, first, count)| {
                port >= first && u16::from(port) < u16::from(first) + u16::from(count)
            })
            .map(|&(major, _, _)| major)
    }
}

/// A USB control request's setup packet.
#[derive(Clone, Copy, Debug)]
struct Setup {
    request_type: u8,
    request: u8,
    value: u16,
    index: u16,
    length: u16,
}

const GET_STATUS: u8 = 0;
const CLEAR_FEATURE: u8 = 1;
const SET_FEATURE: u8 = 3;
const GET_DESCRIPTOR: u8 = 6;
const SET_CONFIGURATION: u8 = 9;
const HID_SET_IDLE: u8 = 0x0A;
const HID_SET_PROTOCOL: u8 = 0x0B;
const PROTOCOL_BOOT: u16 = 0;
const PROTOCOL_REPORT: u16 = 1;
const ENDPOINT_HALT: u16 = 0;
const HUB_PORT_RESET: u16 = 4;
const HUB_PORT_POWER: u16 = 8;
const HUB_C_PORT_RESET_FEATURE: u16 = 20;
/// SET_HUB_DEPTH (USB 3.2 10.16.2.9): a SuperSpeed hub's tier, for the
/// route string it reads.
const SET_HUB_DEPTH: u8 = 12;

/// The controller and what hangs on it.
#[derive(Debug)]
pub struct Xhci<H: Hardware> {
    hw: H,
    mmio_bytes: u32,
    operational: u32,
    runtime: u32,
    doorbells: u32,
    capabilities: Capabilities,
    extended_capabilities: u32,
    pages: Pages,
    dcbaa: u64,
    commands: Option<ProducerRing>,
    events: Option<EventRing>,
    protocols: PortProtocols,
    devices: [Option<Device>; MAX_DEVICES],
    /// Ports and hubs waiting for their turn to be enumerated.
    queue: enumeration::WorkQueue,
    /// The enumeration in progress, a step per poll.
    enumeration: Option<enumeration::Enumeration>,
    /// When the root ports are first looked at.
    scan_at: Option<u64>,
    /// Scancodes of keys let go by a step (a keyboard behind a hub pulled
    /// out), handed on by the poll that ran it.
    released: [u8; RELEASED_BYTES],
    released_count: usize,
    /// What the [`crate::host::HostController`] side keeps (devices by
    /// handle, their commands and pipes); unused by [`Xhci::poll`].
    host: host::HostState,
}

/// Room for the releases of every key a keyboard can hold down (each up
/// to 4 bytes with its prefixes), a few keyboards' worth.
const RELEASED_BYTES: usize = 256;

impl<H: Hardware> Xhci<H> {
    /// Reads the capability registers of a controller whose BAR0 is
    /// `mmio_bytes` long; DMA memory is `dma_bytes` at physical `dma_base`
    /// (page-aligned, below 4 GiB unless the controller has AC64).
    pub fn new(mut hw: H, mmio_bytes: u32, dma_base: u64, dma_bytes: u64) -> Result<Self> {
        let read = |hw: &mut H, offset: u32| {
            if offset.checked_add(4).is_some_and(|end| end <= mmio_bytes) {
                hw.mmio_read(offset)
            } else {
                u32::MAX
            }
        };
        let caplength = read(&mut hw, CAPLENGTH) & 0xFF;
        let hcsparams1 = read(&mut hw, HCSPARAMS1);
        let hcsparams2 = read(&mut hw, HCSPARAMS2);
        let hccparams1 = read(&mut hw, HCCPARAMS1);
        let doorbells = read(&mut hw, DBOFF) & !0x3;
        let runtime = read(&mut hw, RTSOFF) & !0x1F;
        let capabilities = Capabilities {
            slots: hcsparams1 as u8,
            ports: (hcsparams1 >> 24) as u8,
            scratchpads: ((hcsparams2 >> 21) & 0x1F) << 5 | (hcsparams2 >> 27),
            addressing_64: hccparams1 & 1 != 0,
            layout: ContextLayout::new(hccparams1 & (1 << 2) != 0),
        };
        let operational = caplength;
        // Every register the driver will touch must lie inside the BAR.
        let fits = |start: u32, bytes: u64| u64::from(start) + bytes <= u64::from(mmio_bytes);
        if caplength < 0x20
            || !fits(
                operational,
                u64::from(PORTSC) + 0x10 * u64::from(capabilities.ports),
            )
            || !fits(runtime, 0x40)
            || !fits(doorbells, 4 * (u64::from(MAX_SLOTS) + 1))
            || capabilities.slots == 0
            || capabilities.ports == 0
        {
            return Err(XhciError::RegistersOutsideBar);
        }
        let first = dma_base.div_ceil(PAGE_BYTES) * PAGE_BYTES;
        Ok(Xhci {
            hw,
            mmio_bytes,
            operational,
            runtime,
            doorbells,
            capabilities,
            extended_capabilities: (hccparams1 >> 16) << 2,
            pages: Pages {
                next: first,
                end: dma_base + dma_bytes,
                freed: [0; FREED_PAGES],
                freed_count: 0,
            },
            dcbaa: 0,
            commands: None,
            events: None,
            protocols: PortProtocols::default(),
            devices: Default::default(),
            queue: enumeration::WorkQueue::default(),
            enumeration: None,
            scan_at: None,
            released: [0; RELEASED_BYTES],
            released_count: 0,
            host: host::HostState::new(),
        })
    }

    /// What the capability registers said.
    pub fn capabilities(&self) -> Capabilities {
        self.capabilities
    }

    /// The hardware, for the caller's checks (the host tests' model).
    pub fn hardware(&mut self) -> &mut H {
        &mut self.hw
    }

    fn read(&mut self, offset: u32) -> u32 {
        if offset
            .checked_add(4)
            .is_some_and(|end| end <= self.mmio_bytes)
        {
            self.hw.mmio_read(offset)
        } else {
            u32::MAX
        }
    }

    fn write(&mut self, offset: u32, value: u32) {
        if offset
            .checked_add(4)
            .is_some_and(|end| end <= self.mmio_bytes)
        {
            self.hw.mmio_write(offset, value);
        }
    }

    fn write64(&mut self, offset: u32, value: u64) {
        self.write(offset, value as u32);
        self.write(offset + 4, (value >> 32) as u32);
    }

    fn op_read(&mut self, register: u32) -> u32 {
        self.read(self.operational + register)
    }

    fn op_write(&mut self, register: u32, value: u32) {
        self.write(self.operational + register, value);
    }

    fn portsc(&self, port: u8) -> u32 {
        self.operational + PORTSC + 0x10 * (u32::from(port) - 1)
    }

    /// Waits until `done` holds for USBSTS-style reads of `register` or
    /// `micros` pass; returns whether it held.
    fn wait_for(&mut self, register: u32, micros: u64, done: impl Fn(u32) -> bool) -> bool {
        let start = self.hw.now_micros();
        loop {
            if done(self.read(register)) {
                return true;
            }
            if self.hw.now_micros().saturating_sub(start) >= micros {
                return false;
            }
        }
    }

    fn pause(&mut self, micros: u64) {
        let start = self.hw.now_micros();
        while self.hw.now_micros().saturating_sub(start) < micros {}
    }

    fn page(&mut self) -> Result<u64> {
        if self.pages.freed_count > 0 {
            self.pages.freed_count -= 1;
            let page = self.pages.freed[self.pages.freed_count];
            for offset in (0..PAGE_BYTES).step_by(4) {
                self.hw.mem_write(page + offset, 0);
            }
            return Ok(page);
        }
        let page = self.pages.next;
        let limit = if self.capabilities.addressing_64 {
            u64::MAX
        } else {
            1 << 32
        };
        if page + PAGE_BYTES > self.pages.end || page + PAGE_BYTES > limit {
            return Err(XhciError::OutOfDmaMemory);
        }
        self.pages.next += PAGE_BYTES;
        for offset in (0..PAGE_BYTES).step_by(4) {
            self.hw.mem_write(page + offset, 0);
        }
        Ok(page)
    }

    /// Walks the extended capabilities (a bounded walk: each link must go
    /// forward and stay inside the BAR), giving each one's offset and ID.
    fn extended_capabilities(&mut self, mut each: impl FnMut(&mut Self, u32, u32)) {
        let mut offset = self.extended_capabilities;
        for _ in 0..64 {
            if offset == 0
                || offset
                    .checked_add(16)
                    .is_none_or(|end| end > self.mmio_bytes)
            {
                return;
            }
            let header = self.read(offset);
            each(self, offset, header & 0xFF);
            let next = ((header >> 8) & 0xFF) << 2;
            if next == 0 {
                return;
            }
            offset += next;
        }
    }

    /// Takes the controller from the firmware (USB Legacy Support): asks for
    /// it, waits up to [`HANDOFF_MICROS`], takes it if the firmware never
    /// lets go, and turns the firmware's SMIs off.
    pub fn take_ownership(&mut self) -> Handoff {
        let mut legacy = None;
        self.extended_capabilities(|_, offset, id| {
            if id == CAP_LEGACY && legacy.is_none() {
                legacy = Some(offset);
            }
        });
        let Some(legacy) = legacy else {
            return Handoff::NoLegacyCapability;
        };
        let before = self.read(legacy);
        let handoff = if before & LEGACY_BIOS_OWNED == 0 {
            self.write(legacy, before | LEGACY_OS_OWNED);
            Handoff::NotOwned
        } else {
            self.write(legacy, before | LEGACY_OS_OWNED);
            let start = self.hw.now_micros();
            if self.wait_for(legacy, HANDOFF_MICROS, |v| v & LEGACY_BIOS_OWNED == 0) {
                Handoff::Released(self.hw.now_micros().saturating_sub(start))
            } else {
                let now = self.read(legacy);
                self.write(legacy, (now & !LEGACY_BIOS_OWNED) | LEGACY_OS_OWNED);
                Handoff::Forced
            }
        };
        let control = self.read(legacy + 4);
        self.write(
            legacy + 4,
            (control & !LEGACY_SMI_ENABLES) | LEGACY_SMI_STATUS,
        );
        handoff
    }

    fn read_port_protocols(&mut self) {
        let mut protocols = PortProtocols::default();
        self.extended_capabilities(|xhci, offset, id| {
            if id == CAP_PROTOCOL && protocols.count < protocols.ranges.len() {
                let major = (xhci.read(offset) >> 24) as u8;
                let ports = xhci.read(offset + 8);
                protocols.ranges[protocols.count] = (major, ports as u8, (ports >> 8) as u8);
                protocols.count += 1;
            }
        });
        self.protocols = protocols;
    }

    /// Halts and resets the controller, builds the DCBAA (with scratchpads
    /// if it asks), the command ring and the event ring, and starts it.
    pub fn reset_and_start(&mut self) -> Result<()> {
        let command = self.op_read(USBCMD);
        self.op_write(USBCMD, command & !CMD_RUN);
        let usbsts = self.operational + USBSTS;
        if !self.wait_for(usbsts, HALT_MICROS, |s| s & STS_HALTED != 0) {
            return Err(XhciError::NotHalted);
        }
        self.op_write(USBCMD, CMD_RESET);
        // Some Intel controllers hang if read too soon after HCRST (Linux
        // waits 1 ms there too).
        self.pause(1_000);
        let usbcmd = self.operational + USBCMD;
        let start = self.hw.now_micros();
        if !self.wait_for(usbcmd, RESET_MICROS, |c| c & CMD_RESET == 0) {
            return Err(XhciError::NotReady);
        }
        let left = RESET_MICROS.saturating_sub(self.hw.now_micros().saturating_sub(start));
        if !self.wait_for(usbsts, left, |s| s & STS_NOT_READY == 0) {
            return Err(XhciError::NotReady);
        }
        let page_size = self.op_read(PAGESIZE);
        if page_size & 1 == 0 {
            return Err(XhciError::PageSize(page_size));
        }
        self.read_port_protocols();

        let slots = self.capabilities.slots.min(MAX_SLOTS);
        self.op_write(CONFIG, u32::from(slots));
        self.dcbaa = self.page()?;
        let scratchpads = self.capabilities.scratchpads;
        if scratchpads > 0 {
            if u64::from(scratchpads) > PAGE_BYTES / 8 {
                return Err(XhciError::OutOfDmaMemory);
            }
            let array = self.page()?;
            for index in 0..u64::from(scratchpads) {
                let buffer = self.page()?;
                self.hw.mem_write(array + index * 8, buffer as u32);
                self.hw
                    .mem_write(array + index * 8 + 4, (buffer >> 32) as u32);
            }
            self.hw.mem_write(self.dcbaa, array as u32);
            self.hw.mem_write(self.dcbaa + 4, (array >> 32) as u32);
        }
        self.write64(self.operational + DCBAAP, self.dcbaa);

        let commands = ProducerRing::new(self.page()?, RING_TRBS);
        self.write64(self.operational + CRCR, commands.dequeue_pointer());
        self.commands = Some(commands);

        let events = EventRing::new(self.page()?, RING_TRBS);
        let table = self.page()?;
        self.hw.mem_write(table, events.base() as u32);
        self.hw.mem_write(table + 4, (events.base() >> 32) as u32);
        self.hw.mem_write(table + 8, u32::from(events.size()));
        self.write(self.runtime + ERSTSZ, 1);
        self.write64(self.runtime + ERDP, events.base());
        // ERSTBA last: writing it makes the controller read the table.
        self.write64(self.runtime + ERSTBA, table);
        self.events = Some(events);

        self.op_write(USBCMD, CMD_RUN);
        if !self.wait_for(usbsts, HALT_MICROS, |s| s & STS_HALTED == 0) {
            return Err(XhciError::NotRunning);
        }
        // Ports without power (port power control) get it now.
        for port in 1..=self.capabilities.ports {
            let register = self.portsc(port);
            let status = self.read(register);
            if status & PORT_POWER == 0 {
                self.write(register, PORT_POWER);
            }
        }
        Ok(())
    }

    /// The next event, moving the dequeue pointer on.
    fn next_event(&mut self) -> Option<Trb> {
        let events = self.events.as_mut()?;
        let event = events.pop(&mut self.hw)?;
        let dequeue = events.dequeue_address();
        self.write64(self.runtime + ERDP, dequeue | u64::from(ERDP_BUSY));
        Some(event)
    }

    /// Waits for the event `wanted` picks, handling the others as `poll`
    /// would (keys pressed meanwhile are dropped: nobody listens yet).
    fn wait_event(&mut self, micros: u64, wanted: impl Fn(&Trb) -> bool) -> Option<Trb> {
        let start = self.hw.now_micros();
        loop {
            while let Some(event) = self.next_event() {
                if wanted(&event) {
                    return Some(event);
                }
                self.other_event(&event, &mut |_| {});
            }
            if self.hw.now_micros().saturating_sub(start) >= micros {
                return None;
            }
        }
    }

    fn command(&mut self, trb: Trb) -> Result<Trb> {
        let kind = trb.kind();
        let Some(commands) = self.commands.as_mut() else {
            return Err(XhciError::NotRunning);
        };
        let address = commands.push(&mut self.hw, trb);
        self.write(self.doorbells, 0);
        let event = self
            .wait_event(NO_OP_MICROS, |e| {
                e.kind() == trb_type::COMMAND_COMPLETION && e.parameter() == address
            })
            .ok_or(XhciError::CommandTimeout(kind))?;
        if event.completion_code() != COMPLETION_SUCCESS {
            return Err(XhciError::CommandFailed(kind, event.completion_code()));
        }
        Ok(event)
    }

    /// Sends a No Op command: proves the command and event rings work.
    pub fn no_op(&mut self) -> Result<()> {
        self.command(Trb(command::Noop::new().into_raw()))
            .map(|_| ())
    }

    /// Queues a control transfer on device `index`'s endpoint 0 and rings
    /// its doorbell; gives the slot and the Status TRB's address, whose
    /// event ends the transfer.
    fn queue_control(&mut self, index: usize, setup: Setup) -> Result<(u8, u64)> {
        let Some(device) = self.devices[index].as_mut() else {
            return Err(XhciError::TransferTimeout);
        };
        let slot = device.slot;
        let buffer = device.buffer;
        let ring = &mut device.ep0;
        ring.reserve_contiguous(&mut self.hw, 3);
        let device_to_host = setup.request_type & 0x80 != 0;
        let has_data = setup.length > 0;
        let mut setup_stage = transfer::SetupStage::new();
        setup_stage
            .set_request_type(setup.request_type)
            .set_request(setup.request)
            .set_value(setup.value)
            .set_index(setup.index)
            .set_length(setup.length)
            .set_transfer_type(match (has_data, device_to_host) {
                (false, _) => transfer::TransferType::No,
                (true, false) => transfer::TransferType::Out,
                (true, true) => transfer::TransferType::In,
            });
        ring.push(&mut self.hw, Trb(setup_stage.into_raw()));
        if has_data {
            let mut data = transfer::DataStage::new();
            data.set_data_buffer_pointer(buffer)
                .set_trb_transfer_length(u32::from(setup.length))
                .set_direction(if device_to_host {
                    transfer::Direction::In
                } else {
                    transfer::Direction::Out
                });
            ring.push(&mut self.hw, Trb(data.into_raw()));
        }
        // The status stage goes the other way from the data (IN if none).
        let mut status_stage = transfer::StatusStage::new();
        status_stage.set_interrupt_on_completion();
        if !has_data || !device_to_host {
            status_stage.set_direction();
        }
        let status = ring.push(&mut self.hw, Trb(status_stage.into_raw()));
        self.write(self.doorbells + 4 * u32::from(slot), 1);
        Ok((slot, status))
    }

    /// Reads `length` bytes (at most a page) of the control buffer of device `index`.
    fn read_buffer(&mut self, index: usize, out: &mut [u8]) {
        let Some(buffer) = self.devices[index].as_ref().map(|d| d.buffer) else {
            return;
        };
        for (word, chunk) in out.chunks_mut(4).enumerate() {
            let value = self.hw.mem_read(buffer + word as u64 * 4).to_le_bytes();
            chunk.copy_from_slice(&value[..chunk.len()]);
        }
    }

    /// Handles the controller's events (at most a bounded number) and the
    /// keyboards' repeat: `out` gets PS/2 set-1 scancode bytes.
    pub fn poll(&mut self, out: &mut impl FnMut(u8)) {
        for _ in 0..EVENTS_PER_POLL {
            let Some(event) = self.next_event() else {
                break;
            };
            self.other_event(&event, out);
        }
        // Checked here, so that the idle poll pays no call.
        if !self.enumeration_idle() {
            self.advance_enumeration();
            for &byte in &self.released[..self.released_count] {
                out(byte);
            }
            self.released_count = 0;
        }
        let now = self.hw.now_micros();
        for index in 0..MAX_DEVICES {
            let Some(keyboard) = self.devices[index]
                .as_mut()
                .and_then(|d| d.keyboard.as_mut())
            else {
                continue;
            };
            keyboard.state.tick(now, out);
            if keyboard
                .recovery
                .since()
                .is_some_and(|since| now.saturating_sub(since) > RECOVERY_MICROS)
            {
                self.give_up(index, 0, out);
            }
        }
    }

    fn other_event(&mut self, event: &Trb, out: &mut impl FnMut(u8)) {
        // After a Command Abort the ring stops with an event naming the
        // command that would have run next: that command's, it is not.
        if event.kind() == trb_type::COMMAND_COMPLETION
            && event.completion_code() == COMPLETION_COMMAND_RING_STOPPED
        {
            return;
        }
        if self.enumeration_event(event) {
            return;
        }
        match event.kind() {
            trb_type::TRANSFER_EVENT => self.transfer_event(event, out),
            trb_type::COMMAND_COMPLETION => self.recovery_command_done(event),
            trb_type::PORT_STATUS_CHANGE => self.root_port_changed(event.port(), out),
            _ => {}
        }
    }

    fn transfer_event(&mut self, event: &Trb, out: &mut impl FnMut(u8)) {
        let now = self.hw.now_micros();
        let Some(index) = self
            .devices
            .iter()
            .position(|d| d.as_ref().is_some_and(|d| d.slot == event.slot()))
        else {
            return;
        };
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let location = device.location;
        let slot = device.slot;
        if let Some(hub) = device.hub.as_ref() {
            if hub.dci != 0 && event.endpoint() == hub.dci {
                self.hub_status_changed(index, event);
            }
            return;
        }
        let Some(keyboard) = device.keyboard.as_mut() else {
            return;
        };
        if keyboard.failed {
            return;
        }
        if event.endpoint() == 1 {
            // Endpoint 0: the end of a recovery's CLEAR_FEATURE(ENDPOINT_HALT).
            if let Recovery::ClearingHalt { status, .. } = keyboard.recovery {
                if event.parameter() == status {
                    let code = event.completion_code();
                    if code == COMPLETION_SUCCESS || code == COMPLETION_SHORT_PACKET {
                        self.resume_reports(index);
                    } else {
                        self.give_up(index, code, out);
                    }
                }
            }
            return;
        }
        if event.endpoint() != keyboard.dci || keyboard.recovery != Recovery::Running {
            return;
        }
        let code = event.completion_code();
        let Some(trb_index) = keyboard.ring.index_of(event.parameter()) else {
            self.hw.log(format_args!(
                "usb: keyboard on port {location}: event for a TRB not on its ring ignored"
            ));
            return;
        };
        if code != COMPLETION_SUCCESS && code != COMPLETION_SHORT_PACKET {
            self.recover(index, code, out);
            return;
        }
        keyboard.failures_in_a_row = 0;
        let mut report = [0u8; REPORT_BUFFER_BYTES as usize];
        let length =
            (keyboard.report_bytes.saturating_sub(event.residual()) as usize).min(report.len());
        let buffer = keyboard.reports + u64::from(trb_index) * REPORT_BUFFER_BYTES;
        for (word, chunk) in report[..length].chunks_mut(4).enumerate() {
            let value = self.hw.mem_read(buffer + word as u64 * 4).to_le_bytes();
            chunk.copy_from_slice(&value[..chunk.len()]);
        }
        match keyboard.keys(&report[..length]) {
            Ok(keys) => keyboard.state.keys(&keys, now, out),
            Err(Decoded::Unreadable) => {
                keyboard.dropped = keyboard.dropped.saturating_add(1);
                // The first says what happened; a count says how often.
                if keyboard.dropped.is_power_of_two() {
                    self.hw.log(format_args!(
                        "usb: keyboard on port {location}: {} unreadable reports dropped (the last {length} bytes)",
                        keyboard.dropped
                    ));
                }
            }
            Err(_) => {} // rollover, or a report without keys
        }
        queue_report(&mut self.hw, keyboard);
        let dci = keyboard.dci;
        self.write(self.doorbells + 4 * u32::from(slot), u32::from(dci));
    }

    /// A hub's status change endpoint reported: the ports it names are
    /// looked at in their turn.
    fn hub_status_changed(&mut self, index: usize, event: &Trb) {
        let Some(device) = self.devices[index].as_ref() else {
            return;
        };
        let (slot, location) = (device.slot, device.location);
        let Some(hub) = device.hub.as_ref() else {
            return;
        };
        let code = event.completion_code();
        if code != COMPLETION_SUCCESS && code != COMPLETION_SHORT_PACKET {
            // A hub pulled out fails its transfer; its port's change says the rest.
            self.hw.log(format_args!(
                "usb: hub on port {location}: status change transfer failed (completion code {code}); its ports are no longer watched"
            ));
            return;
        }
        let buffer = hub.buffer;
        let changed = self.hw.mem_read(buffer) as u16;
        // Bit 0 is the hub itself (power, over-current): nothing to do there.
        if changed & !1 != 0 {
            self.queue_hub_ports(slot, changed);
        } else {
            self.queue_status_change(index);
        }
    }

    /// A root port's status changed. A device pulled out (or switched away
    /// by a KVM) is let go of with everything behind it; a device plugged in
    /// (or switched back) is enumerated once its connection has settled.
    fn root_port_changed(&mut self, port: u8, out: &mut impl FnMut(u8)) {
        if port == 0 || port > self.capabilities.ports {
            return;
        }
        let register = self.portsc(port);
        let status = self.read(register);
        if status == u32::MAX {
            return;
        }
        let connected = status & PORT_CONNECTED != 0;
        // A reset's own change, acknowledged where the reset is waited for.
        if connected && status & PORT_CONNECT_CHANGE == 0 {
            return;
        }
        // Acknowledge the changes (write-1-to-clear), keeping the power,
        // never writing PED (write-1-to-disable).
        self.write(register, PORT_POWER | (status & PORT_CHANGES));
        let location = Location {
            root_port: port,
            route: 0,
        };
        self.release_under(location, out);
        if connected {
            self.hw
                .log(format_args!("usb: port {port}: device plugged in"));
            self.queue_port(location, false);
        }
    }

    /// The devices at `location` and below are gone: their held keys
    /// released, their slots disabled (queued, not waited for), their pages
    /// kept for the next, and the work queued or running for them dropped.
    fn release_under(&mut self, location: Location, out: &mut impl FnMut(u8)) {
        let mut gone = [0u8; MAX_DEVICES];
        for (index, slot) in gone.iter_mut().enumerate() {
            let Some(device) = self.devices[index].as_mut() else {
                continue;
            };
            if !location.holds(device.location) {
                continue;
            }
            let (at, id) = (device.location, device.slot);
            if let Some(keyboard) = device.keyboard.as_mut() {
                keyboard.state.release_all(out);
            }
            *slot = id;
            self.free_pages_of(index);
            self.disable_slot(id);
            self.hw.log(format_args!(
                "usb: port {at}: device gone; its keys released and slot {id} disabled"
            ));
        }
        self.forget_work_under(location, &gone);
    }

    /// Keeps a page for the next device.
    fn free_page(&mut self, page: u64) {
        if self.pages.freed_count < FREED_PAGES {
            self.pages.freed[self.pages.freed_count] = page;
            self.pages.freed_count += 1;
        }
    }

    /// Forgets a device and keeps its pages for the next. They are
    /// touched again only after a later Enable Slot completes, which the
    /// command ring runs after this device's Disable Slot.
    fn free_pages_of(&mut self, index: usize) {
        let Some(device) = self.devices[index].take() else {
            return;
        };
        let keyboard = device.keyboard.map(|k| [k.ring.base(), k.reports]);
        let hub = device.hub.map(|h| [h.ring.base(), h.buffer]);
        let pages = [
            device.output,
            device.input,
            device.buffer,
            device.ep0.base(),
        ];
        for page in pages
            .into_iter()
            .chain(keyboard.into_iter().flatten())
            .chain(hub.into_iter().flatten())
        {
            self.free_page(page);
        }
    }

    /// A report transfer failed and the endpoint halted: lets go of the
    /// keys (their releases may be lost) and starts the recovery, a step
    /// per event: Reset Endpoint, Set TR Dequeue Pointer past the TRBs
    /// queued, CLEAR_FEATURE(ENDPOINT_HALT) after a stall, then the
    /// reports queued again.
    fn recover(&mut self, index: usize, code: u8, out: &mut impl FnMut(u8)) {
        let now = self.hw.now_micros();
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let (slot, location) = (device.slot, device.location);
        let Some(keyboard) = device.keyboard.as_mut() else {
            return;
        };
        keyboard.failures_in_a_row += 1;
        if keyboard.failures_in_a_row > MAX_RECOVERIES {
            self.give_up(index, code, out);
            return;
        }
        keyboard.state.release_all(out);
        keyboard.keys_by_report = [(u8::MAX, KeySet::default()); KEY_REPORTS];
        let dci = keyboard.dci;
        self.hw.log(format_args!(
            "usb: keyboard on port {location}: report failed (completion code {code}); recovering"
        ));
        let mut reset = command::ResetEndpoint::new();
        reset.set_slot_id(slot).set_endpoint_id(dci);
        let Some(command) = self.queue_command(Trb(reset.into_raw())) else {
            self.give_up(index, code, out);
            return;
        };
        if let Some(keyboard) = self.devices[index]
            .as_mut()
            .and_then(|d| d.keyboard.as_mut())
        {
            keyboard.recovery = Recovery::ResettingEndpoint {
                command,
                since: now,
                stalled: code == COMPLETION_STALL,
            };
        }
    }

    /// A command completed: the next step of the recovery it belongs to.
    fn recovery_command_done(&mut self, event: &Trb) {
        let now = self.hw.now_micros();
        let Some(index) = self.devices.iter().position(|d| {
            d.as_ref()
                .and_then(|d| d.keyboard.as_ref())
                .is_some_and(|k| k.recovery.command() == Some(event.parameter()))
        }) else {
            return;
        };
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let slot = device.slot;
        let Some(keyboard) = device.keyboard.as_mut() else {
            return;
        };
        let code = event.completion_code();
        match keyboard.recovery {
            // Context State Error: the endpoint was not halted after all;
            // the dequeue pointer still has to move past the failed TRB.
            Recovery::ResettingEndpoint { stalled, .. }
                if code == COMPLETION_SUCCESS || code == COMPLETION_CONTEXT_STATE =>
            {
                let mut dequeue = command::SetTrDequeuePointer::new();
                let pointer = keyboard.ring.enqueue_pointer();
                dequeue
                    .set_slot_id(slot)
                    .set_endpoint_id(keyboard.dci)
                    .set_new_tr_dequeue_pointer(pointer & !0xF);
                if pointer & 1 != 0 {
                    dequeue.set_dequeue_cycle_state();
                }
                match self.queue_command(Trb(dequeue.into_raw())) {
                    Some(command) => {
                        if let Some(k) = self.devices[index]
                            .as_mut()
                            .and_then(|d| d.keyboard.as_mut())
                        {
                            k.recovery = Recovery::SettingDequeue {
                                command,
                                since: now,
                                stalled,
                            };
                        }
                    }
                    None => self.give_up(index, code, &mut |_| {}),
                }
            }
            Recovery::SettingDequeue { stalled: true, .. } if code == COMPLETION_SUCCESS => {
                // The device halted its endpoint too: clear it there.
                let endpoint = 0x80 | ((keyboard.dci - 1) / 2);
                let setup = Setup {
                    request_type: 0x02,
                    request: CLEAR_FEATURE,
                    value: ENDPOINT_HALT,
                    index: u16::from(endpoint),
                    length: 0,
                };
                match self.queue_control(index, setup) {
                    Ok((_, status)) => {
                        if let Some(k) = self.devices[index]
                            .as_mut()
                            .and_then(|d| d.keyboard.as_mut())
                        {
                            k.recovery = Recovery::ClearingHalt { status, since: now };
                        }
                    }
                    Err(_) => self.give_up(index, code, &mut |_| {}),
                }
            }
            Recovery::SettingDequeue { .. } if code == COMPLETION_SUCCESS => {
                self.resume_reports(index)
            }
            _ => self.give_up(index, code, &mut |_| {}),
        }
    }

    /// The recovery is done: the reports are queued again.
    fn resume_reports(&mut self, index: usize) {
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let (slot, location) = (device.slot, device.location);
        let Some(keyboard) = device.keyboard.as_mut() else {
            return;
        };
        keyboard.recovery = Recovery::Running;
        for _ in 0..QUEUED_REPORTS {
            queue_report(&mut self.hw, keyboard);
        }
        let dci = keyboard.dci;
        self.write(self.doorbells + 4 * u32::from(slot), u32::from(dci));
        self.hw
            .log(format_args!("usb: keyboard on port {location}: recovered"));
    }

    /// The keyboard failed past recovery: its keys are let go and it is
    /// no longer read.
    fn give_up(&mut self, index: usize, code: u8, out: &mut impl FnMut(u8)) {
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let location = device.location;
        let Some(keyboard) = device.keyboard.as_mut() else {
            return;
        };
        keyboard.failed = true;
        keyboard.recovery = Recovery::Running;
        keyboard.state.release_all(out);
        self.hw.log(format_args!(
            "usb: keyboard on port {location}: not recovered (completion code {code}); keyboard given up"
        ));
    }

    /// Pushes a command and rings the command doorbell, without waiting:
    /// gives the command TRB's address, whose completion event says how it went.
    fn queue_command(&mut self, trb: Trb) -> Option<u64> {
        let address = self.commands.as_mut()?.push(&mut self.hw, trb);
        self.write(self.doorbells, 0);
        Some(address)
    }

    /// Leaves the controller as Linux's shutdown path does before power-off
    /// or reset: the controller halted, then reset, then every root port's
    /// power switched off. Some Intel boards power straight back on, or
    /// wake, from S5 with a controller still running (Linux's
    /// `XHCI_SPURIOUS_REBOOT` and `XHCI_SPURIOUS_WAKEUP`). Every wait is
    /// bounded; a step that fails is said, and the next still runs.
    pub fn shut_down(&mut self) -> Result<()> {
        let command = self.op_read(USBCMD);
        self.op_write(USBCMD, command & !CMD_RUN);
        let usbsts = self.operational + USBSTS;
        let halted = self.wait_for(usbsts, HALT_MICROS, |s| s & STS_HALTED != 0);
        self.commands = None;
        self.events = None;
        self.devices = Default::default();
        let reset = halted && {
            self.op_write(USBCMD, CMD_RESET);
            self.pause(1_000);
            let usbcmd = self.operational + USBCMD;
            self.wait_for(usbcmd, RESET_MICROS, |c| c & CMD_RESET == 0)
                && self.wait_for(usbsts, RESET_MICROS, |s| s & STS_NOT_READY == 0)
        };
        // Last, as a reset may power the ports again: PP written 0, and PED
        // and the change bits (write-1-to-clear) 0 too, so nothing else
        // changes by accident.
        for port in 1..=self.capabilities.ports {
            let register = self.portsc(port);
            self.write(register, 0);
        }
        match (halted, reset) {
            (false, _) => Err(XhciError::NotHalted),
            (true, false) => Err(XhciError::NotReady),
            (true, true) => Ok(()),
        }
    }

    /// The keyboards set up, by where they hang.
    pub fn keyboards(&self) -> impl Iterator<Item = Location> + '_ {
        self.devices
            .iter()
            .flatten()
            .filter(|d| d.keyboard.as_ref().is_some_and(|k| !k.failed))
            .map(|d| d.location)
    }

    /// Reports dropped because they could not be read, over all keyboards.
    pub fn dropped_reports(&self) -> u32 {
        self.devices
            .iter()
            .flatten()
            .filter_map(|d| d.keyboard.as_ref())
            .fold(0, |sum, k| sum.saturating_add(k.dropped))
    }

    /// The slot state of every device with a slot (for the host tests).
    pub fn slot_states(&mut self) -> [u32; MAX_DEVICES] {
        let mut states = [0; MAX_DEVICES];
        for (state, device) in states.iter_mut().zip(self.devices.iter()) {
            if let Some(device) = device {
                *state = self
                    .capabilities
                    .layout
                    .slot_state(&mut self.hw, device.output);
            }
        }
        states
    }
}

/// Queues one Normal TRB for a report into the buffer that belongs to the
/// ring index it lands on.
fn queue_report(hw: &mut impl Hardware, keyboard: &mut Keyboard) {
    let enqueue = keyboard.ring.enqueue_address();
    let index = keyboard.ring.index_of(enqueue).unwrap_or(0);
    let buffer = keyboard.reports + u64::from(index) * REPORT_BUFFER_BYTES;
    let mut normal = transfer::Normal::new();
    normal
        .set_data_buffer_pointer(buffer)
        .set_trb_transfer_length(keyboard.report_bytes)
        .set_interrupt_on_completion()
        .set_interrupt_on_short_packet();
    keyboard.ring.push(hw, Trb(normal.into_raw()));
}

fn configure_endpoint(input: u64, slot: u8) -> Trb {
    let mut configure = command::ConfigureEndpoint::new();
    configure.set_input_context_pointer(input).set_slot_id(slot);
    Trb(configure.into_raw())
}
