//! Enumeration, a step per poll, as Linux's hub.c does it (with its
//! timeouts) but never waiting. One device is enumerated at a time (as
//! Linux serializes the default address); ports wait their turn in a small
//! queue, and so do hubs whose ports changed (their requests go through
//! the hub's endpoint 0, which an enumeration behind the hub uses too).
//! Each poll runs at most one step: a step checks whether what it waits
//! for has happened (a control transfer's end, the clock), acts on it, and
//! starts the next step's transfer, port reset or wait.

use super::*;
use crate::descriptor::{DescriptorError, Function, InterruptIn};
use crate::hid::{self, HidError};
use crate::host::{DeviceInfo, HostError, ResetOutcome, TransferError};

/// Root ports are first looked at this long after the controller starts
/// (devices need time to connect after the reset), as the xHCI driver does.
pub(crate) const CONNECT_MICROS: u64 = 200_000;
/// How long boot enumeration may hold the boot up; what is left carries on
/// from the frame loop. Five tiers of hubs take 200 ms each (power-on and
/// connect times) after the root ports' 200 ms: 2 s holds them.
pub const BOOT_ENUMERATION_MICROS: u64 = 2_000_000;
/// Between two looks at a root port's reset, which its driver times.
const ROOT_RESET_POLL_MICROS: u64 = 1_000;
/// How long a hub port reset may take, however many status checks: Linux's
/// `HUB_RESET_TIMEOUT` (drivers/usb/core/hub.c, 800 ms).
const HUB_RESET_MICROS: u64 = 800_000;
/// Between a hub port's status checks during its reset: Linux's
/// `HUB_SHORT_RESET_TIME` (hub.c, 10 ms); each check is a control transfer.
pub(crate) const HUB_RESET_CHECK_MICROS: u64 = 10_000;
/// A new connection must stay this long before it is enumerated: Linux's
/// `HUB_DEBOUNCE_STABLE` (hub.c, 100 ms)...
pub const DEBOUNCE_MICROS: u64 = 100_000;
/// ...within Linux's `HUB_DEBOUNCE_TIMEOUT` (hub.c, 2000 ms): a port that
/// keeps bouncing longer is dropped until its next change.
pub const DEBOUNCE_TIMEOUT_MICROS: u64 = 2_000_000;
/// After a port reset, the device gets this long before it must answer:
/// TRSTRCY (USB 2.0 7.1.7.3).
pub const RESET_RECOVERY_MICROS: u64 = 10_000;
/// The SET_ADDRESS recovery interval (USB 2.0 9.2.6.3).
pub const SET_ADDRESS_RECOVERY_MICROS: u64 = 2_000;
/// Devices need up to 100 ms to connect after a hub powers its ports
/// (USB 2.0 7.1.7.3), after the hub's own power-on-to-good time.
pub(crate) const HUB_CONNECT_MICROS: u64 = 100_000;
/// Ports and hubs waiting for their turn (a hub's worth of ports).
const QUEUE_LENGTH: usize = MAX_DEVICES;
/// Tries a device gets to be reset, addressed and describe itself, a port
/// reset before each: Linux's `PORT_INIT_TRIES` (hub.c, 4), as real
/// devices often fail the first ("device descriptor read/64, error -71").
pub const ENUMERATION_TRIES: u8 = 4;

/// Hub port status (wPortStatus, low half) and change (wPortChange, high
/// half) bits, USB 2.0 11.24.2.7.
const HUB_PORT_CONNECTION: u32 = 1 << 0;
const HUB_PORT_ENABLE: u32 = 1 << 1;
const HUB_PORT_LOW_SPEED: u32 = 1 << 9;
const HUB_PORT_HIGH_SPEED: u32 = 1 << 10;
const HUB_C_PORT_CONNECTION: u32 = 1 << 16;
const HUB_C_PORT_ENABLE: u32 = 1 << 17;
const HUB_C_PORT_RESET: u32 = 1 << 20;
/// C_PORT_CONNECTION to C_PORT_RESET: each cleared with the feature of its
/// bit's number (16 to 20); and a SuperSpeed hub's C_BH_PORT_RESET,
/// C_PORT_LINK_STATE and C_PORT_CONFIG_ERROR (bits 21 to 23, USB 3.2
/// 10.16.2.6.2), reserved on a USB 2 hub.
const HUB_PORT_CHANGES: u32 = 0xFF << 16;
/// The hub's own changes (wHubChange, USB 2.0 11.24.2.6): C_HUB_LOCAL_POWER
/// and C_HUB_OVER_CURRENT, cleared with features 0 and 1.
const HUB_CHANGES: u32 = 0x3 << 16;
/// Port feature selectors (USB 2.0 table 11-17).
const PORT_ENABLE: u16 = 1;
const PORT_RESET: u16 = 4;
const PORT_POWER: u16 = 8;
const C_PORT_RESET: u16 = 20;
/// bDeviceProtocol of a high-speed hub with a translator per port; its
/// interface's alternate setting 1 turns them on (USB 2.0 11.23.1).
const HUB_PROTOCOL_MULTI_TT: u8 = 2;

/// What waits in the queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Work {
    /// A port with a new connection, enumerated once it has been stable for
    /// [`DEBOUNCE_MICROS`]: when it first and last changed.
    Port {
        location: Location,
        first_change: u64,
        last_change: u64,
        /// Tries it has had already ([`ENUMERATION_TRIES`]).
        tries: u8,
    },
    /// A hub (by its place in the table) whose status change endpoint said
    /// these changed (bit n: port n; bit 0: the hub itself).
    HubChanges { hub: usize, changed: u32 },
}

/// The queue, first come first served (a port becomes ready when its
/// connection has settled).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct WorkQueue {
    items: [Option<Work>; QUEUE_LENGTH],
    len: usize,
}

impl WorkQueue {
    pub(super) fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Queues `work`; a port already queued has its connection's last
    /// change moved on instead, a hub already queued its changes added.
    /// Gives false when the queue is full.
    fn push(&mut self, work: Work) -> bool {
        for item in self.items[..self.len].iter_mut().flatten() {
            match (item, work) {
                (
                    Work::Port {
                        location,
                        last_change,
                        ..
                    },
                    Work::Port {
                        location: new,
                        last_change: now,
                        ..
                    },
                ) if *location == new => {
                    *last_change = now;
                    return true;
                }
                (
                    Work::HubChanges { hub, changed },
                    Work::HubChanges {
                        hub: new,
                        changed: more,
                    },
                ) if *hub == new => {
                    *changed |= more;
                    return true;
                }
                _ => {}
            }
        }
        if self.len == QUEUE_LENGTH {
            return false;
        }
        self.items[self.len] = Some(work);
        self.len += 1;
        true
    }

    /// The port's queued work: when its connection first changed.
    fn first_change(&self, at: Location) -> Option<u64> {
        self.items[..self.len]
            .iter()
            .flatten()
            .find_map(|w| match w {
                Work::Port {
                    location,
                    first_change,
                    ..
                } if *location == at => Some(*first_change),
                _ => None,
            })
    }

    /// Takes the first work that can start now and that `may_start` lets.
    fn take_ready(&mut self, now: u64, may_start: impl Fn(&Work) -> bool) -> Option<Work> {
        let position = self.items[..self.len].iter().position(|item| match item {
            Some(work @ Work::Port { last_change, .. }) => {
                now.saturating_sub(*last_change) >= DEBOUNCE_MICROS && may_start(work)
            }
            Some(work @ Work::HubChanges { .. }) => may_start(work),
            None => false,
        })?;
        let work = self.items[position].take();
        self.items.copy_within(position + 1..self.len, position);
        self.len -= 1;
        self.items[self.len] = None;
        work
    }

    /// Forgets the work `gone` picks.
    fn remove(&mut self, gone: impl Fn(&Work) -> bool) {
        let mut kept = 0;
        for index in 0..self.len {
            if let Some(work) = self.items[index] {
                if !gone(&work) {
                    self.items[kept] = Some(work);
                    kept += 1;
                }
            }
        }
        for item in &mut self.items[kept..self.len] {
            *item = None;
        }
        self.len = kept;
    }
}

/// Why an enumeration step failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum BusError {
    /// A control transfer did not end within [`TRANSFER_MICROS`].
    Timeout,
    /// The device stalled a request.
    Stalled,
    /// A control transfer failed.
    Failed(TransferError),
    /// The driver refused a request.
    Host(HostError),
    /// A descriptor that makes no sense.
    Descriptor(DescriptorError),
    /// A report descriptor that breaks the rules.
    ReportDescriptor(HidError),
    /// Fewer bytes came than the request (or the descriptor) said.
    Short { wanted: usize, got: usize },
    /// Endpoint 0's packet size is not one its speed allows.
    PacketSize(u8),
    /// A port reset did not end, or left the port disabled.
    PortReset,
    /// The device table is full.
    NoRoom,
    /// All 127 addresses are given out.
    NoAddress,
    /// The device (or its hub) went away.
    Gone,
}

impl fmt::Display for BusError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BusError::Timeout => write!(
                f,
                "control transfer not completed in {} ms",
                TRANSFER_MICROS / 1_000
            ),
            BusError::Stalled => write!(f, "request stalled"),
            BusError::Failed(e) => write!(f, "control transfer failed ({e})"),
            BusError::Host(e) => write!(f, "the controller driver refused ({e})"),
            BusError::Descriptor(e) => write!(f, "{e}"),
            BusError::ReportDescriptor(e) => write!(f, "report descriptor refused ({e})"),
            BusError::Short { wanted, got } => {
                write!(f, "{got} bytes came of the {wanted} asked for")
            }
            BusError::PacketSize(size) => {
                write!(
                    f,
                    "endpoint 0 packet size {size} is impossible at its speed"
                )
            }
            BusError::PortReset => write!(f, "port reset failed"),
            BusError::NoRoom => write!(f, "no room: {MAX_DEVICES} devices kept already"),
            BusError::NoAddress => write!(f, "no USB address left"),
            BusError::Gone => write!(f, "the device went away"),
        }
    }
}

impl From<DescriptorError> for BusError {
    fn from(e: DescriptorError) -> Self {
        BusError::Descriptor(e)
    }
}

impl From<HostError> for BusError {
    fn from(e: HostError) -> Self {
        BusError::Host(e)
    }
}

type Result<T> = core::result::Result<T, BusError>;

/// One step of an enumeration (or of a hub's changes): what the step waits
/// for is in [`Job::awaiting`]; the step's function, named for it, runs
/// once that has happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Step {
    /// A root port in reset, until its driver says it is over.
    ResettingRootPort,
    /// GET_STATUS of a hub port about to be reset: is anything there?
    CheckingHubPortConnection,
    /// SET_FEATURE(PORT_RESET) sent to the hub.
    StartingHubPortReset,
    /// Between two checks of a hub port's reset.
    WaitingForHubPortReset,
    /// GET_STATUS of the hub port being reset.
    CheckingHubPortReset,
    /// CLEAR_FEATURE(C_PORT_RESET) sent to the hub.
    ClearingHubPortReset,
    /// The reset recovery time (TRSTRCY).
    RecoveringFromReset,
    /// The device descriptor's first 8 bytes (endpoint 0's packet size).
    ReadingDeviceHeader,
    /// The driver's addressing hook (SET_ADDRESS, or xHCI's Address Device).
    Addressing,
    /// The SET_ADDRESS recovery interval.
    RecoveringFromSetAddress,
    /// The whole device descriptor.
    ReadingDeviceDescriptor,
    /// The configuration descriptor's first 9 bytes (its total length).
    ReadingConfigurationHeader,
    /// The whole configuration.
    ReadingConfiguration,
    /// SET_CONFIGURATION sent to a keyboard.
    ConfiguringKeyboard,
    /// The HID report descriptor.
    ReadingReportDescriptor,
    /// SET_PROTOCOL.
    SettingProtocol,
    /// SET_IDLE.
    SettingIdle,
    /// The hub descriptor.
    ReadingHubDescriptor,
    /// SET_CONFIGURATION sent to a hub.
    ConfiguringHub,
    /// SET_INTERFACE: alternate setting 1, a translator per port.
    SelectingMultiTt,
    /// SET_HUB_DEPTH to a SuperSpeed hub.
    SettingHubDepth,
    /// SET_FEATURE(PORT_POWER) of one hub port.
    PoweringHubPort(u8),
    /// The hub's power-on-to-good time and the devices' connect time.
    WaitingForHubPower,
    /// GET_STATUS of the hub itself (its power or over-current changed).
    ReadingHubStatus,
    /// CLEAR_FEATURE of one of the hub's own changes.
    ClearingHubChange,
    /// GET_STATUS of a hub port that changed (or is looked at first).
    ReadingHubPortStatus(u8),
    /// CLEAR_FEATURE of a hub port's change bit.
    ClearingHubPortChange(u8),
    /// CLEAR_FEATURE(PORT_ENABLE) of the hub port of a device that failed.
    DisablingHubPort,
}

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use Step::*;
        match self {
            ResettingRootPort => write!(f, "resetting the root port"),
            CheckingHubPortConnection => write!(f, "reading the hub port's status"),
            StartingHubPortReset | WaitingForHubPortReset | CheckingHubPortReset => {
                write!(f, "resetting the hub port")
            }
            ClearingHubPortReset => write!(f, "clearing the hub port's reset change"),
            RecoveringFromReset => write!(f, "recovering from the reset"),
            ReadingDeviceHeader => write!(f, "reading the device descriptor's first 8 bytes"),
            Addressing => write!(f, "setting the address"),
            RecoveringFromSetAddress => write!(f, "recovering from SET_ADDRESS"),
            ReadingDeviceDescriptor => write!(f, "reading the device descriptor"),
            ReadingConfigurationHeader => write!(f, "reading the configuration's length"),
            ReadingConfiguration => write!(f, "reading the configuration"),
            ConfiguringKeyboard | ConfiguringHub => write!(f, "setting the configuration"),
            ReadingReportDescriptor => write!(f, "reading the report descriptor"),
            SettingProtocol => write!(f, "setting the protocol"),
            SettingIdle => write!(f, "setting idle"),
            ReadingHubDescriptor => write!(f, "reading the hub descriptor"),
            SelectingMultiTt => write!(f, "selecting a translator per port"),
            SettingHubDepth => write!(f, "setting the hub's depth"),
            PoweringHubPort(port) => write!(f, "powering hub port {port}"),
            WaitingForHubPower => write!(f, "waiting for the hub's power"),
            ReadingHubStatus => write!(f, "reading the hub's status"),
            ClearingHubChange => write!(f, "clearing the hub's changes"),
            ReadingHubPortStatus(port) => write!(f, "reading hub port {port}'s status"),
            ClearingHubPortChange(port) => write!(f, "clearing hub port {port}'s changes"),
            DisablingHubPort => write!(f, "disabling the hub port"),
        }
    }
}

/// What a step waits for before its function runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Awaiting {
    /// The clock to pass `until`.
    Time { until: u64 },
    /// The control transfer on device `device`'s endpoint 0 (`length`
    /// bytes of data stage asked for), given up at `until`.
    Control {
        device: usize,
        length: usize,
        until: u64,
    },
}

/// What a step's function says next.
pub(super) enum Next {
    /// Another step was started.
    Continue,
    /// The work is done.
    Done,
}

/// A keyboard being set up: what it will be read by.
#[derive(Clone, Copy, Debug)]
struct KeyboardSetUp {
    interface: u8,
    endpoint: InterruptIn,
    boot: bool,
    report_descriptor_bytes: u16,
    format: Option<ReportFormat>,
}

/// A hub being set up, or whose ports changed.
#[derive(Clone, Copy, Debug, Default)]
struct HubSetUp {
    ports: u8,
    power_good: u64,
    multi_tt: bool,
    status_change: Option<InterruptIn>,
    /// The hub's own change (bit 0 of its report) is to be looked at.
    hub_changed: bool,
    /// The ports still to be looked at (bit n: port n).
    to_examine: u32,
    /// The status of the port (or hub) being looked at, its changes
    /// cleared one by one.
    status: u32,
    /// Its connection changed (or its enable, with a device there).
    connection_changed: bool,
}

/// The work in progress: one device's enumeration, or one hub's changes.
#[derive(Clone, Debug)]
pub(super) struct Job {
    /// The device's location (for a hub's changes: the hub's).
    pub(super) location: Location,
    pub(super) step: Step,
    awaiting: Awaiting,
    started: u64,
    /// The longest single step, for the log.
    longest_step: u64,
    /// The device being enumerated, once the controller has a handle.
    device: Option<usize>,
    /// The hub whose endpoint 0 carries the port requests (the parent of
    /// a device on a hub port; the hub itself for its changes).
    hub: Option<usize>,
    /// Bytes the last control transfer's data stage brought.
    received: usize,
    speed: Speed,
    translator: Option<TransactionTranslator>,
    /// When a hub port's reset must have ended.
    reset_deadline: u64,
    vendor: u16,
    product: u16,
    device_protocol: u8,
    configuration: u8,
    keyboard: Option<KeyboardSetUp>,
    hub_setup: HubSetUp,
    /// Only a hub's changes, no enumeration.
    changes_only: bool,
    /// The device went away during its root port's reset: the reset is
    /// polled to its end (a driver may have to end it), and that is all.
    abandoned: bool,
    /// Tries before this one ([`ENUMERATION_TRIES`]).
    tries: u8,
    /// The device descriptor's first 8 bytes were read (and endpoint 0's
    /// packet size set).
    header_read: bool,
}

impl Job {
    fn new(location: Location, now: u64) -> Job {
        Job {
            location,
            step: Step::RecoveringFromReset,
            awaiting: Awaiting::Time { until: now },
            started: now,
            longest_step: 0,
            device: None,
            hub: None,
            received: 0,
            speed: Speed::Full,
            translator: None,
            reset_deadline: 0,
            vendor: 0,
            product: 0,
            device_protocol: 0,
            configuration: 0,
            keyboard: None,
            hub_setup: HubSetUp::default(),
            changes_only: false,
            abandoned: false,
            tries: 0,
            header_read: false,
        }
    }

    /// When its control transfer began, if it waits for one.
    #[cfg(test)]
    pub(super) fn control_started(&self) -> Option<u64> {
        match self.awaiting {
            Awaiting::Control { until, .. } => until.checked_sub(TRANSFER_MICROS),
            Awaiting::Time { .. } => None,
        }
    }

    /// Whether the job sends requests to device `index`'s endpoint 0.
    pub(super) fn uses(&self, index: usize) -> bool {
        self.device == Some(index) || self.hub == Some(index)
    }

    fn wait(&mut self, step: Step, until: u64) -> Result<Next> {
        self.step = step;
        self.awaiting = Awaiting::Time { until };
        Ok(Next::Continue)
    }

    fn device(&self) -> Result<usize> {
        self.device.ok_or(BusError::Gone)
    }

    /// Whether a failure `e` gets another try: one of the device's own
    /// while it is reset, addressed and read its device descriptor (what
    /// Linux's `hub_port_init` retries), while tries are left. A lack of
    /// room or addresses, a driver's refusal, a controller error or a
    /// device gone are not the device's fault, and a try more changes
    /// nothing. Nor is a transfer that ran into its 5 s bound tried again
    /// (Linux does): a device that ignored a request that long rarely
    /// answers the next, and every other port waits while it is tried.
    fn may_try_again(&self, e: BusError) -> bool {
        let device_phase = matches!(
            self.step,
            Step::ResettingRootPort
                | Step::CheckingHubPortReset
                | Step::ClearingHubPortReset
                | Step::RecoveringFromReset
                | Step::ReadingDeviceHeader
                | Step::Addressing
                | Step::RecoveringFromSetAddress
                | Step::ReadingDeviceDescriptor
        );
        let devices_fault = !matches!(
            e,
            BusError::NoRoom
                | BusError::NoAddress
                | BusError::Host(_)
                | BusError::Gone
                | BusError::Timeout
                | BusError::Failed(TransferError::Controller | TransferError::NoRoom)
        );
        device_phase && devices_fault && self.tries + 1 < ENUMERATION_TRIES
    }

    /// Linux's schemes, two tries each (hub.c's `use_new_scheme`): the new
    /// one reads up to 64 bytes of the device descriptor at the default
    /// address before SET_ADDRESS (what Windows does, and many devices
    /// expect); the old one sends SET_ADDRESS first, then reads 8 bytes and
    /// the 18 (what some older devices need).
    fn old_scheme(&self) -> bool {
        self.tries / 2 == 1
    }

    fn hub(&self) -> Result<usize> {
        self.hub.ok_or(BusError::Gone)
    }

    /// The hub whose ports the job powers and looks at: the new hub, or
    /// the one whose changes these are.
    fn examined_hub(&self) -> Result<usize> {
        if self.changes_only {
            self.hub()
        } else {
            self.device()
        }
    }
}

/// The new scheme's first read of the device descriptor: Linux asks for
/// 64 bytes (hub.c, `GET_DESCRIPTOR_BUFSIZE`), which a device answers
/// with a short packet, however large endpoint 0 is.
const NEW_SCHEME_HEADER_BYTES: u16 = 64;

/// Endpoint 0's packet size a device of `speed` says in bMaxPacketSize0,
/// if allowed (USB 2.0 5.5.3; USB 3.2 9.6.1: SuperSpeed gives 2^9).
fn endpoint_0_packet(speed: Speed, size: u8) -> Option<u16> {
    match (speed, size) {
        (Speed::Low, 8) | (Speed::Full, 8 | 16 | 32 | 64) | (Speed::High, 64) => {
            Some(u16::from(size))
        }
        (Speed::Super, 9) => Some(512),
        _ => None,
    }
}

/// An interrupt endpoint's bInterval in frames (a power of two, at least
/// 1, at most `most`): frames for full and low speed, 2^(n-1) microframes
/// at high speed (USB 2.0 9.6.6).
fn interval_frames(speed: Speed, interval: u8, most: u8) -> u8 {
    let frames: u32 = match speed {
        Speed::High | Speed::Super => (1u32 << (u32::from(interval.clamp(1, 16)) - 1)) / 8,
        _ => u32::from(interval),
    };
    let frames = frames.clamp(1, u32::from(most.max(1)));
    // Rounded down to a power of two.
    (1u32 << (31 - frames.leading_zeros())) as u8
}

impl<C: HostController> Bus<C> {
    /// A port's connection changed (a device plugged in, pulled out, or a
    /// contact bouncing): whatever was behind it is let go of, and the port
    /// is queued, to be looked at once it has kept still for
    /// [`DEBOUNCE_MICROS`]. When it first changed is kept across changes,
    /// so that a port still bouncing after [`DEBOUNCE_TIMEOUT_MICROS`] is
    /// dropped (Linux's `hub_port_debounce`).
    pub(super) fn port_changed(
        &mut self,
        location: Location,
        connected: bool,
        out: &mut impl FnMut(u8),
    ) {
        let bouncing = self.queue.first_change(location);
        // A connect change with nothing known there (an xHCI's ports after
        // its reset) is not news.
        let known = self
            .devices
            .iter()
            .flatten()
            .any(|device| location.holds(device.location));
        self.release_under(location, out);
        if bouncing.is_none() {
            if connected {
                self.say_at(location, format_args!("device plugged in"));
            } else if known {
                self.say_at(location, format_args!("device pulled out"));
            }
        }
        if connected || bouncing.is_some() {
            self.queue_port(location, false, bouncing);
        }
    }

    /// Queues a port to be looked at (`settled`: it has had its connect
    /// time already, as at boot or after a hub's power-on), its connection
    /// first changed at `first_change` (None: now).
    pub(super) fn queue_port(
        &mut self,
        location: Location,
        settled: bool,
        first_change: Option<u64>,
    ) {
        let now = self.now_micros();
        let changed = if settled {
            now.saturating_sub(DEBOUNCE_MICROS)
        } else {
            now
        };
        let first_change = first_change
            .or(self.queue.first_change(location))
            .unwrap_or(changed);
        if now.saturating_sub(first_change) > DEBOUNCE_TIMEOUT_MICROS {
            self.queue
                .remove(|w| matches!(w, Work::Port { location: at, .. } if *at == location));
            self.say_at(
                location,
                format_args!(
                    "connection never settled within {} ms; left until it changes again",
                    DEBOUNCE_TIMEOUT_MICROS / 1_000
                ),
            );
            return;
        }
        let work = Work::Port {
            location,
            first_change,
            last_change: changed,
            tries: 0,
        };
        if !self.queue.push(work) {
            self.say_at(
                location,
                format_args!("too many ports waiting; left until it changes again"),
            );
        }
    }

    /// A hub's status change endpoint said what changed.
    pub(super) fn queue_hub_changes(&mut self, hub: usize, changed: u32) {
        if !self.queue.push(Work::HubChanges { hub, changed }) {
            let location = self.devices[hub]
                .as_ref()
                .map_or(Location::root(0), |d| d.location);
            self.say_at(
                location,
                format_args!("hub: too much waiting; its port changes are lost"),
            );
        }
    }

    /// Whether root port `port` is being reset for an enumeration. Its
    /// state is unknown until the reset ends (Linux's hub_port_wait_reset):
    /// some controllers report a connect change for the reset itself
    /// (Bochs's UHCI as it begins, real UHCIs as it ends), which the reset's
    /// end clears; a device pulled out meanwhile fails the reset.
    pub(super) fn root_port_in_reset(&self, port: u8) -> bool {
        self.job.as_ref().is_some_and(|job| {
            job.location == Location::root(port)
                && job.step == Step::ResettingRootPort
                && !job.abandoned
        })
    }

    /// Forgets the queued and running work at `location` and below, and
    /// for the devices `gone` names (bit n: device n); a control transfer
    /// still running is cancelled.
    pub(super) fn forget_work_under(&mut self, location: Location, gone: u32) {
        self.queue.remove(|work| match *work {
            Work::Port { location: at, .. } => location.holds(at),
            Work::HubChanges { hub, .. } => gone & (1 << hub) != 0,
        });
        let cancel = self.job.as_ref().is_some_and(|job| {
            location.holds(job.location)
                || (0..MAX_DEVICES).any(|index| gone & (1 << index) != 0 && job.uses(index))
        });
        if !cancel {
            return;
        }
        let Some(mut job) = self.job.take() else {
            return;
        };
        let (at, step) = (job.location, job.step);
        if step == Step::ResettingRootPort {
            if !job.abandoned {
                self.say_at(
                    at,
                    format_args!(
                        "the device went away while {step}; the reset ends, and that is all"
                    ),
                );
            }
            job.abandoned = true;
            self.job = Some(job);
            return;
        }
        if let Awaiting::Control { device, .. } = job.awaiting {
            if let Some(id) = self.devices[device].as_ref().map(|d| d.id) {
                self.controller.control_cancel(id);
            }
        }
        self.say_at(
            at,
            format_args!("the device went away while {step}; enumeration stopped"),
        );
        // A device not yet under `location` (impossible, but cheap to
        // keep right): given back.
        if let Some(index) = job.device {
            if gone & (1 << index) == 0 {
                self.remove_device(index);
            }
        }
    }

    /// Runs at most one enumeration step.
    pub(super) fn advance_enumeration(&mut self, out: &mut impl FnMut(u8)) {
        let now = self.now_micros();
        if self.scan_at.is_some_and(|at| now >= at) {
            self.scan_at = None;
            self.scan_root_ports();
            return;
        }
        let Some(mut job) = self.job.take() else {
            if self.scan_at.is_none() {
                self.start_work(now);
            }
            return;
        };
        let done = match self.wait_over(&mut job, now) {
            None => {
                self.job = Some(job);
                return;
            }
            Some(done) => done,
        };
        let result = self.run_step(&mut job, done, out);
        let took = self.now_micros().saturating_sub(now);
        job.longest_step = job.longest_step.max(took);
        match result {
            Ok(Next::Continue) => self.job = Some(job),
            Ok(Next::Done) => self.finish(job),
            Err(e) => self.fail(job, e),
        }
    }

    /// Whether the step's wait is over: None while it is not, else how it
    /// ended.
    fn wait_over(&mut self, job: &mut Job, now: u64) -> Option<Result<()>> {
        match job.awaiting {
            Awaiting::Time { until } => (now >= until).then_some(Ok(())),
            Awaiting::Control {
                device,
                length,
                until,
            } => {
                let Some((id, address)) = self.devices[device].as_ref().map(|d| (d.id, d.address))
                else {
                    return Some(Err(BusError::Gone));
                };
                let length = length.min(MAX_CONTROL_DATA);
                let transfer = if job.step == Step::Addressing {
                    self.controller.address_poll(id, address)
                } else {
                    self.controller.control_poll(id, &mut self.buffer[..length])
                };
                match transfer {
                    Transfer::Pending if now >= until => {
                        self.controller.control_cancel(id);
                        Some(Err(BusError::Timeout))
                    }
                    Transfer::Pending => None,
                    Transfer::Complete(received) => {
                        // Never more than was asked for, whatever it says.
                        job.received = received.min(length);
                        Some(Ok(()))
                    }
                    Transfer::Stalled => Some(Err(BusError::Stalled)),
                    Transfer::Failed(e) => Some(Err(BusError::Failed(e))),
                }
            }
        }
    }

    fn run_step(
        &mut self,
        job: &mut Job,
        done: Result<()>,
        out: &mut impl FnMut(u8),
    ) -> Result<Next> {
        use Step::*;
        match job.step {
            ResettingRootPort => self.resetting_root_port(job),
            CheckingHubPortConnection => self.checking_hub_port_connection(job, done),
            StartingHubPortReset => self.starting_hub_port_reset(job, done),
            WaitingForHubPortReset => self.waiting_for_hub_port_reset(job),
            CheckingHubPortReset => self.checking_hub_port_reset(job, done),
            ClearingHubPortReset => self.clearing_hub_port_reset(job, done),
            RecoveringFromReset => self.recovering_from_reset(job),
            ReadingDeviceHeader => self.reading_device_header(job, done),
            Addressing => self.addressing(job, done),
            RecoveringFromSetAddress => self.recovering_from_set_address(job),
            ReadingDeviceDescriptor => self.reading_device_descriptor(job, done),
            ReadingConfigurationHeader => self.reading_configuration_header(job, done),
            ReadingConfiguration => self.reading_configuration(job, done),
            ConfiguringKeyboard => self.configuring_keyboard(job, done),
            ReadingReportDescriptor => self.reading_report_descriptor(job, done),
            SettingProtocol => self.setting_protocol(job, done),
            SettingIdle => self.setting_idle(job, done),
            ReadingHubDescriptor => self.reading_hub_descriptor(job, done),
            ConfiguringHub => self.configuring_hub(job, done),
            SelectingMultiTt => self.selecting_multi_tt(job, done),
            SettingHubDepth => self.setting_hub_depth(job, done),
            PoweringHubPort(port) => self.powering_hub_port(job, done, port),
            WaitingForHubPower => self.waiting_for_hub_power(job),
            ReadingHubStatus => self.reading_hub_status(job, done),
            ClearingHubChange => self.clearing_hub_change(job, done),
            ReadingHubPortStatus(port) => self.reading_hub_port_status(job, done, port),
            ClearingHubPortChange(port) => self.clearing_hub_port_change(job, done, port, out),
            DisablingHubPort => {
                if let Err(e) = done {
                    let location = job.location;
                    self.say_at(location, format_args!("hub port not disabled ({e})"));
                }
                Ok(Next::Done)
            }
        }
    }

    /// The root ports connected once the controller has run a while.
    fn scan_root_ports(&mut self) {
        for port in 1..=self.root_ports {
            let status = self.controller.port_status(port);
            if status.companion_owned || !status.connected {
                continue;
            }
            if status.connect_changed {
                self.controller.clear_port_change(port);
            }
            // They have had the connect time to settle.
            self.queue_port(Location::root(port), true, None);
        }
    }

    /// Starts the next work whose turn it is. Work on a hub whose own
    /// status change endpoint is having its halt cleared (through the
    /// same endpoint 0) waits.
    fn start_work(&mut self, now: u64) {
        let recovering = self.recovering;
        let devices = &self.devices;
        let blocked = |hub: Option<usize>| hub.is_some_and(|hub| recovering & (1 << hub) != 0);
        let Some(work) = self.queue.take_ready(now, |work| match *work {
            Work::Port { location, .. } => !blocked(location.hub().and_then(|hub| {
                devices
                    .iter()
                    .position(|d| d.as_ref().is_some_and(|d| d.location == hub))
            })),
            Work::HubChanges { hub, .. } => !blocked(Some(hub)),
        }) else {
            return;
        };
        let (mut job, result) = match work {
            Work::Port {
                location, tries, ..
            } => {
                let mut job = Job::new(location, now);
                job.tries = tries;
                let result = match location.hub() {
                    None => self.start_root_port_reset(&mut job),
                    Some(hub) => self.start_hub_port_reset(&mut job, hub),
                };
                (job, result)
            }
            Work::HubChanges { hub, changed } => {
                let Some((location, ports)) =
                    self.devices[hub].as_ref().and_then(|d| match d.role {
                        Role::Hub(h) => Some((d.location, h.ports)),
                        _ => None,
                    })
                else {
                    return;
                };
                let mut job = Job::new(location, now);
                job.hub = Some(hub);
                job.changes_only = true;
                job.hub_setup.ports = ports;
                job.hub_setup.hub_changed = changed & 1 != 0;
                job.hub_setup.to_examine = changed & !1;
                let result = self.examine_next_hub_port(&mut job);
                (job, result)
            }
        };
        job.longest_step = self.now_micros().saturating_sub(now);
        match result {
            Ok(Next::Continue) => self.job = Some(job),
            Ok(Next::Done) => self.finish(job),
            Err(e) => self.fail(job, e),
        }
    }

    /// Starts a control transfer for `step` on device `index`'s endpoint 0
    /// (no OUT data stage: every request here is IN or has none).
    fn send(&mut self, job: &mut Job, step: Step, index: usize, setup: Setup) -> Result<Next> {
        let id = self.devices[index]
            .as_ref()
            .map(|d| d.id)
            .ok_or(BusError::Gone)?;
        self.controller.control_begin(id, setup, &[])?;
        self.await_control(job, step, index, usize::from(setup.length))
    }

    /// The step waits for the control transfer just begun on device
    /// `index`'s endpoint 0, `length` bytes of data stage asked for.
    fn await_control(
        &mut self,
        job: &mut Job,
        step: Step,
        index: usize,
        length: usize,
    ) -> Result<Next> {
        job.step = step;
        job.received = 0;
        job.awaiting = Awaiting::Control {
            device: index,
            length,
            until: self.now_micros() + TRANSFER_MICROS,
        };
        Ok(Next::Continue)
    }

    /// A request without a data stage.
    fn request(
        &mut self,
        job: &mut Job,
        step: Step,
        index: usize,
        (request_type, request, value, at): (u8, u8, u16, u16),
    ) -> Result<Next> {
        let setup = Setup {
            request_type,
            request,
            value,
            index: at,
            length: 0,
        };
        self.send(job, step, index, setup)
    }

    /// GET_DESCRIPTOR of the job's device (a hub descriptor is a class
    /// request).
    fn get_descriptor(&mut self, job: &mut Job, step: Step, kind: u8, length: u16) -> Result<Next> {
        let index = job.device()?;
        let request_type = if matches!(
            kind,
            descriptor::kind::HUB | descriptor::kind::SUPERSPEED_HUB
        ) {
            0xA0
        } else {
            0x80
        };
        let setup = Setup {
            request_type,
            request: GET_DESCRIPTOR,
            value: u16::from(kind) << 8,
            index: 0,
            length,
        };
        self.send(job, step, index, setup)
    }

    /// GET_STATUS of a hub port (`port` 1-based) or of the hub (`port` 0).
    fn get_hub_status(&mut self, job: &mut Job, step: Step, hub: usize, port: u8) -> Result<Next> {
        let setup = Setup {
            request_type: if port == 0 { 0xA0 } else { 0xA3 },
            request: GET_STATUS,
            value: 0,
            index: u16::from(port),
            length: 4,
        };
        self.send(job, step, hub, setup)
    }

    /// The four bytes of status and change a GET_STATUS brought.
    fn received_status(&self, job: &Job) -> Result<u32> {
        if job.received < 4 {
            return Err(BusError::Short {
                wanted: 4,
                got: job.received,
            });
        }
        Ok(u32::from_le_bytes([
            self.buffer[0],
            self.buffer[1],
            self.buffer[2],
            self.buffer[3],
        ]))
    }

    /// The bytes received, if `wanted` came.
    fn received(&self, job: &Job, wanted: usize) -> Result<&[u8]> {
        if job.received < wanted {
            return Err(BusError::Short {
                wanted,
                got: job.received,
            });
        }
        Ok(&self.buffer[..job.received])
    }

    // The steps, in the order they run.

    fn start_root_port_reset(&mut self, job: &mut Job) -> Result<Next> {
        let port = job.location.root_port();
        let status = self.controller.port_status(port);
        if !status.connected || status.companion_owned {
            // Gone before its turn: its disconnection says the rest.
            return Ok(Next::Done);
        }
        self.controller.port_reset_begin(port);
        let until = self.now_micros() + ROOT_RESET_POLL_MICROS;
        job.wait(Step::ResettingRootPort, until)
    }

    fn resetting_root_port(&mut self, job: &mut Job) -> Result<Next> {
        let port = job.location.root_port();
        let Some(outcome) = self.controller.port_reset_poll(port) else {
            let until = self.now_micros() + ROOT_RESET_POLL_MICROS;
            return job.wait(Step::ResettingRootPort, until);
        };
        if job.abandoned {
            // Whatever is there now is queued, and reset again in its turn.
            if let ResetOutcome::Enabled(_) = outcome {
                self.controller.port_disable(port);
            }
            return Ok(Next::Done);
        }
        match outcome {
            ResetOutcome::Enabled(speed) => {
                // A change the reset itself made is not a new device (as
                // Linux clears C_PORT_CONNECTION after a reset).
                self.controller.clear_port_change(port);
                job.speed = speed;
                let until = self.now_micros() + RESET_RECOVERY_MICROS;
                job.wait(Step::RecoveringFromReset, until)
            }
            ResetOutcome::HandedToCompanion => {
                let location = job.location;
                self.say_at(
                    location,
                    format_args!("a full- or low-speed device: handed to the companion controller"),
                );
                Ok(Next::Done)
            }
            ResetOutcome::Failed => Err(BusError::PortReset),
        }
    }

    fn start_hub_port_reset(&mut self, job: &mut Job, hub: Location) -> Result<Next> {
        let Some(index) = self.device_at(hub) else {
            // The hub went first; nothing is left to enumerate.
            return Ok(Next::Done);
        };
        job.hub = Some(index);
        let port = job.location.port();
        self.get_hub_status(job, Step::CheckingHubPortConnection, index, port)
    }

    /// The port's connection before its reset: a port that bounced and
    /// ended up empty has nothing to reset.
    fn checking_hub_port_connection(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let hub = job.hub()?;
        if self.received_status(job)? & HUB_PORT_CONNECTION == 0 {
            return Ok(Next::Done);
        }
        job.reset_deadline = self.now_micros() + HUB_RESET_MICROS;
        let port = u16::from(job.location.port());
        self.request(
            job,
            Step::StartingHubPortReset,
            hub,
            (0x23, SET_FEATURE, PORT_RESET, port),
        )
    }

    fn starting_hub_port_reset(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let until = self.now_micros() + HUB_RESET_CHECK_MICROS;
        job.wait(Step::WaitingForHubPortReset, until)
    }

    fn waiting_for_hub_port_reset(&mut self, job: &mut Job) -> Result<Next> {
        let hub = job.hub()?;
        let port = job.location.port();
        self.get_hub_status(job, Step::CheckingHubPortReset, hub, port)
    }

    fn checking_hub_port_reset(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let hub = job.hub()?;
        let status = self.received_status(job)?;
        let now = self.now_micros();
        if status & HUB_C_PORT_RESET == 0 {
            if now >= job.reset_deadline {
                return Err(BusError::PortReset);
            }
            return job.wait(Step::WaitingForHubPortReset, now + HUB_RESET_CHECK_MICROS);
        }
        job.hub_setup.status = status;
        let port = u16::from(job.location.port());
        self.request(
            job,
            Step::ClearingHubPortReset,
            hub,
            (0x23, CLEAR_FEATURE, C_PORT_RESET, port),
        )
    }

    fn clearing_hub_port_reset(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let status = job.hub_setup.status;
        if status & HUB_PORT_ENABLE == 0 || status & HUB_PORT_CONNECTION == 0 {
            return Err(BusError::PortReset);
        }
        let hub = job.hub()?;
        let parent = self.devices[hub].as_ref().ok_or(BusError::Gone)?;
        // Below a SuperSpeed hub everything is SuperSpeed (its USB 2 half
        // is a hub of its own); bit 9 is its power bit, not low speed.
        job.speed = if parent.speed == Speed::Super {
            Speed::Super
        } else if status & HUB_PORT_LOW_SPEED != 0 {
            Speed::Low
        } else if status & HUB_PORT_HIGH_SPEED != 0 && parent.speed == Speed::High {
            Speed::High
        } else {
            Speed::Full
        };
        // A full- or low-speed device is reached through the transaction
        // translator of the nearest high-speed hub above it: this hub's,
        // or the one this hub itself is reached through.
        job.translator = if parent.speed == Speed::High {
            (job.speed != Speed::High).then_some(TransactionTranslator {
                hub_address: parent.address,
                hub_port: job.location.port(),
            })
        } else {
            parent.translator
        };
        let until = self.now_micros() + RESET_RECOVERY_MICROS;
        job.wait(Step::RecoveringFromReset, until)
    }

    /// The device answers at address 0: it gets a handle and its device
    /// descriptor's first 8 bytes are read (endpoint 0's packet size).
    fn recovering_from_reset(&mut self, job: &mut Job) -> Result<Next> {
        let index = self
            .devices
            .iter()
            .position(Option::is_none)
            .ok_or(BusError::NoRoom)?;
        let hub_ports = job.location.hub_ports();
        let info = DeviceInfo {
            speed: job.speed,
            root_port: job.location.root_port(),
            route: hub_ports.iter().rev().try_fold(0, |route, &port| {
                (1..=15)
                    .contains(&port)
                    .then_some(route << 4 | u32::from(port))
            }),
            translator: job.translator,
        };
        let id = self.controller.device_new(info)?;
        self.devices[index] = Some(Device {
            id,
            location: job.location,
            speed: job.speed,
            address: 0,
            translator: job.translator,
            role: Role::Enumerating,
        });
        job.device = Some(index);
        if job.old_scheme() {
            let address = self.addresses.take().ok_or(BusError::NoAddress)?;
            if let Some(device) = self.devices[index].as_mut() {
                device.address = address;
            }
            self.controller.address_begin(id, address)?;
            return self.await_control(job, Step::Addressing, index, 0);
        }
        if job.speed == Speed::Full {
            // Linux's first guess at full speed: a device whose endpoint 0
            // is smaller ends the read with a short packet, one whose
            // endpoint 0 is 64 is not cut short (a babble).
            self.controller.device_set_max_packet(id, 64)?;
        }
        self.get_descriptor(
            job,
            Step::ReadingDeviceHeader,
            descriptor::kind::DEVICE,
            NEW_SCHEME_HEADER_BYTES,
        )
    }

    fn reading_device_header(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let index = job.device()?;
        let header = descriptor::device(self.received(job, 8)?)?;
        let size = header.max_packet_0;
        let Some(packet) = endpoint_0_packet(job.speed, size) else {
            return Err(BusError::PacketSize(size));
        };
        job.header_read = true;
        if let Some(id) = self.devices[index]
            .as_ref()
            .filter(|d| d.address != 0)
            .map(|d| d.id)
        {
            // The old scheme: addressed already.
            self.controller.device_set_max_packet(id, packet)?;
            return self.get_descriptor(
                job,
                Step::ReadingDeviceDescriptor,
                descriptor::kind::DEVICE,
                18,
            );
        }
        let address = self.addresses.take().ok_or(BusError::NoAddress)?;
        let device = self.devices[index].as_mut().ok_or(BusError::Gone)?;
        // Kept with the device from now on, so that its removal frees it.
        device.address = address;
        let id = device.id;
        self.controller.device_set_max_packet(id, packet)?;
        self.controller.address_begin(id, address)?;
        self.await_control(job, Step::Addressing, index, 0)
    }

    fn addressing(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let until = self.now_micros() + SET_ADDRESS_RECOVERY_MICROS;
        job.wait(Step::RecoveringFromSetAddress, until)
    }

    fn recovering_from_set_address(&mut self, job: &mut Job) -> Result<Next> {
        if !job.header_read {
            return self.get_descriptor(
                job,
                Step::ReadingDeviceHeader,
                descriptor::kind::DEVICE,
                8,
            );
        }
        self.get_descriptor(
            job,
            Step::ReadingDeviceDescriptor,
            descriptor::kind::DEVICE,
            18,
        )
    }

    fn reading_device_descriptor(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let bytes = self.received(job, 18)?;
        let device = descriptor::device(bytes)?;
        let protocol = bytes[6];
        (job.vendor, job.product) = (device.vendor, device.product);
        job.device_protocol = protocol;
        self.get_descriptor(
            job,
            Step::ReadingConfigurationHeader,
            descriptor::kind::CONFIGURATION,
            9,
        )
    }

    fn reading_configuration_header(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let total = descriptor::configuration_total_length(self.received(job, 9)?)?;
        let length = usize::from(total).clamp(9, MAX_CONTROL_DATA) as u16;
        self.get_descriptor(
            job,
            Step::ReadingConfiguration,
            descriptor::kind::CONFIGURATION,
            length,
        )
    }

    fn reading_configuration(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let index = job.device()?;
        let header = self.received(job, 9)?;
        // A device that sends less than its header announces lies about
        // the rest too.
        let total = usize::from(descriptor::configuration_total_length(header)?);
        let configuration =
            descriptor::configuration(self.received(job, total.clamp(9, MAX_CONTROL_DATA))?)?;
        job.configuration = configuration.value;
        let location = job.location;
        match configuration.function {
            Some(Function::Keyboard {
                interface,
                endpoint,
                boot,
                report_descriptor_bytes,
            }) => {
                job.keyboard = Some(KeyboardSetUp {
                    interface,
                    endpoint,
                    boot,
                    report_descriptor_bytes,
                    format: None,
                });
                self.request(
                    job,
                    Step::ConfiguringKeyboard,
                    index,
                    (0x00, SET_CONFIGURATION, u16::from(configuration.value), 0),
                )
            }
            Some(Function::Hub { status_change }) if location.depth() < MAX_HUB_TIERS => {
                job.hub_setup.status_change = status_change;
                // A SuperSpeed hub has its own descriptor type (USB 3.2 10.15.2.1).
                let (kind, length) = if job.speed == Speed::Super {
                    (descriptor::kind::SUPERSPEED_HUB, 12)
                } else {
                    (descriptor::kind::HUB, 9)
                };
                self.get_descriptor(job, Step::ReadingHubDescriptor, kind, length)
            }
            Some(Function::Hub { .. }) => {
                self.say_at(
                    location,
                    format_args!("hub past the {MAX_HUB_TIERS} hub tiers USB allows; left alone"),
                );
                self.left_alone(job)
            }
            None => {
                let (vendor, product) = (job.vendor, job.product);
                match configuration.first_interface {
                    Some(class) => self.say_at(
                        location,
                        format_args!(
                            "device {vendor:04x}:{product:04x} ({class}) is not a keyboard or a hub; left alone"
                        ),
                    ),
                    None => self.say_at(
                        location,
                        format_args!(
                            "device {vendor:04x}:{product:04x} has no interface; left alone"
                        ),
                    ),
                }
                self.left_alone(job)
            }
        }
    }

    /// The device is not ours (but did nothing wrong): it keeps its
    /// address and handle, unused, until it goes.
    fn left_alone(&mut self, job: &mut Job) -> Result<Next> {
        let index = job.device()?;
        if let Some(device) = self.devices[index].as_mut() {
            device.role = Role::Other;
        }
        Ok(Next::Done)
    }

    /// The keyboard is configured: its report descriptor decides how its
    /// reports are read (a keyboard it describes is kept in the report
    /// protocol; a boot keyboard whose descriptor cannot be read is put in
    /// the boot protocol; a descriptor that lies is refused, and so is the
    /// keyboard), as the xHCI driver does.
    fn configuring_keyboard(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let index = job.device()?;
        let set_up = job.keyboard.ok_or(BusError::Gone)?;
        if set_up.report_descriptor_bytes == 0 {
            return self.choose_report_format(job, Err(None));
        }
        let length = usize::from(set_up.report_descriptor_bytes)
            .min(hid::MAX_DESCRIPTOR_BYTES)
            .min(MAX_CONTROL_DATA);
        let setup = Setup {
            request_type: 0x81,
            request: GET_DESCRIPTOR,
            value: u16::from(descriptor::kind::REPORT) << 8,
            index: u16::from(set_up.interface),
            length: length as u16,
        };
        self.send(job, Step::ReadingReportDescriptor, index, setup)
    }

    fn reading_report_descriptor(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        if let Err(e) = done {
            return self.choose_report_format(job, Err(Some(e)));
        }
        match hid::parse(&self.buffer[..job.received]) {
            Ok(layout) => self.choose_report_format(job, Ok(layout)),
            Err(lie) => {
                let location = job.location;
                let e = BusError::ReportDescriptor(lie);
                self.say_at(location, format_args!("{e}; device left alone"));
                self.left_alone(job)
            }
        }
    }

    fn not_a_keyboard(&mut self, job: &mut Job) -> Result<Next> {
        let (location, vendor, product) = (job.location, job.vendor, job.product);
        self.say_at(
            location,
            format_args!(
                "device {vendor:04x}:{product:04x} is a HID device without keys; left alone"
            ),
        );
        self.left_alone(job)
    }

    /// How the reports are read, given the report descriptor (or why there
    /// is none); then the protocol is set.
    fn choose_report_format(
        &mut self,
        job: &mut Job,
        layout: core::result::Result<KeyboardLayout, Option<BusError>>,
    ) -> Result<Next> {
        let index = job.device()?;
        let location = job.location;
        let set_up = job.keyboard.ok_or(BusError::Gone)?;
        let format = match layout {
            Ok(layout) if layout.has_keys() => ReportFormat::Described(layout),
            Ok(_) => return self.not_a_keyboard(job),
            Err(why) if set_up.boot => {
                if let Some(e) = why {
                    self.say_at(
                        location,
                        format_args!("keyboard: no report descriptor ({e}); boot protocol"),
                    );
                }
                ReportFormat::Boot
            }
            Err(_) => return self.not_a_keyboard(job),
        };
        if let Some(set_up) = job.keyboard.as_mut() {
            set_up.format = Some(format);
        }
        // SET_PROTOCOL exists only on boot interfaces; the others are
        // always in the report protocol.
        let interface = u16::from(set_up.interface);
        if set_up.boot {
            let protocol = match format {
                ReportFormat::Described(_) => PROTOCOL_REPORT,
                ReportFormat::Boot => PROTOCOL_BOOT,
            };
            return self.request(
                job,
                Step::SettingProtocol,
                index,
                (0x21, HID_SET_PROTOCOL, protocol, interface),
            );
        }
        self.request(
            job,
            Step::SettingIdle,
            index,
            (0x21, HID_SET_IDLE, 0, interface),
        )
    }

    fn setting_protocol(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        let location = job.location;
        let set_up = job.keyboard.ok_or(BusError::Gone)?;
        match (done, set_up.format) {
            (Ok(()), _) => {}
            // Reports are read by the descriptor whatever it answers.
            (Err(e), Some(ReportFormat::Described(_))) => self.say_at(
                location,
                format_args!("keyboard: SET_PROTOCOL refused ({e})"),
            ),
            (Err(e), _) => return Err(e),
        }
        let index = job.device()?;
        // Reports only when something changes; repeat is ours.
        self.request(
            job,
            Step::SettingIdle,
            index,
            (0x21, HID_SET_IDLE, 0, u16::from(set_up.interface)),
        )
    }

    /// The last step of a keyboard: its interrupt pipe opens.
    fn setting_idle(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        let location = job.location;
        // Some keyboards refuse SET_IDLE; that costs nothing but reports.
        if let Err(e) = done {
            self.say_at(location, format_args!("keyboard: SET_IDLE refused ({e})"));
        }
        let index = job.device()?;
        let set_up = job.keyboard.ok_or(BusError::Gone)?;
        let format = set_up.format.ok_or(BusError::Gone)?;
        let (id, speed) = self.devices[index]
            .as_ref()
            .map(|d| (d.id, d.speed))
            .ok_or(BusError::Gone)?;
        // wMaxPacketSize's bits 11-12 (high-bandwidth) are not a size.
        let most = if speed == Speed::Low {
            8
        } else {
            MAX_REPORT as u16
        };
        let max_packet = (set_up.endpoint.max_packet & 0x7FF).clamp(1, most);
        let pipe = self.controller.interrupt_open(
            id,
            set_up.endpoint.number,
            max_packet,
            KEYBOARD_INTERVAL_FRAMES,
        )?;
        if let Some(device) = self.devices[index].as_mut() {
            device.role = Role::Keyboard(Keyboard {
                pipe: Pipe::new(pipe, set_up.endpoint.number),
                format,
                packets: Packets::new(max_packet),
                keys_by_report: [(u8::MAX, KeySet::default()); KEY_REPORTS],
                state: BootKeyboard::new(),
                dropped: 0,
            });
        }
        let kind = self.kind;
        match format {
            ReportFormat::Boot => self.controller.hardware().log(format_args!(
                "keyboard: USB keyboard, boot protocol, on {kind} port {location}"
            )),
            ReportFormat::Described(layout) => self.controller.hardware().log(format_args!(
                "keyboard: USB keyboard, read by its report descriptor ({} key fields, {}-byte reports{}), on {kind} port {location}",
                layout.fields().count(),
                layout.longest_key_report(),
                if layout.numbered { ", numbered" } else { "" }
            )),
        }
        Ok(Next::Done)
    }

    fn reading_hub_descriptor(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let index = job.device()?;
        let described = descriptor::hub(&self.buffer[..job.received])?;
        job.hub_setup.ports = described.ports.min(MAX_HUB_PORTS);
        if described.ports > MAX_HUB_PORTS {
            let location = job.location;
            self.say_at(
                location,
                format_args!(
                    "hub: {} ports; those past {MAX_HUB_PORTS} are left alone",
                    described.ports
                ),
            );
        }
        job.hub_setup.power_good =
            (u64::from(described.power_on_to_good_2ms) * 2_000).clamp(20_000, 500_000);
        let configuration = job.configuration;
        self.request(
            job,
            Step::ConfiguringHub,
            index,
            (0x00, SET_CONFIGURATION, u16::from(configuration), 0),
        )
    }

    /// The hub is configured; a high-speed hub with a translator per port
    /// gets them turned on, as Linux does.
    fn configuring_hub(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        let index = job.device()?;
        if job.speed == Speed::Super {
            // Its tier, for the route string it reads (USB 3.2 10.16.2.9):
            // 0 on a root port.
            let depth = job.location.depth() as u16;
            return self.request(
                job,
                Step::SettingHubDepth,
                index,
                (0x20, SET_HUB_DEPTH, depth, 0),
            );
        }
        if job.speed == Speed::High && job.device_protocol == HUB_PROTOCOL_MULTI_TT {
            return self.request(
                job,
                Step::SelectingMultiTt,
                index,
                (0x01, SET_INTERFACE, 1, 0),
            );
        }
        self.mark_hub(job)
    }

    fn setting_hub_depth(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        self.mark_hub(job)
    }

    fn selecting_multi_tt(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        match done {
            Ok(()) => job.hub_setup.multi_tt = true,
            // One translator for all ports works too, only slower.
            Err(e) => {
                let location = job.location;
                self.say_at(
                    location,
                    format_args!("hub: a translator per port refused ({e}); one for all"),
                );
            }
        }
        self.mark_hub(job)
    }

    /// Tells the driver the device is a hub, then powers its ports.
    fn mark_hub(&mut self, job: &mut Job) -> Result<Next> {
        let index = job.device()?;
        let id = self.devices[index]
            .as_ref()
            .map(|d| d.id)
            .ok_or(BusError::Gone)?;
        let (ports, multi_tt) = (job.hub_setup.ports, job.hub_setup.multi_tt);
        self.controller.device_is_hub(id, ports, multi_tt)?;
        self.power_hub_port(job, 1)
    }

    fn power_hub_port(&mut self, job: &mut Job, port: u8) -> Result<Next> {
        let index = job.device()?;
        if port > job.hub_setup.ports {
            let until = self.now_micros() + job.hub_setup.power_good + HUB_CONNECT_MICROS;
            return job.wait(Step::WaitingForHubPower, until);
        }
        self.request(
            job,
            Step::PoweringHubPort(port),
            index,
            (0x23, SET_FEATURE, PORT_POWER, u16::from(port)),
        )
    }

    fn powering_hub_port(&mut self, job: &mut Job, done: Result<()>, port: u8) -> Result<Next> {
        done?;
        self.power_hub_port(job, port + 1)
    }

    /// The ports have power and their devices have had time to connect:
    /// the status change endpoint opens, and every port is looked at once.
    fn waiting_for_hub_power(&mut self, job: &mut Job) -> Result<Next> {
        let index = job.device()?;
        let location = job.location;
        let (id, speed) = self.devices[index]
            .as_ref()
            .map(|d| (d.id, d.speed))
            .ok_or(BusError::Gone)?;
        let ports = job.hub_setup.ports;
        let pipe = match job.hub_setup.status_change {
            Some(endpoint) => {
                let max_packet = (endpoint.max_packet & 0x7FF).clamp(1, 8);
                let interval = interval_frames(speed, endpoint.interval, HUB_INTERVAL_FRAMES);
                match self
                    .controller
                    .interrupt_open(id, endpoint.number, max_packet, interval)
                {
                    Ok(pipe) => Some(Pipe::new(pipe, endpoint.number)),
                    Err(e) => {
                        self.say_at(
                            location,
                            format_args!(
                                "hub: status change endpoint refused ({e}); devices plugged in later are not seen"
                            ),
                        );
                        None
                    }
                }
            }
            None => {
                self.say_at(
                    location,
                    format_args!(
                        "hub: no status change endpoint; devices plugged in later are not seen"
                    ),
                );
                None
            }
        };
        if let Some(device) = self.devices[index].as_mut() {
            device.role = Role::Hub(Hub { ports, pipe });
        }
        job.hub_setup.to_examine = (((1u64 << (u32::from(ports) + 1)) - 2) & 0xFFFF_FFFF) as u32;
        self.examine_next_hub_port(job)
    }

    /// GET_STATUS of the hub (if its own status changed) or of the next
    /// port to look at; done when none is left.
    fn examine_next_hub_port(&mut self, job: &mut Job) -> Result<Next> {
        let hub = job.examined_hub()?;
        if job.hub_setup.hub_changed {
            job.hub_setup.hub_changed = false;
            return self.get_hub_status(job, Step::ReadingHubStatus, hub, 0);
        }
        if job.hub_setup.to_examine == 0 {
            return Ok(Next::Done);
        }
        let port = job.hub_setup.to_examine.trailing_zeros() as u8;
        job.hub_setup.to_examine &= !(1 << port);
        job.hub_setup.connection_changed = false;
        self.get_hub_status(job, Step::ReadingHubPortStatus(port), hub, port)
    }

    fn reading_hub_status(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        job.hub_setup.status = self.received_status(job)?;
        self.clear_next_hub_change(job)
    }

    /// Clears the hub's next own change (local power, over-current).
    fn clear_next_hub_change(&mut self, job: &mut Job) -> Result<Next> {
        let hub = job.examined_hub()?;
        let pending = job.hub_setup.status & HUB_CHANGES;
        if pending == 0 {
            return self.examine_next_hub_port(job);
        }
        let bit = pending.trailing_zeros();
        job.hub_setup.status &= !(1 << bit);
        let feature = (bit - 16) as u16;
        self.request(
            job,
            Step::ClearingHubChange,
            hub,
            (0x20, CLEAR_FEATURE, feature, 0),
        )
    }

    fn clearing_hub_change(&mut self, job: &mut Job, done: Result<()>) -> Result<Next> {
        done?;
        self.clear_next_hub_change(job)
    }

    fn reading_hub_port_status(
        &mut self,
        job: &mut Job,
        done: Result<()>,
        port: u8,
    ) -> Result<Next> {
        done?;
        let status = self.received_status(job)?;
        job.hub_setup.status = status;
        // A port the hub disabled (an error on it) with a device still
        // there is a new connection, as Linux takes it.
        job.hub_setup.connection_changed = status & HUB_C_PORT_CONNECTION != 0
            || (status & HUB_C_PORT_ENABLE != 0
                && status & HUB_PORT_ENABLE == 0
                && status & HUB_PORT_CONNECTION != 0);
        self.clear_next_hub_port_change(job, port, &mut |_| {})
    }

    /// Clears the port's next change bit (one request a step); when none is
    /// left, acts on the port's status.
    fn clear_next_hub_port_change(
        &mut self,
        job: &mut Job,
        port: u8,
        out: &mut impl FnMut(u8),
    ) -> Result<Next> {
        let hub = job.examined_hub()?;
        let pending = job.hub_setup.status & HUB_PORT_CHANGES;
        if pending != 0 {
            let bit = pending.trailing_zeros();
            job.hub_setup.status &= !(1 << bit);
            // SuperSpeed's changes past C_PORT_RESET have features of
            // their own (USB 3.2 table 10-9).
            let feature = match bit {
                21 => 29,
                22 => 25,
                23 => 26,
                bit => bit as u16,
            };
            return self.request(
                job,
                Step::ClearingHubPortChange(port),
                hub,
                (0x23, CLEAR_FEATURE, feature, u16::from(port)),
            );
        }
        self.hub_port_examined(job, port, out)
    }

    fn clearing_hub_port_change(
        &mut self,
        job: &mut Job,
        done: Result<()>,
        port: u8,
        out: &mut impl FnMut(u8),
    ) -> Result<Next> {
        done?;
        self.clear_next_hub_port_change(job, port, out)
    }

    /// A hub port's status is known and its changes cleared: a device gone
    /// is let go of, a new one queued.
    fn hub_port_examined(
        &mut self,
        job: &mut Job,
        port: u8,
        out: &mut impl FnMut(u8),
    ) -> Result<Next> {
        let status = job.hub_setup.status;
        let first_look = !job.changes_only;
        if job.hub_setup.connection_changed || first_look {
            let Some(location) = job.location.below(port) else {
                return self.examine_next_hub_port(job);
            };
            let connected = status & HUB_PORT_CONNECTION != 0;
            if !first_look {
                self.port_changed(location, connected, out);
            } else if connected {
                // Ports looked at right after the power-on wait have had
                // their connect time.
                self.queue_port(location, true, None);
            }
        }
        self.examine_next_hub_port(job)
    }

    /// The work is done: said, with what it took.
    fn finish(&mut self, job: Job) {
        if job.changes_only || job.abandoned || job.step == Step::DisablingHubPort {
            return;
        }
        let Some(index) = job.device else {
            return;
        };
        let took = self.now_micros().saturating_sub(job.started);
        let (location, longest, speed) = (job.location, job.longest_step, job.speed);
        if let Some(Role::Hub(hub)) = self.devices[index].as_ref().map(|d| &d.role) {
            let ports = hub.ports;
            self.say_at(location, format_args!("hub with {ports} ports set up"));
        }
        self.say_at(
            location,
            format_args!("enumerated in {took} us at {speed} speed, its longest step {longest} us"),
        );
    }

    /// A step failed or timed out: said; the device's handle and address
    /// given back, its port disabled (a hub port through the hub, a step
    /// more), and the port left until it changes again.
    fn fail(&mut self, mut job: Job, e: BusError) {
        let took = self.now_micros().saturating_sub(job.started);
        let (location, step) = (job.location, job.step);
        if job.changes_only {
            // The changes are still set: the hub reports them again.
            self.say_at(
                location,
                format_args!(
                    "hub: {e} while {step}; its changes are looked at again at its next report"
                ),
            );
            return;
        }
        if step == Step::DisablingHubPort {
            self.say_at(location, format_args!("hub port not disabled ({e})"));
            return;
        }
        let tries = job.tries + 1;
        if job.may_try_again(e) {
            let scheme = if tries / 2 == 1 { "old" } else { "new" };
            self.say_at(
                location,
                format_args!(
                    "{e} while {step}, try {tries} of {ENUMERATION_TRIES} (after {took} us); the port is reset for try {} ({scheme} scheme)",
                    tries + 1
                ),
            );
            self.queue_retry(location, tries);
        } else if tries > 1 {
            self.say_at(
                location,
                format_args!(
                    "{e} while {step}; port disabled after {tries} tries, left until it changes again (after {took} us)"
                ),
            );
        } else {
            self.say_at(
                location,
                format_args!(
                    "{e} while {step}; port disabled, left until it changes again (after {took} us)"
                ),
            );
        }
        // Ports of a hub that failed half set up were queued: dropped.
        self.queue.remove(|work| match *work {
            Work::Port { location: at, .. } => location.holds(at) && at != location,
            Work::HubChanges { hub, .. } => job.device == Some(hub),
        });
        if let Some(index) = job.device.take() {
            self.remove_device(index);
        }
        match location.hub() {
            None => self.controller.port_disable(location.root_port()),
            Some(_) => {
                let Some(hub) = job.hub else {
                    return;
                };
                let port = u16::from(location.port());
                match self.request(
                    &mut job,
                    Step::DisablingHubPort,
                    hub,
                    (0x23, CLEAR_FEATURE, PORT_ENABLE, port),
                ) {
                    Ok(_) => self.job = Some(job),
                    Err(e) => self.say_at(location, format_args!("hub port not disabled ({e})")),
                }
            }
        }
    }

    /// Queues the port whose device failed try `tries` for the next one, at
    /// once (its connection settled long ago); a reset starts it.
    fn queue_retry(&mut self, location: Location, tries: u8) {
        let now = self.now_micros();
        let work = Work::Port {
            location,
            first_change: now,
            last_change: now.saturating_sub(DEBOUNCE_MICROS),
            tries,
        };
        if !self.queue.push(work) {
            self.say_at(
                location,
                format_args!("too many ports waiting; left until it changes again"),
            );
        }
    }

    /// Gives device `index` back to the controller, quietly: its pipe
    /// closed, its handle and address freed.
    pub(super) fn remove_device(&mut self, index: usize) {
        let Some(mut device) = self.devices[index].take() else {
            return;
        };
        self.holding &= !(1 << index);
        self.recovering &= !(1 << index);
        if let Some(pipe) = device.pipe_mut() {
            if pipe.state != PipeState::GivenUp {
                let id = pipe.id;
                self.controller.interrupt_close(id);
            }
        }
        self.controller.device_remove(device.id);
        self.addresses.free(device.address);
    }
}
