//! The EHCI host controller (USB 2.0 high speed, EHCI 1.0), polled, behind
//! [`HostController`]: taking it from the firmware (USBLEGSUP in PCI
//! configuration space), resetting and starting it with an asynchronous
//! schedule (a queue head per device's endpoint 0) and a periodic one (a
//! queue head per interrupt-in pipe, linked from the 1024-entry frame
//! list), root ports with the hand-over of full- and low-speed devices to
//! the companion controller, and split transactions for full- and
//! low-speed devices behind a high-speed hub's transaction translator,
//! each interrupt pipe placed where the bus has the time for it
//! (`ehci/budget.rs`).
//!
//! Every register offset is checked against BAR0 once, in [`Ehci::new`];
//! every wait is bounded by the clock; every count the controller writes
//! back is checked before it is used. All DMA structures live in fixed
//! pools inside the one region the kernel gives, reused as devices go.

pub(crate) mod budget;
mod layout;
#[cfg(test)]
mod tests;

use crate::host::wait_until;
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, RootReset, Setup, Speed, Transfer, TransferError, MAX_CONTROL_DATA, MAX_REPORT,
};
use crate::PciHardware;
use budget::{Booking, Translator, BUDGET_FRAMES};
use core::fmt;
use layout::{
    buffer_pointers, capabilities, characteristics, qh_link, token, token_remaining, Layout, Stage,
    FRAME_LIST_ENTRIES, HEAD_OF_RECLAMATION, LINK_TERMINATE, PID_IN, PID_OUT, PID_SETUP,
    QH_CAPABILITIES, QH_CHARACTERISTICS, QH_HORIZONTAL, QH_OVERLAY_ALTERNATE, QH_OVERLAY_NEXT,
    QH_OVERLAY_TOKEN, QTD_ALTERNATE, QTD_BUFFERS, QTD_BUFFERS_HIGH, QTD_NEXT, QTD_TOKEN,
    TOKEN_ACTIVE, TOKEN_BABBLE, TOKEN_CERR, TOKEN_DATA_BUFFER, TOKEN_ERRORS, TOKEN_HALTED,
    TOKEN_MISSED_MICRO_FRAME, TOKEN_TOGGLE, TOKEN_TRANSACTION_ERROR,
};
pub use layout::{DMA_BYTES_USED, MAX_DEVICES, MAX_PIPES};

/// How long the firmware gets to let go (Linux's ehci_bios_handoff: 1 s).
pub const HANDOFF_MICROS: u64 = 1_000_000;
/// How long halting may take: the spec says 16 micro-frames (2 ms), but an
/// emulated controller runs its micro-frames on a host timer that a busy
/// host runs late (QEMU under load took over 20 ms). The wait ends as soon
/// as HCHalted reads 1; only a controller that never halts costs it all.
const HALT_MICROS: u64 = 250_000;
/// How long HCRESET may take (Linux's ehci_reset: 250 ms).
const RESET_MICROS: u64 = 250_000;
/// How long the controller may take to start running and to start both
/// schedules after it is told to.
/// (Bounded as generously as a halt, for the same reason.)
const START_MICROS: u64 = 250_000;
/// How long a port may take to end its reset after PR is written 0: the
/// spec says 2 ms.
const PORT_RESET_END_MICROS: u64 = 5_000;
/// A root reset's stages after the port is held in reset (stage 0): PR
/// written 0, waiting for the port to end it; or no reset at all, the
/// port given to the companion at its beginning.
const RESET_ENDING: u32 = 1;
const RESET_HANDED: u32 = 2;
/// How long the Interrupt on Async Advance doorbell may take (Linux's
/// EHCI_IAA_MSECS).
const ASYNC_ADVANCE_MICROS: u64 = 10_000;
/// How long two frame boundaries may take to pass after a periodic unlink.
const PERIODIC_RELEASE_MICROS: u64 = 5_000;

// Capability registers, from BAR0.
/// CAPLENGTH (bits 7:0) and HCIVERSION (bits 31:16).
const CAPLENGTH: u32 = 0x00;
const HCSPARAMS: u32 = 0x04;
const HCCPARAMS: u32 = 0x08;
/// The capability registers read before CAPLENGTH is known.
const CAPABILITY_BYTES: u32 = 0x0C;

// Operational registers, from CAPLENGTH.
const USBCMD: u32 = 0x00;
const USBSTS: u32 = 0x04;
const USBINTR: u32 = 0x08;
const FRINDEX: u32 = 0x0C;
const CTRLDSSEGMENT: u32 = 0x10;
const PERIODICLISTBASE: u32 = 0x14;
const ASYNCLISTADDR: u32 = 0x18;
const CONFIGFLAG: u32 = 0x40;
/// PORTSC of port 1; port n is at PORTSC + 4 (n - 1).
const PORTSC: u32 = 0x44;

const HCSPARAMS_PORTS: u32 = 0xF;
const HCSPARAMS_PORT_POWER_CONTROL: u32 = 1 << 4;
const HCSPARAMS_COMPANIONS_SHIFT: u32 = 12;
const HCCPARAMS_64_BIT: u32 = 1 << 0;
const HCCPARAMS_EECP_SHIFT: u32 = 8;

const CMD_RUN: u32 = 1 << 0;
const CMD_HCRESET: u32 = 1 << 1;
/// Frame list size (bits 3:2): 00b, 1024 entries.
const CMD_FRAME_LIST_1024: u32 = 0 << 2;
const CMD_PERIODIC_ENABLE: u32 = 1 << 4;
const CMD_ASYNC_ENABLE: u32 = 1 << 5;
const CMD_ASYNC_ADVANCE_DOORBELL: u32 = 1 << 6;
/// Interrupt threshold: 8 micro-frames, the default.
const CMD_THRESHOLD_8: u32 = 8 << 16;

const STS_USBINT: u32 = 1 << 0;
const STS_ERROR: u32 = 1 << 1;
const STS_PORT_CHANGE: u32 = 1 << 2;
const STS_HOST_SYSTEM_ERROR: u32 = 1 << 4;
const STS_ASYNC_ADVANCE: u32 = 1 << 5;
const STS_HALTED: u32 = 1 << 12;
const STS_PERIODIC_RUNNING: u32 = 1 << 14;
const STS_ASYNC_RUNNING: u32 = 1 << 15;

const PORT_CONNECTED: u32 = 1 << 0;
const PORT_CONNECT_CHANGE: u32 = 1 << 1;
const PORT_ENABLED: u32 = 1 << 2;
const PORT_ENABLE_CHANGE: u32 = 1 << 3;
const PORT_OVER_CURRENT_CHANGE: u32 = 1 << 5;
const PORT_RESET: u32 = 1 << 8;
const PORT_LINE_STATUS: u32 = 3 << 10;
/// Line status K: D- high, a low-speed device (EHCI 2.3.9).
const PORT_LINE_K: u32 = 1 << 10;
const PORT_POWER: u32 = 1 << 12;
const PORT_OWNER: u32 = 1 << 13;
/// The write-1-to-clear change bits, written 0 except when clearing them.
const PORT_CHANGES: u32 = PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE | PORT_OVER_CURRENT_CHANGE;

/// USB Legacy Support extended capability (EHCI 2.1.7).
const CAP_LEGACY: u32 = 1;
const LEGACY_BIOS_OWNED: u32 = 1 << 16;
const LEGACY_OS_OWNED: u32 = 1 << 24;
/// USBLEGCTLSTS, after USBLEGSUP.
const LEGACY_CONTROL: u8 = 4;
/// USBLEGCTLSTS written with every SMI enable 0 and the three
/// write-1-to-clear SMI status bits (OS ownership change, PCI command, BAR) 1.
const LEGACY_CONTROL_SILENT: u32 = 0xE000_0000;
/// Extended capabilities live in PCI configuration space above the header.
const FIRST_EXTENDED_CAPABILITY: u8 = 0x40;

/// Why the driver could not set the controller up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EhciError {
    /// BAR0 is smaller than the registers the capabilities name.
    RegistersOutsideBar,
    /// CAPLENGTH is too short or not dword aligned.
    BadCapabilityLength(u8),
    /// HCSPARAMS says there are no ports.
    NoPorts,
    /// The DMA region is not page aligned.
    DmaUnaligned,
    /// The DMA region is smaller than [`DMA_BYTES_USED`].
    DmaTooSmall,
    /// The DMA region reaches above 4 GiB.
    DmaAbove4GiB,
    /// The firmware never let go: the controller is left alone.
    FirmwareOwns,
    /// The controller did not halt.
    NotHalted,
    /// HCRESET never cleared.
    ResetStuck,
    /// The controller or its schedules did not start.
    NotRunning,
}

impl fmt::Display for EhciError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EhciError::RegistersOutsideBar => write!(f, "registers lie outside BAR0"),
            EhciError::BadCapabilityLength(l) => write!(f, "CAPLENGTH {l:#x} makes no sense"),
            EhciError::NoPorts => write!(f, "no root ports"),
            EhciError::DmaUnaligned => write!(f, "DMA memory not page aligned"),
            EhciError::DmaTooSmall => write!(f, "too little DMA memory"),
            EhciError::DmaAbove4GiB => write!(f, "DMA memory above 4 GiB"),
            EhciError::FirmwareOwns => write!(f, "the firmware kept the controller"),
            EhciError::NotHalted => write!(f, "the controller did not halt"),
            EhciError::ResetStuck => write!(f, "the controller's reset (HCRESET) did not end"),
            EhciError::NotRunning => write!(f, "the controller or its schedules did not start"),
        }
    }
}

/// Where the controller stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not touched yet.
    Fresh,
    /// The firmware never let go: nothing is written.
    FirmwareOwns,
    /// Reset and started.
    Running,
    /// Halted by [`HostController::halt`] or a failed start.
    Stopped,
}

/// A slot of a fixed pool.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Slot {
    Free,
    Used,
    /// The controller never said it let go of the slot's queue head (no
    /// async advance): its memory is never reused.
    Lost,
}

/// A control transfer under way on a device's endpoint 0.
#[derive(Clone, Copy, Debug)]
struct Control {
    length: u16,
    is_in: bool,
}

#[derive(Clone, Copy, Debug)]
struct Device {
    slot: Slot,
    info: DeviceInfo,
    address: u8,
    max_packet: u16,
    transfer: Option<Control>,
    /// A hub with a transaction translator per port.
    multi_tt: bool,
}

impl Device {
    const NONE: Device = Device {
        slot: Slot::Free,
        info: DeviceInfo {
            route: Some(0),
            speed: Speed::High,
            root_port: 0,
            translator: None,
        },
        address: 0,
        max_packet: 0,
        transfer: None,
        multi_tt: false,
    };
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PipeState {
    /// The qTD is queued; a report completes it.
    Armed,
    /// Stalled or failed: waits for `interrupt_restart`.
    Stopped,
}

#[derive(Clone, Copy, Debug)]
struct Pipe {
    slot: Slot,
    device: u8,
    max_packet: u16,
    /// Where it is polled, and the bus time it takes there.
    booking: Booking,
    state: PipeState,
}

impl Pipe {
    const NONE: Pipe = Pipe {
        slot: Slot::Free,
        device: 0,
        max_packet: 0,
        booking: Booking::new(Speed::High, 0, 1, None),
        state: PipeState::Stopped,
    };
}

/// A polled EHCI controller over `H`.
#[derive(Debug)]
pub struct Ehci<H: PciHardware> {
    hw: H,
    operational: u32,
    ports: u8,
    port_power_control: bool,
    companions: u8,
    sixty_four_bit: bool,
    eecp: u8,
    layout: Layout,
    state: State,
    devices: [Device; MAX_DEVICES],
    pipes: [Pipe; MAX_PIPES],
    /// Device slots on the asynchronous ring, in ring order after the head.
    async_order: [u8; MAX_DEVICES],
    async_count: usize,
    /// The root port reset running (one at a time).
    reset: Option<RootReset>,
    /// A host system error was logged.
    system_error_logged: bool,
}

impl<H: PciHardware> Ehci<H> {
    /// Reads the capability registers and checks every register offset
    /// against `mmio_bytes` (BAR0's size) and the DMA region
    /// `[dma_base, dma_base + dma_bytes)`. Writes nothing.
    #[optimize(size)] // run once at start-up: small beats fast
    pub fn new(
        mut hw: H,
        mmio_bytes: u32,
        dma_base: u64,
        dma_bytes: u64,
    ) -> Result<Self, EhciError> {
        if mmio_bytes < CAPABILITY_BYTES {
            return Err(EhciError::RegistersOutsideBar);
        }
        let caplength = (hw.mmio_read(CAPLENGTH) & 0xFF) as u8;
        if u32::from(caplength) < CAPABILITY_BYTES || caplength % 4 != 0 {
            return Err(EhciError::BadCapabilityLength(caplength));
        }
        let hcsparams = hw.mmio_read(HCSPARAMS);
        let hccparams = hw.mmio_read(HCCPARAMS);
        let ports = (hcsparams & HCSPARAMS_PORTS) as u8;
        if ports == 0 {
            return Err(EhciError::NoPorts);
        }
        let operational = u32::from(caplength);
        let last_port_end = operational + PORTSC + 4 * u32::from(ports);
        if last_port_end > mmio_bytes {
            return Err(EhciError::RegistersOutsideBar);
        }
        if dma_base % 0x1000 != 0 {
            return Err(EhciError::DmaUnaligned);
        }
        if dma_bytes < DMA_BYTES_USED {
            return Err(EhciError::DmaTooSmall);
        }
        // Everything the controller reads is below 4 GiB, whether or not
        // it could reach higher: CTRLDSSEGMENT is then 0.
        if dma_base + DMA_BYTES_USED > 1 << 32 {
            return Err(EhciError::DmaAbove4GiB);
        }
        let companions = (hcsparams >> HCSPARAMS_COMPANIONS_SHIFT & 0xF) as u8;
        let sixty_four_bit = hccparams & HCCPARAMS_64_BIT != 0;
        hw.log(format_args!(
            "ehci: {} ports, {} companion controllers{}{}",
            ports,
            companions,
            if hcsparams & HCSPARAMS_PORT_POWER_CONTROL != 0 {
                ", port power switched"
            } else {
                ""
            },
            if sixty_four_bit { ", 64-bit" } else { "" }
        ));
        Ok(Ehci {
            hw,
            operational,
            ports,
            port_power_control: hcsparams & HCSPARAMS_PORT_POWER_CONTROL != 0,
            companions,
            sixty_four_bit,
            eecp: (hccparams >> HCCPARAMS_EECP_SHIFT & 0xFF) as u8,
            layout: Layout::new(dma_base),
            state: State::Fresh,
            devices: [Device::NONE; MAX_DEVICES],
            pipes: [Pipe::NONE; MAX_PIPES],
            async_order: [0; MAX_DEVICES],
            async_count: 0,
            reset: None,
            system_error_logged: false,
        })
    }

    /// Whether descriptors use the 64-bit layout (HCCPARAMS bit 0).
    pub fn sixty_four_bit(&self) -> bool {
        self.sixty_four_bit
    }

    /// The companion controllers HCSPARAMS names (0: none, as with an
    /// integrated rate-matching hub).
    pub fn companions(&self) -> u8 {
        self.companions
    }

    /// Device and pipe slots free for reuse (the rest are in use or lost).
    pub fn free_slots(&self) -> (usize, usize) {
        (
            self.devices.iter().filter(|d| d.slot == Slot::Free).count(),
            self.pipes.iter().filter(|p| p.slot == Slot::Free).count(),
        )
    }

    /// The open interrupt pipes' places in the periodic schedule.
    pub fn bookings(&self) -> impl Iterator<Item = Booking> + '_ {
        self.pipes
            .iter()
            .filter(|p| p.slot == Slot::Used)
            .map(|p| p.booking)
    }

    // Registers.

    fn read(&mut self, register: u32) -> u32 {
        self.hw.mmio_read(self.operational + register)
    }

    fn write(&mut self, register: u32, value: u32) {
        self.hw.mmio_write(self.operational + register, value);
    }

    /// PORTSC of `port` (1-based, checked by the caller).
    fn port_register(port: u8) -> u32 {
        PORTSC + 4 * (u32::from(port) - 1)
    }

    fn valid_port(&self, port: u8) -> bool {
        (1..=self.ports).contains(&port)
    }

    /// Waits, at most `micros`, for `register` to satisfy `done`
    /// ([`wait_until`]'s pace).
    fn wait_for(&mut self, register: u32, micros: u64, done: impl Fn(u32) -> bool) -> bool {
        wait_until(self, micros, |ehci| done(ehci.read(register)))
    }

    // The firmware hand-off.

    /// The USB Legacy Support capability's offset in PCI configuration
    /// space: the EECP list walked with a bound, each dword at most once.
    fn legacy_capability(&mut self) -> Option<u8> {
        let mut offset = self.eecp;
        let mut visited = 0u64;
        // 48 dwords lie between 0x40 and 0x100: no list is longer.
        for _ in 0..48 {
            if offset == 0 {
                return None;
            }
            // USBLEGCTLSTS must fit after USBLEGSUP too.
            if offset < FIRST_EXTENDED_CAPABILITY || offset % 4 != 0 || offset > 0xF8 {
                self.hw.log(format_args!(
                    "ehci: extended capability pointer {offset:#x} is bad: no hand-off"
                ));
                return None;
            }
            let bit = 1u64 << ((offset - FIRST_EXTENDED_CAPABILITY) / 4);
            if visited & bit != 0 {
                self.hw.log(format_args!(
                    "ehci: extended capabilities loop at {offset:#x}: no hand-off"
                ));
                return None;
            }
            visited |= bit;
            let capability = self.hw.pci_config_read(offset);
            if capability & 0xFF == CAP_LEGACY {
                return Some(offset);
            }
            offset = (capability >> 8 & 0xFF) as u8;
        }
        None
    }

    // Reset and start.

    // DMA helpers.

    fn clear_qh(&mut self, qh: u64) {
        let words = if self.sixty_four_bit { 17 } else { 12 };
        for word in 0..words {
            self.hw.mem_write(qh + 4 * word, 0);
        }
        self.hw.mem_write(qh + QH_HORIZONTAL, LINK_TERMINATE);
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, LINK_TERMINATE);
        self.hw.mem_write(qh + QH_OVERLAY_ALTERNATE, LINK_TERMINATE);
    }

    /// Writes a qTD (not yet linked anywhere).
    fn write_qtd(
        &mut self,
        qtd: u64,
        next: u32,
        alternate: u32,
        token: u32,
        buffer: u64,
        bytes: usize,
    ) {
        self.hw.mem_write(qtd + QTD_NEXT, next);
        self.hw.mem_write(qtd + QTD_ALTERNATE, alternate);
        for (i, pointer) in buffer_pointers(buffer, bytes).into_iter().enumerate() {
            self.hw.mem_write(qtd + QTD_BUFFERS + 4 * i as u64, pointer);
            if self.sixty_four_bit {
                self.hw.mem_write(qtd + QTD_BUFFERS_HIGH + 4 * i as u64, 0);
            }
        }
        // The token last: it makes the qTD active.
        self.hw.mem_write(qtd + QTD_TOKEN, token);
    }

    fn write_bytes(&mut self, address: u64, bytes: &[u8]) {
        for (i, chunk) in bytes.chunks(4).enumerate() {
            let mut word = [0u8; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.hw
                .mem_write(address + 4 * i as u64, u32::from_le_bytes(word));
        }
    }

    fn read_bytes(&mut self, address: u64, into: &mut [u8]) {
        for (i, chunk) in into.chunks_mut(4).enumerate() {
            let word = self.hw.mem_read(address + 4 * i as u64).to_le_bytes();
            chunk.copy_from_slice(&word[..chunk.len()]);
        }
    }

    /// Points a queue head's overlay at `first` qTD, safely whether the
    /// overlay is halted or finished: first nothing to fetch, then the
    /// halt cleared (keeping `toggle`), then the new qTD.
    fn restart_overlay(&mut self, qh: u64, first: u64, toggle: bool) {
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, LINK_TERMINATE);
        self.hw.mem_write(qh + QH_OVERLAY_ALTERNATE, LINK_TERMINATE);
        self.hw
            .mem_write(qh + QH_OVERLAY_TOKEN, if toggle { TOKEN_TOGGLE } else { 0 });
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, first as u32);
    }

    /// What a halted token's status says went wrong, in Linux's order
    /// (ehci-q.c, qtd_copy_status): errors halt only once the error
    /// counter has run out, so a halt with CERR left is a STALL.
    fn halt_reason(token: u32) -> Transfer {
        if token & TOKEN_BABBLE != 0 {
            Transfer::Failed(TransferError::Babble)
        } else if token & TOKEN_CERR != 0 {
            Transfer::Stalled
        } else if token & TOKEN_MISSED_MICRO_FRAME != 0 {
            Transfer::Failed(TransferError::Split)
        } else if token & TOKEN_DATA_BUFFER != 0 {
            Transfer::Failed(TransferError::DataBuffer)
        } else if token & TOKEN_TRANSACTION_ERROR != 0 {
            Transfer::Failed(TransferError::NoResponse)
        } else {
            Transfer::Failed(TransferError::Controller)
        }
    }

    // The asynchronous schedule.

    /// Puts device `index`'s queue head on the ring, right after the head.
    fn async_link(&mut self, index: usize) {
        let head = self.layout.async_head();
        let qh = self.layout.device_qh(index);
        let next = match self.async_count {
            0 => head,
            _ => self.layout.device_qh(usize::from(self.async_order[0])),
        };
        self.hw.mem_write(qh + QH_HORIZONTAL, qh_link(next));
        self.hw.mem_write(head + QH_HORIZONTAL, qh_link(qh));
        self.async_order.copy_within(0..self.async_count, 1);
        self.async_order[0] = index as u8;
        self.async_count += 1;
    }

    /// Takes device `index`'s queue head off the ring. Its memory may be
    /// reused only after [`Self::async_advance`].
    fn async_unlink(&mut self, index: usize) {
        let Some(position) = self.async_order[..self.async_count]
            .iter()
            .position(|&d| usize::from(d) == index)
        else {
            return;
        };
        let previous = match position {
            0 => self.layout.async_head(),
            p => self.layout.device_qh(usize::from(self.async_order[p - 1])),
        };
        let next = if position + 1 < self.async_count {
            self.layout
                .device_qh(usize::from(self.async_order[position + 1]))
        } else {
            self.layout.async_head()
        };
        self.hw.mem_write(previous + QH_HORIZONTAL, qh_link(next));
        self.async_order
            .copy_within(position + 1..self.async_count, position);
        self.async_count -= 1;
    }

    /// Rings the Interrupt on Async Advance doorbell and waits, bounded,
    /// until the controller says it holds no pointer to an unlinked queue
    /// head. False if it never did (the memory must then not be reused).
    fn async_advance(&mut self) -> bool {
        if self.state != State::Running || self.read(USBSTS) & STS_HALTED != 0 {
            // A halted controller holds nothing.
            return true;
        }
        self.write(USBSTS, STS_ASYNC_ADVANCE);
        let command = self.read(USBCMD);
        self.write(USBCMD, command & !CMD_HCRESET | CMD_ASYNC_ADVANCE_DOORBELL);
        let advanced = self.wait_for(USBSTS, ASYNC_ADVANCE_MICROS, |s| {
            s & (STS_ASYNC_ADVANCE | STS_HALTED) != 0
        });
        self.write(USBSTS, STS_ASYNC_ADVANCE);
        if !advanced {
            self.hw
                .log(format_args!("ehci: no async advance after the doorbell"));
        }
        advanced
    }

    // The periodic schedule.

    /// Relinks every open pipe's queue head as a tree, as Linux's
    /// `qh_link_periodic` does: each frame's list holds the pipes due in
    /// it, slowest period first. Periods are powers of two, so the pipes
    /// after one in its frames are the same in every one of them, and its
    /// one horizontal link serves them all. Links are written from the
    /// fastest pipe up, so nothing points at a queue head before its own
    /// link is right.
    fn periodic_relink(&mut self) {
        let mut order = [0u8; MAX_PIPES];
        let mut count = 0;
        for (i, pipe) in self.pipes.iter().enumerate() {
            if pipe.slot == Slot::Used {
                order[count] = i as u8;
                count += 1;
            }
        }
        let pipes = self.pipes;
        let booking = |i: u8| pipes[usize::from(i)].booking;
        // Slowest first, and by index among equals: an insertion sort, as
        // `order` starts in index order and holds a few pipes (the library's
        // sort was 11 KB of the kernel for them).
        for sorted in 1..count {
            let mut at = sorted;
            while at > 0 && booking(order[at - 1]).period < booking(order[at]).period {
                order.swap(at - 1, at);
                at -= 1;
            }
        }
        for (position, &i) in order[..count].iter().enumerate().rev() {
            let own = booking(i);
            // The next pipe due whenever this one is.
            let next = order[position + 1..count]
                .iter()
                .find(|&&j| own.phase % booking(j).period == booking(j).phase);
            let link = match next {
                Some(&j) => qh_link(self.layout.pipe_qh(usize::from(j))),
                None => LINK_TERMINATE,
            };
            let qh = self.layout.pipe_qh(usize::from(i));
            self.hw.mem_write(qh + QH_HORIZONTAL, link);
        }
        let frame_list = self.layout.frame_list();
        for frame in 0..FRAME_LIST_ENTRIES {
            let first = order[..count].iter().find(|&&i| booking(i).due(frame));
            let entry = match first {
                Some(&i) => qh_link(self.layout.pipe_qh(usize::from(i))),
                None => LINK_TERMINATE,
            };
            self.hw.mem_write(frame_list + 4 * frame as u64, entry);
        }
    }

    /// The translator a split to a device behind `tt` goes through: the
    /// hub's one, or its port's on a multi-TT hub.
    fn translator(&self, tt: crate::host::TransactionTranslator) -> Translator {
        let multi_tt = self
            .devices
            .iter()
            .any(|d| d.slot == Slot::Used && d.address == tt.hub_address && d.multi_tt);
        Translator {
            hub_address: tt.hub_address,
            port: if multi_tt { tt.hub_port } else { 0 },
        }
    }

    /// Waits, bounded, for two frame boundaries to pass, after which the
    /// controller holds no pointer to a queue head unlinked before.
    fn periodic_release(&mut self) -> bool {
        if self.state != State::Running || self.read(USBSTS) & STS_HALTED != 0 {
            return true;
        }
        let start_frame = self.read(FRINDEX) >> 3;
        let released = self.wait_for(FRINDEX, PERIODIC_RELEASE_MICROS, |index| {
            (index >> 3).wrapping_sub(start_frame) & 0x7FF >= 2
        });
        if !released {
            self.hw
                .log(format_args!("ehci: the frame index stood still"));
        }
        released || self.read(USBSTS) & STS_HALTED != 0
    }

    // Handles.

    fn device(&self, device: DeviceId) -> Result<usize, HostError> {
        let index = usize::from(device.0);
        match self.devices.get(index) {
            Some(d) if d.slot == Slot::Used => Ok(index),
            _ => Err(HostError::UnknownHandle),
        }
    }

    fn pipe(&self, pipe: PipeId) -> Option<usize> {
        let index = usize::from(pipe.0);
        match self.pipes.get(index) {
            Some(p) if p.slot == Slot::Used => Some(index),
            _ => None,
        }
    }

    fn running(&self) -> Result<(), HostError> {
        match self.state {
            State::Running => Ok(()),
            _ => Err(HostError::ControllerGone),
        }
    }

    /// Rewrites endpoint 0's characteristics (address, packet size) of an
    /// idle device.
    fn write_device_characteristics(&mut self, index: usize) {
        let d = self.devices[index];
        let qh = self.layout.device_qh(index);
        self.hw.mem_write(
            qh + QH_CHARACTERISTICS,
            characteristics(d.address, 0, d.info.speed, d.max_packet, true),
        );
    }

    /// Closes pipe `index` and waits for the controller to let go of it.
    fn close_pipe(&mut self, index: usize) {
        self.pipes[index].slot = Slot::Lost;
        self.periodic_relink();
        self.pipes[index].slot = if self.periodic_release() {
            Slot::Free
        } else {
            Slot::Lost
        };
    }

    /// Deactivates device `index`'s transfer: off the ring, the doorbell,
    /// the overlay and qTDs cleared. False if the controller never let go.
    fn quiesce_device(&mut self, index: usize) -> bool {
        self.async_unlink(index);
        if !self.async_advance() {
            return false;
        }
        let qh = self.layout.device_qh(index);
        self.restart_overlay(qh, u64::from(LINK_TERMINATE), false);
        for stage in [Stage::Setup, Stage::Data, Stage::Status] {
            let qtd = self.layout.device_qtd(index, stage);
            self.hw.mem_write(qtd + QTD_TOKEN, 0);
        }
        true
    }
}

impl<H: PciHardware> HostController for Ehci<H> {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Ehci
    }

    type Hardware = H;

    fn hardware(&mut self) -> &mut H {
        &mut self.hw
    }

    type StartError = EhciError;

    /// Takes the controller from the firmware (Linux's ehci_bios_handoff):
    /// sets OS-owned, waits at most [`HANDOFF_MICROS`] for BIOS-owned to
    /// clear, then turns the firmware's SMIs off. A firmware that never
    /// lets go keeps the controller: the request is withdrawn, it is
    /// logged, and the driver writes nothing to the controller after.
    #[optimize(size)] // run once at start-up: small beats fast
    fn take_ownership(&mut self) -> Handoff {
        let Some(legacy) = self.legacy_capability() else {
            return Handoff::NotOwned;
        };
        let support = self.hw.pci_config_read(legacy);
        // USBLEGSUP is written as a dword: BIOS-owned is written back as it
        // was read, which leaves it as the firmware has it.
        self.hw.pci_config_write(legacy, support | LEGACY_OS_OWNED);
        if support & LEGACY_BIOS_OWNED == 0 {
            self.hw
                .pci_config_write(legacy + LEGACY_CONTROL, LEGACY_CONTROL_SILENT);
            return Handoff::NotOwned;
        }
        let start = self.hw.now_micros();
        let mut support = support;
        let released = wait_until(self, HANDOFF_MICROS, |ehci| {
            support = ehci.hw.pci_config_read(legacy);
            support & LEGACY_BIOS_OWNED == 0
        });
        let waited = self.hw.now_micros().saturating_sub(start);
        if released {
            self.hw
                .pci_config_write(legacy + LEGACY_CONTROL, LEGACY_CONTROL_SILENT);
            return Handoff::Released { micros: waited };
        }
        // Its keyboard emulation is then all there is: leave it be.
        self.hw.pci_config_write(legacy, support & !LEGACY_OS_OWNED);
        self.state = State::FirmwareOwns;
        self.hw.log(format_args!(
            "ehci: the firmware kept the controller for {} ms (USBLEGSUP {support:#010x}): left alone",
            waited / 1000
        ));
        Handoff::NeverReleased
    }

    /// Halts and resets the controller, builds both schedules, starts it,
    /// routes every port to it (CONFIGFLAG) and powers the ports. Every
    /// wait is bounded.
    #[optimize(size)] // run once at start-up: small beats fast
    fn reset_and_start(&mut self) -> Result<(), EhciError> {
        if self.state == State::FirmwareOwns {
            return Err(EhciError::FirmwareOwns);
        }
        self.state = State::Stopped;
        self.write(USBINTR, 0);
        if self.read(USBSTS) & STS_HALTED == 0 {
            let command = self.read(USBCMD);
            self.write(USBCMD, command & !(CMD_RUN | CMD_HCRESET));
            if !self.wait_for(USBSTS, HALT_MICROS, |s| s & STS_HALTED != 0) {
                return Err(EhciError::NotHalted);
            }
        }
        self.write(USBCMD, CMD_HCRESET);
        if !self.wait_for(USBCMD, RESET_MICROS, |c| c & CMD_HCRESET == 0) {
            return Err(EhciError::ResetStuck);
        }
        self.devices = [Device::NONE; MAX_DEVICES];
        self.pipes = [Pipe::NONE; MAX_PIPES];
        self.async_count = 0;
        self.reset = None;
        if self.sixty_four_bit {
            // All of the DMA region is below 4 GiB.
            self.write(CTRLDSSEGMENT, 0);
        }
        let frame_list = self.layout.frame_list();
        for entry in 0..FRAME_LIST_ENTRIES as u64 {
            self.hw.mem_write(frame_list + 4 * entry, LINK_TERMINATE);
        }
        // The reclamation head: points to itself, halted so it never runs
        // a transfer (as Linux's ehci->async).
        let head = self.layout.async_head();
        self.clear_qh(head);
        self.hw.mem_write(head + QH_HORIZONTAL, qh_link(head));
        self.hw.mem_write(
            head + QH_CHARACTERISTICS,
            HEAD_OF_RECLAMATION | characteristics(0, 0, Speed::High, 64, false),
        );
        self.hw.mem_write(head + QH_OVERLAY_TOKEN, TOKEN_HALTED);
        self.write(PERIODICLISTBASE, frame_list as u32);
        self.write(ASYNCLISTADDR, head as u32);
        self.write(USBINTR, 0);
        self.write(
            USBCMD,
            CMD_THRESHOLD_8
                | CMD_FRAME_LIST_1024
                | CMD_PERIODIC_ENABLE
                | CMD_ASYNC_ENABLE
                | CMD_RUN,
        );
        let running = STS_PERIODIC_RUNNING | STS_ASYNC_RUNNING;
        if !self.wait_for(USBSTS, START_MICROS, |s| {
            s & STS_HALTED == 0 && s & running == running
        }) {
            return Err(EhciError::NotRunning);
        }
        // Every port to this controller; read back so the write is posted.
        self.write(CONFIGFLAG, 1);
        let _ = self.read(CONFIGFLAG);
        if self.port_power_control {
            for port in 1..=self.ports {
                let register = Self::port_register(port);
                let status = self.read(register);
                self.write(register, status & !PORT_CHANGES | PORT_POWER);
            }
        }
        self.state = State::Running;
        Ok(())
    }

    fn root_ports(&self) -> u8 {
        self.ports
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        if !self.valid_port(port) || self.state != State::Running {
            return PortStatus::default();
        }
        let status = self.read(Self::port_register(port));
        let connected = status & PORT_CONNECTED != 0;
        let enabled = status & PORT_ENABLED != 0;
        PortStatus {
            connected,
            enabled,
            low_speed: connected && !enabled && status & PORT_LINE_STATUS == PORT_LINE_K,
            connect_changed: status & PORT_CONNECT_CHANGE != 0,
            companion_owned: status & PORT_OWNER != 0,
        }
    }

    fn clear_port_change(&mut self, port: u8) {
        if !self.valid_port(port) || self.state != State::Running {
            return;
        }
        let register = Self::port_register(port);
        let status = self.read(register);
        self.write(register, status & !PORT_CHANGES | (status & PORT_CHANGES));
    }

    fn port_reset_begin(&mut self, port: u8) {
        if !self.valid_port(port) || self.state != State::Running {
            return;
        }
        let mut reset = RootReset::begin(port, self.hw.now_micros(), u64::MAX);
        let register = Self::port_register(port);
        let status = self.read(register);
        if status & PORT_OWNER != 0 {
            reset.stage = RESET_HANDED;
            self.reset = Some(reset);
            return;
        }
        let low_speed = status & (PORT_CONNECTED | PORT_ENABLED) == PORT_CONNECTED
            && status & PORT_LINE_STATUS == PORT_LINE_K;
        if low_speed && self.companions > 0 {
            // Linux's ehci_hub_control: K-state before the reset is a
            // low-speed device, the companion's at once.
            self.write(register, status & !PORT_CHANGES | PORT_OWNER);
            reset.stage = RESET_HANDED;
            self.reset = Some(reset);
            self.hw.log(format_args!(
                "ehci: port {port}: low-speed device, handed to the companion"
            ));
            return;
        }
        // PE is written 0 with PR 1, as the spec asks.
        self.write(
            register,
            status & !(PORT_CHANGES | PORT_ENABLED) | PORT_RESET,
        );
        self.reset = Some(reset);
    }

    /// Software ends the reset once TDRSTR has passed (PR written 0), and
    /// the port has `PORT_RESET_END_MICROS` to finish it.
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome> {
        let running = self.state == State::Running;
        let Some(mut reset) = self.reset.filter(|r| r.port == port && running) else {
            return Some(ResetOutcome::Failed);
        };
        let now = self.hw.now_micros();
        let register = Self::port_register(port);
        match reset.stage {
            RESET_HANDED => {
                self.reset = None;
                return Some(ResetOutcome::HandedToCompanion);
            }
            0 if now < reset.until => return None,
            0 => {
                let status = self.read(register);
                self.write(register, status & !(PORT_CHANGES | PORT_RESET));
                reset.stage = RESET_ENDING;
                reset.bound = now + PORT_RESET_END_MICROS;
                self.reset = Some(reset);
                return None;
            }
            _ => {}
        }
        let status = self.read(register);
        if status & PORT_RESET != 0 {
            if now < reset.bound {
                return None;
            }
            self.reset = None;
            self.hw
                .log(format_args!("ehci: port {port}: the reset did not end"));
            return Some(ResetOutcome::Failed);
        }
        self.reset = None;
        if status & PORT_CONNECTED == 0 {
            return Some(ResetOutcome::Failed);
        }
        if status & PORT_ENABLED != 0 {
            return Some(ResetOutcome::Enabled(Speed::High));
        }
        // No chirp: a full-speed device.
        if self.companions == 0 {
            self.hw.log(format_args!(
                "ehci: port {port}: a full-speed device and no companion controller: not used"
            ));
            return Some(ResetOutcome::Failed);
        }
        self.write(register, status & !PORT_CHANGES | PORT_OWNER);
        self.hw.log(format_args!(
            "ehci: port {port}: full-speed device, handed to the companion"
        ));
        Some(ResetOutcome::HandedToCompanion)
    }

    fn port_disable(&mut self, port: u8) {
        if !self.valid_port(port) || self.state != State::Running {
            return;
        }
        let register = Self::port_register(port);
        let status = self.read(register);
        self.write(register, status & !(PORT_CHANGES | PORT_ENABLED));
    }

    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError> {
        self.running()?;
        if !self.valid_port(info.root_port) {
            return Err(HostError::Invalid);
        }
        // Full and low speed reach EHCI only through a translator.
        match (info.speed, info.translator) {
            (Speed::High, None) => {}
            (Speed::Full | Speed::Low, Some(tt))
                if (1..=127).contains(&tt.hub_address) && (1..=127).contains(&tt.hub_port) => {}
            _ => return Err(HostError::Invalid),
        }
        let Some(index) = self.devices.iter().position(|d| d.slot == Slot::Free) else {
            self.hw
                .log(format_args!("ehci: no room for another device"));
            return Err(HostError::NoRoom);
        };
        // High speed's endpoint 0 is always 64 bytes (USB 2.0 5.5.3).
        let max_packet = if info.speed == Speed::High { 64 } else { 8 };
        self.devices[index] = Device {
            slot: Slot::Used,
            info,
            address: 0,
            max_packet,
            transfer: None,
            multi_tt: false,
        };
        let qh = self.layout.device_qh(index);
        self.clear_qh(qh);
        self.write_device_characteristics(index);
        self.hw
            .mem_write(qh + QH_CAPABILITIES, capabilities(info.translator, 0, 0));
        self.async_link(index);
        Ok(DeviceId(index as u8))
    }

    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        let index = self.device(device)?;
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[index].address = address;
        self.write_device_characteristics(index);
        Ok(())
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> Result<(), HostError> {
        let index = self.device(device)?;
        let valid = match self.devices[index].info.speed {
            Speed::High => max_packet == 64,
            Speed::Full => matches!(max_packet, 8 | 16 | 32 | 64),
            Speed::Low => max_packet == 8,
            Speed::Super => false,
        };
        if !valid {
            self.hw.log(format_args!(
                "ehci: endpoint 0 packet size {max_packet} refused"
            ));
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[index].max_packet = max_packet;
        self.write_device_characteristics(index);
        Ok(())
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        _ports: u8,
        multi_tt: bool,
    ) -> Result<(), HostError> {
        // Split transactions name the hub in each device's queue head; the
        // budget needs to know how many translators it has.
        let index = self.device(device)?;
        self.devices[index].multi_tt = multi_tt;
        Ok(())
    }

    fn device_remove(&mut self, device: DeviceId) {
        let Ok(index) = self.device(device) else {
            return;
        };
        for p in 0..MAX_PIPES {
            if self.pipes[p].slot == Slot::Used && usize::from(self.pipes[p].device) == index {
                self.close_pipe(p);
            }
        }
        self.devices[index].transfer = None;
        self.async_unlink(index);
        self.devices[index].slot = if self.async_advance() {
            Slot::Free
        } else {
            self.hw.log(format_args!(
                "ehci: device slot {index} kept: the controller may still read it"
            ));
            Slot::Lost
        };
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError> {
        self.running()?;
        let index = self.device(device)?;
        let length = usize::from(setup.length);
        if length > MAX_CONTROL_DATA || (!setup.is_in() && out.len() < length) {
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        let qh = self.layout.device_qh(index);
        // Nothing for the controller to fetch while the qTDs are written.
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, LINK_TERMINATE);
        self.hw.mem_write(qh + QH_OVERLAY_ALTERNATE, LINK_TERMINATE);
        self.hw.mem_write(qh + QH_OVERLAY_TOKEN, 0);

        let setup_qtd = self.layout.device_qtd(index, Stage::Setup);
        let data_qtd = self.layout.device_qtd(index, Stage::Data);
        let status_qtd = self.layout.device_qtd(index, Stage::Status);
        let setup_buffer = self.layout.device_setup(index);
        let data_buffer = self.layout.device_data(index);
        self.write_bytes(setup_buffer, &setup.bytes());
        // The status stage goes the other way from the data (IN when there
        // is no data), always DATA1.
        let status_pid = if length > 0 && setup.is_in() {
            PID_OUT
        } else {
            PID_IN
        };
        self.write_qtd(
            status_qtd,
            LINK_TERMINATE,
            LINK_TERMINATE,
            token(status_pid, 0, true, true),
            data_buffer,
            0,
        );
        let after_setup = if length > 0 {
            let pid = if setup.is_in() {
                PID_IN
            } else {
                self.write_bytes(data_buffer, &out[..length]);
                PID_OUT
            };
            // A short IN packet goes on to the status stage.
            self.write_qtd(
                data_qtd,
                status_qtd as u32,
                status_qtd as u32,
                token(pid, setup.length, true, false),
                data_buffer,
                length,
            );
            data_qtd
        } else {
            status_qtd
        };
        self.write_qtd(
            setup_qtd,
            after_setup as u32,
            LINK_TERMINATE,
            token(PID_SETUP, 8, false, false),
            setup_buffer,
            8,
        );
        self.devices[index].transfer = Some(Control {
            length: setup.length,
            is_in: setup.is_in(),
        });
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, setup_qtd as u32);
        Ok(())
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        let Ok(index) = self.device(device) else {
            return Transfer::Failed(TransferError::Controller);
        };
        let Some(control) = self.devices[index].transfer else {
            return Transfer::Failed(TransferError::Controller);
        };
        let status_qtd = self.layout.device_qtd(index, Stage::Status);
        let status = self.hw.mem_read(status_qtd + QTD_TOKEN);
        if status & (TOKEN_ACTIVE | TOKEN_HALTED) == 0 {
            let moved = if control.length > 0 {
                let data_qtd = self.layout.device_qtd(index, Stage::Data);
                let data = self.hw.mem_read(data_qtd + QTD_TOKEN);
                let remaining = token_remaining(data);
                if data & TOKEN_ACTIVE != 0 || remaining > u32::from(control.length) {
                    self.devices[index].transfer = None;
                    self.hw.log(format_args!(
                        "ehci: a control transfer finished with a data token {data:#010x}"
                    ));
                    return Transfer::Failed(TransferError::Controller);
                }
                usize::from(control.length) - remaining as usize
            } else {
                0
            };
            if control.is_in {
                let n = moved.min(into.len());
                let data_buffer = self.layout.device_data(index);
                self.read_bytes(data_buffer, &mut into[..n]);
            }
            self.devices[index].transfer = None;
            return Transfer::Complete(moved);
        }
        let qh = self.layout.device_qh(index);
        let overlay = self.hw.mem_read(qh + QH_OVERLAY_TOKEN);
        if overlay & TOKEN_HALTED != 0 || status & TOKEN_HALTED != 0 {
            self.devices[index].transfer = None;
            return Self::halt_reason(overlay | status & TOKEN_ERRORS);
        }
        Transfer::Pending
    }

    fn control_cancel(&mut self, device: DeviceId) {
        let Ok(index) = self.device(device) else {
            return;
        };
        if self.devices[index].transfer.take().is_none() {
            return;
        }
        if self.quiesce_device(index) {
            self.async_link(index);
        } else {
            self.devices[index].slot = Slot::Lost;
            self.hw.log(format_args!(
                "ehci: device slot {index} given up: its transfer could not be stopped"
            ));
        }
    }

    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> Result<PipeId, HostError> {
        self.running()?;
        let device_index = self.device(device)?;
        let d = self.devices[device_index];
        let largest = match d.info.speed {
            Speed::Low => 8,
            _ => MAX_REPORT as u16,
        };
        if !(1..=15).contains(&endpoint) || !(1..=largest).contains(&max_packet) {
            return Err(HostError::Invalid);
        }
        let Some(index) = self.pipes.iter().position(|p| p.slot == Slot::Free) else {
            self.hw.log(format_args!("ehci: no room for another pipe"));
            return Err(HostError::NoRoom);
        };
        // The largest power of two not above the interval, at most the
        // budget's frames (a host may poll more often).
        let asked = u16::from(interval.max(1)).min(BUDGET_FRAMES as u16);
        let period = 1u16 << (15 - asked.leading_zeros());
        let translator = d.info.translator.map(|tt| self.translator(tt));
        let wanted = Booking::new(d.info.speed, max_packet, period, translator);
        let Some(booking) = budget::place(self.bookings(), wanted) else {
            self.hw.log(format_args!(
                "ehci: no room in the periodic schedule for endpoint {endpoint} of device {} ({:?} speed, {max_packet} bytes every {period} frames{}): pipe refused",
                d.address,
                d.info.speed,
                budget::Through(translator)
            ));
            return Err(HostError::NoRoom);
        };
        self.pipes[index] = Pipe {
            slot: Slot::Used,
            device: device_index as u8,
            max_packet,
            booking,
            state: PipeState::Armed,
        };
        let qh = self.layout.pipe_qh(index);
        let qtd = self.layout.pipe_qtd(index);
        self.clear_qh(qh);
        self.hw.mem_write(
            qh + QH_CHARACTERISTICS,
            characteristics(d.address, endpoint, d.info.speed, max_packet, false),
        );
        self.hw.mem_write(
            qh + QH_CAPABILITIES,
            capabilities(d.info.translator, booking.s_mask, booking.c_mask),
        );
        self.arm_pipe(index);
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, qtd as u32);
        self.periodic_relink();
        Ok(PipeId(index as u8))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        let Some(index) = self.pipe(pipe) else {
            return Transfer::Failed(TransferError::Controller);
        };
        if self.pipes[index].state != PipeState::Armed {
            return Transfer::Pending;
        }
        let qtd = self.layout.pipe_qtd(index);
        let status = self.hw.mem_read(qtd + QTD_TOKEN);
        if status & TOKEN_ACTIVE != 0 {
            return Transfer::Pending;
        }
        if status & TOKEN_HALTED != 0 {
            self.pipes[index].state = PipeState::Stopped;
            return Self::halt_reason(status);
        }
        let max_packet = self.pipes[index].max_packet;
        let remaining = token_remaining(status);
        if remaining > u32::from(max_packet) {
            self.pipes[index].state = PipeState::Stopped;
            self.hw.log(format_args!(
                "ehci: an interrupt transfer finished with token {status:#010x}"
            ));
            return Transfer::Failed(TransferError::Controller);
        }
        let n = usize::from(max_packet) - remaining as usize;
        let copied = n.min(into.len());
        let buffer = self.layout.pipe_buffer(index);
        self.read_bytes(buffer, &mut into[..copied]);
        // Again, on the same queue head: its overlay keeps the toggle.
        self.arm_pipe(index);
        let qh = self.layout.pipe_qh(index);
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, qtd as u32);
        Transfer::Complete(n)
    }

    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError> {
        self.running()?;
        let index = self.pipe(pipe).ok_or(HostError::UnknownHandle)?;
        if self.pipes[index].state == PipeState::Armed {
            return Ok(());
        }
        let qh = self.layout.pipe_qh(index);
        let toggle = !reset_toggle && self.hw.mem_read(qh + QH_OVERLAY_TOKEN) & TOKEN_TOGGLE != 0;
        self.hw.mem_write(qh + QH_OVERLAY_NEXT, LINK_TERMINATE);
        self.arm_pipe(index);
        let qtd = self.layout.pipe_qtd(index);
        self.restart_overlay(qh, qtd, toggle);
        self.pipes[index].state = PipeState::Armed;
        Ok(())
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        if let Some(index) = self.pipe(pipe) {
            self.close_pipe(index);
        }
    }

    fn anything_happened(&mut self) -> bool {
        let status = self.read(USBSTS);
        let happened = status & (STS_USBINT | STS_ERROR | STS_PORT_CHANGE | STS_HOST_SYSTEM_ERROR);
        if happened == 0 {
            return false;
        }
        self.write(USBSTS, happened);
        if happened & STS_HOST_SYSTEM_ERROR != 0 && !self.system_error_logged {
            self.system_error_logged = true;
            self.hw.log(format_args!(
                "ehci: host system error: the controller halted"
            ));
        }
        true
    }

    fn halt(&mut self) -> bool {
        match self.state {
            State::Fresh | State::FirmwareOwns => {
                return self.read(USBSTS) & STS_HALTED != 0;
            }
            State::Running | State::Stopped => {}
        }
        self.state = State::Stopped;
        self.write(USBINTR, 0);
        let command = self.read(USBCMD);
        self.write(
            USBCMD,
            command & !(CMD_RUN | CMD_HCRESET | CMD_ASYNC_ADVANCE_DOORBELL),
        );
        let halted = self.wait_for(USBSTS, HALT_MICROS, |s| s & STS_HALTED != 0);
        // Every port back to the companions, as Linux's shutdown does.
        self.write(CONFIGFLAG, 0);
        let _ = self.read(CONFIGFLAG);
        halted
    }
}

impl<H: PciHardware> Ehci<H> {
    /// Writes pipe `index`'s qTD afresh: IN, its packet size, an interrupt
    /// on completion; the toggle comes from the queue head (DTC 0).
    fn arm_pipe(&mut self, index: usize) {
        let qtd = self.layout.pipe_qtd(index);
        let buffer = self.layout.pipe_buffer(index);
        let bytes = self.pipes[index].max_packet;
        self.write_qtd(
            qtd,
            LINK_TERMINATE,
            LINK_TERMINATE,
            token(PID_IN, bytes, false, true),
            buffer,
            usize::from(bytes),
        );
    }
}
