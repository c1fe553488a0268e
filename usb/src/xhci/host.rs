//! xHCI as one [`HostController`] under the controller-independent device
//! layer ([`crate::bus::Bus`]).
//!
//! What xHCI does differently from the other controllers, and how it is
//! hidden behind the trait:
//!
//! - Devices are slots, made and changed by commands that complete later.
//!   Each device keeps a short queue of its commands (Enable Slot, Address
//!   Device, Evaluate Context, Configure Endpoint, Reset Endpoint, Set TR
//!   Dequeue Pointer), one on the command ring at a time, so that its one
//!   input context is never rewritten under a command. A control transfer
//!   asked for meanwhile waits until the queue is empty, and
//!   [`HostController::control_poll`] says [`Transfer::Pending`] until then:
//!   nothing here waits for a command.
//! - The controller, not the host software, sends SET_ADDRESS: the
//!   addressing hook ([`HostController::address_begin`]) is Address Device
//!   (BSR=0), and its completion is the transfer's.
//! - A slot names its place by root port and route string, both in
//!   [`DeviceInfo`], and a full- or low-speed device behind a high-speed hub
//!   names that hub by its slot, found by the USB address the device layer
//!   gave it.
//! - A stall or an error halts the endpoint in the controller too:
//!   endpoint 0 is reset (Reset Endpoint, Set TR Dequeue Pointer past what
//!   was queued) before its next transfer, an interrupt pipe on
//!   [`HostController::interrupt_restart`].
//! - A USB 3 root port trains its link by itself: its device is
//!   SuperSpeed once enabled (a USB 3 hub's USB 2 half, where keyboards
//!   hang, is on a USB 2 root port of its own).
//!
//! DMA: a device takes two pages (its output context, endpoint 0's ring
//! and control buffer; its input context, and its one interrupt pipe's
//! ring and report buffers), taken when its slot is enabled and kept for
//! the next device when it goes (after Disable Slot is queued: the command
//! ring runs it before the Enable Slot of whoever gets them next).

use super::context::{endpoint_type, speed, EndpointContext, SlotContext};
use super::ring::{trb_type, ProducerRing, Trb};
use super::{
    configure_endpoint, EventRing, Xhci, XhciError, CAP_LEGACY, CMD_RESET, CMD_RUN,
    COMPLETION_COMMAND_RING_STOPPED, COMPLETION_CONTEXT_STATE, COMPLETION_SHORT_PACKET,
    COMPLETION_STALL, COMPLETION_SUCCESS, CONFIG, CRCR, CRCR_COMMAND_ABORT, DCBAAP, ERDP, ERSTBA,
    ERSTSZ, EVENTS_PER_POLL, HALT_MICROS, HANDOFF_MICROS, LEGACY_BIOS_OWNED, LEGACY_OS_OWNED,
    LEGACY_SMI_ENABLES, LEGACY_SMI_STATUS, MAX_SLOTS, PAGESIZE, PAGE_BYTES, PORT_CHANGES,
    PORT_CONNECTED, PORT_CONNECT_CHANGE, PORT_ENABLED, PORT_POWER, PORT_RESET, PORT_RESET_CHANGE,
    RESET_MICROS, RING_TRBS, STS_HALTED, STS_NOT_READY, USBCMD, USBSTS,
};
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, RootReset, Setup, Speed, Transfer, TransferError, MAX_CONTROL_DATA, MAX_REPORT,
};
use crate::Hardware;
use core::fmt;
use xhci::ring::trb::{command, transfer};

/// How long a command may take before it is aborted (Linux's
/// `XHCI_CMD_DEFAULT_TIMEOUT`, 5 s).
pub(super) const COMMAND_MICROS: u64 = 5_000_000;
/// Devices kept: one a slot the driver enables (CONFIG's MaxSlotsEn).
pub const HOST_DEVICES: usize = MAX_SLOTS as usize;

/// Page one of a device: the output device context from 0 (32 contexts of
/// at most 64 bytes), endpoint 0's ring, then the control data buffer.
const EP0_RING_OFFSET: u64 = 2048;
const EP0_RING_TRBS: u16 = 64;
const CONTROL_BUFFER_OFFSET: u64 = 3072;
/// Page two: the input context from 0 (33 contexts of at most 64 bytes,
/// 2112 bytes), then the interrupt pipe's ring and its report buffers (one
/// per ring TRB, so that a report is found by its TRB's place).
const PIPE_RING_OFFSET: u64 = 2176;
const PIPE_RING_TRBS: u16 = 16;
const PIPE_BUFFERS_OFFSET: u64 = 2432;
const PIPE_BUFFER_BYTES: u64 = MAX_REPORT as u64;
/// Transfers kept queued on an interrupt pipe: reports the controller
/// takes before the device layer reads them (fewer than the ring's TRBs,
/// so that a report not yet read is never overwritten).
const PIPE_QUEUED: usize = 8;
/// Commands a device may have waiting.
const DEVICE_COMMANDS: usize = 8;
/// How long a USB 2 root port's reset, which the controller times and ends
/// itself, may run (Linux's `HUB_LONG_RESET_TIME` for a root port).
pub(super) const ROOT_RESET_BOUND_MICROS: u64 = 200_000;
/// PORTSC bits written back as read (port indicator control, wake enables);
/// everything else written is 0 unless meant: PED and the change bits are
/// write-1-to-clear, PR write-1-to-start.
const PORT_KEEP: u32 = (0x3 << 14) | (0x7 << 25);
/// The change bits the device layer does not follow (warm reset, over-
/// current, link state, config error), cleared with the connect and enable
/// changes so that the next change raises a Port Status Change event again.
const PORT_CONNECT_CHANGES: u32 = PORT_CHANGES & !PORT_RESET_CHANGE;
const PORT_RESET_DONE_CHANGES: u32 = PORT_RESET_CHANGE | (1 << 19) | (1 << 18);
/// PORTSC's Warm Port Reset (WPR, bit 31): a USB 3 port's BH reset, the
/// way out of SS.Inactive and Compliance Mode (xHCI 4.19.5.1).
const PORT_WARM_RESET: u32 = 1 << 31;
/// PORTSC's Port Link State (PLS, bits 8:5) and the stuck ones.
const PORT_LINK_STATE_SHIFT: u32 = 5;
const LINK_INACTIVE: u32 = 6;
const LINK_COMPLIANCE: u32 = 10;
/// The [`RootReset`] stage of a USB 3 port whose warm reset was asked for.
const WARM_RESET_STAGE: u32 = 1;
/// Completion codes mapped to the device layer's errors.
const COMPLETION_DATA_BUFFER: u8 = 2;
const COMPLETION_BABBLE: u8 = 3;
const COMPLETION_TRANSACTION: u8 = 4;
const COMPLETION_NO_SLOTS: u8 = 9;
const COMPLETION_RING_UNDERRUN: u8 = 14;
const COMPLETION_RING_OVERRUN: u8 = 15;
const COMPLETION_SPLIT: u8 = 36;

/// A command a device waits for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Op {
    EnableSlot,
    /// Address Device with BSR=1: slot and endpoint 0 set up, the device
    /// left at the default address.
    AddressDefault,
    /// Evaluate Context: endpoint 0's packet size.
    Evaluate,
    /// Address Device with BSR=0: the controller sends SET_ADDRESS.
    Address,
    /// Configure Endpoint: the slot's hub fields.
    ConfigureHub,
    /// Configure Endpoint: the interrupt pipe's endpoint added.
    OpenPipe,
    /// Configure Endpoint: the interrupt pipe's endpoint dropped.
    ClosePipe,
    /// Reset Endpoint (Transfer State Preserve: the data toggle kept).
    ResetEndpoint {
        dci: u8,
        preserve: bool,
    },
    /// Set TR Dequeue Pointer: past everything queued on the endpoint.
    SetDequeue {
        dci: u8,
    },
    /// Stop Endpoint: a control transfer given up.
    StopEndpoint {
        dci: u8,
    },
}

/// A device's commands, the first on the command ring (from `since`,
/// its TRB at `trb`) once issued.
#[derive(Clone, Copy, Debug)]
struct Ops {
    items: [Option<Op>; DEVICE_COMMANDS],
    len: usize,
    in_flight: Option<(u64, u64)>,
}

impl Ops {
    const fn new() -> Ops {
        Ops {
            items: [None; DEVICE_COMMANDS],
            len: 0,
            in_flight: None,
        }
    }

    fn push(&mut self, op: Op) -> Result<(), HostError> {
        if self.len == DEVICE_COMMANDS {
            return Err(HostError::Busy);
        }
        self.items[self.len] = Some(op);
        self.len += 1;
        Ok(())
    }

    /// Puts `op` first (the next step of the command just done).
    fn push_front(&mut self, op: Op) {
        if self.len == DEVICE_COMMANDS {
            self.len -= 1;
        }
        self.items.copy_within(0..self.len, 1);
        self.items[0] = Some(op);
        self.len += 1;
    }

    fn first(&self) -> Option<Op> {
        self.items[0].filter(|_| self.len > 0)
    }

    fn pop(&mut self) -> Option<Op> {
        let first = self.first()?;
        self.items.copy_within(1..self.len, 0);
        self.len -= 1;
        self.items[self.len] = None;
        Some(first)
    }

    fn clear(&mut self) {
        // What is on the command ring still completes; it matches no one.
        *self = Ops::new();
    }
}

/// Where a device's control transfer stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Control {
    Idle,
    /// Asked for; waits for the device's commands to finish.
    Waiting(Setup),
    /// Its TRBs are on endpoint 0's ring: the Data TRB (if any) and the
    /// Status TRB, whose events end it; the data stage's residual once known.
    Running {
        setup: Setup,
        data: Option<u64>,
        status: u64,
        residual: u32,
    },
    /// SET_ADDRESS, sent by Address Device.
    SettingAddress,
    /// Finished, not yet told.
    Done(Transfer),
}

/// One finished transfer of an interrupt pipe, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PipeDone {
    /// A report in the buffer of ring TRB `index`, `length` bytes.
    Report { index: u16, length: u16 },
    /// The transfer failed with this completion code; the endpoint halted.
    Error(u8),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PipeState {
    /// Configure Endpoint queued.
    Opening,
    Running,
    /// Stopped after an error, until `interrupt_restart`.
    Halted,
    /// Reset Endpoint and Set TR Dequeue Pointer queued.
    Restarting,
    /// Configure Endpoint (drop) queued.
    Closing,
}

/// A device's interrupt-in pipe.
#[derive(Clone, Debug)]
struct Pipe {
    dci: u8,
    max_packet: u16,
    interval: u8,
    ring: ProducerRing,
    buffers: u64,
    state: PipeState,
    /// Normal TRBs on the ring not yet finished.
    outstanding: usize,
    done: [Option<PipeDone>; PIPE_QUEUED + 1],
    done_len: usize,
}

impl Pipe {
    fn push_done(&mut self, done: PipeDone) {
        if self.done_len < self.done.len() {
            self.done[self.done_len] = Some(done);
            self.done_len += 1;
        }
    }

    fn pop_done(&mut self) -> Option<PipeDone> {
        if self.done_len == 0 {
            return None;
        }
        let first = self.done[0];
        self.done.copy_within(1..self.done_len, 0);
        self.done_len -= 1;
        self.done[self.done_len] = None;
        first
    }
}

/// The memory a device has once its slot is enabled.
#[derive(Clone, Debug)]
struct Slot {
    id: u8,
    /// Output context, endpoint 0's ring and the control buffer.
    page: u64,
    /// Input context and the pipe.
    input: u64,
    ep0: ProducerRing,
}

/// A device the device layer has a [`DeviceId`] for.
#[derive(Clone, Debug)]
struct HostDevice {
    info: DeviceInfo,
    /// None until Enable Slot completes.
    slot: Option<Slot>,
    context: SlotContext,
    /// The slot context's MTT bit: a hub with a translator per port, or a
    /// device reached through one.
    multi_tt: bool,
    max_packet_0: u16,
    /// The USB address the device layer knows it by.
    address: u8,
    hub: bool,
    ops: Ops,
    control: Control,
    pipe: Option<Pipe>,
    /// The slot never came, or a command failed: every transfer fails so.
    failed: Option<TransferError>,
    /// The device layer let go of it while its slot was being enabled: the
    /// slot is disabled as soon as it is known.
    removed: bool,
}

/// What the [`HostController`] side of the driver keeps.
#[derive(Debug)]
pub(super) struct HostState {
    devices: [Option<HostDevice>; HOST_DEVICES],
    /// Events were taken outside [`HostController::anything_happened`]
    /// (their results wait to be polled).
    news: bool,
    /// The root port reset running (one at a time).
    reset: Option<RootReset>,
}

impl HostState {
    pub(super) const fn new() -> HostState {
        HostState {
            devices: [const { None }; HOST_DEVICES],
            news: false,
            reset: None,
        }
    }
}

/// The hub tiers a route string names (its non-zero nibbles from the lowest).
fn route_depth(route: u32) -> u32 {
    (0..5)
        .take_while(|tier| (route >> (4 * tier)) & 0xF != 0)
        .count() as u32
}

/// What a transfer's completion code means to the device layer.
fn transfer_result(code: u8) -> Transfer {
    match code {
        COMPLETION_STALL => Transfer::Stalled,
        COMPLETION_BABBLE => Transfer::Failed(TransferError::Babble),
        COMPLETION_TRANSACTION => Transfer::Failed(TransferError::NoResponse),
        COMPLETION_DATA_BUFFER | COMPLETION_RING_UNDERRUN | COMPLETION_RING_OVERRUN => {
            Transfer::Failed(TransferError::DataBuffer)
        }
        COMPLETION_SPLIT => Transfer::Failed(TransferError::Split),
        _ => Transfer::Failed(TransferError::Controller),
    }
}

/// The slot context's speed for the device layer's.
fn speed_id(speed: Speed) -> u32 {
    match speed {
        Speed::Low => speed::LOW,
        Speed::Full => speed::FULL,
        Speed::High => speed::HIGH,
        Speed::Super => speed::SUPER,
    }
}

/// The xHCI interval (2^n x 125 us) for a pipe polled every `frames` ms:
/// the power of two at or below, within what the speed allows.
fn interval_exponent(speed: Speed, frames: u8) -> u8 {
    let exponent = 3 + (7 - frames.max(1).leading_zeros() as u8);
    let most = if matches!(speed, Speed::High | Speed::Super) {
        15
    } else {
        10
    };
    exponent.clamp(3, most)
}

fn ep0_context(dequeue: u64, max_packet: u16) -> EndpointContext {
    EndpointContext {
        kind: endpoint_type::CONTROL,
        max_packet,
        interval: 0,
        dequeue,
        average_trb_length: 8,
    }
}

impl<H: Hardware> Xhci<H> {
    fn host_device(&mut self, device: DeviceId) -> Result<&mut HostDevice, HostError> {
        self.host
            .devices
            .get_mut(usize::from(device.0))
            .and_then(Option::as_mut)
            .filter(|d| !d.removed)
            .ok_or(HostError::UnknownHandle)
    }

    /// Says something on the log, naming the controller.
    /// The device, its endpoint 0 free for a transfer; None when the
    /// device has failed, and the transfer with it.
    fn idle_control(&mut self, device: DeviceId) -> Result<Option<&mut HostDevice>, HostError> {
        let entry = self.host_device(device)?;
        if !matches!(entry.control, Control::Idle | Control::Done(_)) {
            return Err(HostError::Busy);
        }
        if let Some(why) = entry.failed {
            entry.control = Control::Done(Transfer::Failed(why));
            return Ok(None);
        }
        Ok(Some(entry))
    }

    fn say(&mut self, message: fmt::Arguments<'_>) {
        self.hw.log(format_args!("usb: xhci: {message}"));
    }

    /// Takes the events waiting (a bounded number): command completions
    /// move their device's commands on, transfer events end control
    /// transfers and fill interrupt pipes. Port changes need nothing: the
    /// device layer reads PORTSC. Gives how many were taken.
    fn take_events(&mut self) -> u32 {
        let mut taken = 0;
        while taken < EVENTS_PER_POLL {
            let Some(event) = self.next_event() else {
                break;
            };
            taken += 1;
            match event.kind() {
                trb_type::COMMAND_COMPLETION => self.command_completed(&event),
                trb_type::TRANSFER_EVENT => self.transfer_completed(&event),
                _ => {}
            }
        }
        taken
    }

    /// Events taken where the device layer does not ask: it is told at its
    /// next [`HostController::anything_happened`].
    fn take_events_meanwhile(&mut self) {
        if self.take_events() > 0 {
            self.host.news = true;
        }
        self.check_command_timeouts();
    }

    /// A command stuck past Linux's 5 s is aborted (CRCR's CA) and counts
    /// as failed for its device; says whether one was.
    fn check_command_timeouts(&mut self) -> bool {
        if !self
            .host
            .devices
            .iter()
            .flatten()
            .any(|d| d.ops.in_flight.is_some())
        {
            return false;
        }
        let mut aborted = false;
        let now = self.hw.now_micros();
        for index in 0..HOST_DEVICES {
            let stuck = self.host.devices[index]
                .as_ref()
                .and_then(|d| d.ops.in_flight)
                .is_some_and(|(_, since)| now.saturating_sub(since) > COMMAND_MICROS);
            if stuck {
                self.write(self.operational + CRCR, CRCR_COMMAND_ABORT);
                self.say(format_args!(
                    "a command for device {index} not completed in {} ms; aborted",
                    COMMAND_MICROS / 1_000
                ));
                self.command_done(index, None, 0);
                aborted = true;
            }
        }
        aborted
    }

    fn command_completed(&mut self, event: &Trb) {
        let code = event.completion_code();
        if code == COMPLETION_COMMAND_RING_STOPPED {
            // After an abort: the commands still waiting run when the
            // doorbell rings again.
            if self
                .host
                .devices
                .iter()
                .flatten()
                .any(|d| d.ops.in_flight.is_some())
            {
                self.write(self.doorbells, 0);
            }
            return;
        }
        let trb = event.parameter();
        let Some(index) = self.host.devices.iter().position(|d| {
            d.as_ref()
                .and_then(|d| d.ops.in_flight)
                .is_some_and(|(at, _)| at == trb)
        }) else {
            return; // a Disable Slot, or a command given up
        };
        self.command_done(index, Some(code), event.slot());
    }

    /// Device `index`'s first command ended with `code` (None: timed out).
    fn command_done(&mut self, index: usize, code: Option<u8>, event_slot: u8) {
        let Some(device) = self.host.devices[index].as_mut() else {
            return;
        };
        device.ops.in_flight = None;
        let Some(op) = device.ops.pop() else {
            return;
        };
        let ok = code == Some(COMPLETION_SUCCESS);
        match op {
            Op::EnableSlot => self.slot_enabled(index, code, event_slot),
            Op::AddressDefault | Op::Evaluate if !ok => {
                self.say(format_args!(
                    "device {index}: {op:?} failed (completion code {})",
                    code.unwrap_or(0)
                ));
                self.fail_device(index, TransferError::Controller);
            }
            Op::AddressDefault | Op::Evaluate => {}
            Op::Address => {
                let result = match code {
                    Some(COMPLETION_SUCCESS) => Transfer::Complete(0),
                    Some(code) => transfer_result(code),
                    None => Transfer::Failed(TransferError::Controller),
                };
                if device.control == Control::SettingAddress {
                    device.control = Control::Done(result);
                }
            }
            Op::ConfigureHub if !ok => self.say(format_args!(
                "device {index}: not marked as a hub (completion code {}); devices behind its translator may fail",
                code.unwrap_or(0)
            )),
            Op::ConfigureHub => {}
            Op::OpenPipe => {
                if let Some(pipe) = device.pipe.as_mut() {
                    if ok {
                        pipe.state = PipeState::Running;
                        self.queue_reports(index);
                    } else {
                        pipe.state = PipeState::Halted;
                        pipe.push_done(PipeDone::Error(code.unwrap_or(0)));
                    }
                }
            }
            Op::ClosePipe => device.pipe = None,
            Op::ResetEndpoint { dci, .. } | Op::StopEndpoint { dci }
                if ok || code == Some(COMPLETION_CONTEXT_STATE) =>
            {
                // Context State Error: it was not halted (or not running);
                // the dequeue pointer still moves past what was queued.
                device.ops.push_front(Op::SetDequeue { dci });
            }
            Op::SetDequeue { dci } if ok && dci != 1 => {
                if let Some(pipe) = device.pipe.as_mut() {
                    pipe.state = PipeState::Running;
                    pipe.outstanding = 0;
                    self.queue_reports(index);
                }
            }
            Op::SetDequeue { .. } if ok => {}
            Op::ResetEndpoint { dci, .. }
            | Op::StopEndpoint { dci }
            | Op::SetDequeue { dci } => {
                if let Some(pipe) = device.pipe.as_mut().filter(|_| dci != 1) {
                    pipe.state = PipeState::Halted;
                    pipe.push_done(PipeDone::Error(code.unwrap_or(0)));
                }
                self.say(format_args!(
                    "device {index}: endpoint {dci} not recovered (completion code {})",
                    code.unwrap_or(0)
                ));
                // Endpoint 0 lost, or a controller that stopped answering
                // commands: nothing more will work on this device.
                if dci == 1 || code.is_none() {
                    self.fail_device(index, TransferError::Controller);
                }
            }
        }
        self.next_command(index);
    }

    /// Enable Slot ended: the device gets its slot and pages, or fails.
    fn slot_enabled(&mut self, index: usize, code: Option<u8>, slot: u8) {
        let most = self.capabilities.slots.min(MAX_SLOTS);
        let taken = self
            .host
            .devices
            .iter()
            .flatten()
            .any(|d| d.slot.as_ref().is_some_and(|s| s.id == slot));
        let valid = code == Some(COMPLETION_SUCCESS) && (1..=most).contains(&slot) && !taken;
        let removed = self.host.devices[index].as_ref().is_some_and(|d| d.removed);
        if code == Some(COMPLETION_SUCCESS) && !valid {
            self.say(format_args!("Enable Slot gave slot {slot}; refused"));
        }
        if removed {
            if valid {
                self.disable_slot(slot);
            }
            self.host.devices[index] = None;
            return;
        }
        if !valid {
            let why = match code {
                Some(COMPLETION_NO_SLOTS) => TransferError::NoRoom,
                _ => TransferError::Controller,
            };
            self.fail_device(index, why);
            return;
        }
        let page = match self.page() {
            Ok(page) => page,
            Err(_) => return self.out_of_memory(index, slot, None),
        };
        let input = match self.page() {
            Ok(input) => input,
            Err(_) => return self.out_of_memory(index, slot, Some(page)),
        };
        self.hw
            .mem_write(self.dcbaa + 8 * u64::from(slot), page as u32);
        self.hw
            .mem_write(self.dcbaa + 8 * u64::from(slot) + 4, (page >> 32) as u32);
        if let Some(device) = self.host.devices[index].as_mut() {
            device.slot = Some(Slot {
                id: slot,
                page,
                input,
                ep0: ProducerRing::new(page + EP0_RING_OFFSET, EP0_RING_TRBS),
            });
        }
    }

    fn out_of_memory(&mut self, index: usize, slot: u8, page: Option<u64>) {
        if let Some(page) = page {
            self.free_page(page);
        }
        self.disable_slot(slot);
        self.say(format_args!("device {index}: no DMA memory left"));
        self.fail_device(index, TransferError::NoRoom);
    }

    /// Every transfer of device `index` fails with `why` from now on.
    fn fail_device(&mut self, index: usize, why: TransferError) {
        let Some(device) = self.host.devices[index].as_mut() else {
            return;
        };
        device.failed = Some(why);
        device.ops.clear();
        if !matches!(device.control, Control::Idle | Control::Done(_)) {
            device.control = Control::Done(Transfer::Failed(why));
        }
        if let Some(pipe) = device.pipe.as_mut() {
            pipe.state = PipeState::Halted;
            pipe.push_done(PipeDone::Error(0));
        }
    }

    /// Issues device `index`'s next command if none is on the ring; with
    /// none left, starts the control transfer waiting.
    fn next_command(&mut self, index: usize) {
        loop {
            let Some(device) = self.host.devices[index].as_mut() else {
                return;
            };
            if device.ops.in_flight.is_some() {
                return;
            }
            let Some(op) = device.ops.first() else {
                self.start_waiting_control(index);
                return;
            };
            match self.command_trb(index, op) {
                Some(trb) => {
                    let now = self.hw.now_micros();
                    match self.queue_command(trb) {
                        Some(at) => {
                            if let Some(device) = self.host.devices[index].as_mut() {
                                device.ops.in_flight = Some((at, now));
                            }
                        }
                        None => self.fail_device(index, TransferError::Controller),
                    }
                    return;
                }
                // Nothing to do after all (the pipe went): the next.
                None => {
                    if let Some(device) = self.host.devices[index].as_mut() {
                        device.ops.pop();
                    }
                }
            }
        }
    }

    /// Builds `op`'s TRB for device `index` (its input context written first).
    fn command_trb(&mut self, index: usize, op: Op) -> Option<Trb> {
        let layout = self.capabilities.layout;
        let device = self.host.devices[index].as_mut()?;
        if op == Op::EnableSlot {
            return Some(Trb(command::EnableSlot::new().into_raw()));
        }
        let slot = device.slot.as_mut()?;
        let (id, input) = (slot.id, slot.input);
        let mut context = device.context;
        let pipe_dci = device.pipe.as_ref().map_or(1, |p| p.dci);
        match op {
            Op::EnableSlot => None,
            Op::AddressDefault | Op::Address => {
                let dequeue = if op == Op::Address {
                    // The `xhci` crate takes only 64-byte aligned dequeue
                    // pointers: No Ops fill up to one, and are skipped.
                    slot.ep0.align_enqueue(&mut self.hw, 64);
                    slot.ep0.enqueue_pointer()
                } else {
                    slot.ep0.dequeue_pointer()
                };
                context.context_entries = 1;
                let max_packet = device.max_packet_0;
                let multi_tt = device.multi_tt;
                layout.start_input(&mut self.hw, input, 0b11);
                self.write_slot_context(input, &context, multi_tt);
                layout.write_endpoint(&mut self.hw, input, 1, &ep0_context(dequeue, max_packet));
                let mut address = command::AddressDevice::new();
                address.set_input_context_pointer(input).set_slot_id(id);
                if op == Op::AddressDefault {
                    address.set_block_set_address_request();
                }
                Some(Trb(address.into_raw()))
            }
            Op::Evaluate => {
                let max_packet = device.max_packet_0;
                layout.start_input(&mut self.hw, input, 0b10);
                // A dequeue pointer of 0: not evaluated.
                layout.write_endpoint(&mut self.hw, input, 1, &ep0_context(0, max_packet));
                let mut evaluate = command::EvaluateContext::new();
                evaluate.set_input_context_pointer(input).set_slot_id(id);
                Some(Trb(evaluate.into_raw()))
            }
            Op::ConfigureHub => {
                context.context_entries = u32::from(pipe_dci);
                let multi_tt = device.multi_tt;
                layout.start_input(&mut self.hw, input, 1);
                self.write_slot_context(input, &context, multi_tt);
                Some(configure_endpoint(input, id))
            }
            Op::OpenPipe => {
                let pipe = device.pipe.as_ref()?;
                let endpoint = EndpointContext {
                    kind: endpoint_type::INTERRUPT_IN,
                    max_packet: pipe.max_packet,
                    interval: pipe.interval,
                    dequeue: pipe.ring.dequeue_pointer(),
                    average_trb_length: pipe.max_packet,
                };
                let dci = pipe.dci;
                context.context_entries = u32::from(dci);
                let multi_tt = device.multi_tt;
                layout.start_input(&mut self.hw, input, 1 | 1 << dci);
                self.write_slot_context(input, &context, multi_tt);
                layout.write_endpoint(&mut self.hw, input, dci, &endpoint);
                Some(configure_endpoint(input, id))
            }
            Op::ClosePipe => {
                let dci = device.pipe.as_ref()?.dci;
                context.context_entries = 1;
                let multi_tt = device.multi_tt;
                layout.start_input(&mut self.hw, input, 1);
                // The drop flags, the input control context's first word.
                self.hw.mem_write(input, 1 << dci);
                self.write_slot_context(input, &context, multi_tt);
                Some(configure_endpoint(input, id))
            }
            Op::ResetEndpoint { dci, preserve } => {
                let mut reset = command::ResetEndpoint::new();
                reset.set_slot_id(id).set_endpoint_id(dci);
                if preserve {
                    reset.set_transfer_state_preserve();
                }
                Some(Trb(reset.into_raw()))
            }
            Op::StopEndpoint { dci } => {
                let mut stop = command::StopEndpoint::new();
                stop.set_slot_id(id).set_endpoint_id(dci);
                Some(Trb(stop.into_raw()))
            }
            Op::SetDequeue { dci } => {
                let pointer = if dci == 1 {
                    slot.ep0.enqueue_pointer()
                } else {
                    device
                        .pipe
                        .as_ref()
                        .filter(|p| p.dci == dci)?
                        .ring
                        .enqueue_pointer()
                };
                let mut dequeue = command::SetTrDequeuePointer::new();
                dequeue
                    .set_slot_id(id)
                    .set_endpoint_id(dci)
                    .set_new_tr_dequeue_pointer(pointer & !0xF);
                if pointer & 1 != 0 {
                    dequeue.set_dequeue_cycle_state();
                }
                Some(Trb(dequeue.into_raw()))
            }
        }
    }

    /// Writes the slot context, with the MTT bit the context type lacks.
    fn write_slot_context(&mut self, input: u64, context: &SlotContext, multi_tt: bool) {
        let layout = self.capabilities.layout;
        layout.write_slot(&mut self.hw, input, context);
        if multi_tt {
            let at = layout.input_slot(input);
            let word = self.hw.mem_read(at);
            self.hw.mem_write(at, word | 1 << 25);
        }
    }

    /// Queues device `index`'s command, and issues it if it is the only one.
    fn push_command(&mut self, index: usize, op: Op) -> Result<(), HostError> {
        let device = self.host.devices[index]
            .as_mut()
            .ok_or(HostError::UnknownHandle)?;
        device.ops.push(op)?;
        self.next_command(index);
        Ok(())
    }

    /// The control transfer waiting is put on endpoint 0's ring, now that
    /// the device's commands are done.
    fn start_waiting_control(&mut self, index: usize) {
        let Some(device) = self.host.devices[index].as_mut() else {
            return;
        };
        let Control::Waiting(setup) = device.control else {
            return;
        };
        let Some(slot) = device.slot.as_mut() else {
            return;
        };
        let id = slot.id;
        let buffer = slot.page + CONTROL_BUFFER_OFFSET;
        let ring = &mut slot.ep0;
        ring.reserve_contiguous(&mut self.hw, 3);
        let has_data = setup.length > 0;
        let device_to_host = setup.is_in();
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
        let data = has_data.then(|| {
            let mut data = transfer::DataStage::new();
            // An event for the data stage too: its residual says how many
            // bytes came.
            data.set_data_buffer_pointer(buffer)
                .set_trb_transfer_length(u32::from(setup.length))
                .set_interrupt_on_short_packet()
                .set_interrupt_on_completion()
                .set_direction(if device_to_host {
                    transfer::Direction::In
                } else {
                    transfer::Direction::Out
                });
            ring.push(&mut self.hw, Trb(data.into_raw()))
        });
        // The status stage goes the other way from the data (IN if none).
        let mut status_stage = transfer::StatusStage::new();
        status_stage.set_interrupt_on_completion();
        if !has_data || !device_to_host {
            status_stage.set_direction();
        }
        let status = ring.push(&mut self.hw, Trb(status_stage.into_raw()));
        device.control = Control::Running {
            setup,
            data,
            status,
            residual: 0,
        };
        self.write(self.doorbells + 4 * u32::from(id), 1);
    }

    fn transfer_completed(&mut self, event: &Trb) {
        let slot = event.slot();
        let Some(index) = self.host.devices.iter().position(|d| {
            d.as_ref()
                .and_then(|d| d.slot.as_ref())
                .is_some_and(|s| s.id == slot)
        }) else {
            return;
        };
        if event.endpoint() == 1 {
            self.control_event(index, event);
        } else {
            self.pipe_event(index, event);
        }
    }

    fn control_event(&mut self, index: usize, event: &Trb) {
        let Some(device) = self.host.devices[index].as_mut() else {
            return;
        };
        let Control::Running {
            setup,
            data,
            status,
            residual,
        } = device.control
        else {
            return; // a transfer given up
        };
        let at = event.parameter();
        if at != status && Some(at) != data {
            return;
        }
        let code = event.completion_code();
        if code != COMPLETION_SUCCESS && code != COMPLETION_SHORT_PACKET {
            // Endpoint 0 halted in the controller: reset before the next.
            device.control = Control::Done(transfer_result(code));
            let _ = device.ops.push(Op::ResetEndpoint {
                dci: 1,
                preserve: false,
            });
            self.next_command(index);
            return;
        }
        if Some(at) == data {
            // Never more than was asked for, whatever it says.
            let residual = event.residual().min(u32::from(setup.length));
            device.control = Control::Running {
                setup,
                data,
                status,
                residual,
            };
            return;
        }
        let length = u32::from(setup.length).saturating_sub(residual) as usize;
        device.control = Control::Done(Transfer::Complete(length));
    }

    fn pipe_event(&mut self, index: usize, event: &Trb) {
        let Some(pipe) = self.host.devices[index]
            .as_mut()
            .and_then(|d| d.pipe.as_mut())
        else {
            return;
        };
        if event.endpoint() != pipe.dci || pipe.state != PipeState::Running {
            return;
        }
        let Some(trb) = pipe.ring.index_of(event.parameter()) else {
            self.say(format_args!(
                "device {index}: an event for a TRB not on its pipe's ring; ignored"
            ));
            return;
        };
        pipe.outstanding = pipe.outstanding.saturating_sub(1);
        let code = event.completion_code();
        if code == COMPLETION_SUCCESS || code == COMPLETION_SHORT_PACKET {
            let asked = u32::from(pipe.max_packet);
            let length = asked.saturating_sub(event.residual().min(asked)) as u16;
            pipe.push_done(PipeDone::Report { index: trb, length });
        } else {
            pipe.state = PipeState::Halted;
            pipe.push_done(PipeDone::Error(code));
        }
    }

    /// Fills the pipe's ring up to [`PIPE_QUEUED`] transfers and rings its doorbell.
    fn queue_reports(&mut self, index: usize) {
        let Some(device) = self.host.devices[index].as_mut() else {
            return;
        };
        let Some(id) = device.slot.as_ref().map(|s| s.id) else {
            return;
        };
        let Some(pipe) = device.pipe.as_mut() else {
            return;
        };
        if pipe.state != PipeState::Running {
            return;
        }
        // Reports finished and not yet read keep their buffers too.
        while pipe.outstanding + pipe.done_len < PIPE_QUEUED {
            let trb = pipe.ring.index_of(pipe.ring.enqueue_address()).unwrap_or(0);
            let mut normal = transfer::Normal::new();
            normal
                .set_data_buffer_pointer(pipe.buffers + u64::from(trb) * PIPE_BUFFER_BYTES)
                .set_trb_transfer_length(u32::from(pipe.max_packet))
                .set_interrupt_on_completion()
                .set_interrupt_on_short_packet();
            pipe.ring.push(&mut self.hw, Trb(normal.into_raw()));
            pipe.outstanding += 1;
        }
        let dci = pipe.dci;
        self.write(self.doorbells + 4 * u32::from(id), u32::from(dci));
    }

    /// Reads `into.len()` bytes at `address` in DMA memory.
    fn read_dma(&mut self, address: u64, into: &mut [u8]) {
        for (word, chunk) in into.chunks_mut(4).enumerate() {
            let value = self.hw.mem_read(address + word as u64 * 4).to_le_bytes();
            chunk.copy_from_slice(&value[..chunk.len()]);
        }
    }

    /// Writes `bytes` at `address` in DMA memory, a word at a time.
    fn write_dma(&mut self, address: u64, bytes: &[u8]) {
        for (word, chunk) in bytes.chunks(4).enumerate() {
            let mut value = [0u8; 4];
            value[..chunk.len()].copy_from_slice(chunk);
            self.hw
                .mem_write(address + word as u64 * 4, u32::from_le_bytes(value));
        }
    }

    /// Starts a USB 3 port's warm reset (WPR), said with the link state.
    fn warm_reset(&mut self, port: u8, status: u32) {
        let link = (status >> PORT_LINK_STATE_SHIFT) & 0xF;
        self.say(format_args!(
            "port {port}: USB 3 link stuck (link state {link}); warm reset"
        ));
        let register = self.portsc(port);
        self.write(
            register,
            PORT_POWER | (status & PORT_KEEP) | PORT_WARM_RESET,
        );
    }

    fn valid_port(&self, port: u8) -> bool {
        (1..=self.capabilities.ports).contains(&port)
    }

    fn usb3_port(&self, port: u8) -> bool {
        self.protocols.major(port) == Some(3)
    }
}

impl<H: Hardware> HostController for Xhci<H> {
    fn kind(&self) -> ControllerKind {
        ControllerKind::Xhci
    }

    type Hardware = H;

    fn hardware(&mut self) -> &mut H {
        &mut self.hw
    }

    type StartError = XhciError;

    /// Takes the controller from the firmware (USB Legacy Support): asks for
    /// it, waits up to [`HANDOFF_MICROS`], takes it if the firmware never
    /// lets go, and turns the firmware's SMIs off.
    #[optimize(size)] // run once at start-up: small beats fast
    fn take_ownership(&mut self) -> Handoff {
        let mut legacy = None;
        self.extended_capabilities(|_, offset, id| {
            if id == CAP_LEGACY && legacy.is_none() {
                legacy = Some(offset);
            }
        });
        let Some(legacy) = legacy else {
            return Handoff::NotOwned;
        };
        let before = self.read(legacy);
        let handoff = if before & LEGACY_BIOS_OWNED == 0 {
            self.write(legacy, before | LEGACY_OS_OWNED);
            Handoff::NotOwned
        } else {
            self.write(legacy, before | LEGACY_OS_OWNED);
            let start = self.hw.now_micros();
            if self.wait_for(legacy, HANDOFF_MICROS, |v| v & LEGACY_BIOS_OWNED == 0) {
                Handoff::Released {
                    micros: self.hw.now_micros().saturating_sub(start),
                }
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

    /// Halts and resets the controller, builds the DCBAA (with scratchpads
    /// if it asks), the command ring and the event ring, starts it, powers
    /// its ports and sends a No Op.
    #[optimize(size)] // run once at start-up: small beats fast
    fn reset_and_start(&mut self) -> Result<(), XhciError> {
        let command = self.op_read(USBCMD);
        self.op_write(USBCMD, command & !CMD_RUN);
        let usbsts = self.operational + USBSTS;
        if !self.wait_for(usbsts, HALT_MICROS, |s| s & STS_HALTED != 0) {
            return Err(XhciError::NotHalted);
        }
        self.op_write(USBCMD, CMD_RESET);
        // Some Intel controllers hang if read too soon after HCRST (Linux
        // waits 1 ms there too).
        self.hw.pause(1_000);
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
        // The No Op proves the command and event rings work.
        self.no_op()
    }

    fn root_ports(&self) -> u8 {
        self.capabilities.ports
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        if !self.valid_port(port) {
            return PortStatus::default();
        }
        let status = self.read(self.portsc(port));
        if status == u32::MAX {
            return PortStatus::default();
        }
        let connected = status & PORT_CONNECTED != 0;
        PortStatus {
            connected,
            enabled: status & PORT_ENABLED != 0,
            low_speed: connected && !self.usb3_port(port) && (status >> 10) & 0xF == speed::LOW,
            connect_changed: status & PORT_CONNECT_CHANGE != 0,
            companion_owned: false,
        }
    }

    fn clear_port_change(&mut self, port: u8) {
        if !self.valid_port(port) {
            return;
        }
        let register = self.portsc(port);
        let status = self.read(register);
        if status == u32::MAX {
            return;
        }
        // Write-1-to-clear: the changes seen, never PED, the power kept.
        self.write(
            register,
            PORT_POWER | (status & PORT_KEEP) | (status & PORT_CONNECT_CHANGES),
        );
    }

    fn port_reset_begin(&mut self, port: u8) {
        if !self.valid_port(port) {
            return;
        }
        let now = self.hw.now_micros();
        self.host.reset = Some(RootReset::begin(port, now, ROOT_RESET_BOUND_MICROS));
        let register = self.portsc(port);
        let status = self.read(register);
        if status == u32::MAX {
            return;
        }
        if self.usb3_port(port) {
            // USB 3 ports train and enable by themselves, unless the link
            // is stuck.
            if link_stuck(status) {
                self.warm_reset(port, status);
            }
            return;
        }
        self.write(register, PORT_POWER | (status & PORT_KEEP) | PORT_RESET);
    }

    /// The controller ends a USB 2 port's reset itself (PR cleared); it is
    /// looked at until `ROOT_RESET_BOUND_MICROS`.
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome> {
        let Some(reset) = self.host.reset.take().filter(|r| r.port == port) else {
            return Some(ResetOutcome::Failed);
        };
        let register = self.portsc(port);
        let status = self.read(register);
        let both = PORT_CONNECTED | PORT_ENABLED;
        // A USB 3 link trains and enables by itself, given the hold's time.
        let usb3 = self.usb3_port(port);
        let (running, deadline) = if usb3 {
            (status & both != both, reset.until)
        } else {
            (status & PORT_RESET != 0, reset.bound)
        };
        if status != u32::MAX && running {
            let now = self.hw.now_micros();
            // A USB 3 link that fell into SS.Inactive or Compliance, or did
            // not reach U0 within the hold: a warm reset, once, bounded
            // as a USB 2 port's reset is (Linux's hub_port_reset does the
            // same, "warm reset" in its log).
            if usb3 && reset.stage != WARM_RESET_STAGE && (link_stuck(status) || now >= deadline) {
                self.warm_reset(port, status);
                self.host.reset = Some(RootReset {
                    stage: WARM_RESET_STAGE,
                    until: reset.bound,
                    ..reset
                });
                return None;
            }
            if now < deadline {
                self.host.reset = Some(reset);
                return None;
            }
            if !usb3 {
                let held = ROOT_RESET_BOUND_MICROS / 1_000;
                self.say(format_args!(
                    "port {port}: the reset did not end in {held} ms"
                ));
            }
            return Some(ResetOutcome::Failed);
        }
        if status == u32::MAX {
            return Some(ResetOutcome::Failed);
        }
        if usb3 {
            if reset.stage == WARM_RESET_STAGE {
                // The warm reset's changes (WRC, PRC) are the reset's own.
                self.write(
                    register,
                    PORT_POWER | (status & PORT_KEEP) | (status & PORT_RESET_DONE_CHANGES),
                );
            }
            return Some(ResetOutcome::Enabled(Speed::Super));
        }
        self.write(
            register,
            PORT_POWER | (status & PORT_KEEP) | (status & PORT_RESET_DONE_CHANGES),
        );
        if status & both != both {
            return Some(ResetOutcome::Failed);
        }
        // A USB 2 port's speed IDs by the protocol's defaults (xHCI 7.2.2.1.1).
        Some(match (status >> 10) & 0xF {
            speed::FULL => ResetOutcome::Enabled(Speed::Full),
            speed::LOW => ResetOutcome::Enabled(Speed::Low),
            speed::HIGH => ResetOutcome::Enabled(Speed::High),
            other => {
                self.say(format_args!("port {port}: speed ID {other} unknown"));
                ResetOutcome::Failed
            }
        })
    }

    fn port_disable(&mut self, port: u8) {
        if !self.valid_port(port) {
            return;
        }
        let register = self.portsc(port);
        let status = self.read(register);
        if status == u32::MAX {
            return;
        }
        // PED is write-1-to-disable; the change bits are left as they are.
        self.write(register, PORT_POWER | (status & PORT_KEEP) | PORT_ENABLED);
    }

    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError> {
        if !self.valid_port(info.root_port) {
            return Err(HostError::Invalid);
        }
        if self.commands.is_none() {
            return Err(HostError::ControllerGone);
        }
        // Where the device hangs, as the slot context names it.
        let Some(route) = info
            .route
            .filter(|&route| route_depth(route) <= 5 && route >> 20 == 0)
        else {
            self.say(format_args!(
                "port {}: a hub port a route string cannot name (past port 15 or five tiers)",
                info.root_port
            ));
            return Err(HostError::Invalid);
        };
        // The translator's hub, by the address the device layer gave it.
        let (tt_hub_slot, tt_port, multi_tt) = match info.translator {
            None => (0, 0, false),
            Some(tt) => {
                let hub =
                    self.host.devices.iter().flatten().find(|d| {
                        d.hub && d.address == tt.hub_address && d.info.speed == Speed::High
                    });
                let Some((slot, multi_tt)) =
                    hub.and_then(|d| d.slot.as_ref().map(|s| (s.id, d.multi_tt)))
                else {
                    return Err(HostError::Invalid);
                };
                (slot, tt.hub_port, multi_tt)
            }
        };
        let index = self
            .host
            .devices
            .iter()
            .position(Option::is_none)
            .ok_or(HostError::NoRoom)?;
        let context = SlotContext {
            route_string: route,
            speed: speed_id(info.speed),
            hub: false,
            context_entries: 1,
            root_port: info.root_port,
            hub_ports: 0,
            tt_hub_slot,
            tt_port,
        };
        self.host.devices[index] = Some(HostDevice {
            info,
            slot: None,
            context,
            multi_tt,
            max_packet_0: match info.speed {
                Speed::Super => 512,
                Speed::High => 64,
                Speed::Full | Speed::Low => 8,
            },
            address: 0,
            hub: false,
            ops: Ops::new(),
            control: Control::Idle,
            pipe: None,
            failed: None,
            removed: false,
        });
        if let Some(device) = self.host.devices[index].as_mut() {
            // Both fit an empty queue.
            let _ = device.ops.push(Op::EnableSlot);
            let _ = device.ops.push(Op::AddressDefault);
        }
        self.next_command(index);
        Ok(DeviceId(index as u8))
    }

    /// Address Device (BSR=0): the controller sends SET_ADDRESS itself
    /// (xHCI 4.6.5), and the command's completion is the transfer's.
    fn address_begin(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        let Some(entry) = self.idle_control(device)? else {
            return Ok(());
        };
        entry.ops.push(Op::Address)?;
        entry.control = Control::SettingAddress;
        self.next_command(usize::from(device.0));
        Ok(())
    }

    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        // The controller chose its own; the device layer's names the
        // device as a translator's hub.
        self.host_device(device)?.address = address;
        Ok(())
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> Result<(), HostError> {
        let entry = self.host_device(device)?;
        let allowed = match entry.info.speed {
            Speed::Low => max_packet == 8,
            Speed::Full => matches!(max_packet, 8 | 16 | 32 | 64),
            Speed::High => max_packet == 64,
            Speed::Super => max_packet == 512,
        };
        if !allowed {
            return Err(HostError::Invalid);
        }
        if entry.max_packet_0 == max_packet {
            return Ok(());
        }
        entry.max_packet_0 = max_packet;
        self.push_command(usize::from(device.0), Op::Evaluate)
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        ports: u8,
        multi_tt: bool,
    ) -> Result<(), HostError> {
        let entry = self.host_device(device)?;
        entry.hub = true;
        entry.context.hub = true;
        entry.context.hub_ports = ports;
        // Only a high-speed hub has translators.
        entry.multi_tt = multi_tt && entry.info.speed == Speed::High;
        self.push_command(usize::from(device.0), Op::ConfigureHub)
    }

    fn device_remove(&mut self, device: DeviceId) {
        let index = usize::from(device.0);
        let Some(entry) = self.host.devices.get_mut(index).and_then(Option::as_mut) else {
            return;
        };
        if entry.removed {
            return;
        }
        match entry.slot.take() {
            Some(slot) => {
                self.host.devices[index] = None;
                self.disable_slot(slot.id);
                self.free_page(slot.page);
                self.free_page(slot.input);
            }
            // Its slot is still being enabled: disabled once it is.
            None if entry.ops.in_flight.is_some() && entry.ops.first() == Some(Op::EnableSlot) => {
                entry.removed = true;
                entry.ops.len = 1;
                entry.ops.items[1..].fill(None);
            }
            None => self.host.devices[index] = None,
        }
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError> {
        let index = usize::from(device.0);
        let length = usize::from(setup.length);
        if length > MAX_CONTROL_DATA || (!setup.is_in() && out.len() < length) {
            return Err(HostError::Invalid);
        }
        let Some(entry) = self.idle_control(device)? else {
            return Ok(());
        };
        if !setup.is_in() && length > 0 {
            let Some(buffer) = entry.slot.as_ref().map(|s| s.page + CONTROL_BUFFER_OFFSET) else {
                return Err(HostError::Busy);
            };
            self.write_dma(buffer, &out[..length]);
        }
        let entry = self.host_device(device)?;
        entry.control = Control::Waiting(setup);
        if entry.ops.first().is_none() {
            self.start_waiting_control(index);
        }
        Ok(())
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        self.take_events_meanwhile();
        let Ok(entry) = self.host_device(device) else {
            return Transfer::Failed(TransferError::Controller);
        };
        let Control::Done(result) = entry.control else {
            return Transfer::Pending;
        };
        entry.control = Control::Idle;
        let buffer = entry.slot.as_ref().map(|s| s.page + CONTROL_BUFFER_OFFSET);
        match (result, buffer) {
            (Transfer::Complete(length), Some(buffer)) => {
                let length = length.min(into.len());
                self.read_dma(buffer, &mut into[..length]);
                Transfer::Complete(length)
            }
            (result, _) => result,
        }
    }

    fn control_cancel(&mut self, device: DeviceId) {
        let index = usize::from(device.0);
        let Ok(entry) = self.host_device(device) else {
            return;
        };
        let running = matches!(entry.control, Control::Running { .. });
        entry.control = Control::Idle;
        if running {
            // Endpoint 0 stopped and its ring moved past the transfer.
            let _ = entry.ops.push(Op::StopEndpoint { dci: 1 });
            self.next_command(index);
        }
    }

    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> Result<PipeId, HostError> {
        if !(1..=15).contains(&endpoint) || !(1..=MAX_REPORT as u16).contains(&max_packet) {
            return Err(HostError::Invalid);
        }
        let entry = self.host_device(device)?;
        if entry.pipe.is_some() {
            return Err(HostError::NoRoom);
        }
        let Some(input) = entry.slot.as_ref().map(|s| s.input) else {
            return Err(HostError::Busy);
        };
        let speed = entry.info.speed;
        // A ring closed before leaves its TRBs: cleared.
        for offset in (PIPE_RING_OFFSET..PIPE_BUFFERS_OFFSET).step_by(4) {
            self.hw.mem_write(input + offset, 0);
        }
        let entry = self.host_device(device)?;
        entry.pipe = Some(Pipe {
            dci: 2 * endpoint + 1,
            max_packet,
            interval: interval_exponent(speed, interval),
            ring: ProducerRing::new(input + PIPE_RING_OFFSET, PIPE_RING_TRBS),
            buffers: input + PIPE_BUFFERS_OFFSET,
            state: PipeState::Opening,
            outstanding: 0,
            done: [None; PIPE_QUEUED + 1],
            done_len: 0,
        });
        if let Err(e) = self.push_command(usize::from(device.0), Op::OpenPipe) {
            if let Ok(entry) = self.host_device(device) {
                entry.pipe = None;
            }
            return Err(e);
        }
        Ok(PipeId(device.0))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        self.take_events_meanwhile();
        let index = usize::from(pipe.0);
        let Some(done) = self
            .host_device(DeviceId(pipe.0))
            .ok()
            .and_then(|d| d.pipe.as_mut())
            .filter(|p| p.state != PipeState::Closing)
            .map(Pipe::pop_done)
        else {
            return Transfer::Failed(TransferError::Controller);
        };
        match done {
            None => Transfer::Pending,
            Some(PipeDone::Error(code)) => transfer_result(code),
            Some(PipeDone::Report { index: trb, length }) => {
                let Some(buffers) = self.host.devices[index]
                    .as_ref()
                    .and_then(|d| d.pipe.as_ref())
                    .map(|p| p.buffers)
                else {
                    return Transfer::Failed(TransferError::Controller);
                };
                let length = usize::from(length).min(into.len());
                self.read_dma(
                    buffers + u64::from(trb) * PIPE_BUFFER_BYTES,
                    &mut into[..length],
                );
                self.queue_reports(index);
                Transfer::Complete(length)
            }
        }
    }

    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError> {
        let entry = self.host_device(DeviceId(pipe.0))?;
        let failed = entry.failed;
        let Some(state) = entry.pipe.as_mut() else {
            return Err(HostError::UnknownHandle);
        };
        if failed.is_some() {
            return Err(HostError::ControllerGone);
        }
        match state.state {
            PipeState::Halted => {}
            PipeState::Running => return Ok(()),
            PipeState::Opening | PipeState::Restarting => return Err(HostError::Busy),
            PipeState::Closing => return Err(HostError::UnknownHandle),
        }
        state.state = PipeState::Restarting;
        state.done = [None; PIPE_QUEUED + 1];
        state.done_len = 0;
        let dci = state.dci;
        // The device reset its toggle (CLEAR_FEATURE(ENDPOINT_HALT)): the
        // controller's too; else it keeps it.
        self.push_command(
            usize::from(pipe.0),
            Op::ResetEndpoint {
                dci,
                preserve: !reset_toggle,
            },
        )
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        let index = usize::from(pipe.0);
        let Ok(entry) = self.host_device(DeviceId(pipe.0)) else {
            return;
        };
        let Some(state) = entry.pipe.as_mut() else {
            return;
        };
        if state.state == PipeState::Closing {
            return;
        }
        state.state = PipeState::Closing;
        state.done_len = 0;
        if entry.ops.push(Op::ClosePipe).is_err() {
            // No room to drop the endpoint: it goes with the slot.
            return;
        }
        self.next_command(index);
    }

    fn anything_happened(&mut self) -> bool {
        // One DMA word when idle: the event ring's next TRB's cycle bit.
        let news = core::mem::take(&mut self.host.news);
        let taken = self.take_events();
        if taken == EVENTS_PER_POLL {
            // More may wait: the next call looks again.
            self.host.news = true;
        }
        // A command past its time fails its device: news too (no read
        // unless a command is on the ring).
        let aborted = self.check_command_timeouts();
        news || taken > 0 || aborted
    }

    fn halt(&mut self) -> bool {
        self.host = HostState::new();
        self.shut_down().is_ok()
    }
}

/// Whether a USB 3 port's link is in SS.Inactive or Compliance Mode, out
/// of which only a warm reset takes it.
fn link_stuck(status: u32) -> bool {
    matches!(
        (status >> PORT_LINK_STATE_SHIFT) & 0xF,
        LINK_INACTIVE | LINK_COMPLIANCE
    )
}
