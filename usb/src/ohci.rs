//! The OHCI (Open Host Controller Interface 1.0a) driver, polled, behind
//! [`HostController`]: USB 1.1 full- and low-speed devices on AMD, SiS,
//! ALi, NEC, VIA and Apple chipsets, and the companions of their EHCIs.
//!
//! - Taken from the firmware as Linux's `quirk_usb_handoff_ohci` does: an
//!   ownership change request while SMM holds InterruptRouting, bounded to
//!   500 ms; a firmware that never lets go keeps the controller.
//! - Reset as `ohci_run` does: the frame interval saved and restored (FIT
//!   toggled), PeriodicStart at 90 %, the HCCA, the lists, then
//!   UsbOperational with the control and periodic lists enabled, no
//!   interrupts (polled), the root ports powered.
//! - Control transfers: an ED per device on the control list, SETUP, data
//!   and status TDs queued at the ED's dummy tail, ControlListFilled.
//! - Interrupt-in pipes: an ED hung on a static tree of 63 skipped EDs
//!   below the HCCA's 32-entry interrupt table, one TD and a dummy, the
//!   toggle carried by the ED.
//! - Every ED, TD and buffer comes from fixed pools in the DMA region given
//!   to [`Ohci::new`]; an ED leaves its list with sKip set and is reused
//!   only after the controller has started a new frame.

mod descriptors;
mod registers;
#[cfg(test)]
mod tests;

use crate::host::wait_until;
pub use crate::host::Handoff;
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, RootReset, Setup, Speed, Transfer, TransferError, MAX_CONTROL_DATA, MAX_REPORT,
    ROOT_RESET_MICROS,
};
use crate::PciHardware;
use core::fmt;
use descriptors::{
    condition, ed, td, tree_node, tree_parent, Layout, CONTROL_TDS, MAX_INTERVAL, PIPE_TDS,
    TREE_NODES,
};
pub use descriptors::{MAX_DEVICES, MAX_PIPES};
use registers::*;

/// How long SMM gets to let go after the ownership change request
/// (Linux's pci-quirks: 500 ms).
pub const HANDOFF_MICROS: u64 = 500_000;
/// How long the software reset may take: 10 us by the specification,
/// bounded generously.
const RESET_MICROS: u64 = 1_000;
/// Linux's wait after putting a running controller into UsbReset, so the
/// devices see a reset (`ohci_run`: 50 ms).
const USB_RESET_MICROS: u64 = 50_000;
/// Linux's wait after UsbResume from a suspended controller (10 ms).
const USB_RESUME_MICROS: u64 = 10_000;
/// How long a frame may take to start (one is 1 ms).
const FRAME_WAIT_MICROS: u64 = 5_000;
/// A root port reset pulse as the controller times it (Linux's
/// `PORT_RESET_HW_MSEC`), repeated until the port has been in reset for
/// [`ROOT_RESET_MICROS`], as Linux's `root_port_reset` does.
const PORT_RESET_PULSE_MICROS: u64 = 10_000;
/// At most this many pulses, however slowly the polls come.
const PORT_RESET_PULSES: u32 = (ROOT_RESET_MICROS / PORT_RESET_PULSE_MICROS) as u32 + 1;
/// How long a pulse may run before the reset is given up.
const PORT_RESET_PULSE_BOUND_MICROS: u64 = 2 * PORT_RESET_PULSE_MICROS;
/// How long HcControl may take to show UsbReset after a halt.
const HALT_MICROS: u64 = 10_000;
/// Frame intervals (FI, bit times minus one) taken as plausible from the
/// firmware; anything else is replaced by the nominal 11,999.
const FRAME_INTERVALS: core::ops::RangeInclusive<u32> = 11_000..=13_000;
/// The most a root port's power-on-to-power-good wait may be (POTPGT is
/// 8 bits of 2 ms).
const MAX_POWER_ON_MICROS: u64 = 510_000;

/// Why the driver could not start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OhciError {
    /// BAR0 is smaller than the registers the driver uses.
    RegistersTooSmall,
    /// The DMA region is too small, or not below 4 GiB.
    BadDmaRegion,
    /// The registers read all ones: no controller answers.
    Absent,
    /// SMM never let go of the controller; it was left alone.
    OwnedByFirmware,
    /// HostControllerReset did not clear within the bound.
    ResetTimedOut,
    /// The controller lost its frame interval or periodic start, or the
    /// HCCA did not take.
    BadInitialisation,
    /// The controller did not enter UsbOperational.
    NotOperational,
}

impl fmt::Display for OhciError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            OhciError::RegistersTooSmall => "BAR0 too small for the OHCI registers",
            OhciError::BadDmaRegion => "DMA region too small or above 4 GiB",
            OhciError::Absent => "no controller answers (registers read all ones)",
            OhciError::OwnedByFirmware => "SMM never released the controller",
            OhciError::ResetTimedOut => "HostControllerReset did not finish",
            OhciError::BadInitialisation => "frame interval, periodic start or HCCA did not take",
            OhciError::NotOperational => "the controller did not become operational",
        })
    }
}

/// Where the driver is with the controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Made, not yet started.
    New,
    /// SMM kept it: the driver touches nothing.
    LeftToFirmware,
    /// Operational: the lists run.
    Running,
    /// Halted by [`HostController::halt`], or gone (all ones, an
    /// unrecoverable error).
    Stopped,
}

/// A control transfer on a device's endpoint 0.
#[derive(Clone, Copy, Debug)]
struct ControlTransfer {
    /// The ring slot of the SETUP TD; the data TD (if any) and the status
    /// TD follow it.
    first: usize,
    /// Bytes of the data stage (0: none).
    length: usize,
    /// The data stage is device-to-host.
    is_in: bool,
}

#[derive(Clone, Copy, Debug, Default)]
struct Device {
    in_use: bool,
    address: u8,
    low_speed: bool,
    max_packet: u16,
    /// The ring slot of the dummy TD at the ED's TailP.
    tail: usize,
    transfer: Option<ControlTransfer>,
}

#[derive(Clone, Copy, Debug, Default)]
struct Pipe {
    in_use: bool,
    device: usize,
    max_packet: u16,
    /// The polling interval in frames (a power of two, 1-32).
    interval: u8,
    /// The branch of the interrupt tree the ED hangs on.
    branch: usize,
    /// The ring slot of the dummy TD at the ED's TailP (the other TD is
    /// the one in flight).
    tail: usize,
    /// The ED's NextED as the driver wrote it.
    next: u32,
    /// A stall or error was reported: the pipe waits for a restart.
    stopped: bool,
}

/// An OHCI controller and everything the driver keeps of it.
pub struct Ohci<H: PciHardware> {
    hw: H,
    mmio_bytes: u32,
    layout: Layout,
    state: State,
    /// Root ports, from HcRhDescriptorA.NDP, bounded.
    ports: u8,
    devices: [Device; MAX_DEVICES],
    pipes: [Pipe; MAX_PIPES],
    /// The devices whose EDs are on the control list, in list order.
    control_list: [u8; MAX_DEVICES],
    control_len: usize,
    /// Each static tree ED's NextED as the driver wrote it.
    tree_next: [u32; TREE_NODES],
    /// HcFmInterval's FI and FSMPS, to restore after a reset.
    frame_interval: u32,
    /// HcControl.RWC as the firmware left it (kept, as Linux keeps it).
    remote_wakeup_connected: u32,
    /// Done queue heads consumed (WDH), for the tests.
    done_heads: u32,
    /// A nonsense done head was logged already.
    bad_done_head_logged: bool,
    /// The root port reset running (one at a time).
    reset: Option<RootReset>,
}

impl<H: PciHardware> fmt::Debug for Ohci<H> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Ohci")
            .field("state", &self.state)
            .field("ports", &self.ports)
            .field("devices", &self.devices_in_use())
            .field("pipes", &self.pipes_in_use())
            .finish()
    }
}

type Result<T> = core::result::Result<T, OhciError>;

impl<H: PciHardware> Ohci<H> {
    /// Takes the controller whose registers are BAR0 (`mmio_bytes` long)
    /// with the DMA region `[dma_base, dma_base + dma_bytes)`, physically
    /// contiguous and below 4 GiB. Touches no register yet.
    #[optimize(size)] // run once at start-up: small beats fast
    pub fn new(hw: H, mmio_bytes: u32, dma_base: u64, dma_bytes: u64) -> Result<Self> {
        if mmio_bytes < HC_RH_PORT_STATUS + 4 {
            return Err(OhciError::RegistersTooSmall);
        }
        // OHCI's pointers are 32 bits: the whole region is below 4 GiB.
        let region_end = dma_base
            .checked_add(dma_bytes)
            .ok_or(OhciError::BadDmaRegion)?;
        if region_end > 1 << 32 {
            return Err(OhciError::BadDmaRegion);
        }
        let layout = Layout::new(dma_base);
        if layout.end > region_end {
            return Err(OhciError::BadDmaRegion);
        }
        Ok(Ohci {
            hw,
            mmio_bytes,
            layout,
            state: State::New,
            ports: 0,
            devices: [Device::default(); MAX_DEVICES],
            pipes: [Pipe::default(); MAX_PIPES],
            control_list: [0; MAX_DEVICES],
            control_len: 0,
            tree_next: [0; TREE_NODES],
            frame_interval: 0,
            remote_wakeup_connected: 0,
            done_heads: 0,
            bad_done_head_logged: false,
            reset: None,
        })
    }

    /// Devices in the driver's table (the tests check none leak).
    pub fn devices_in_use(&self) -> usize {
        self.devices.iter().filter(|d| d.in_use).count()
    }

    /// Interrupt pipes open (the tests check none leak).
    pub fn pipes_in_use(&self) -> usize {
        self.pipes.iter().filter(|p| p.in_use).count()
    }

    /// Done queue heads consumed so far.
    pub fn done_heads_consumed(&self) -> u32 {
        self.done_heads
    }

    fn read(&mut self, offset: u32) -> u32 {
        if offset
            .checked_add(4)
            .is_none_or(|end| end > self.mmio_bytes)
        {
            return u32::MAX;
        }
        self.hw.mmio_read(offset)
    }

    fn write(&mut self, offset: u32, value: u32) {
        if offset
            .checked_add(4)
            .is_some_and(|end| end <= self.mmio_bytes)
        {
            self.hw.mmio_write(offset, value);
        }
    }

    fn port_register(port: u8) -> u32 {
        HC_RH_PORT_STATUS + 4 * (u32::from(port) - 1)
    }

    fn valid_port(&self, port: u8) -> bool {
        (1..=self.ports).contains(&port)
    }

    /// Reads `offset` until `done` says so or `micros` pass
    /// ([`wait_until`]'s pace); gives the last value read and whether
    /// `done` held.
    fn wait_register(
        &mut self,
        offset: u32,
        micros: u64,
        done: impl Fn(u32) -> bool,
    ) -> (u32, bool) {
        let mut value = 0;
        let held = wait_until(self, micros, |ohci| {
            value = ohci.read(offset);
            done(value)
        });
        (value, held)
    }

    /// Waits until the controller starts a new frame (HcFmNumber moves):
    /// whatever it was doing with a list in the last one is over.
    fn wait_next_frame(&mut self) -> bool {
        if self.state != State::Running {
            return true;
        }
        let before = self.read(HC_FM_NUMBER) & 0xFFFF;
        let (_, moved) = self.wait_register(HC_FM_NUMBER, FRAME_WAIT_MICROS, |now| {
            now & 0xFFFF != before
        });
        if !moved {
            self.hw
                .log(format_args!("ohci: the frame counter stopped at {before}"));
        }
        moved
    }

    /// Clears the HCCA, builds the static interrupt tree (every ED
    /// skipped, each linked to the node of half its interval) and points
    /// the 32 interrupt table entries at the interval-32 nodes. Forgets
    /// every device and pipe.
    fn build_schedule(&mut self) {
        let hcca = self.layout.hcca;
        for word in 0..HCCA_BYTES / 4 {
            self.hw.mem_write(hcca + word * 4, 0);
        }
        for shift in 0..=5u8 {
            let interval = 1u8 << shift;
            for branch in 0..usize::from(interval) {
                let node = tree_node(interval, branch);
                let address = self.layout.tree_ed(node);
                let next = tree_parent(interval, branch)
                    .map_or(0, |parent| self.layout.tree_ed(parent) as u32);
                self.hw.mem_write(address, ed::SKIP);
                self.hw.mem_write(address + 4, 0);
                self.hw.mem_write(address + 8, 0);
                self.hw.mem_write(address + 12, next);
                self.tree_next[node] = next;
            }
        }
        for entry in 0..HCCA_INTERRUPT_ENTRIES {
            let node = self.layout.tree_ed(tree_node(MAX_INTERVAL, entry)) as u32;
            self.hw.mem_write(hcca + entry as u64 * 4, node);
        }
        self.devices = [Device::default(); MAX_DEVICES];
        self.pipes = [Pipe::default(); MAX_PIPES];
        self.control_len = 0;
    }

    /// Powers the root ports as HcRhDescriptorA says (none to switch, all
    /// together, or each on its own), then waits POTPGT x 2 ms before
    /// anyone uses them.
    fn power_ports(&mut self) {
        let descriptor = self.read(HC_RH_DESCRIPTOR_A);
        let reported = (descriptor & RH_A_NDP_MASK) as u8;
        let fit = ((self.mmio_bytes - HC_RH_PORT_STATUS) / 4).min(u32::from(MAX_ROOT_PORTS)) as u8;
        self.ports = reported.min(fit);
        if reported == 0 || reported != self.ports {
            self.hw.log(format_args!(
                "ohci: HcRhDescriptorA says {reported} ports; using {}",
                self.ports
            ));
        }
        if descriptor & RH_A_NPS == 0 {
            // Global power covers ganged ports (and, with PSM, those not
            // in PortPowerControlMask); SetPortPower the others.
            self.write(HC_RH_STATUS, RH_STATUS_SET_GLOBAL_POWER);
            if descriptor & RH_A_PSM != 0 {
                for port in 1..=self.ports {
                    self.write(Self::port_register(port), PORT_SET_POWER);
                }
            }
        }
        let power_on = u64::from(descriptor >> RH_A_POTPGT_SHIFT) * 2_000;
        self.hw.pause(power_on.min(MAX_POWER_ON_MICROS));
    }

    fn device(&self, device: DeviceId) -> core::result::Result<usize, HostError> {
        let index = usize::from(device.0);
        if index < MAX_DEVICES && self.devices[index].in_use {
            Ok(index)
        } else {
            Err(HostError::UnknownHandle)
        }
    }

    fn pipe(&self, pipe: PipeId) -> core::result::Result<usize, HostError> {
        let index = usize::from(pipe.0);
        if index < MAX_PIPES && self.pipes[index].in_use {
            Ok(index)
        } else {
            Err(HostError::UnknownHandle)
        }
    }

    fn running(&self) -> core::result::Result<(), HostError> {
        if self.state == State::Running {
            Ok(())
        } else {
            Err(HostError::ControllerGone)
        }
    }

    /// Writes the control ED's dword 0 from the device's address, speed
    /// and packet size (the controller reads it each visit).
    fn write_control_ed(&mut self, index: usize, skip: bool) {
        let device = self.devices[index];
        let control = ed::control(
            device.address,
            0,
            ed::DIRECTION_FROM_TD,
            device.low_speed,
            device.max_packet,
        ) | if skip { ed::SKIP } else { 0 };
        let address = self.layout.control_ed(index);
        self.hw.mem_write(address, control);
    }

    fn write_td(&mut self, address: u64, control: u32, buffer: u64, length: usize, next: u64) {
        let (start, end) = if length == 0 {
            (0, 0)
        } else {
            (buffer as u32, (buffer + length as u64 - 1) as u32)
        };
        self.hw.mem_write(address, control);
        self.hw.mem_write(address + 4, start);
        self.hw.mem_write(address + 8, next as u32);
        self.hw.mem_write(address + 12, end);
    }

    /// A fresh dummy TD at a ring's tail: the controller never processes
    /// the TD TailP points at.
    fn write_dummy_td(&mut self, address: u64) {
        self.write_td(address, td::NOT_ACCESSED, 0, 0, 0);
    }

    fn copy_to_dma(&mut self, address: u64, bytes: &[u8]) {
        for (index, chunk) in bytes.chunks(4).enumerate() {
            let mut word = [0u8; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.hw
                .mem_write(address + index as u64 * 4, u32::from_le_bytes(word));
        }
    }

    fn copy_from_dma(&mut self, address: u64, into: &mut [u8]) {
        for (index, chunk) in into.chunks_mut(4).enumerate() {
            let word = self.hw.mem_read(address + index as u64 * 4).to_le_bytes();
            let length = chunk.len();
            chunk.copy_from_slice(&word[..length]);
        }
    }

    /// How many bytes a retired TD moved: all of them when its
    /// CurrentBufferPointer is 0, else up to that pointer. A pointer
    /// outside the buffer is the controller's error.
    fn bytes_moved(&mut self, td_address: u64, buffer: u64, length: usize) -> Option<usize> {
        let current = u64::from(self.hw.mem_read(td_address + 4));
        if current == 0 {
            Some(length)
        } else if current >= buffer && current <= buffer + length as u64 {
            Some((current - buffer) as usize)
        } else {
            None
        }
    }

    /// Takes the done queue the controller wrote to the HCCA (WDH): the
    /// head is read and zeroed, then WDH cleared so the controller may
    /// write the next. Completions are read from the TDs and EDs
    /// themselves; the head is only checked to be one of the driver's TDs.
    fn consume_done_head(&mut self) {
        let address = self.layout.hcca + HCCA_DONE_HEAD;
        let head = self.hw.mem_read(address);
        self.hw.mem_write(address, 0);
        self.write(HC_INTERRUPT_STATUS, INTERRUPT_WDH);
        self.done_heads = self.done_heads.wrapping_add(1);
        let td = u64::from(head & ed::POINTER);
        if !self.layout.is_td(td) && !self.bad_done_head_logged {
            self.bad_done_head_logged = true;
            self.hw.log(format_args!(
                "ohci: done head {head:#010x} is none of the driver's TDs"
            ));
        }
    }

    /// Appends the device's ED to the control list.
    fn link_control_ed(&mut self, index: usize) {
        let address = self.layout.control_ed(index) as u32;
        self.hw.mem_write(address as u64 + 12, 0);
        match self.control_len.checked_sub(1) {
            None => self.write(HC_CONTROL_HEAD_ED, address),
            Some(last) => {
                let previous = usize::from(self.control_list[last]);
                let previous_address = self.layout.control_ed(previous);
                self.hw.mem_write(previous_address + 12, address);
            }
        }
        self.control_list[self.control_len] = index as u8;
        self.control_len += 1;
    }

    /// Takes the device's ED off the control list (its sKip is set
    /// already). The controller may still hold it in HcControlCurrentED,
    /// so the list is disabled until [`Self::finish_control_unlink`].
    fn unlink_control_ed(&mut self, index: usize) {
        let Some(position) = self.control_list[..self.control_len]
            .iter()
            .position(|&d| usize::from(d) == index)
        else {
            return;
        };
        let next = match self.control_list[..self.control_len].get(position + 1) {
            Some(&following) => self.layout.control_ed(usize::from(following)) as u32,
            None => 0,
        };
        if position == 0 {
            self.write(HC_CONTROL_HEAD_ED, next);
        } else {
            let previous = usize::from(self.control_list[position - 1]);
            let previous_address = self.layout.control_ed(previous);
            self.hw.mem_write(previous_address + 12, next);
        }
        self.control_list
            .copy_within(position + 1..self.control_len, position);
        self.control_len -= 1;
        let control = self.read(HC_CONTROL);
        self.write(HC_CONTROL, control & !CONTROL_CLE);
    }

    /// After a new frame: the controller is off the unlinked ED, so
    /// HcControlCurrentED is cleared (allowed while CLE is clear) and the
    /// list enabled again.
    fn finish_control_unlink(&mut self) {
        self.write(HC_CONTROL_CURRENT_ED, 0);
        let control = self.read(HC_CONTROL);
        self.write(HC_CONTROL, control | CONTROL_CLE);
        self.write(HC_COMMAND_STATUS, COMMAND_CLF);
    }

    /// The predecessor of pipe `index`'s ED on its branch: the static
    /// node, or another pipe; `None` for the node.
    fn pipe_predecessor(&self, index: usize) -> Option<Option<usize>> {
        let pipe = self.pipes[index];
        let node = tree_node(pipe.interval, pipe.branch);
        let me = self.layout.pipe_ed(index) as u32;
        if self.tree_next[node] == me {
            return Some(None);
        }
        (0..MAX_PIPES)
            .find(|&other| {
                other != index && self.pipes[other].in_use && self.pipes[other].next == me
            })
            .map(Some)
    }

    /// Sets the pipe's sKip and takes its ED off the interrupt tree. The
    /// caller waits for a new frame before reusing it.
    fn unlink_pipe(&mut self, index: usize) {
        let address = self.layout.pipe_ed(index);
        let control = self.hw.mem_read(address);
        self.hw.mem_write(address, control | ed::SKIP);
        let next = self.pipes[index].next;
        match self.pipe_predecessor(index) {
            Some(None) => {
                let node = tree_node(self.pipes[index].interval, self.pipes[index].branch);
                self.hw.mem_write(self.layout.tree_ed(node) + 12, next);
                self.tree_next[node] = next;
            }
            Some(Some(previous)) => {
                self.hw.mem_write(self.layout.pipe_ed(previous) + 12, next);
                self.pipes[previous].next = next;
            }
            None => self
                .hw
                .log(format_args!("ohci: pipe {index} was on no list")),
        }
    }

    /// Queues an IN TD for the pipe's next report in the dummy at the
    /// tail and makes the other TD the new dummy (TailP written last).
    fn queue_report(&mut self, index: usize) {
        let pipe = self.pipes[index];
        let request = self.layout.pipe_td(index, pipe.tail);
        let dummy = self.layout.pipe_td(index, pipe.tail + 1);
        let buffer = self.layout.report(index);
        self.write_dummy_td(dummy);
        self.write_td(
            request,
            td::NOT_ACCESSED
                | td::PID_IN
                | td::BUFFER_ROUNDING
                | td::DELAY_INTERRUPT_NONE
                | td::TOGGLE_FROM_ED,
            buffer,
            usize::from(pipe.max_packet),
            dummy,
        );
        self.pipes[index].tail = (pipe.tail + 1) % PIPE_TDS;
        self.hw
            .mem_write(self.layout.pipe_ed(index) + 4, dummy as u32);
    }

    /// What a retired TD's ConditionCode means for the transfer.
    fn outcome(code: u32) -> core::result::Result<(), Transfer> {
        match code {
            condition::NO_ERROR => Ok(()),
            condition::STALL => Err(Transfer::Stalled),
            condition::CRC
            | condition::BIT_STUFFING
            | condition::DEVICE_NOT_RESPONDING
            | condition::PID_CHECK_FAILURE
            | condition::UNEXPECTED_PID => Err(Transfer::Failed(TransferError::NoResponse)),
            condition::DATA_TOGGLE_MISMATCH => Err(Transfer::Failed(TransferError::Toggle)),
            condition::DATA_OVERRUN => Err(Transfer::Failed(TransferError::Babble)),
            // With bufferRounding set a short packet is no error, so an
            // underrun is the memory's (or the controller's) fault.
            condition::DATA_UNDERRUN | condition::BUFFER_OVERRUN | condition::BUFFER_UNDERRUN => {
                Err(Transfer::Failed(TransferError::DataBuffer))
            }
            // Reserved, or NotAccessed on a TD the controller retired.
            _ => Err(Transfer::Failed(TransferError::Controller)),
        }
    }

    /// Puts a halted (or skipped) ED's HeadP back at its TailP, dropping
    /// whatever TDs are left, with Halted clear and the toggle carry kept
    /// (or reset to DATA0).
    fn restart_ed(&mut self, ed_address: u64, tail: u64, reset_toggle: bool) {
        let head = self.hw.mem_read(ed_address + 8);
        let carry = if reset_toggle {
            0
        } else {
            head & ed::TOGGLE_CARRY
        };
        self.hw.mem_write(ed_address + 4, tail as u32);
        self.hw.mem_write(ed_address + 8, tail as u32 | carry);
    }
}

impl<H: PciHardware> HostController for Ohci<H> {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Ohci
    }

    type Hardware = H;

    fn hardware(&mut self) -> &mut H {
        &mut self.hw
    }

    type StartError = OhciError;

    /// Takes the controller from the firmware. SMM owns it while
    /// HcControl.InterruptRouting is set: an OwnershipChangeRequest asks
    /// it to let go, and the driver waits up to 500 ms (Linux). If it never
    /// does, the controller is left alone: no reset, no schedule.
    #[optimize(size)] // run once at start-up: small beats fast
    fn take_ownership(&mut self) -> Handoff {
        if self.state != State::New {
            return Handoff::NotOwned;
        }
        let control = self.read(HC_CONTROL);
        if control == u32::MAX || control & CONTROL_IR == 0 {
            return Handoff::NotOwned;
        }
        let start = self.hw.now_micros();
        // The ownership change interrupt is what SMM waits for.
        self.write(HC_INTERRUPT_ENABLE, INTERRUPT_OC);
        self.write(HC_COMMAND_STATUS, COMMAND_OCR);
        let (control, released) =
            self.wait_register(HC_CONTROL, HANDOFF_MICROS, |c| c & CONTROL_IR == 0);
        if released {
            let micros = self.hw.now_micros().saturating_sub(start);
            Handoff::Released { micros }
        } else {
            self.hw.log(format_args!(
                "ohci: SMM kept the controller for {} ms (HcControl {control:#010x}): left alone",
                HANDOFF_MICROS / 1000
            ));
            self.state = State::LeftToFirmware;
            Handoff::NeverReleased
        }
    }

    /// Resets the controller, builds the HCCA and the interrupt tree,
    /// makes it operational with the control and periodic lists on and
    /// every interrupt off, and powers the root ports. Bounded throughout.
    #[optimize(size)] // run once at start-up: small beats fast
    fn reset_and_start(&mut self) -> Result<()> {
        match self.state {
            State::LeftToFirmware => return Err(OhciError::OwnedByFirmware),
            State::New | State::Stopped => {}
            State::Running => return Ok(()),
        }
        let revision = self.read(HC_REVISION);
        let control = self.read(HC_CONTROL);
        if revision == u32::MAX || control == u32::MAX {
            return Err(OhciError::Absent);
        }
        if revision & 0xFF != 0x10 {
            self.hw.log(format_args!(
                "ohci: revision {:#04x}, not 1.0; trying",
                revision & 0xFF
            ));
        }
        self.remote_wakeup_connected = control & CONTROL_RWC;
        self.write(HC_INTERRUPT_DISABLE, INTERRUPT_ALL);

        // What the firmware left running is stopped as Linux's ohci_run
        // does: an operational controller is reset at once, a suspended
        // one resumed first, anything else held in UsbReset for 50 ms so
        // the devices see a bus reset.
        let (next_state, wait) = match control & CONTROL_HCFS_MASK {
            HCFS_OPERATIONAL => (HCFS_OPERATIONAL, 0),
            HCFS_SUSPEND | HCFS_RESUME => (HCFS_RESUME, USB_RESUME_MICROS),
            _ => (HCFS_RESET, USB_RESET_MICROS),
        };
        self.write(HC_CONTROL, self.remote_wakeup_connected | next_state);
        self.read(HC_CONTROL);
        self.hw.pause(wait);

        let saved = self.read(HC_FM_INTERVAL);
        let mut interval = saved & FM_INTERVAL_FI_MASK;
        if !FRAME_INTERVALS.contains(&interval) {
            self.hw.log(format_args!(
                "ohci: frame interval {interval} from the firmware is implausible; using {FRAME_INTERVAL_DEFAULT}"
            ));
            interval = FRAME_INTERVAL_DEFAULT;
        }
        // FSLargestDataPacket as the specification computes it (5.4):
        // the frame less the maximum bit-stuffing and SOF overhead.
        let largest_packet = (6 * (interval - 210) / 7) & FM_INTERVAL_FSMPS_MASK;
        self.frame_interval = largest_packet << FM_INTERVAL_FSMPS_SHIFT | interval;

        // Everything in memory is ready before the reset: after it the
        // controller must be made operational within 2 ms.
        self.build_schedule();

        self.write(HC_COMMAND_STATUS, COMMAND_HCR);
        let (_, reset_done) =
            self.wait_register(HC_COMMAND_STATUS, RESET_MICROS, |s| s & COMMAND_HCR == 0);
        if !reset_done {
            self.hw
                .log(format_args!("ohci: HostControllerReset did not clear"));
            self.state = State::Stopped;
            return Err(OhciError::ResetTimedOut);
        }
        // Now in UsbSuspend.
        self.write(HC_CONTROL_HEAD_ED, 0);
        self.write(HC_BULK_HEAD_ED, 0);
        let hcca = self.layout.hcca as u32;
        self.write(HC_HCCA, hcca);
        let toggle = self.read(HC_FM_INTERVAL) & FM_INTERVAL_FIT;
        self.write(
            HC_FM_INTERVAL,
            (toggle ^ FM_INTERVAL_FIT) | self.frame_interval,
        );
        self.write(HC_PERIODIC_START, (9 * interval / 10) & FM_INTERVAL_FI_MASK);
        let frame_interval = self.read(HC_FM_INTERVAL);
        let periodic_start = self.read(HC_PERIODIC_START);
        let hcca_back = self.read(HC_HCCA);
        if frame_interval >> FM_INTERVAL_FSMPS_SHIFT & FM_INTERVAL_FSMPS_MASK == 0
            || periodic_start == 0
            || hcca_back != hcca
        {
            self.hw.log(format_args!(
                "ohci: init failed: HcFmInterval {frame_interval:#010x}, HcPeriodicStart {periodic_start:#x}, HcHCCA {hcca_back:#x}"
            ));
            self.state = State::Stopped;
            return Err(OhciError::BadInitialisation);
        }
        self.write(HC_INTERRUPT_STATUS, INTERRUPT_ALL & !INTERRUPT_MIE);
        self.write(
            HC_CONTROL,
            self.remote_wakeup_connected
                | CONTROL_CBSR_4_TO_1
                | CONTROL_PLE
                | CONTROL_CLE
                | HCFS_OPERATIONAL,
        );
        let control = self.read(HC_CONTROL);
        if control & CONTROL_HCFS_MASK != HCFS_OPERATIONAL {
            self.hw.log(format_args!(
                "ohci: not operational: HcControl {control:#010x}"
            ));
            self.state = State::Stopped;
            return Err(OhciError::NotOperational);
        }
        self.state = State::Running;
        self.power_ports();
        Ok(())
    }

    fn root_ports(&self) -> u8 {
        self.ports
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        if self.state != State::Running || !self.valid_port(port) {
            return PortStatus::default();
        }
        let status = self.read(Self::port_register(port));
        if status == u32::MAX {
            return PortStatus::default();
        }
        PortStatus {
            connected: status & PORT_CCS != 0,
            enabled: status & PORT_PES != 0,
            low_speed: status & PORT_LSDA != 0,
            connect_changed: status & PORT_CSC != 0,
            companion_owned: false,
        }
    }

    fn clear_port_change(&mut self, port: u8) {
        if self.state == State::Running && self.valid_port(port) {
            // Only the write-1-to-clear change bits: bit 0 would be
            // ClearPortEnable.
            self.write(
                Self::port_register(port),
                PORT_CSC | PORT_PESC | PORT_PSSC | PORT_OCIC,
            );
        }
    }

    fn port_reset_begin(&mut self, port: u8) {
        if self.state == State::Running && self.valid_port(port) {
            let register = Self::port_register(port);
            self.write(register, PORT_PRSC);
            self.write(register, PORT_PRS);
            let now = self.hw.now_micros();
            self.reset = Some(RootReset::begin(port, now, PORT_RESET_PULSE_BOUND_MICROS));
        }
    }

    /// The controller times each pulse and says it is over with
    /// PortResetStatusChange; another is started while the port has been
    /// in reset less than [`ROOT_RESET_MICROS`] (stage: pulses after the first).
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome> {
        let reset = self.reset.take().filter(|r| r.port == port);
        let (Some(mut reset), State::Running) = (reset, self.state) else {
            return Some(ResetOutcome::Failed);
        };
        let register = Self::port_register(port);
        let status = self.read(register);
        let now = self.hw.now_micros();
        if status == u32::MAX {
            return Some(ResetOutcome::Failed);
        }
        if status & PORT_PRS != 0 || status & PORT_PRSC == 0 {
            if now < reset.bound {
                self.reset = Some(reset);
                return None;
            }
            self.write(register, PORT_PRSC | PORT_PESC);
            self.hw.log(format_args!(
                "ohci: port {port} reset did not end: {status:#010x}"
            ));
            return Some(ResetOutcome::Failed);
        }
        self.write(register, PORT_PRSC | PORT_PESC);
        if status & PORT_CCS != 0 && now < reset.until && reset.stage + 1 < PORT_RESET_PULSES {
            self.write(register, PORT_PRS);
            reset.stage += 1;
            reset.bound = now + PORT_RESET_PULSE_BOUND_MICROS;
            self.reset = Some(reset);
            return None;
        }
        if status & PORT_CCS == 0 || status & PORT_PES == 0 {
            return Some(ResetOutcome::Failed);
        }
        Some(ResetOutcome::Enabled(if status & PORT_LSDA != 0 {
            Speed::Low
        } else {
            Speed::Full
        }))
    }

    fn port_disable(&mut self, port: u8) {
        if self.state == State::Running && self.valid_port(port) {
            self.write(Self::port_register(port), PORT_CLEAR_ENABLE);
        }
    }

    fn device_new(&mut self, info: DeviceInfo) -> core::result::Result<DeviceId, HostError> {
        self.running()?;
        if matches!(info.speed, Speed::High | Speed::Super) || !self.valid_port(info.root_port) {
            return Err(HostError::Invalid);
        }
        let Some(index) = self.devices.iter().position(|d| !d.in_use) else {
            self.hw
                .log(format_args!("ohci: no room for another device"));
            return Err(HostError::NoRoom);
        };
        self.devices[index] = Device {
            in_use: true,
            address: 0,
            low_speed: info.speed == Speed::Low,
            max_packet: 8,
            tail: 0,
            transfer: None,
        };
        let address = self.layout.control_ed(index);
        let dummy = self.layout.control_td(index, 0);
        self.write_dummy_td(dummy);
        self.write_control_ed(index, false);
        self.hw.mem_write(address + 4, dummy as u32);
        self.hw.mem_write(address + 8, dummy as u32);
        self.link_control_ed(index);
        Ok(DeviceId(index as u8))
    }

    fn device_set_address(
        &mut self,
        device: DeviceId,
        address: u8,
    ) -> core::result::Result<(), HostError> {
        let index = self.device(device)?;
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[index].address = address;
        self.write_control_ed(index, false);
        Ok(())
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> core::result::Result<(), HostError> {
        let index = self.device(device)?;
        let allowed = if self.devices[index].low_speed {
            max_packet == 8
        } else {
            matches!(max_packet, 8 | 16 | 32 | 64)
        };
        if !allowed {
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[index].max_packet = max_packet;
        self.write_control_ed(index, false);
        Ok(())
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        _ports: u8,
        _multi_tt: bool,
    ) -> core::result::Result<(), HostError> {
        // A full-speed hub needs nothing of the controller: low-speed
        // packets to the devices behind it go with PRE from the ED's S bit.
        self.device(device).map(|_| ())
    }

    fn device_remove(&mut self, device: DeviceId) {
        let Ok(index) = self.device(device) else {
            return;
        };
        self.write_control_ed(index, true);
        let mut pipes = [false; MAX_PIPES];
        for (pipe, closing) in pipes.iter_mut().enumerate() {
            if self.pipes[pipe].in_use && self.pipes[pipe].device == index {
                self.unlink_pipe(pipe);
                *closing = true;
            }
        }
        self.unlink_control_ed(index);
        if self.state == State::Running {
            // One new frame and the controller holds none of these EDs.
            self.wait_next_frame();
            self.finish_control_unlink();
        }
        for (pipe, closing) in pipes.iter().enumerate() {
            if *closing {
                self.pipes[pipe] = Pipe::default();
            }
        }
        self.devices[index] = Device::default();
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> core::result::Result<(), HostError> {
        self.running()?;
        let index = self.device(device)?;
        let length = usize::from(setup.length);
        if length > MAX_CONTROL_DATA || (!setup.is_in() && out.len() < length) {
            return Err(HostError::Invalid);
        }
        if self.devices[index].transfer.is_some() {
            return Err(HostError::Busy);
        }
        let first = self.devices[index].tail;
        let setup_buffer = self.layout.setup(index);
        let data_buffer = self.layout.control_data(index);
        self.copy_to_dma(setup_buffer, &setup.bytes());
        if !setup.is_in() {
            self.copy_to_dma(data_buffer, &out[..length]);
        }
        let setup_td = self.layout.control_td(index, first);
        let mut slot = first + 1;
        let mut next = self.layout.control_td(index, slot);
        self.write_td(
            setup_td,
            td::NOT_ACCESSED | td::PID_SETUP | td::TOGGLE_DATA0 | td::DELAY_INTERRUPT_NONE,
            setup_buffer,
            8,
            next,
        );
        if length > 0 {
            let data_td = next;
            slot += 1;
            next = self.layout.control_td(index, slot);
            let pid = if setup.is_in() {
                td::PID_IN | td::BUFFER_ROUNDING
            } else {
                td::PID_OUT
            };
            // The data stage starts at DATA1; the controller toggles
            // between its packets in the TD.
            self.write_td(
                data_td,
                td::NOT_ACCESSED | pid | td::TOGGLE_DATA1 | td::DELAY_INTERRUPT_NONE,
                data_buffer,
                length,
                next,
            );
        }
        let status_td = next;
        slot += 1;
        let dummy = self.layout.control_td(index, slot);
        // The status stage goes the other way from the data (IN without
        // data), always DATA1.
        let status_pid = if length > 0 && setup.is_in() {
            td::PID_OUT
        } else {
            td::PID_IN
        };
        self.write_td(
            status_td,
            td::NOT_ACCESSED | status_pid | td::TOGGLE_DATA1 | td::DELAY_INTERRUPT_NONE,
            0,
            0,
            dummy,
        );
        self.write_dummy_td(dummy);
        self.devices[index].tail = slot % CONTROL_TDS;
        self.devices[index].transfer = Some(ControlTransfer {
            first,
            length,
            is_in: setup.is_in(),
        });
        // TailP last: the TDs are the controller's from here.
        self.hw
            .mem_write(self.layout.control_ed(index) + 4, dummy as u32);
        self.write(HC_COMMAND_STATUS, COMMAND_CLF);
        Ok(())
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        let Ok(index) = self.device(device) else {
            return Transfer::Failed(TransferError::Controller);
        };
        let Some(transfer) = self.devices[index].transfer else {
            return Transfer::Failed(TransferError::Controller);
        };
        if self.state != State::Running {
            self.devices[index].transfer = None;
            return Transfer::Failed(TransferError::Controller);
        }
        let ed_address = self.layout.control_ed(index);
        let tail = self.layout.control_td(index, self.devices[index].tail);
        let head = self.hw.mem_read(ed_address + 8);
        let halted = head & ed::HALTED != 0;
        if !halted && u64::from(head & ed::POINTER) != tail {
            return Transfer::Pending;
        }
        // Every TD is retired, or the ED halted on one: the first that
        // did not end in NoError says how the transfer went.
        let stages = if transfer.length > 0 { 3 } else { 2 };
        let mut result = Ok(());
        for stage in 0..stages {
            let address = self.layout.control_td(index, transfer.first + stage);
            let code = td::condition(self.hw.mem_read(address));
            if let Err(failure) = Self::outcome(code) {
                result = Err(failure);
                break;
            }
        }
        if halted {
            self.restart_ed(ed_address, tail, true);
        }
        self.devices[index].transfer = None;
        if let Err(failure) = result {
            return failure;
        }
        if halted {
            // Halted, yet every TD says NoError.
            return Transfer::Failed(TransferError::Controller);
        }
        if transfer.length == 0 {
            return Transfer::Complete(0);
        }
        let data_td = self.layout.control_td(index, transfer.first + 1);
        let buffer = self.layout.control_data(index);
        let Some(moved) = self.bytes_moved(data_td, buffer, transfer.length) else {
            return Transfer::Failed(TransferError::Controller);
        };
        if transfer.is_in {
            let copied = moved.min(into.len());
            self.copy_from_dma(buffer, &mut into[..copied]);
        }
        Transfer::Complete(moved)
    }

    fn control_cancel(&mut self, device: DeviceId) {
        let Ok(index) = self.device(device) else {
            return;
        };
        if self.devices[index].transfer.take().is_none() {
            return;
        }
        let ed_address = self.layout.control_ed(index);
        let tail = self.layout.control_td(index, self.devices[index].tail);
        // sKip, a new frame, and the controller is off the ED's TDs.
        self.write_control_ed(index, true);
        self.wait_next_frame();
        self.restart_ed(ed_address, tail, true);
        self.write_control_ed(index, false);
    }

    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> core::result::Result<PipeId, HostError> {
        self.running()?;
        let device_index = self.device(device)?;
        if !(1..=15).contains(&endpoint) || max_packet == 0 || usize::from(max_packet) > MAX_REPORT
        {
            return Err(HostError::Invalid);
        }
        let Some(index) = self.pipes.iter().position(|p| !p.in_use) else {
            self.hw
                .log(format_args!("ohci: no room for another interrupt pipe"));
            return Err(HostError::NoRoom);
        };
        // The largest power of two not above the interval, at most 32.
        let interval = match interval.min(MAX_INTERVAL) {
            0 => 1,
            frames => 1 << (7 - frames.leading_zeros()),
        };
        // The branch of that interval with the fewest pipes on it.
        let branch = (0..usize::from(interval))
            .min_by_key(|&branch| {
                self.pipes
                    .iter()
                    .filter(|p| p.in_use && p.interval == interval && p.branch == branch)
                    .count()
            })
            .unwrap_or(0);
        let node = tree_node(interval, branch);
        let owner = self.devices[device_index];
        self.pipes[index] = Pipe {
            in_use: true,
            device: device_index,
            max_packet,
            interval,
            branch,
            tail: 0,
            next: self.tree_next[node],
            stopped: false,
        };
        let ed_address = self.layout.pipe_ed(index);
        let first = self.layout.pipe_td(index, 0);
        self.hw.mem_write(
            ed_address,
            ed::control(
                owner.address,
                endpoint,
                ed::DIRECTION_IN,
                owner.low_speed,
                max_packet,
            ),
        );
        self.hw.mem_write(ed_address + 8, first as u32);
        self.hw.mem_write(ed_address + 12, self.tree_next[node]);
        // HeadP at slot 0, which the first request fills.
        self.queue_report(index);
        // Then the ED goes on the tree after its node.
        self.hw
            .mem_write(self.layout.tree_ed(node) + 12, ed_address as u32);
        self.tree_next[node] = ed_address as u32;
        Ok(PipeId(index as u8))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        let Ok(index) = self.pipe(pipe) else {
            return Transfer::Failed(TransferError::Controller);
        };
        if self.pipes[index].stopped {
            return Transfer::Pending;
        }
        if self.state != State::Running {
            self.pipes[index].stopped = true;
            return Transfer::Failed(TransferError::Controller);
        }
        let ed_address = self.layout.pipe_ed(index);
        let request = self.layout.pipe_td(index, self.pipes[index].tail + 1);
        let dummy = self.layout.pipe_td(index, self.pipes[index].tail);
        let head = self.hw.mem_read(ed_address + 8);
        let halted = head & ed::HALTED != 0;
        let retired = u64::from(head & ed::POINTER) == dummy;
        if !halted && !retired {
            return Transfer::Pending;
        }
        if !retired {
            // Halted on a TD it did not retire: nothing to trust.
            self.pipes[index].stopped = true;
            return Transfer::Failed(TransferError::Controller);
        }
        let code = td::condition(self.hw.mem_read(request));
        if let Err(failure) = Self::outcome(code) {
            self.pipes[index].stopped = true;
            return failure;
        }
        if halted {
            self.pipes[index].stopped = true;
            return Transfer::Failed(TransferError::Controller);
        }
        let buffer = self.layout.report(index);
        let length = usize::from(self.pipes[index].max_packet);
        let Some(moved) = self.bytes_moved(request, buffer, length) else {
            self.pipes[index].stopped = true;
            return Transfer::Failed(TransferError::Controller);
        };
        let copied = moved.min(into.len());
        self.copy_from_dma(buffer, &mut into[..copied]);
        self.queue_report(index);
        Transfer::Complete(moved)
    }

    fn interrupt_restart(
        &mut self,
        pipe: PipeId,
        reset_toggle: bool,
    ) -> core::result::Result<(), HostError> {
        let index = self.pipe(pipe)?;
        self.running()?;
        let ed_address = self.layout.pipe_ed(index);
        let head = self.hw.mem_read(ed_address + 8);
        let control = self.hw.mem_read(ed_address);
        let halted = head & ed::HALTED != 0;
        if !halted {
            // The controller may be working on it: sKip for a frame.
            self.hw.mem_write(ed_address, control | ed::SKIP);
            self.wait_next_frame();
        }
        // The ED is halted or skipped: HeadP is the driver's to write.
        // Back at the dummy with Halted clear (nothing queued), then the
        // next request goes in as always.
        let dummy = self.layout.pipe_td(index, self.pipes[index].tail);
        self.restart_ed(ed_address, dummy, reset_toggle);
        self.queue_report(index);
        self.hw.mem_write(ed_address, control & !ed::SKIP);
        self.pipes[index].stopped = false;
        Ok(())
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        let Ok(index) = self.pipe(pipe) else {
            return;
        };
        self.unlink_pipe(index);
        self.wait_next_frame();
        self.pipes[index] = Pipe::default();
    }

    fn anything_happened(&mut self) -> bool {
        if self.state != State::Running {
            return false;
        }
        let status = self.read(HC_INTERRUPT_STATUS);
        if status == u32::MAX {
            self.hw.log(format_args!(
                "ohci: registers read all ones: controller gone"
            ));
            self.state = State::Stopped;
            return false;
        }
        let events = status & (INTERRUPT_WDH | INTERRUPT_RHSC | INTERRUPT_UE);
        if events == 0 {
            return false;
        }
        if events & INTERRUPT_WDH != 0 {
            self.consume_done_head();
        }
        if events & INTERRUPT_UE != 0 {
            self.hw.log(format_args!(
                "ohci: unrecoverable error: controller stopped"
            ));
            self.state = State::Stopped;
        }
        self.write(HC_INTERRUPT_STATUS, events & !INTERRUPT_WDH);
        true
    }

    fn halt(&mut self) -> bool {
        match self.state {
            State::LeftToFirmware => {
                self.hw
                    .log(format_args!("ohci: left to the firmware, not halted"));
                return false;
            }
            State::New | State::Stopped | State::Running => {}
        }
        // As Linux's shutdown: no interrupts, the lists stopped, the
        // controller in UsbReset; the ports keep their power.
        self.write(HC_INTERRUPT_DISABLE, INTERRUPT_ALL);
        self.write(HC_CONTROL, self.remote_wakeup_connected | HCFS_RESET);
        self.state = State::Stopped;
        let (control, halted) = self.wait_register(HC_CONTROL, HALT_MICROS, |c| {
            c != u32::MAX && c & (CONTROL_HCFS_MASK | CONTROL_PLE | CONTROL_CLE) == HCFS_RESET
        });
        if !halted {
            self.hw.log(format_args!(
                "ohci: did not halt: HcControl {control:#010x}"
            ));
        }
        halted
    }
}
