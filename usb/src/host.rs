//! The one narrow, polled interface between the controller-independent
//! device layer ([`crate::bus`]) and a host controller driver (EHCI, OHCI,
//! UHCI and xHCI).
//!
//! Nothing here waits for a device: every call either does its register and
//! DMA work and returns, or starts something whose end a later `*_poll` call
//! reports. The only waits are for the controller itself, bounded to a few
//! milliseconds: a reset, a halt, and the removal calls, which wait until
//! the controller has let go of the memory they reuse (a frame boundary, or
//! EHCI's doorbell). A driver times its root ports' resets by its own clock.
//! The device layer owns every other timeout (Linux's, in [`crate::bus`]); a
//! driver only says [`Transfer::Pending`] until the controller has finished.
//! Like Linux's `hc_driver`, the device layer never sees a queue head, an
//! endpoint descriptor or a transfer descriptor.

use crate::Platform;
use core::fmt;

/// Which kind of controller, for the log and the facts record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ControllerKind {
    /// Universal Host Controller Interface (Intel, VIA): USB 1.1, I/O ports.
    Uhci,
    /// Open Host Controller Interface (AMD, SiS, ALi, NEC, Apple): USB 1.1.
    Ohci,
    /// Enhanced Host Controller Interface: USB 2.0 high speed, with companions.
    Ehci,
    /// Extensible Host Controller Interface: every speed.
    Xhci,
}

impl ControllerKind {
    /// The PCI programming interface of class 0C03h that names this kind.
    pub const fn prog_if(self) -> u8 {
        match self {
            ControllerKind::Uhci => 0x00,
            ControllerKind::Ohci => 0x10,
            ControllerKind::Ehci => 0x20,
            ControllerKind::Xhci => 0x30,
        }
    }

    /// The kind a PCI class 0C03h programming interface names, if any.
    pub const fn from_prog_if(prog_if: u8) -> Option<ControllerKind> {
        match prog_if {
            0x00 => Some(ControllerKind::Uhci),
            0x10 => Some(ControllerKind::Ohci),
            0x20 => Some(ControllerKind::Ehci),
            0x30 => Some(ControllerKind::Xhci),
            _ => None,
        }
    }

    /// The short lower-case name the log and the facts record use.
    pub const fn name(self) -> &'static str {
        match self {
            ControllerKind::Uhci => "uhci",
            ControllerKind::Ohci => "ohci",
            ControllerKind::Ehci => "ehci",
            ControllerKind::Xhci => "xhci",
        }
    }
}

impl fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A device's bus speed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Speed {
    /// 1.5 Mbit/s.
    Low,
    /// 12 Mbit/s.
    Full,
    /// 480 Mbit/s.
    High,
    /// 5 Gbit/s and up (USB 3, xHCI only): endpoint 0 takes 512-byte
    /// packets, its bMaxPacketSize0 is the exponent 9.
    Super,
}

impl fmt::Display for Speed {
    /// The log's word for it: `low`, `full`, `high`, `super`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Speed::Low => "low",
            Speed::Full => "full",
            Speed::High => "high",
            Speed::Super => "super",
        })
    }
}

/// A root port as the controller reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PortStatus {
    /// Something is attached.
    pub connected: bool,
    /// The port is enabled (after a reset).
    pub enabled: bool,
    /// The attached device is low speed (line state before the reset; UHCI
    /// and OHCI report it directly). High speed is known only after a reset.
    pub low_speed: bool,
    /// The connection changed since the last [`HostController::clear_port_change`].
    pub connect_changed: bool,
    /// The port belongs to a companion controller (EHCI's PORT_OWNER).
    pub companion_owned: bool,
}

/// How long a root port is held in reset: TDRSTR (USB 2.0 7.1.7.5), and
/// Linux's `PORT_RESET_MSEC` (ohci-hub.c) and root-port 50 ms.
pub const ROOT_RESET_MICROS: u64 = 50_000;

/// A root port reset as its driver times it, from
/// [`HostController::port_reset_begin`] to the poll that ends it: `stage`
/// is the driver's own count (0 while the port is held in reset), `until`
/// when the hold (or the stage's wait) is over, `bound` when the reset fails.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct RootReset {
    pub(crate) port: u8,
    pub(crate) stage: u32,
    pub(crate) until: u64,
    pub(crate) bound: u64,
}

impl RootReset {
    /// The reset of `port` begun at `now`, held for [`ROOT_RESET_MICROS`],
    /// given up `bound_micros` from now.
    pub(crate) fn begin(port: u8, now: u64, bound_micros: u64) -> RootReset {
        RootReset {
            port,
            stage: 0,
            until: now + ROOT_RESET_MICROS,
            bound: now.saturating_add(bound_micros),
        }
    }
}

/// What a root port reset ended in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetOutcome {
    /// The port is enabled with a device at this speed.
    Enabled(Speed),
    /// The device is full or low speed on an EHCI root port, and the port
    /// was handed to the companion controller (PORT_OWNER set): this
    /// controller forgets it.
    HandedToCompanion,
    /// Nothing is attached any more, or the port did not enable.
    Failed,
}

/// The transaction translator a full- or low-speed device behind a
/// high-speed hub is reached through (EHCI split transactions): the
/// high-speed hub's address and the hub port the device's subtree hangs on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TransactionTranslator {
    /// The high-speed hub's USB address.
    pub hub_address: u8,
    /// The port of that hub (1-based) the device is below.
    pub hub_port: u8,
}

/// Everything a driver needs to reach a device's endpoint 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// The device's speed.
    pub speed: Speed,
    /// The root port (1-based) the device is below.
    pub root_port: u8,
    /// Its place below the root port as a route string (USB 3.2 8.9, xHCI
    /// 4.5.2): the hub port on each tier, four bits a tier, the first tier
    /// lowest; `Some(0)` on a root port. `None` when a hub port past 15 is
    /// on the way, which a route string cannot name (only xHCI needs it).
    pub route: Option<u32>,
    /// For a full- or low-speed device reached through a high-speed hub:
    /// that hub's transaction translator. `None` on UHCI and OHCI.
    pub translator: Option<TransactionTranslator>,
}

/// A device as the driver knows it: an index in the driver's own table,
/// which the driver gives from [`HostController::device_new`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceId(pub u8);

/// An interrupt-in pipe, as [`HostController::interrupt_open`] gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PipeId(pub u8);

/// A control request's SETUP packet (USB 2.0 9.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Setup {
    /// bmRequestType.
    pub request_type: u8,
    /// bRequest.
    pub request: u8,
    /// wValue.
    pub value: u16,
    /// wIndex.
    pub index: u16,
    /// wLength: the bytes of the data stage.
    pub length: u16,
}

impl Setup {
    /// The eight bytes on the wire.
    pub fn bytes(&self) -> [u8; 8] {
        let [v0, v1] = self.value.to_le_bytes();
        let [i0, i1] = self.index.to_le_bytes();
        let [l0, l1] = self.length.to_le_bytes();
        [self.request_type, self.request, v0, v1, i0, i1, l0, l1]
    }

    /// Whether the data stage (if any) is device-to-host.
    pub fn is_in(&self) -> bool {
        self.request_type & 0x80 != 0
    }
}

/// Where a transfer stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transfer {
    /// Not finished (or, for an interrupt pipe, no new report).
    Pending,
    /// Finished with this many data bytes (copied into the caller's buffer
    /// for an IN transfer).
    Complete(usize),
    /// The device answered STALL (the pipe needs CLEAR_FEATURE(ENDPOINT_HALT)
    /// for an interrupt endpoint; endpoint 0 clears at the next SETUP).
    Stalled,
    /// The transfer failed; the driver has retired it.
    Failed(TransferError),
}

/// Why a transfer failed, as the controller says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransferError {
    /// No handshake after the controller's retries (CRC or timeout).
    NoResponse,
    /// The device sent more than asked for.
    Babble,
    /// The controller could not keep up with memory (overrun/underrun).
    DataBuffer,
    /// A data toggle mismatch the controller could not resolve.
    Toggle,
    /// A split transaction's translator failed (EHCI).
    Split,
    /// The controller is halted, dead or reported something impossible.
    Controller,
    /// The driver has no room (descriptors, DMA memory) for another transfer.
    NoRoom,
}

impl fmt::Display for TransferError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            TransferError::NoResponse => "no response",
            TransferError::Babble => "babble",
            TransferError::DataBuffer => "data buffer error",
            TransferError::Toggle => "data toggle error",
            TransferError::Split => "split transaction error",
            TransferError::Controller => "controller error",
            TransferError::NoRoom => "no room",
        })
    }
}

/// Why a driver refused a request.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostError {
    /// No room for another device or pipe.
    NoRoom,
    /// The device or pipe is not one this driver gave out.
    UnknownHandle,
    /// A transfer is already running on this device's endpoint 0.
    Busy,
    /// The request cannot be done (too long, bad endpoint or packet size).
    Invalid,
    /// The controller is halted or gone.
    ControllerGone,
}

impl fmt::Display for HostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            HostError::NoRoom => "no room",
            HostError::UnknownHandle => "unknown device or pipe",
            HostError::Busy => "busy",
            HostError::Invalid => "invalid request",
            HostError::ControllerGone => "controller halted or gone",
        })
    }
}

/// Largest data stage the device layer asks for (a configuration
/// descriptor of a keyboard with many interfaces, a report descriptor).
pub const MAX_CONTROL_DATA: usize = 1024;
/// Largest interrupt report read.
pub const MAX_REPORT: usize = 64;

/// SET_ADDRESS's bRequest (USB 2.0 table 9-4).
pub(crate) const SET_ADDRESS: u8 = 5;

/// A polled host controller, as the device layer drives it. Ports are
/// 1-based. A driver checks every handle and index it is given.
pub trait HostController {
    /// Which kind this is.
    fn kind(&self) -> ControllerKind;

    /// The machine the driver runs on: its registers and DMA memory,
    /// and the platform's clock and log, which the device layer uses too.
    type Hardware: crate::Platform;

    /// The driver's hardware (for the clock and the log; the kernel's and
    /// the host tests' checks).
    fn hardware(&mut self) -> &mut Self::Hardware;

    /// Why the controller would not start.
    type StartError: fmt::Display;

    /// Start-up, first: takes the controller from the firmware (BIOS
    /// legacy support or SMM), bounded. The kernel takes every controller
    /// before it starts any.
    fn take_ownership(&mut self) -> Handoff;

    /// Start-up, then: resets the controller, builds its schedules, starts
    /// it and powers its ports, every wait bounded. A controller the
    /// firmware kept ([`Handoff::NeverReleased`]) is refused untouched.
    fn reset_and_start(&mut self) -> Result<(), Self::StartError>;

    /// The number of root ports.
    fn root_ports(&self) -> u8;

    /// A root port's status.
    fn port_status(&mut self, port: u8) -> PortStatus;

    /// Acknowledges a root port's connect (and enable) change.
    fn clear_port_change(&mut self, port: u8);

    /// Starts a root port reset, which the driver times by its own clock
    /// (at least [`ROOT_RESET_MICROS`]) and ends itself; the device layer
    /// polls [`Self::port_reset_poll`] until it says what is there.
    fn port_reset_begin(&mut self, port: u8);

    /// `None` while the root port's reset runs; then what is there, the
    /// port enabled. Never blocks: the driver bounds each of its waits and
    /// says [`ResetOutcome::Failed`] past the bound (and for a port not in
    /// reset). An EHCI driver hands a full- or low-speed device to its
    /// companion here. The driver clears the change bits its own reset
    /// caused; the device layer also calls [`Self::clear_port_change`]
    /// after [`ResetOutcome::Enabled`], as Linux does.
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome>;

    /// Disables a root port (a device given up, or gone).
    fn port_disable(&mut self, port: u8);

    /// Makes a device at the default address 0 with an 8-byte endpoint 0
    /// (64 bytes at high speed, the only size high speed allows).
    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError>;

    /// Starts giving the device at the default address its `address`
    /// (1-127), as Linux's `address_device` hook: by default SET_ADDRESS on
    /// endpoint 0 (xHCI's is Address Device). [`Self::control_cancel`] stops it.
    fn address_begin(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        if !(1..=127).contains(&address) {
            return Err(HostError::Invalid);
        }
        let setup = Setup {
            request_type: 0x00,
            request: SET_ADDRESS,
            value: u16::from(address),
            index: 0,
            length: 0,
        };
        self.control_begin(device, setup, &[])
    }

    /// Where the addressing stands; once it has completed the driver
    /// reaches the device at `address` ([`Self::device_set_address`]).
    fn address_poll(&mut self, device: DeviceId, address: u8) -> Transfer {
        match self.control_poll(device, &mut []) {
            Transfer::Complete(_) => match self.device_set_address(device, address) {
                Ok(()) => Transfer::Complete(0),
                Err(_) => Transfer::Failed(TransferError::Controller),
            },
            other => other,
        }
    }

    /// Records that the device answers at `address` now: the end of the
    /// default [`Self::address_poll`]. The device layer never calls it.
    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError>;

    /// The device's endpoint 0 packet size, from its device descriptor.
    fn device_set_max_packet(&mut self, device: DeviceId, max_packet: u16)
        -> Result<(), HostError>;

    /// The device is a hub: `ports` downstream ports; `multi_tt` if it has a
    /// translator per port. Drivers that need nothing of this ignore it.
    fn device_is_hub(
        &mut self,
        device: DeviceId,
        ports: u8,
        multi_tt: bool,
    ) -> Result<(), HostError>;

    /// Forgets the device: its pipes are closed and its memory reused.
    fn device_remove(&mut self, device: DeviceId);

    /// Starts a control transfer on the device's endpoint 0. An OUT data
    /// stage's bytes are `out` (`setup.length` of them); an IN data stage
    /// of `setup.length` bytes is read at [`Self::control_poll`].
    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError>;

    /// Where the device's control transfer stands; when complete, an IN
    /// data stage's bytes are copied into `into`.
    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer;

    /// Stops the device's control transfer (the device layer's timeout).
    fn control_cancel(&mut self, device: DeviceId);

    /// Opens an interrupt-in pipe on `endpoint` (1-15) of `max_packet`
    /// bytes, polled every `interval` frames (a power of two the driver
    /// may round down), and starts its first transfer.
    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> Result<PipeId, HostError>;

    /// A new report, if one came: copied into `into`, and the next
    /// transfer started with the right data toggle. After `Stalled` or
    /// `Failed` the pipe waits for [`Self::interrupt_restart`].
    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer;

    /// Starts the pipe again after a stall or error; `reset_toggle` after a
    /// CLEAR_FEATURE(ENDPOINT_HALT), which resets the device's toggle to DATA0.
    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError>;

    /// Closes the pipe.
    fn interrupt_close(&mut self, pipe: PipeId);

    /// One register read or DMA word: whether anything may have happened
    /// (a transfer completed, a root port changed) since the last call.
    /// The device layer skips the rest of an idle poll when this is false.
    fn anything_happened(&mut self) -> bool;

    /// Halts the controller, bounded, and hands shared ports back (EHCI
    /// clears CONFIGFLAG), before power-off or reset. Says whether it halted.
    fn halt(&mut self) -> bool;
}

/// How often a controller's bounded wait looks at the controller. QEMU
/// serves each register read under its one global lock, and runs the
/// controller's frames (which halt it and start its schedules) on its main
/// thread, which needs that lock too: a wait that read with no pause held
/// the lock nearly all the time, so on a loaded host that thread, once
/// scheduled, mostly found it taken and slept again, and the controller's
/// frames fell behind the clock by more than a whole bound ("schedules did
/// not start" beside busy loops). Between reads the wait watches only the
/// clock, leaving the lock free. Under half a micro-frame, so no wait ends
/// later than that.
pub const POLL_INTERVAL_MICROS: u64 = 50;

/// Every driver's bounded wait: asks `done` (which reads the controller)
/// once every [`POLL_INTERVAL_MICROS`], watching only the platform's clock
/// in between, for at most `micros`, and once more at the bound. Says
/// whether `done` held.
pub(crate) fn wait_until<C: HostController + ?Sized>(
    controller: &mut C,
    micros: u64,
    mut done: impl FnMut(&mut C) -> bool,
) -> bool {
    let start = controller.hardware().now_micros();
    loop {
        if done(controller) {
            return true;
        }
        let read_at = controller.hardware().now_micros();
        loop {
            let now = controller.hardware().now_micros();
            if now.saturating_sub(start) >= micros {
                return done(controller);
            }
            if now.saturating_sub(read_at) >= POLL_INTERVAL_MICROS {
                break;
            }
            core::hint::spin_loop();
        }
    }
}

/// How a controller was taken from the firmware (BIOS legacy support or SMM).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handoff {
    /// The firmware did not own it.
    NotOwned,
    /// The firmware let go after this many microseconds.
    Released {
        /// How long it took.
        micros: u64,
    },
    /// The firmware never let go within the bound, and the driver took the
    /// controller anyway (xHCI, as Linux does).
    Forced,
    /// The firmware never let go within the bound: the driver logged it
    /// and leaves the controller alone (no reset, no schedule).
    NeverReleased,
}
