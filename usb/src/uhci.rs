//! A polled UHCI driver (UHCI 1.1: Intel PIIX and ICH, VIA), the
//! [`HostController`] the device layer drives for USB 1.1 keyboards and hubs.
//!
//! - Taking it from the BIOS: the SMI enables in PCI configuration register
//!   LEGSUP (0xC0) cleared and its trap status bits written back, as Linux's
//!   `uhci_check_and_reset_hc` does; bounded.
//! - Reset: a global reset held 20 ms, then a host controller reset with a
//!   bounded wait; the root ports counted as Linux does (bit 7 reads 1).
//! - The schedule (`usb/src/uhci/layout.rs`): a 1024-entry frame list whose entries point
//!   at one of five interrupt skeleton queue heads (periods 2 to 32), each
//!   of which ends in the period-1 skeleton, which ends in the control
//!   skeleton: every frame visits its interrupt queues, then every device's
//!   control queue head. A pipe's queue head hangs after its period's
//!   skeleton; a device's after the control skeleton.
//! - Control transfers: SETUP (DATA0), data TDs of the device's packet size
//!   (DATA1 first, alternating, short packet detect on IN), status (DATA1,
//!   interrupt on completion), linked depth first so a transfer can end in
//!   one frame; completion read by walking the TDs.
//! - Interrupt-in pipes: one TD per pipe whose data toggle the driver keeps,
//!   flipped on each good report and re-armed.
//! - Every slot (device, pipe) has its own fixed memory, reused once a frame
//!   has passed since the controller could last have seen it.

mod layout;
#[cfg(test)]
mod tests;

use crate::host::wait_until;
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, RootReset, Setup, Speed, Transfer, TransferError, MAX_CONTROL_DATA, MAX_REPORT,
};
use crate::PciHardware;
use core::fmt;
use layout::{
    frame_skeleton, period_index, td_actual_length, td_token, Layout, CMD_CONFIGURE,
    CMD_GLOBAL_RESET, CMD_HOST_RESET, CMD_MAX_PACKET_64, CMD_RUN, CONTROL_SKELETON, FRAMES,
    FRBASEADD, FRNUM, LEGACY_OFFSET, LEGACY_PIRQ_ENABLE, LEGACY_SMI_ENABLES, LEGACY_STATUS_CLEAR,
    LINK_DEPTH_FIRST, LINK_QUEUE_HEAD, LINK_TERMINATE, MAX_CONTROL_TDS, MAX_PORT_REGISTERS,
    PERIODS, PID_IN, PID_OUT, PID_SETUP, PORTSC1, PORT_ALWAYS_ONE, PORT_CONNECTED,
    PORT_CONNECT_CHANGE, PORT_ENABLED, PORT_ENABLE_CHANGE, PORT_LOW_SPEED, PORT_RESET,
    PORT_WRITE_CLEAR, PORT_WRITE_ZERO, SKELETONS, STS_CAUSES, STS_ERROR_INTERRUPT, STS_HALTED,
    STS_HOST_SYSTEM_ERROR, STS_INTERRUPT, STS_PROCESS_ERROR, TD_ACTIVE, TD_BABBLE, TD_BITSTUFF,
    TD_CRC_TIMEOUT, TD_DATA_BUFFER_ERROR, TD_INTERRUPT_ON_COMPLETE, TD_LOW_SPEED,
    TD_SHORT_PACKET_DETECT, TD_STALLED, TD_THREE_ERRORS, USBCMD, USBINTR, USBSTS,
};
pub use layout::{DMA_BYTES_NEEDED, MAX_DEVICES, MAX_PIPES};

/// How long the global reset is held (UHCI 1.1 2.1.1: at least 10 ms).
pub const GLOBAL_RESET_MICROS: u64 = 20_000;
/// The longest wait for HCRESET to clear itself.
pub const HOST_RESET_MICROS: u64 = 50_000;
/// The longest wait for HCHalted to follow Run/Stop (a frame is 1 ms).
pub const HALT_MICROS: u64 = 10_000;
/// The longest the firmware is given to let its SMI enables go.
pub const HANDOFF_MICROS: u64 = 10_000;
/// The longest wait for the frame number to move on before memory the
/// controller may have seen is used again.
pub const FRAME_WAIT_MICROS: u64 = 3_000;
/// After Port Reset is cleared, before the port is enabled (Linux: 10 us).
pub const PORT_RESET_RECOVERY_MICROS: u64 = 10;
/// The longest wait for a port to leave reset and take its enable.
pub const PORT_ENABLE_MICROS: u64 = 5_000;
/// Tries at setting Port Enabled after a reset.
pub const PORT_ENABLE_TRIES: u32 = 10;
/// `anything_happened` reads a root port instead of USBSTS once in this
/// many calls (UHCI has no port-change bit in USBSTS).
pub const PORT_CHECK_EVERY: u32 = 16;

/// Why the driver could not take or start the controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UhciError {
    /// The DMA region is too small, above 4 GiB, or wraps.
    DmaRegion,
    /// The firmware kept its SMI enables: the controller is left alone.
    FirmwareOwns,
    /// HCRESET did not clear itself.
    ResetTimeout,
    /// The controller did not halt (after the reset).
    NotHalted,
    /// FRBASEADD did not keep the frame list's address.
    FrameListRejected,
    /// No port register reads as a port.
    NoRootPorts,
    /// The controller stayed halted after Run/Stop was set.
    StartTimeout,
}

impl fmt::Display for UhciError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            UhciError::DmaRegion => "DMA region too small or above 4 GiB",
            UhciError::FirmwareOwns => "the firmware keeps the controller",
            UhciError::ResetTimeout => "host controller reset never ended",
            UhciError::NotHalted => "controller not halted after its reset",
            UhciError::FrameListRejected => "FRBASEADD did not take the frame list",
            UhciError::NoRootPorts => "no root port registers",
            UhciError::StartTimeout => "controller did not start",
        })
    }
}

/// Where the controller stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// As the driver found it.
    Fresh,
    /// Taken from the firmware, not yet reset.
    Owned,
    /// The firmware did not let go: hands off.
    FirmwareOwned,
    /// Running the schedule.
    Running,
    /// Halted by [`HostController::halt`], or found halted, dead or gone.
    Stopped,
}

/// A control transfer in flight on a device's endpoint 0.
#[derive(Clone, Copy, Debug)]
struct Control {
    /// TDs used: SETUP, `tds - 2` data TDs, status.
    tds: usize,
    /// The data stage is IN.
    is_in: bool,
    /// The data stage's bytes asked for.
    length: usize,
    /// The first TD not yet seen complete.
    cursor: usize,
    /// Data bytes moved by the TDs seen complete.
    moved: usize,
}

#[derive(Clone, Copy, Debug)]
struct DeviceSlot {
    in_use: bool,
    address: u8,
    max_packet: u16,
    low_speed: bool,
    control: Option<Control>,
    /// The frame in which the controller may last have seen this slot's
    /// queue head or TDs (unlinked or retired then): reused only after it.
    quiet_after: Option<u16>,
}

const FREE_DEVICE: DeviceSlot = DeviceSlot {
    in_use: false,
    address: 0,
    max_packet: 8,
    low_speed: false,
    control: None,
    quiet_after: None,
};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PipeState {
    /// The TD is armed.
    Armed,
    /// Stalled or failed: waits for `interrupt_restart`.
    Waiting,
}

#[derive(Clone, Copy, Debug)]
struct PipeSlot {
    in_use: bool,
    device: usize,
    endpoint: u8,
    max_packet: u16,
    /// The data toggle the next report must come with.
    toggle: bool,
    /// Skeleton index: polled every 2^period frames.
    period: usize,
    state: PipeState,
    quiet_after: Option<u16>,
}

const FREE_PIPE: PipeSlot = PipeSlot {
    in_use: false,
    device: 0,
    endpoint: 0,
    max_packet: 0,
    toggle: false,
    period: 0,
    state: PipeState::Waiting,
    quiet_after: None,
};

/// A UHCI controller and everything the driver keeps of it.
#[derive(Debug)]
pub struct Uhci<H: PciHardware> {
    hw: H,
    layout: Layout,
    ports: u8,
    state: State,
    devices: [DeviceSlot; MAX_DEVICES],
    pipes: [PipeSlot; MAX_PIPES],
    /// `anything_happened` calls, for the port check every
    /// [`PORT_CHECK_EVERY`]th.
    idle_calls: u32,
    /// The root port (0-based) the next port check reads.
    next_port_checked: u8,
    /// The root port reset running (one at a time).
    reset: Option<RootReset>,
}

impl<H: PciHardware> Uhci<H> {
    /// A driver for the controller behind `hw`, with the DMA memory
    /// [dma_base, dma_base + dma_bytes) (physically contiguous, below
    /// 4 GiB, at least [`DMA_BYTES_NEEDED`] from its first 4 KiB boundary).
    /// Touches nothing yet.
    #[optimize(size)] // run once at start-up: small beats fast
    pub fn new(hw: H, dma_base: u64, dma_bytes: u64) -> Result<Self, UhciError> {
        let layout = Layout::new(dma_base, dma_bytes).ok_or(UhciError::DmaRegion)?;
        Ok(Uhci {
            hw,
            layout,
            ports: 0,
            state: State::Fresh,
            devices: [FREE_DEVICE; MAX_DEVICES],
            pipes: [FREE_PIPE; MAX_PIPES],
            idle_calls: 0,
            next_port_checked: 0,
            reset: None,
        })
    }

    /// Devices and pipes in use, for the tests.
    #[cfg(test)]
    fn slots_in_use(&self) -> (usize, usize) {
        let devices = self.devices.iter().filter(|d| d.in_use).count();
        let pipes = self.pipes.iter().filter(|p| p.in_use).count();
        (devices, pipes)
    }

    /// Linux's `uhci_count_ports`: the port registers are read until one
    /// has bit 7 (always 1) clear or reads all ones; more than 7 means the
    /// guess went wrong and 2 are taken, as the specification has.
    fn count_ports(&mut self) -> u8 {
        let mut count = 0;
        while count < MAX_PORT_REGISTERS {
            let value = self.hw.read16(PORTSC1 + 2 * u32::from(count));
            if value & PORT_ALWAYS_ONE == 0 || value == 0xFFFF {
                break;
            }
            count += 1;
        }
        if count > 7 {
            self.hw
                .log(format_args!("uhci: {count} ports read as ports; taking 2"));
            count = 2;
        }
        count
    }

    /// The frame list, the skeleton queue heads and empty slots.
    fn build_schedule(&mut self) {
        // Skeletons first, so every frame entry points at a finished chain.
        for index in 0..SKELETONS {
            let qh = self.layout.skeleton(index);
            let next = self.skeleton_next(index);
            self.dma_write(qh, next);
            self.dma_write(qh + 4, LINK_TERMINATE);
        }
        for slot in 0..MAX_DEVICES {
            let qh = self.layout.device_qh(slot);
            self.dma_write(qh, LINK_TERMINATE);
            self.dma_write(qh + 4, LINK_TERMINATE);
        }
        for slot in 0..MAX_PIPES {
            let qh = self.layout.pipe_qh(slot);
            self.dma_write(qh, LINK_TERMINATE);
            self.dma_write(qh + 4, LINK_TERMINATE);
            self.dma_write(self.layout.pipe_td(slot) + 4, 0);
        }
        for frame in 0..FRAMES {
            let skeleton = self.layout.skeleton(frame_skeleton(frame));
            self.dma_write(
                self.layout.frame_list() + 4 * frame,
                skeleton | LINK_QUEUE_HEAD,
            );
        }
    }

    /// Where a skeleton's chain goes after its own queue heads: every
    /// period-2^k skeleton to period 1, period 1 to control, control ends.
    fn skeleton_next(&self, index: usize) -> u32 {
        match index {
            0 => self.layout.skeleton(CONTROL_SKELETON) | LINK_QUEUE_HEAD,
            CONTROL_SKELETON => LINK_TERMINATE,
            _ => self.layout.skeleton(0) | LINK_QUEUE_HEAD,
        }
    }

    /// Re-links the control skeleton's chain: every device in use, in slot
    /// order. Written from the tail, so the controller always finds a whole
    /// chain; an unlinked queue head keeps its link into the chain.
    fn relink_devices(&mut self) {
        let mut next = LINK_TERMINATE;
        for slot in (0..MAX_DEVICES).rev() {
            if self.devices[slot].in_use {
                let qh = self.layout.device_qh(slot);
                self.dma_write(qh, next);
                next = qh | LINK_QUEUE_HEAD;
            }
        }
        self.dma_write(self.layout.skeleton(CONTROL_SKELETON), next);
    }

    /// Re-links period `period`'s chain, as [`Self::relink_devices`] does.
    fn relink_period(&mut self, period: usize) {
        let mut next = self.skeleton_next(period);
        for slot in (0..MAX_PIPES).rev() {
            let pipe = self.pipes[slot];
            if pipe.in_use && pipe.period == period {
                let qh = self.layout.pipe_qh(slot);
                self.dma_write(qh, next);
                next = qh | LINK_QUEUE_HEAD;
            }
        }
        self.dma_write(self.layout.skeleton(period), next);
    }

    fn dma_write(&mut self, address: u32, value: u32) {
        self.hw.mem_write(u64::from(address), value);
    }

    fn dma_read(&mut self, address: u32) -> u32 {
        self.hw.mem_read(u64::from(address))
    }

    /// Copies `bytes` to DMA memory at `address` (4-byte aligned), the last
    /// word padded with zeros.
    fn write_bytes(&mut self, address: u32, bytes: &[u8]) {
        for (index, chunk) in bytes.chunks(4).enumerate() {
            let mut word = [0; 4];
            word[..chunk.len()].copy_from_slice(chunk);
            self.dma_write(address + 4 * index as u32, u32::from_le_bytes(word));
        }
    }

    /// Copies DMA memory at `address` (4-byte aligned) into `into`.
    fn read_bytes(&mut self, address: u32, into: &mut [u8]) {
        for (index, chunk) in into.chunks_mut(4).enumerate() {
            let word = self.dma_read(address + 4 * index as u32).to_le_bytes();
            chunk.copy_from_slice(&word[..chunk.len()]);
        }
    }

    /// Busy-waits `micros` on the hardware clock.
    fn wait_micros(&mut self, micros: u64) {
        self.hw.pause(micros);
    }

    /// Waits until `(register & mask) == want`, at most `micros`
    /// ([`wait_until`]'s pace).
    fn wait_register(&mut self, offset: u32, mask: u16, want: u16, micros: u64) -> bool {
        wait_until(self, micros, |uhci| uhci.hw.read16(offset) & mask == want)
    }

    /// The current frame number (11 bits).
    fn frame_number(&mut self) -> u16 {
        self.hw.read16(FRNUM) & 0x7FF
    }

    /// Waits until the controller has left frame `frame` (or is halted),
    /// at most [`FRAME_WAIT_MICROS`]: after that it can no longer be
    /// looking at what was unlinked during that frame. A frame that does
    /// not end in time is logged and the wait ends anyway.
    fn wait_frame_after(&mut self, frame: u16) {
        let left = wait_until(self, FRAME_WAIT_MICROS, |uhci| {
            uhci.frame_number() != frame || uhci.hw.read16(USBSTS) & STS_HALTED != 0
        });
        if !left {
            // Real controllers move on every millisecond; an emulated one
            // moves on its host's timer, which a busy host runs late.
            // Giving up the controller would lose every keyboard on it for
            // a slow frame: the memory is reused, and at worst one transfer
            // fails and is recovered. A controller that has really stopped
            // is caught by USBSTS in `poll`.
            self.hw.log(format_args!(
                "uhci: frame number stuck at {frame} for {FRAME_WAIT_MICROS} us; going on"
            ));
        }
    }

    fn port_offset(&self, port: u8) -> Option<u32> {
        (1..=self.ports)
            .contains(&port)
            .then(|| PORTSC1 + 2 * u32::from(port - 1))
    }

    /// Reads a port register; `None` if the port does not exist or the
    /// register reads all ones (the controller is gone).
    fn read_port(&mut self, port: u8) -> Option<(u32, u16)> {
        let offset = self.port_offset(port)?;
        let value = self.hw.read16(offset);
        (value != 0xFFFF).then_some((offset, value))
    }

    /// What a port register may be written back as: no change bit cleared
    /// by accident, reserved bits zero (Linux's `CLR_RH_PORTSTAT`).
    fn port_keep(value: u16) -> u16 {
        value & !(PORT_WRITE_CLEAR | PORT_WRITE_ZERO)
    }

    fn device_slot(&self, device: DeviceId) -> Result<usize, HostError> {
        let slot = usize::from(device.0);
        if slot < MAX_DEVICES && self.devices[slot].in_use {
            Ok(slot)
        } else {
            Err(HostError::UnknownHandle)
        }
    }

    fn pipe_slot(&self, pipe: PipeId) -> Result<usize, HostError> {
        let slot = usize::from(pipe.0);
        if slot < MAX_PIPES && self.pipes[slot].in_use {
            Ok(slot)
        } else {
            Err(HostError::UnknownHandle)
        }
    }

    fn running(&self) -> Result<(), HostError> {
        if self.state == State::Running {
            Ok(())
        } else {
            Err(HostError::ControllerGone)
        }
    }

    /// Stops the device's control queue (if it was started) and notes the
    /// frame: its TDs are not written again until the frame has passed.
    fn retire_control(&mut self, slot: usize) {
        let qh = self.layout.device_qh(slot);
        self.dma_write(qh + 4, LINK_TERMINATE);
        self.devices[slot].control = None;
        let frame = self.frame_number();
        self.devices[slot].quiet_after = Some(frame);
    }

    /// Waits, if need be, until the controller can no longer see device
    /// slot `slot`'s old queue and TDs.
    fn quiet_device(&mut self, slot: usize) {
        if let Some(frame) = self.devices[slot].quiet_after.take() {
            self.wait_frame_after(frame);
        }
    }

    fn quiet_pipe(&mut self, slot: usize) {
        if let Some(frame) = self.pipes[slot].quiet_after.take() {
            self.wait_frame_after(frame);
        }
    }

    /// Which error an inactive TD's status names, if any.
    fn td_error(status: u32) -> Option<Transfer> {
        if status & TD_BABBLE != 0 {
            Some(Transfer::Failed(TransferError::Babble))
        } else if status & TD_DATA_BUFFER_ERROR != 0 {
            Some(Transfer::Failed(TransferError::DataBuffer))
        } else if status & (TD_CRC_TIMEOUT | TD_BITSTUFF) != 0 {
            Some(Transfer::Failed(TransferError::NoResponse))
        } else if status & TD_STALLED != 0 {
            Some(Transfer::Stalled)
        } else {
            None
        }
    }

    /// Writes a TD: link, token and buffer first, its control and status
    /// word (with Active) last, so the controller never runs half a TD.
    fn write_td(&mut self, address: u32, next: u32, control: u32, token: u32, buffer: u32) {
        self.dma_write(address, next);
        self.dma_write(address + 8, token);
        self.dma_write(address + 12, buffer);
        self.dma_write(address + 4, control);
    }

    /// Arms pipe `slot`'s TD with its current toggle and hands it to the
    /// controller through its queue head.
    fn arm_pipe(&mut self, slot: usize) {
        let pipe = self.pipes[slot];
        let device = self.devices[pipe.device];
        let speed = if device.low_speed { TD_LOW_SPEED } else { 0 };
        let token = td_token(
            PID_IN,
            device.address,
            pipe.endpoint,
            pipe.toggle,
            usize::from(pipe.max_packet),
        );
        let address = self.layout.pipe_td(slot);
        let buffer = self.layout.pipe_buffer(slot);
        self.write_td(
            address,
            LINK_TERMINATE,
            TD_ACTIVE | TD_THREE_ERRORS | TD_INTERRUPT_ON_COMPLETE | speed,
            token,
            buffer,
        );
        self.dma_write(self.layout.pipe_qh(slot) + 4, address);
        self.pipes[slot].state = PipeState::Armed;
    }

    /// Stops pipe `slot`'s queue after an error and notes the frame.
    fn stop_pipe(&mut self, slot: usize) {
        self.dma_write(self.layout.pipe_qh(slot) + 4, LINK_TERMINATE);
        self.pipes[slot].state = PipeState::Waiting;
        let frame = self.frame_number();
        self.pipes[slot].quiet_after = Some(frame);
    }

    /// Notices the controller halted behind the driver's back (a host
    /// system or process error, or a surprise removal).
    fn controller_died(&mut self, usbsts: u16) {
        self.hw.log(format_args!(
            "uhci: controller stopped (USBSTS {usbsts:#06x}); given up"
        ));
        self.state = State::Stopped;
    }
}

impl<H: PciHardware> HostController for Uhci<H> {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Uhci
    }

    type Hardware = H;

    fn hardware(&mut self) -> &mut H {
        &mut self.hw
    }

    type StartError = UhciError;

    /// Takes the controller from the BIOS: the SMI enables in LEGSUP are
    /// cleared and its trap status bits written back (Linux's
    /// `USBLEGSUP_RWC`, then 0: no PIRQ, the driver polls), re-tried until
    /// they read clear or [`HANDOFF_MICROS`] passed. Then USBINTR is zeroed
    /// and the controller stopped. A firmware that keeps its enables is
    /// logged and the controller left alone.
    #[optimize(size)] // run once at start-up: small beats fast
    fn take_ownership(&mut self) -> Handoff {
        let dword = self.hw.pci_config_read(LEGACY_OFFSET);
        let above = dword & 0xFFFF_0000;
        let found = dword as u16;
        let owned = found & LEGACY_SMI_ENABLES != 0;
        let start = self.hw.now_micros();
        let (mut last_write, mut legsup) = (None, found);
        let released = wait_until(self, HANDOFF_MICROS, |uhci| {
            let now = uhci.hw.now_micros();
            if last_write.is_none_or(|at| now.saturating_sub(at) >= 1_000) {
                uhci.hw
                    .pci_config_write(LEGACY_OFFSET, above | u32::from(LEGACY_STATUS_CLEAR));
                uhci.hw.pci_config_write(LEGACY_OFFSET, above);
                last_write = Some(now);
            }
            legsup = uhci.hw.pci_config_read(LEGACY_OFFSET) as u16;
            legsup & (LEGACY_SMI_ENABLES | LEGACY_PIRQ_ENABLE) == 0
        });
        let micros = self.hw.now_micros().saturating_sub(start);
        if !released {
            self.hw.log(format_args!(
                "uhci: the firmware keeps LEGSUP {legsup:#06x} (found {found:#06x}) after {micros} us; controller left alone"
            ));
            self.state = State::FirmwareOwned;
            return Handoff::NeverReleased;
        }
        // Ours now: no interrupt line, and nothing run from the
        // firmware's schedule (its memory is not ours).
        self.hw.write16(USBINTR, 0);
        let cmd = self.hw.read16(USBCMD);
        self.hw.write16(USBCMD, cmd & !CMD_RUN);
        self.state = State::Owned;
        if owned {
            self.hw.log(format_args!(
                "uhci: LEGSUP {found:#06x}: SMI enables cleared in {micros} us"
            ));
            Handoff::Released { micros }
        } else {
            Handoff::NotOwned
        }
    }

    /// Resets the controller (global reset, then host controller reset),
    /// builds the schedule, counts the root ports and starts it. Every wait
    /// is bounded.
    #[optimize(size)] // run once at start-up: small beats fast
    fn reset_and_start(&mut self) -> Result<(), UhciError> {
        if self.state == State::FirmwareOwned {
            return Err(UhciError::FirmwareOwns);
        }
        self.state = State::Stopped;
        self.hw.write16(USBINTR, 0);
        self.hw.write16(USBCMD, CMD_GLOBAL_RESET);
        self.wait_micros(GLOBAL_RESET_MICROS);
        self.hw.write16(USBCMD, 0);
        self.hw.write16(USBCMD, CMD_HOST_RESET);
        if !self.wait_register(USBCMD, CMD_HOST_RESET, 0, HOST_RESET_MICROS) {
            self.hw.log(format_args!("uhci: HCRESET never cleared"));
            return Err(UhciError::ResetTimeout);
        }
        if !self.wait_register(USBSTS, STS_HALTED, STS_HALTED, HALT_MICROS) {
            self.hw.log(format_args!("uhci: not halted after HCRESET"));
            return Err(UhciError::NotHalted);
        }
        self.hw.write16(USBINTR, 0);

        self.devices = [FREE_DEVICE; MAX_DEVICES];
        self.pipes = [FREE_PIPE; MAX_PIPES];
        self.build_schedule();
        let frame_list = self.layout.frame_list();
        self.hw.mmio_write(FRBASEADD, frame_list);
        if self.hw.mmio_read(FRBASEADD) & !0xFFF != frame_list {
            self.hw
                .log(format_args!("uhci: FRBASEADD did not keep {frame_list:#x}"));
            return Err(UhciError::FrameListRejected);
        }
        self.hw.write16(FRNUM, 0);
        // SOFMOD keeps its reset value (64: 1 ms frames), as the BIOS may
        // have tuned it.

        self.ports = self.count_ports();
        if self.ports == 0 {
            self.hw.log(format_args!("uhci: no root port reads as one"));
            return Err(UhciError::NoRootPorts);
        }

        self.hw.write16(USBSTS, STS_CAUSES);
        self.hw
            .write16(USBCMD, CMD_RUN | CMD_CONFIGURE | CMD_MAX_PACKET_64);
        if !self.wait_register(USBSTS, STS_HALTED, 0, HALT_MICROS) {
            self.hw
                .log(format_args!("uhci: still halted after Run/Stop"));
            return Err(UhciError::StartTimeout);
        }
        self.state = State::Running;
        self.hw.log(format_args!(
            "uhci: running, {} root ports, frame list at {frame_list:#x}",
            self.ports
        ));
        Ok(())
    }

    fn root_ports(&self) -> u8 {
        self.ports
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        let Some((_, value)) = self.read_port(port) else {
            return PortStatus::default();
        };
        let connected = value & PORT_CONNECTED != 0;
        PortStatus {
            connected,
            enabled: connected && value & PORT_ENABLED != 0,
            low_speed: connected && value & PORT_LOW_SPEED != 0,
            connect_changed: value & PORT_CONNECT_CHANGE != 0,
            companion_owned: false,
        }
    }

    fn clear_port_change(&mut self, port: u8) {
        if let Some((offset, value)) = self.read_port(port) {
            let clear = PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE;
            self.hw.write16(offset, Self::port_keep(value) | clear);
        }
    }

    fn port_reset_begin(&mut self, port: u8) {
        if let Some((offset, value)) = self.read_port(port) {
            let value = (Self::port_keep(value) | PORT_RESET) & !PORT_ENABLED;
            self.hw.write16(offset, value);
            self.reset = Some(RootReset::begin(port, self.hw.now_micros(), u64::MAX));
        }
    }

    /// Software ends the reset once TDRSTR has passed, then sets Port
    /// Enabled, [`PORT_RESET_RECOVERY_MICROS`] apart, until it holds
    /// (Linux's uhci_check_ports): stage n is the (n-1)th try.
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome> {
        let reset = self.reset.take().filter(|r| r.port == port);
        let (Some(mut reset), Some((offset, value))) = (reset, self.read_port(port)) else {
            return Some(ResetOutcome::Failed);
        };
        let now = self.hw.now_micros();
        if now < reset.until {
            self.reset = Some(reset);
            return None;
        }
        reset.until = now + PORT_RESET_RECOVERY_MICROS;
        if reset.stage == 0 {
            self.hw
                .write16(offset, Self::port_keep(value) & !PORT_RESET);
            reset.stage = 1;
            reset.bound = now + PORT_ENABLE_MICROS;
            self.reset = Some(reset);
            return None;
        }
        if value & PORT_CONNECTED == 0 {
            return Some(ResetOutcome::Failed);
        }
        let reset_over = value & PORT_RESET == 0;
        if reset_over && value & PORT_ENABLED != 0 {
            let speed = if value & PORT_LOW_SPEED != 0 {
                Speed::Low
            } else {
                Speed::Full
            };
            return Some(ResetOutcome::Enabled(speed));
        }
        // One more look. Past the bound only after two: a poll that comes
        // late (a busy host, an SMI) has not yet asked the port to enable.
        reset.stage += 1;
        let looks = reset.stage - 1;
        if looks > PORT_ENABLE_TRIES || (looks > 2 && now > reset.bound) {
            self.hw.log(format_args!(
                "uhci: port {port} did not enable after its reset (PORTSC {value:#06x})"
            ));
            return Some(ResetOutcome::Failed);
        }
        if reset_over {
            // The reset's own connect and enable changes go, and the
            // port is enabled.
            let clear = value & (PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE);
            self.hw
                .write16(offset, Self::port_keep(value) | clear | PORT_ENABLED);
        }
        self.reset = Some(reset);
        None
    }

    fn port_disable(&mut self, port: u8) {
        if let Some((offset, value)) = self.read_port(port) {
            self.hw
                .write16(offset, Self::port_keep(value) & !PORT_ENABLED);
        }
    }

    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError> {
        self.running()?;
        let low_speed = match info.speed {
            Speed::Low => true,
            Speed::Full => false,
            Speed::High | Speed::Super => return Err(HostError::Invalid),
        };
        if info.translator.is_some() || !(1..=self.ports).contains(&info.root_port) {
            return Err(HostError::Invalid);
        }
        // A slot whose frame has long passed first, so that usually no
        // wait is needed.
        let free = |d: &DeviceSlot| !d.in_use;
        let slot = self
            .devices
            .iter()
            .position(|d| free(d) && d.quiet_after.is_none())
            .or_else(|| self.devices.iter().position(free));
        let Some(slot) = slot else {
            self.hw.log(format_args!(
                "uhci: no room for another device ({MAX_DEVICES} in use)"
            ));
            return Err(HostError::NoRoom);
        };
        self.quiet_device(slot);
        self.devices[slot] = DeviceSlot {
            in_use: true,
            address: 0,
            max_packet: 8,
            low_speed,
            control: None,
            quiet_after: None,
        };
        let qh = self.layout.device_qh(slot);
        self.dma_write(qh + 4, LINK_TERMINATE);
        self.relink_devices();
        Ok(DeviceId(slot as u8))
    }

    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        let slot = self.device_slot(device)?;
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        if self.devices[slot].control.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[slot].address = address;
        Ok(())
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> Result<(), HostError> {
        let slot = self.device_slot(device)?;
        let valid = if self.devices[slot].low_speed {
            max_packet == 8
        } else {
            matches!(max_packet, 8 | 16 | 32 | 64)
        };
        if !valid {
            return Err(HostError::Invalid);
        }
        if self.devices[slot].control.is_some() {
            return Err(HostError::Busy);
        }
        self.devices[slot].max_packet = max_packet;
        Ok(())
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        _ports: u8,
        _multi_tt: bool,
    ) -> Result<(), HostError> {
        // UHCI reaches a hub's devices by address alone (low-speed ones
        // with the LS bit and PRE): nothing to record.
        self.device_slot(device).map(|_| ())
    }

    fn device_remove(&mut self, device: DeviceId) {
        let Ok(slot) = self.device_slot(device) else {
            return;
        };
        for pipe in 0..MAX_PIPES {
            if self.pipes[pipe].in_use && self.pipes[pipe].device == slot {
                self.interrupt_close(PipeId(pipe as u8));
            }
        }
        self.devices[slot].in_use = false;
        self.relink_devices();
        // Whether or not a transfer ran, the queue head was in the
        // schedule during this frame.
        self.retire_control(slot);
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError> {
        self.running()?;
        let slot = self.device_slot(device)?;
        if self.devices[slot].control.is_some() {
            return Err(HostError::Busy);
        }
        let length = usize::from(setup.length);
        let is_in = setup.is_in();
        if length > MAX_CONTROL_DATA || (!is_in && out.len() < length) {
            return Err(HostError::Invalid);
        }
        self.quiet_device(slot);
        let dev = self.devices[slot];
        let max_packet = usize::from(dev.max_packet);
        let data_tds = length.div_ceil(max_packet);
        let tds = data_tds + 2;
        if tds > MAX_CONTROL_TDS {
            return Err(HostError::Invalid);
        }

        let buffer = self.layout.device_buffer(slot);
        self.write_bytes(buffer, &setup.bytes());
        if !is_in {
            self.write_bytes(buffer + 8, &out[..length]);
        }
        let speed = if dev.low_speed { TD_LOW_SPEED } else { 0 };
        let active = TD_ACTIVE | TD_THREE_ERRORS | speed;
        let layout = self.layout;
        let td_at = |index: usize| layout.device_td(slot, index);
        let next = |index: usize| td_at(index + 1) | LINK_DEPTH_FIRST;

        // Status: the other direction (IN when there is no data), DATA1,
        // no data, interrupt on completion. Written from the last TD to
        // the first, each TD's status word last.
        let status_pid = if is_in && length > 0 { PID_OUT } else { PID_IN };
        let token = td_token(status_pid, dev.address, 0, true, 0);
        self.write_td(
            td_at(tds - 1),
            LINK_TERMINATE,
            active | TD_INTERRUPT_ON_COMPLETE,
            token,
            0,
        );
        let (data_pid, detect) = if is_in {
            (PID_IN, TD_SHORT_PACKET_DETECT)
        } else {
            (PID_OUT, 0)
        };
        for packet in (0..data_tds).rev() {
            let offset = packet * max_packet;
            let bytes = max_packet.min(length - offset);
            let toggle = packet % 2 == 0;
            let token = td_token(data_pid, dev.address, 0, toggle, bytes);
            let index = packet + 1;
            self.write_td(
                td_at(index),
                next(index),
                active | detect,
                token,
                buffer + 8 + offset as u32,
            );
        }
        let token = td_token(PID_SETUP, dev.address, 0, false, 8);
        self.write_td(td_at(0), next(0), active, token, buffer);
        self.dma_write(self.layout.device_qh(slot) + 4, td_at(0));
        self.devices[slot].control = Some(Control {
            tds,
            is_in,
            length,
            cursor: 0,
            moved: 0,
        });
        Ok(())
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        let Ok(slot) = self.device_slot(device) else {
            return Transfer::Failed(TransferError::Controller);
        };
        let Some(mut control) = self.devices[slot].control else {
            return Transfer::Failed(TransferError::Controller);
        };
        if self.state != State::Running {
            self.retire_control(slot);
            return Transfer::Failed(TransferError::Controller);
        }
        let max_packet = usize::from(self.devices[slot].max_packet);
        let status_index = control.tds - 1;
        while control.cursor < control.tds {
            let index = control.cursor;
            let status = self.dma_read(self.layout.device_td(slot, index) + 4);
            if status & TD_ACTIVE != 0 {
                self.devices[slot].control = Some(control);
                return Transfer::Pending;
            }
            if let Some(error) = Self::td_error(status) {
                self.retire_control(slot);
                return error;
            }
            let moved = td_actual_length(status);
            let asked = match index {
                0 => 8,
                i if i == status_index => 0,
                i => max_packet.min(control.length - (i - 1) * max_packet),
            };
            if moved > asked {
                self.retire_control(slot);
                return Transfer::Failed(TransferError::Babble);
            }
            if (1..status_index).contains(&index) {
                control.moved += moved;
                if moved < asked {
                    if !control.is_in {
                        // An OUT moves what it was given or fails.
                        self.retire_control(slot);
                        return Transfer::Failed(TransferError::Controller);
                    }
                    // A short packet ends the data stage: the controller
                    // stopped on this TD (short packet detect), so the
                    // queue goes on at the status TD.
                    let status_td = self.layout.device_td(slot, status_index);
                    self.dma_write(self.layout.device_qh(slot) + 4, status_td);
                    control.cursor = status_index;
                    continue;
                }
            } else if moved != asked {
                self.retire_control(slot);
                return Transfer::Failed(TransferError::Controller);
            }
            control.cursor += 1;
        }
        self.devices[slot].control = None;
        if control.is_in {
            let bytes = control.moved.min(into.len());
            let buffer = self.layout.device_buffer(slot) + 8;
            self.read_bytes(buffer, &mut into[..bytes]);
            Transfer::Complete(bytes)
        } else {
            Transfer::Complete(control.moved)
        }
    }

    fn control_cancel(&mut self, device: DeviceId) {
        if let Ok(slot) = self.device_slot(device) {
            if self.devices[slot].control.is_some() {
                self.retire_control(slot);
            }
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
        let device_slot = self.device_slot(device)?;
        let largest = if self.devices[device_slot].low_speed {
            8
        } else {
            MAX_REPORT as u16
        };
        if !(1..=15).contains(&endpoint) || !(1..=largest).contains(&max_packet) {
            return Err(HostError::Invalid);
        }
        let free = |p: &PipeSlot| !p.in_use;
        let slot = self
            .pipes
            .iter()
            .position(|p| free(p) && p.quiet_after.is_none())
            .or_else(|| self.pipes.iter().position(free));
        let Some(slot) = slot else {
            self.hw.log(format_args!(
                "uhci: no room for another interrupt pipe ({MAX_PIPES} in use)"
            ));
            return Err(HostError::NoRoom);
        };
        self.quiet_pipe(slot);
        let period = period_index(interval);
        self.pipes[slot] = PipeSlot {
            in_use: true,
            device: device_slot,
            endpoint,
            max_packet,
            toggle: false,
            period,
            state: PipeState::Waiting,
            quiet_after: None,
        };
        let qh = self.layout.pipe_qh(slot);
        self.dma_write(qh + 4, LINK_TERMINATE);
        self.arm_pipe(slot);
        self.relink_period(period);
        Ok(PipeId(slot as u8))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        let Ok(slot) = self.pipe_slot(pipe) else {
            return Transfer::Failed(TransferError::Controller);
        };
        if self.pipes[slot].state != PipeState::Armed {
            return Transfer::Pending;
        }
        if self.state != State::Running {
            self.stop_pipe(slot);
            return Transfer::Failed(TransferError::Controller);
        }
        let status = self.dma_read(self.layout.pipe_td(slot) + 4);
        if status & TD_ACTIVE != 0 {
            return Transfer::Pending;
        }
        if let Some(error) = Self::td_error(status) {
            self.stop_pipe(slot);
            return error;
        }
        let moved = td_actual_length(status);
        if moved > usize::from(self.pipes[slot].max_packet) {
            self.stop_pipe(slot);
            return Transfer::Failed(TransferError::Babble);
        }
        let bytes = moved.min(into.len());
        let buffer = self.layout.pipe_buffer(slot);
        self.read_bytes(buffer, &mut into[..bytes]);
        // The controller took the report with the toggle the TD named:
        // the next one comes with the other.
        self.pipes[slot].toggle = !self.pipes[slot].toggle;
        self.arm_pipe(slot);
        Transfer::Complete(bytes)
    }

    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError> {
        self.running()?;
        let slot = self.pipe_slot(pipe)?;
        if self.pipes[slot].state == PipeState::Armed {
            return Err(HostError::Busy);
        }
        self.quiet_pipe(slot);
        if reset_toggle {
            self.pipes[slot].toggle = false;
        }
        self.arm_pipe(slot);
        Ok(())
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        let Ok(slot) = self.pipe_slot(pipe) else {
            return;
        };
        self.pipes[slot].in_use = false;
        let period = self.pipes[slot].period;
        self.relink_period(period);
        self.stop_pipe(slot);
    }

    /// One USBSTS read (its causes written back to clear them). UHCI has no
    /// port-change bit in USBSTS, so every [`PORT_CHECK_EVERY`]th call reads
    /// one root port's PORTSC instead, round-robin: still one register read
    /// per call; a USBSTS cause latched meanwhile is seen at the next call.
    fn anything_happened(&mut self) -> bool {
        if self.state != State::Running {
            return false;
        }
        self.idle_calls = self.idle_calls.wrapping_add(1);
        if self.idle_calls.is_multiple_of(PORT_CHECK_EVERY) && self.ports > 0 {
            let port = self.next_port_checked % self.ports;
            self.next_port_checked = (port + 1) % self.ports;
            let value = self.hw.read16(PORTSC1 + 2 * u32::from(port));
            return value != 0xFFFF && value & (PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE) != 0;
        }
        let usbsts = self.hw.read16(USBSTS);
        if usbsts == 0xFFFF
            || usbsts & (STS_HALTED | STS_HOST_SYSTEM_ERROR | STS_PROCESS_ERROR) != 0
        {
            self.controller_died(usbsts);
            return true;
        }
        let causes = usbsts & STS_CAUSES;
        if causes != 0 {
            self.hw.write16(USBSTS, causes);
        }
        causes & (STS_INTERRUPT | STS_ERROR_INTERRUPT) != 0
    }

    fn halt(&mut self) -> bool {
        match self.state {
            State::FirmwareOwned | State::Fresh => return false,
            State::Owned | State::Running | State::Stopped => {}
        }
        self.state = State::Stopped;
        let cmd = self.hw.read16(USBCMD);
        self.hw.write16(USBCMD, cmd & !CMD_RUN);
        let halted = self.wait_register(USBSTS, STS_HALTED, STS_HALTED, HALT_MICROS);
        self.hw.write16(USBINTR, 0);
        // As Linux leaves it (uhci_reset_hc): trap status cleared, SMI and
        // PIRQ enables off.
        let above = self.hw.pci_config_read(LEGACY_OFFSET) & 0xFFFF_0000;
        self.hw
            .pci_config_write(LEGACY_OFFSET, above | u32::from(LEGACY_STATUS_CLEAR));
        if !halted {
            self.hw
                .log(format_args!("uhci: did not halt within {HALT_MICROS} us"));
        }
        halted
    }
}

const _: () = assert!(PERIODS + 1 == SKELETONS);
