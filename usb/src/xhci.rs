//! The xHCI controller, polled: no interrupts, MSI or IOAPIC routing. The
//! device layer ([`crate::bus::Bus`]) drives it through
//! [`crate::host::HostController`] (`xhci/host.rs`); every wait in here is bounded
//! by the clock, every index the controller or a device gives is checked,
//! and every failure is an [`XhciError`] the caller logs and survives.

use super::Hardware;
use crate::host::wait_until;
use context::ContextLayout;
use ring::{trb_type, EventRing, ProducerRing, Trb};
// TRBs are built with the `xhci` crate's layouts; the rings here own the
// cycle bit.
use xhci::ring::trb::command;

pub mod context;
mod host;
#[cfg(test)]
mod host_tests;
pub mod ring;
pub use host::HOST_DEVICES;

/// Bytes in a page: DMA memory is handed out a page at a time.
pub const PAGE_BYTES: u64 = 4096;
/// TRBs in the command and event rings (one page each).
const RING_TRBS: u16 = 256;
/// Slots enabled in CONFIG (the DCBAA has this many entries plus one).
const MAX_SLOTS: u8 = 16;
/// Events handled in one poll, so a controller that floods cannot stall the loop.
const EVENTS_PER_POLL: u32 = 64;

/// How long the firmware gets to let go of the controller.
pub const HANDOFF_MICROS: u64 = 1_000_000;
const HALT_MICROS: u64 = 50_000;
/// How long Controller Not Ready and the reset may take.
pub const RESET_MICROS: u64 = 500_000;
/// How long the No Op at start may take (a check that the rings work).
const NO_OP_MICROS: u64 = 300_000;

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
        }
    }
}

type Result<T> = core::result::Result<T, XhciError>;

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
    /// What the [`crate::host::HostController`] side keeps (devices by
    /// handle, their commands and pipes).
    host: host::HostState,
}
impl<H: Hardware> Xhci<H> {
    /// Reads the capability registers of a controller whose BAR0 is
    /// `mmio_bytes` long; DMA memory is `dma_bytes` at physical `dma_base`
    /// (page-aligned, below 4 GiB unless the controller has AC64).
    #[optimize(size)] // run once at start-up: small beats fast
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
            host: host::HostState::new(),
        })
    }

    /// What the capability registers said.
    pub fn capabilities(&self) -> Capabilities {
        self.capabilities
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

    /// Waits until `done` holds for reads of `register` or `micros` pass
    /// ([`wait_until`]'s pace); returns whether it held.
    fn wait_for(&mut self, register: u32, micros: u64, done: impl Fn(u32) -> bool) -> bool {
        wait_until(self, micros, |xhci| done(xhci.read(register)))
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

    /// The next event, moving the dequeue pointer on.
    fn next_event(&mut self) -> Option<Trb> {
        let events = self.events.as_mut()?;
        let event = events.pop(&mut self.hw)?;
        let dequeue = events.dequeue_address();
        self.write64(self.runtime + ERDP, dequeue | u64::from(ERDP_BUSY));
        Some(event)
    }

    /// Waits for the event `wanted` picks (the No Op at start, before any
    /// device: the others are dropped).
    fn wait_event(&mut self, micros: u64, wanted: impl Fn(&Trb) -> bool) -> Option<Trb> {
        let mut found = None;
        wait_until(self, micros, |xhci| {
            while let Some(event) = xhci.next_event() {
                if wanted(&event) {
                    found = Some(event);
                    return true;
                }
            }
            false
        });
        found
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

    /// Keeps a page for the next device.
    fn free_page(&mut self, page: u64) {
        if self.pages.freed_count < FREED_PAGES {
            self.pages.freed[self.pages.freed_count] = page;
            self.pages.freed_count += 1;
        }
    }

    /// Disable Slot, queued: the slot's pages are reused only after a
    /// later Enable Slot completes, which the ring runs after this.
    fn disable_slot(&mut self, slot: u8) {
        let mut disable = command::DisableSlot::new();
        disable.set_slot_id(slot);
        let _ = self.queue_command(Trb(disable.into_raw()));
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
        self.host = host::HostState::new();
        let reset = halted && {
            self.op_write(USBCMD, CMD_RESET);
            self.hw.pause(1_000);
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
}

fn configure_endpoint(input: u64, slot: u8) -> Trb {
    let mut configure = command::ConfigureEndpoint::new();
    configure.set_input_context_pointer(input).set_slot_id(slot);
    Trb(configure.into_raw())
}
