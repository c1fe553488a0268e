//! Enumeration, a step per poll. One device is enumerated at a time (as
//! Linux serializes the default address); ports wait their turn in a small
//! queue, and so do hubs whose ports changed (their requests go through the
//! hub's endpoint 0, which an enumeration behind the hub uses too). Each
//! call of [`Xhci::poll`] runs at most one step: a step checks whether what
//! it waits for has happened (a command's completion, a control transfer's
//! event, a root port's reset, the clock), acts on it, and issues the next
//! step's command, transfer or port write, never waiting itself.

use super::*;

/// How long an xHCI command may take: Linux's `XHCI_CMD_DEFAULT_TIMEOUT`
/// (drivers/usb/host/xhci.h, 5 * HZ).
pub(super) const COMMAND_MICROS: u64 = 5_000_000;
/// How long a port reset may take, however many status checks: Linux's
/// `HUB_RESET_TIMEOUT` (drivers/usb/core/hub.c, 800 ms). A root port's
/// PORTSC is checked on every poll (a register read; Linux sleeps
/// `HUB_ROOT_RESET_TIME`, 60 ms, between checks because it can).
const PORT_RESET_MICROS: u64 = 800_000;
// Linux's other hub timeouts are the device layer's, one set for every
// controller: the debounce, reset recovery, SET_ADDRESS recovery, a hub's
// connect time and its reset checks, the root ports' first look, a control
// transfer's bound and boot enumeration's.
pub use crate::bus::BOOT_ENUMERATION_MICROS;
use crate::bus::{
    CONNECT_MICROS, DEBOUNCE_MICROS, DEBOUNCE_TIMEOUT_MICROS, HUB_CONNECT_MICROS,
    HUB_RESET_CHECK_MICROS, RESET_RECOVERY_MICROS, SET_ADDRESS_RECOVERY_MICROS, TRANSFER_MICROS,
};
/// Ports and hubs waiting for their turn.
const QUEUE_LENGTH: usize = 16;

/// Hub port status (wPortStatus, low half) and change (wPortChange, high
/// half) bits, USB 2.0 11.24.2.7.
const HUB_PORT_CONNECTION: u32 = 1 << 0;
const HUB_PORT_ENABLE: u32 = 1 << 1;
const HUB_PORT_LOW_SPEED: u32 = 1 << 9;
const HUB_PORT_HIGH_SPEED: u32 = 1 << 10;
const HUB_C_PORT_CONNECTION: u32 = 1 << 16;
const HUB_C_PORT_RESET: u32 = 1 << 20;
/// C_PORT_CONNECTION to C_PORT_RESET: cleared with the feature of the same
/// number (16 to 20).
const HUB_PORT_CHANGES: u32 = 0x1F << 16;
/// A SuperSpeed hub's further changes (USB 3.2 10.16.2.6.2):
/// C_BH_PORT_RESET, C_PORT_LINK_STATE, C_PORT_CONFIG_ERROR.
const SUPERSPEED_HUB_PORT_CHANGES: u32 = 0x7 << 21;

/// What waits in the queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Work {
    /// A port with a new connection, enumerated once it has been stable for
    /// [`DEBOUNCE_MICROS`]: when it first and last changed.
    Port {
        location: Location,
        first_change: u64,
        last_change: u64,
    },
    /// A hub (by slot) whose status change endpoint said these ports
    /// changed (bit n: port n).
    HubPorts { slot: u8, changed: u16 },
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
    /// change moved on instead. Gives false when the queue is full.
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
                    Work::HubPorts { slot, changed },
                    Work::HubPorts {
                        slot: new,
                        changed: more,
                    },
                ) if *slot == new => {
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

    /// Takes the first work that can start now.
    fn take_ready(&mut self, now: u64) -> Option<Work> {
        let position = self.items[..self.len].iter().position(|item| match item {
            Some(Work::Port { last_change, .. }) => {
                now.saturating_sub(*last_change) >= DEBOUNCE_MICROS
            }
            Some(Work::HubPorts { .. }) => true,
            None => false,
        })?;
        let work = self.items[position].take();
        self.items.copy_within(position + 1..self.len, position);
        self.len -= 1;
        self.items[self.len] = None;
        work
    }

    /// Forgets what is queued for `location` and below, and for the hubs
    /// whose slots `gone` names.
    fn remove(&mut self, location: Location, gone: impl Fn(u8) -> bool) {
        let mut kept = 0;
        for index in 0..self.len {
            let keep = match self.items[index] {
                Some(Work::Port { location: at, .. }) => !location.holds(at),
                Some(Work::HubPorts { slot, .. }) => !gone(slot),
                None => false,
            };
            if keep {
                self.items[kept] = self.items[index];
                kept += 1;
            }
        }
        for item in &mut self.items[kept..self.len] {
            *item = None;
        }
        self.len = kept;
    }
}

impl Location {
    /// Whether `other` is this location or lies below it.
    pub(super) fn holds(&self, other: Location) -> bool {
        let depth = self.depth();
        let mask = (1u32 << (4 * depth)) - 1;
        other.root_port == self.root_port
            && other.depth() >= depth
            && other.route & mask == self.route
    }

    /// The hub this location's port belongs to (None on a root port).
    pub(super) fn hub(&self) -> Option<Location> {
        let depth = self.depth();
        (depth > 0).then(|| Location {
            root_port: self.root_port,
            route: self.route & ((1u32 << (4 * (depth - 1))) - 1),
        })
    }

    /// The port on its hub (the root port on the root hub).
    pub(super) fn port(&self) -> u8 {
        match self.depth() {
            0 => self.root_port,
            depth => ((self.route >> (4 * (depth - 1))) & 0xF) as u8,
        }
    }
}

/// One step of an enumeration (or of a hub's port change handling): what
/// the step waits for is in [`Enumeration::awaiting`]; the step's function,
/// named for it, runs once that has happened.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum EnumerationStep {
    /// A root port is being reset (PORTSC's PR written).
    ResettingRootPort,
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
    /// Enable Slot.
    EnablingSlot,
    /// Address Device with BSR=1: the device stays at the default address.
    AddressingWithoutSetAddress,
    /// Address Device: SET_ADDRESS sent.
    Addressing,
    /// The SET_ADDRESS recovery interval.
    RecoveringFromSetAddress,
    /// The device descriptor's first 8 bytes (endpoint 0's packet size).
    ReadingDeviceHeader,
    /// Evaluate Context: endpoint 0's packet size.
    EvaluatingPacketSize,
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
    /// Configure Endpoint: the keyboard's report endpoint.
    ConfiguringReportEndpoint,
    /// SET_PROTOCOL.
    SettingProtocol,
    /// SET_IDLE.
    SettingIdle,
    /// The hub descriptor.
    ReadingHubDescriptor,
    /// SET_CONFIGURATION sent to a hub.
    ConfiguringHub,
    /// SET_HUB_DEPTH sent to a SuperSpeed hub.
    SettingHubDepth,
    /// Configure Endpoint: the slot marked as a hub, its status change
    /// endpoint added.
    MarkingHub,
    /// SET_FEATURE(PORT_POWER) of one hub port.
    PoweringHubPort(u8),
    /// The hub's power-on-to-good time and the devices' connect time.
    WaitingForHubPower,
    /// GET_STATUS of a hub port that changed (or is looked at first).
    ReadingHubPortStatus(u8),
    /// CLEAR_FEATURE of a hub port's change bit.
    ClearingHubPortChange(u8),
}

impl core::fmt::Display for EnumerationStep {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        use EnumerationStep::*;
        match self {
            ResettingRootPort => write!(f, "resetting the root port"),
            StartingHubPortReset | WaitingForHubPortReset | CheckingHubPortReset => {
                write!(f, "resetting the hub port")
            }
            ClearingHubPortReset => write!(f, "clearing the hub port's reset change"),
            RecoveringFromReset => write!(f, "recovering from the reset"),
            EnablingSlot => write!(f, "enabling a slot"),
            AddressingWithoutSetAddress => write!(f, "addressing (BSR=1)"),
            Addressing => write!(f, "addressing"),
            RecoveringFromSetAddress => write!(f, "recovering from SET_ADDRESS"),
            ReadingDeviceHeader => write!(f, "reading the device descriptor's first 8 bytes"),
            EvaluatingPacketSize => write!(f, "evaluating endpoint 0's packet size"),
            ReadingDeviceDescriptor => write!(f, "reading the device descriptor"),
            ReadingConfigurationHeader => write!(f, "reading the configuration's length"),
            ReadingConfiguration => write!(f, "reading the configuration"),
            ConfiguringKeyboard | ConfiguringHub => write!(f, "setting the configuration"),
            ReadingReportDescriptor => write!(f, "reading the report descriptor"),
            ConfiguringReportEndpoint => write!(f, "configuring the report endpoint"),
            SettingProtocol => write!(f, "setting the protocol"),
            SettingIdle => write!(f, "setting idle"),
            ReadingHubDescriptor => write!(f, "reading the hub descriptor"),
            SettingHubDepth => write!(f, "setting the hub's depth"),
            MarkingHub => write!(f, "marking the slot as a hub"),
            PoweringHubPort(port) => write!(f, "powering hub port {port}"),
            WaitingForHubPower => write!(f, "waiting for the hub's power"),
            ReadingHubPortStatus(port) => write!(f, "reading hub port {port}'s status"),
            ClearingHubPortChange(port) => write!(f, "clearing hub port {port}'s changes"),
        }
    }
}

/// What a step waits for before its function runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Awaiting {
    /// The clock to pass the deadline.
    Time,
    /// The completion of the command TRB at `trb` (matched by the TRB's
    /// address, so that a late completion of a command given up is never
    /// taken for a later one's).
    Command { trb: u64, kind: u32 },
    /// The event of the control transfer on `slot` whose Status TRB is at `status`.
    Transfer { slot: u8, status: u64 },
    /// A root port's reset to end (PORTSC's PRC set, PR clear).
    RootPortReset(u8),
}

/// What a step's function says next.
enum Next {
    /// Another step was issued.
    Continue,
    /// The work is done.
    Done,
}

/// A keyboard being set up: what it will be read by.
#[derive(Clone, Debug)]
struct KeyboardSetUp {
    interface: u8,
    endpoint: InterruptIn,
    boot: bool,
    report_descriptor_bytes: u16,
    keyboard: Option<Keyboard>,
}

/// A hub being set up, or whose ports changed.
#[derive(Clone, Copy, Debug, Default)]
struct HubSetUp {
    ports: u8,
    power_good: u64,
    status_change: Option<InterruptIn>,
    /// The ports still to be looked at (bit n: port n).
    to_examine: u16,
    /// The status of the port being looked at (its changes cleared one by one).
    port_status: u32,
    /// Its C_PORT_CONNECTION was set.
    connection_changed: bool,
}

/// The work in progress: one device's enumeration, or one hub's port
/// changes.
#[derive(Clone, Debug)]
pub(super) struct Enumeration {
    /// The device's location (for a hub's port changes: the hub's).
    location: Location,
    step: EnumerationStep,
    awaiting: Awaiting,
    deadline: u64,
    /// The event that ended the wait.
    completion: Option<Trb>,
    started: u64,
    /// The longest single step, for the log.
    longest_step: u64,
    /// The device's place in `devices` once its slot is enabled (for a
    /// hub's port changes: the hub's).
    index: Option<usize>,
    /// A slot enabled, not yet in `devices`.
    slot: u8,
    speed: u32,
    translator: Option<(u8, u8)>,
    /// When a hub port's reset must have ended.
    reset_deadline: u64,
    hub_port_status: u32,
    max_packet_0: u16,
    two_step: bool,
    header_read: bool,
    vendor: u16,
    product: u16,
    configuration: u8,
    keyboard: Option<KeyboardSetUp>,
    hub: HubSetUp,
    /// Only a hub's port changes, no enumeration.
    hub_changes_only: bool,
}

impl Enumeration {
    fn new(location: Location, now: u64) -> Enumeration {
        Enumeration {
            location,
            step: EnumerationStep::RecoveringFromReset,
            awaiting: Awaiting::Time,
            deadline: now,
            completion: None,
            started: now,
            longest_step: 0,
            index: None,
            slot: 0,
            speed: 0,
            translator: None,
            reset_deadline: 0,
            hub_port_status: 0,
            max_packet_0: 8,
            two_step: false,
            header_read: false,
            vendor: 0,
            product: 0,
            configuration: 0,
            keyboard: None,
            hub: HubSetUp::default(),
            hub_changes_only: false,
        }
    }

    fn wait(&mut self, step: EnumerationStep, until: u64) -> Result<Next> {
        self.step = step;
        self.awaiting = Awaiting::Time;
        self.deadline = until;
        Ok(Next::Continue)
    }
}

impl<H: Hardware> Xhci<H> {
    /// Starts enumeration: the root ports are looked at once devices have
    /// had time to connect; from then on [`Xhci::poll`] enumerates them.
    pub fn start_enumeration(&mut self) {
        self.scan_at = Some(self.hw.now_micros() + CONNECT_MICROS);
    }

    /// Whether nothing is being enumerated or waits to be.
    #[inline]
    pub fn enumeration_idle(&self) -> bool {
        self.scan_at.is_none() && self.enumeration.is_none() && self.queue.is_empty()
    }

    /// Boot enumeration: starts it and drives [`Xhci::poll`] until nothing
    /// is left to enumerate or [`BOOT_ENUMERATION_MICROS`] pass (keys
    /// pressed meanwhile are dropped: nobody listens yet); whatever is left
    /// carries on from the caller's later polls. Returns the keyboards found.
    pub fn enumerate(&mut self) -> usize {
        let start = self.hw.now_micros();
        self.start_enumeration();
        while !self.enumeration_idle() {
            if self.hw.now_micros().saturating_sub(start) >= BOOT_ENUMERATION_MICROS {
                let at = self.enumeration.as_ref().map(|e| (e.location, e.step));
                match at {
                    Some((location, step)) => self.hw.log(format_args!(
                        "usb: boot enumeration cut short after {} ms, port {location} still {step}; it carries on from the frame loop",
                        BOOT_ENUMERATION_MICROS / 1_000
                    )),
                    None => self.hw.log(format_args!(
                        "usb: boot enumeration cut short after {} ms; the ports queued carry on from the frame loop",
                        BOOT_ENUMERATION_MICROS / 1_000
                    )),
                }
                break;
            }
            self.poll(&mut |_| {});
        }
        self.devices
            .iter()
            .flatten()
            .filter(|d| d.keyboard.is_some())
            .count()
    }

    /// Takes an event the enumeration waits for; gives whether it did.
    pub(super) fn enumeration_event(&mut self, event: &Trb) -> bool {
        let Some(job) = self.enumeration.as_mut() else {
            return false;
        };
        let wanted = match job.awaiting {
            Awaiting::Command { trb, .. } => {
                event.kind() == trb_type::COMMAND_COMPLETION && event.parameter() == trb
            }
            Awaiting::Transfer { slot, .. } => {
                event.kind() == trb_type::TRANSFER_EVENT
                    && event.slot() == slot
                    && event.endpoint() == 1
            }
            _ => false,
        };
        if wanted {
            job.completion = Some(*event);
        }
        wanted
    }

    /// Queues a port whose connection changed.
    pub(super) fn queue_port(&mut self, location: Location, settled: bool) {
        let now = self.hw.now_micros();
        let changed = if settled {
            now.saturating_sub(DEBOUNCE_MICROS)
        } else {
            now
        };
        // A port that kept bouncing past the debounce timeout starts over.
        if let Some(Work::Port { first_change, .. }) = self.queue.items[..self.queue.len]
            .iter()
            .flatten()
            .find(|w| matches!(w, Work::Port { location: at, .. } if *at == location))
        {
            if now.saturating_sub(*first_change) > DEBOUNCE_TIMEOUT_MICROS {
                self.queue.remove(location, |_| false);
                self.hw.log(format_args!(
                    "usb: port {location}: connection never settled within {} ms; left until it changes again",
                    DEBOUNCE_TIMEOUT_MICROS / 1_000
                ));
                return;
            }
        }
        let work = Work::Port {
            location,
            first_change: changed,
            last_change: changed,
        };
        if !self.queue.push(work) {
            self.hw.log(format_args!(
                "usb: port {location}: too many ports waiting; left until it changes again"
            ));
        }
    }

    /// A hub's status change endpoint said which of its ports changed.
    pub(super) fn queue_hub_ports(&mut self, slot: u8, changed: u16) {
        if !self.queue.push(Work::HubPorts { slot, changed }) {
            self.hw.log(format_args!(
                "usb: hub in slot {slot}: too much waiting; its port changes are lost"
            ));
        }
    }

    /// Forgets queued and running work at `location` and below (its
    /// devices are gone). A command still outstanding is aborted.
    pub(super) fn forget_work_under(&mut self, location: Location, gone_slots: &[u8]) {
        self.queue
            .remove(location, |slot| gone_slots.contains(&slot));
        let cancel = self.enumeration.as_ref().is_some_and(|job| {
            location.holds(job.location) || (job.slot != 0 && gone_slots.contains(&job.slot))
        });
        if cancel {
            if let Some(job) = self.enumeration.take() {
                let (at, step) = (job.location, job.step);
                self.hw.log(format_args!(
                    "usb: port {at}: the device went away while {step}; enumeration stopped"
                ));
                if let Awaiting::Command { .. } = job.awaiting {
                    self.abort_command();
                }
                if job.index.is_none() && job.slot != 0 {
                    self.disable_slot(job.slot);
                }
                if let Some(keyboard) = job.keyboard.and_then(|k| k.keyboard) {
                    self.free_page(keyboard.ring.base());
                    self.free_page(keyboard.reports);
                }
            }
        }
    }

    /// Runs at most one enumeration step.
    pub(super) fn advance_enumeration(&mut self) {
        let now = self.hw.now_micros();
        if self.scan_at.is_some_and(|at| now >= at) {
            self.scan_at = None;
            self.scan_root_ports();
            return;
        }
        let Some(mut job) = self.enumeration.take() else {
            if self.scan_at.is_none() {
                self.start_work(now);
            }
            return;
        };
        let done = match self.wait_over(&mut job, now) {
            None => {
                self.enumeration = Some(job);
                return;
            }
            Some(done) => done,
        };
        let result = self.run_step(&mut job, done);
        let took = self.hw.now_micros().saturating_sub(now);
        job.longest_step = job.longest_step.max(took);
        match result {
            Ok(Next::Continue) => self.enumeration = Some(job),
            Ok(Next::Done) => self.finish(job),
            Err(e) => self.fail(job, e),
        }
    }

    /// Whether the step's wait is over: None while it is not, else how it
    /// ended.
    fn wait_over(&mut self, job: &mut Enumeration, now: u64) -> Option<Result<()>> {
        match job.awaiting {
            Awaiting::Time => (now >= job.deadline).then_some(Ok(())),
            Awaiting::Command { kind, .. } => match job.completion {
                Some(event) if event.completion_code() == COMPLETION_SUCCESS => Some(Ok(())),
                Some(event) => Some(Err(XhciError::CommandFailed(kind, event.completion_code()))),
                None if now >= job.deadline => {
                    self.abort_command();
                    Some(Err(XhciError::CommandTimeout(kind)))
                }
                None => None,
            },
            Awaiting::Transfer { status, .. } => match job.completion {
                Some(event) => {
                    let code = event.completion_code();
                    if event.parameter() == status
                        && (code == COMPLETION_SUCCESS || code == COMPLETION_SHORT_PACKET)
                    {
                        Some(Ok(()))
                    } else {
                        Some(Err(XhciError::TransferFailed(code)))
                    }
                }
                None if now >= job.deadline => Some(Err(XhciError::TransferTimeout)),
                None => None,
            },
            Awaiting::RootPortReset(port) => {
                let status = self.read(self.portsc(port));
                if status != u32::MAX && status & PORT_RESET_CHANGE != 0 && status & PORT_RESET == 0
                {
                    Some(Ok(()))
                } else if now >= job.deadline {
                    Some(Err(XhciError::PortReset))
                } else {
                    None
                }
            }
        }
    }

    fn run_step(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        use EnumerationStep::*;
        match job.step {
            ResettingRootPort => self.resetting_root_port(job, done),
            StartingHubPortReset => self.starting_hub_port_reset(job, done),
            WaitingForHubPortReset => self.waiting_for_hub_port_reset(job),
            CheckingHubPortReset => self.checking_hub_port_reset(job, done),
            ClearingHubPortReset => self.clearing_hub_port_reset(job, done),
            RecoveringFromReset => self.recovering_from_reset(job),
            EnablingSlot => self.enabling_slot(job, done),
            AddressingWithoutSetAddress => self.addressing_without_set_address(job, done),
            Addressing => self.addressing(job, done),
            RecoveringFromSetAddress => self.recovering_from_set_address(job),
            ReadingDeviceHeader => self.reading_device_header(job, done),
            EvaluatingPacketSize => self.evaluating_packet_size(job, done),
            ReadingDeviceDescriptor => self.reading_device_descriptor(job, done),
            ReadingConfigurationHeader => self.reading_configuration_header(job, done),
            ReadingConfiguration => self.reading_configuration(job, done),
            ConfiguringKeyboard => self.configuring_keyboard(job, done),
            ReadingReportDescriptor => self.reading_report_descriptor(job, done),
            ConfiguringReportEndpoint => self.configuring_report_endpoint(job, done),
            SettingProtocol => self.setting_protocol(job, done),
            SettingIdle => self.setting_idle(job, done),
            ReadingHubDescriptor => self.reading_hub_descriptor(job, done),
            ConfiguringHub => self.configuring_hub(job, done),
            SettingHubDepth => self.setting_hub_depth(job, done),
            MarkingHub => self.marking_hub(job, done),
            PoweringHubPort(port) => self.powering_hub_port(job, done, port),
            WaitingForHubPower => self.waiting_for_hub_power(job),
            ReadingHubPortStatus(port) => self.reading_hub_port_status(job, done, port),
            ClearingHubPortChange(port) => self.clearing_hub_port_change(job, done, port),
        }
    }

    /// The root ports connected once the controller has run a while.
    fn scan_root_ports(&mut self) {
        for port in 1..=self.capabilities.ports {
            let status = self.read(self.portsc(port));
            if status != u32::MAX && status & PORT_CONNECTED != 0 {
                let location = Location {
                    root_port: port,
                    route: 0,
                };
                // They have had the connect time to settle.
                self.queue_port(location, true);
            }
        }
    }

    /// Starts the next work whose turn it is.
    fn start_work(&mut self, now: u64) {
        let Some(work) = self.queue.take_ready(now) else {
            return;
        };
        match work {
            Work::Port { location, .. } => {
                let mut job = Enumeration::new(location, now);
                let result = match location.hub() {
                    None => self.start_root_port_reset(&mut job),
                    Some(hub) => self.start_hub_port_reset(&mut job, hub),
                };
                match result {
                    Ok(Next::Continue) => self.enumeration = Some(job),
                    Ok(Next::Done) => {}
                    Err(e) => self.fail(job, e),
                }
            }
            Work::HubPorts { slot, changed } => {
                let Some(index) = self.device_by_slot(slot) else {
                    return;
                };
                let Some(device) = self.devices[index].as_ref() else {
                    return;
                };
                let Some(hub) = device.hub.as_ref() else {
                    return;
                };
                let ports = hub.ports;
                let mut job = Enumeration::new(device.location, now);
                job.index = Some(index);
                job.slot = slot;
                job.hub_changes_only = true;
                job.hub.ports = ports;
                job.hub.to_examine = changed & (((1u32 << (ports + 1)) - 2) as u16);
                match self.examine_next_hub_port(&mut job) {
                    Ok(Next::Continue) => self.enumeration = Some(job),
                    Ok(Next::Done) => self.finish(job),
                    Err(e) => self.fail(job, e),
                }
            }
        }
    }

    fn device_by_slot(&self, slot: u8) -> Option<usize> {
        self.devices
            .iter()
            .position(|d| d.as_ref().is_some_and(|d| d.slot == slot))
    }

    fn device_at(&self, location: Location) -> Option<usize> {
        self.devices
            .iter()
            .position(|d| d.as_ref().is_some_and(|d| d.location == location))
    }

    /// Pushes a command for `step` and rings the command doorbell.
    fn send_command(
        &mut self,
        job: &mut Enumeration,
        step: EnumerationStep,
        trb: Trb,
    ) -> Result<Next> {
        let kind = trb.kind();
        let address = self.queue_command(trb).ok_or(XhciError::NotRunning)?;
        job.step = step;
        job.completion = None;
        job.awaiting = Awaiting::Command { trb: address, kind };
        job.deadline = self.hw.now_micros() + COMMAND_MICROS;
        Ok(Next::Continue)
    }

    /// Queues a control transfer for `step` on device `index`'s endpoint 0.
    fn send_control(
        &mut self,
        job: &mut Enumeration,
        step: EnumerationStep,
        index: usize,
        setup: Setup,
    ) -> Result<Next> {
        let (slot, status) = self.queue_control(index, setup)?;
        job.step = step;
        job.completion = None;
        job.awaiting = Awaiting::Transfer { slot, status };
        job.deadline = self.hw.now_micros() + TRANSFER_MICROS;
        Ok(Next::Continue)
    }

    fn device_index(job: &Enumeration) -> Result<usize> {
        job.index.ok_or(XhciError::Gone)
    }

    fn get_descriptor(
        &mut self,
        job: &mut Enumeration,
        step: EnumerationStep,
        kind: u8,
        length: u16,
    ) -> Result<Next> {
        let index = Self::device_index(job)?;
        let request_type =
            if kind == descriptor::kind::HUB || kind == descriptor::kind::SUPERSPEED_HUB {
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
        self.send_control(job, step, index, setup)
    }

    fn request(
        &mut self,
        job: &mut Enumeration,
        step: EnumerationStep,
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
        self.send_control(job, step, index, setup)
    }

    // The steps, in the order they run.

    fn start_root_port_reset(&mut self, job: &mut Enumeration) -> Result<Next> {
        let port = job.location.root_port;
        let register = self.portsc(port);
        let status = self.read(register);
        if status == u32::MAX || status & PORT_CONNECTED == 0 {
            // Gone before its turn: its disconnection says the rest.
            return Ok(Next::Done);
        }
        job.speed = (status >> 10) & 0xF;
        if self.protocols.major(port) == Some(3) && status & PORT_ENABLED != 0 {
            // USB 3 ports train and enable by themselves.
            return self.recovering_from_reset(job);
        }
        // PED is write-1-to-disable, and the change bits write-1-to-clear:
        // write neither by accident.
        self.write(register, PORT_POWER | PORT_RESET);
        job.step = EnumerationStep::ResettingRootPort;
        job.awaiting = Awaiting::RootPortReset(port);
        job.deadline = self.hw.now_micros() + PORT_RESET_MICROS;
        Ok(Next::Continue)
    }

    fn resetting_root_port(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let register = self.portsc(job.location.root_port);
        let status = self.read(register);
        self.write(register, PORT_POWER | (status & PORT_CHANGES));
        if status & PORT_ENABLED == 0 {
            return Err(XhciError::PortReset);
        }
        job.speed = (status >> 10) & 0xF;
        let until = self.hw.now_micros() + RESET_RECOVERY_MICROS;
        job.wait(EnumerationStep::RecoveringFromReset, until)
    }

    fn start_hub_port_reset(&mut self, job: &mut Enumeration, hub: Location) -> Result<Next> {
        let Some(index) = self.device_at(hub) else {
            // The hub went first; nothing is left to enumerate.
            return Ok(Next::Done);
        };
        job.reset_deadline = self.hw.now_micros() + PORT_RESET_MICROS;
        let port = u16::from(job.location.port());
        self.request(
            job,
            EnumerationStep::StartingHubPortReset,
            index,
            (0x23, SET_FEATURE, HUB_PORT_RESET, port),
        )
    }

    fn parent_hub(&self, job: &Enumeration) -> Result<usize> {
        job.location
            .hub()
            .and_then(|hub| self.device_at(hub))
            .ok_or(XhciError::PortReset)
    }

    fn starting_hub_port_reset(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let until = self.hw.now_micros() + HUB_RESET_CHECK_MICROS;
        job.wait(EnumerationStep::WaitingForHubPortReset, until)
    }

    fn waiting_for_hub_port_reset(&mut self, job: &mut Enumeration) -> Result<Next> {
        let hub = self.parent_hub(job)?;
        let setup = Setup {
            request_type: 0xA3,
            request: GET_STATUS,
            value: 0,
            index: u16::from(job.location.port()),
            length: 4,
        };
        self.send_control(job, EnumerationStep::CheckingHubPortReset, hub, setup)
    }

    fn read_port_status(&mut self, index: usize) -> u32 {
        let mut bytes = [0u8; 4];
        self.read_buffer(index, &mut bytes);
        u32::from_le_bytes(bytes)
    }

    fn checking_hub_port_reset(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let hub = self.parent_hub(job)?;
        let status = self.read_port_status(hub);
        let now = self.hw.now_micros();
        if status & HUB_C_PORT_RESET == 0 {
            if now >= job.reset_deadline {
                return Err(XhciError::PortReset);
            }
            return job.wait(
                EnumerationStep::WaitingForHubPortReset,
                now + HUB_RESET_CHECK_MICROS,
            );
        }
        job.hub_port_status = status;
        let port = u16::from(job.location.port());
        self.request(
            job,
            EnumerationStep::ClearingHubPortReset,
            hub,
            (0x23, CLEAR_FEATURE, HUB_C_PORT_RESET_FEATURE, port),
        )
    }

    fn clearing_hub_port_reset(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let status = job.hub_port_status;
        if status & HUB_PORT_ENABLE == 0 {
            return Err(XhciError::PortReset);
        }
        let hub = self.parent_hub(job)?;
        let Some(parent) = self.devices[hub].as_ref() else {
            return Err(XhciError::PortReset);
        };
        // Behind a SuperSpeed hub every device is SuperSpeed (its port
        // status has no speed bits of USB 2.0's meaning; bit 9 is power).
        job.speed = if parent.speed == speed::SUPER {
            speed::SUPER
        } else if status & HUB_PORT_LOW_SPEED != 0 {
            speed::LOW
        } else if status & HUB_PORT_HIGH_SPEED != 0 {
            speed::HIGH
        } else {
            speed::FULL
        };
        // A full- or low-speed device is reached through the transaction
        // translator of the nearest high-speed hub above it: this hub's,
        // or the one this hub itself uses.
        job.translator = if parent.speed == speed::SUPER {
            None
        } else if parent.speed == speed::HIGH {
            (job.speed != speed::HIGH).then_some((parent.slot, job.location.port()))
        } else {
            let context = parent.slot_context;
            (context.tt_hub_slot != 0).then_some((context.tt_hub_slot, context.tt_port))
        };
        let until = self.hw.now_micros() + RESET_RECOVERY_MICROS;
        job.wait(EnumerationStep::RecoveringFromReset, until)
    }

    fn recovering_from_reset(&mut self, job: &mut Enumeration) -> Result<Next> {
        if !self.devices.iter().any(Option::is_none) {
            return Err(XhciError::TooManyDevices);
        }
        self.send_command(
            job,
            EnumerationStep::EnablingSlot,
            Trb(command::EnableSlot::new().into_raw()),
        )
    }

    fn enabling_slot(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let slot = job.completion.map_or(0, |e| e.slot());
        if slot == 0 || slot > self.capabilities.slots.min(MAX_SLOTS) {
            return Err(XhciError::BadSlot(slot));
        }
        job.slot = slot;
        let index = self
            .devices
            .iter()
            .position(Option::is_none)
            .ok_or(XhciError::TooManyDevices)?;
        let (output, input, ep0_page, buffer) =
            (self.page()?, self.page()?, self.page()?, self.page()?);
        self.hw
            .mem_write(self.dcbaa + 8 * u64::from(slot), output as u32);
        self.hw
            .mem_write(self.dcbaa + 8 * u64::from(slot) + 4, (output >> 32) as u32);
        let ep0 = ProducerRing::new(ep0_page, RING_TRBS);
        let (tt_hub_slot, tt_port) = job.translator.unwrap_or((0, 0));
        let slot_context = SlotContext {
            route_string: job.location.route,
            speed: job.speed,
            hub: false,
            context_entries: 1,
            root_port: job.location.root_port,
            hub_ports: 0,
            tt_hub_slot,
            tt_port,
        };
        job.max_packet_0 = match job.speed {
            speed::LOW | speed::FULL => 8,
            speed::HIGH => 64,
            _ => 512,
        };
        let ep0_dequeue = ep0.dequeue_pointer();
        self.devices[index] = Some(Device {
            slot,
            location: job.location,
            speed: job.speed,
            output,
            input,
            buffer,
            ep0,
            slot_context,
            keyboard: None,
            hub: None,
        });
        job.index = Some(index);
        // Full- and low-speed devices are addressed in two steps, as the
        // specification (4.6.5) and Linux do: first without SET_ADDRESS
        // (BSR=1), so that the device descriptor's first 8 bytes are read at
        // the default address with an 8-byte packet size; endpoint 0 then
        // gets its real packet size; only then is the address set. Some
        // devices take no address before their descriptor has been read.
        job.two_step = matches!(job.speed, speed::LOW | speed::FULL);
        let without_set_address = job.two_step;
        self.address_device(
            job,
            slot,
            input,
            &slot_context,
            ep0_dequeue,
            without_set_address,
        )
    }

    /// Writes the input context Address Device reads (the slot and endpoint
    /// 0 whole, endpoint 0's ring from `ep0_dequeue`) and sends the command,
    /// `without_set_address` (BSR=1) for a two-step device's first time.
    fn address_device(
        &mut self,
        job: &mut Enumeration,
        slot: u8,
        input: u64,
        slot_context: &SlotContext,
        ep0_dequeue: u64,
        without_set_address: bool,
    ) -> Result<Next> {
        let layout = self.capabilities.layout;
        layout.start_input(&mut self.hw, input, 0b11);
        layout.write_slot(&mut self.hw, input, slot_context);
        layout.write_endpoint(
            &mut self.hw,
            input,
            1,
            &ep0_context(ep0_dequeue, job.max_packet_0),
        );
        let mut address = command::AddressDevice::new();
        address.set_input_context_pointer(input).set_slot_id(slot);
        let step = if without_set_address {
            address.set_block_set_address_request();
            EnumerationStep::AddressingWithoutSetAddress
        } else {
            EnumerationStep::Addressing
        };
        self.send_command(job, step, Trb(address.into_raw()))
    }

    fn addressing_without_set_address(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
    ) -> Result<Next> {
        done?;
        self.get_descriptor(
            job,
            EnumerationStep::ReadingDeviceHeader,
            descriptor::kind::DEVICE,
            8,
        )
    }

    fn addressing(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let until = self.hw.now_micros() + SET_ADDRESS_RECOVERY_MICROS;
        job.wait(EnumerationStep::RecoveringFromSetAddress, until)
    }

    fn recovering_from_set_address(&mut self, job: &mut Enumeration) -> Result<Next> {
        if job.header_read {
            self.get_descriptor(
                job,
                EnumerationStep::ReadingDeviceDescriptor,
                descriptor::kind::DEVICE,
                18,
            )
        } else {
            self.get_descriptor(
                job,
                EnumerationStep::ReadingDeviceHeader,
                descriptor::kind::DEVICE,
                8,
            )
        }
    }

    fn reading_device_header(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let mut header = [0u8; 8];
        self.read_buffer(index, &mut header);
        job.header_read = true;
        let first = descriptor::device(&header)?;
        let announced = if job.speed == speed::SUPER {
            1u16 << first.max_packet_0.min(9)
        } else {
            u16::from(first.max_packet_0)
        };
        if announced != job.max_packet_0 && matches!(announced, 8 | 16 | 32 | 64 | 512) {
            // Evaluate Context: endpoint 0's new packet size only.
            let (slot, input) = self.devices[index]
                .as_ref()
                .map(|d| (d.slot, d.input))
                .ok_or(XhciError::Gone)?;
            let layout = self.capabilities.layout;
            let dequeue = 0; // not evaluated by Evaluate Context
            layout.start_input(&mut self.hw, input, 0b10);
            layout.write_endpoint(&mut self.hw, input, 1, &ep0_context(dequeue, announced));
            job.max_packet_0 = announced;
            let mut evaluate = command::EvaluateContext::new();
            evaluate.set_input_context_pointer(input).set_slot_id(slot);
            return self.send_command(
                job,
                EnumerationStep::EvaluatingPacketSize,
                Trb(evaluate.into_raw()),
            );
        }
        self.packet_size_known(job)
    }

    fn evaluating_packet_size(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        self.packet_size_known(job)
    }

    /// Endpoint 0's packet size is right: the address is set now (two-step)
    /// or the whole device descriptor read.
    fn packet_size_known(&mut self, job: &mut Enumeration) -> Result<Next> {
        if !job.two_step {
            return self.get_descriptor(
                job,
                EnumerationStep::ReadingDeviceDescriptor,
                descriptor::kind::DEVICE,
                18,
            );
        }
        // The second Address Device reads the input context again: the
        // slot and endpoint 0 whole, endpoint 0's ring from where it now
        // stands.
        let index = Self::device_index(job)?;
        let Some(device) = self.devices[index].as_mut() else {
            return Err(XhciError::Gone);
        };
        // The `xhci` crate takes only 64-byte aligned dequeue pointers: No
        // Ops fill up to one, and are skipped.
        device.ep0.align_enqueue(&mut self.hw, 64);
        let (slot, input, slot_context, ep0_dequeue) = (
            device.slot,
            device.input,
            device.slot_context,
            device.ep0.enqueue_pointer(),
        );
        self.address_device(job, slot, input, &slot_context, ep0_dequeue, false)
    }

    fn reading_device_descriptor(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
    ) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let mut bytes = [0u8; 18];
        self.read_buffer(index, &mut bytes);
        let device = descriptor::device(&bytes)?;
        (job.vendor, job.product) = (device.vendor, device.product);
        self.get_descriptor(
            job,
            EnumerationStep::ReadingConfigurationHeader,
            descriptor::kind::CONFIGURATION,
            9,
        )
    }

    fn reading_configuration_header(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
    ) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let mut header = [0u8; 9];
        self.read_buffer(index, &mut header);
        let total = descriptor::configuration_total_length(&header)?.clamp(9, CONFIGURATION_BYTES);
        self.get_descriptor(
            job,
            EnumerationStep::ReadingConfiguration,
            descriptor::kind::CONFIGURATION,
            total,
        )
    }

    fn reading_configuration(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let mut header = [0u8; 9];
        self.read_buffer(index, &mut header);
        let total = usize::from(
            descriptor::configuration_total_length(&header)?.clamp(9, CONFIGURATION_BYTES),
        );
        let mut bytes = [0u8; CONFIGURATION_BYTES as usize];
        self.read_buffer(index, &mut bytes[..total]);
        let configuration = descriptor::configuration(&bytes[..total])?;
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
                    keyboard: None,
                });
                self.request(
                    job,
                    EnumerationStep::ConfiguringKeyboard,
                    index,
                    (0x00, SET_CONFIGURATION, u16::from(configuration.value), 0),
                )
            }
            Some(Function::Hub { status_change }) if location.depth() < MAX_HUB_TIERS => {
                job.hub.status_change = status_change;
                // A SuperSpeed hub has its own descriptor.
                let (kind, length) = if job.speed == speed::SUPER {
                    (descriptor::kind::SUPERSPEED_HUB, 12)
                } else {
                    (descriptor::kind::HUB, 9)
                };
                self.get_descriptor(job, EnumerationStep::ReadingHubDescriptor, kind, length)
            }
            Some(Function::Hub { .. }) => {
                self.hw.log(format_args!(
                    "usb: hub on port {location}: past the five hub tiers a route string names; left alone"
                ));
                // Left addressed and unused, as a device that is not ours.
                Ok(Next::Done)
            }
            None => {
                match configuration.first_interface {
                    Some(class) => self.hw.log(format_args!(
                        "usb: port {location}: device {:04x}:{:04x} ({class}) is not a keyboard \
                         or a hub; left alone",
                        job.vendor, job.product
                    )),
                    None => self.hw.log(format_args!(
                        "usb: port {location}: device {:04x}:{:04x} has no interface; left alone",
                        job.vendor, job.product
                    )),
                }
                // Not an error: the device is simply not ours. Its slot
                // stays addressed and unused.
                Ok(Next::Done)
            }
        }
    }

    /// The keyboard is configured: its report descriptor decides how its
    /// reports are read (a keyboard it describes is kept in the report
    /// protocol; a boot keyboard whose descriptor cannot be read is put in
    /// the boot protocol; a descriptor that lies is refused, and so is the
    /// keyboard).
    fn configuring_keyboard(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let Some(set_up) = job.keyboard.as_ref() else {
            return Err(XhciError::Gone);
        };
        if set_up.report_descriptor_bytes == 0 {
            return self.choose_report_format(job, Err(None));
        }
        let length = usize::from(set_up.report_descriptor_bytes).min(hid::MAX_DESCRIPTOR_BYTES);
        let setup = Setup {
            request_type: 0x81,
            request: GET_DESCRIPTOR,
            value: u16::from(descriptor::kind::REPORT) << 8,
            index: u16::from(set_up.interface),
            length: length as u16,
        };
        self.send_control(job, EnumerationStep::ReadingReportDescriptor, index, setup)
    }

    fn reading_report_descriptor(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
    ) -> Result<Next> {
        let index = Self::device_index(job)?;
        let length = job.keyboard.as_ref().map_or(0, |k| {
            usize::from(k.report_descriptor_bytes).min(hid::MAX_DESCRIPTOR_BYTES)
        });
        if let Err(e) = done {
            return self.choose_report_format(job, Err(Some(e)));
        }
        let mut descriptor = [0u8; hid::MAX_DESCRIPTOR_BYTES];
        self.read_buffer(index, &mut descriptor[..length]);
        match hid::parse(&descriptor[..length]) {
            Ok(layout) => self.choose_report_format(job, Ok(layout)),
            Err(lie) => {
                let location = job.location;
                self.hw.log(format_args!(
                    "usb: port {location}: report descriptor refused ({lie}); device left alone"
                ));
                Ok(Next::Done)
            }
        }
    }

    fn not_a_keyboard(&mut self, job: &Enumeration) -> Result<Next> {
        let location = job.location;
        self.hw.log(format_args!(
            "usb: port {location}: device {:04x}:{:04x} is a HID device without keys; left alone",
            job.vendor, job.product
        ));
        Ok(Next::Done)
    }

    /// How the reports are read, given the report descriptor (or why there
    /// is none); then the report endpoint is configured.
    fn choose_report_format(
        &mut self,
        job: &mut Enumeration,
        layout: core::result::Result<KeyboardLayout, Option<XhciError>>,
    ) -> Result<Next> {
        let index = Self::device_index(job)?;
        let location = job.location;
        let Some(set_up) = job.keyboard.as_ref() else {
            return Err(XhciError::Gone);
        };
        let (endpoint, boot) = (set_up.endpoint, set_up.boot);
        let format = match layout {
            Ok(layout) if layout.has_keys() => ReportFormat::Described(layout),
            Ok(_) => return self.not_a_keyboard(job),
            Err(why) if boot => {
                if let Some(e) = why {
                    self.hw.log(format_args!(
                        "usb: keyboard on port {location}: no report descriptor ({e}); boot protocol"
                    ));
                }
                ReportFormat::Boot
            }
            Err(_) => return self.not_a_keyboard(job),
        };
        let longest_report = match &format {
            ReportFormat::Boot => report::REPORT_BYTES,
            ReportFormat::Described(layout) => layout.longest_key_report(),
        };
        let ring_page = self.page()?;
        let reports = match self.page() {
            Ok(page) => page,
            Err(e) => {
                self.free_page(ring_page);
                return Err(e);
            }
        };
        let layout = self.capabilities.layout;
        let Some(device) = self.devices[index].as_mut() else {
            return Err(XhciError::Gone);
        };
        let dci = 2 * endpoint.number + 1;
        let ring = ProducerRing::new(ring_page, INTERRUPT_RING_TRBS);
        device.slot_context.context_entries = u32::from(dci);
        let (slot, input, speed_id, slot_context) =
            (device.slot, device.input, device.speed, device.slot_context);
        let max_packet = endpoint.max_packet.clamp(1, REPORT_BUFFER_BYTES as u16);
        // A transfer ends with a short packet or when its length is reached:
        // one packet's worth, unless a report needs more (then whole packets,
        // so that a report of exactly that length still ends it).
        let report_bytes = if longest_report <= usize::from(max_packet) {
            u32::from(max_packet)
        } else {
            (longest_report as u32).next_multiple_of(u32::from(max_packet))
        }
        .min(REPORT_BUFFER_BYTES as u32);
        layout.start_input(&mut self.hw, input, 1 | 1 << dci);
        layout.write_slot(&mut self.hw, input, &slot_context);
        layout.write_endpoint(
            &mut self.hw,
            input,
            dci,
            &EndpointContext {
                kind: endpoint_type::INTERRUPT_IN,
                max_packet,
                interval: interrupt_interval(speed_id, endpoint.interval).min(KEYBOARD_INTERVAL),
                dequeue: ring.dequeue_pointer(),
                average_trb_length: max_packet,
            },
        );
        if let Some(set_up) = job.keyboard.as_mut() {
            set_up.keyboard = Some(Keyboard {
                dci,
                ring,
                reports,
                report_bytes,
                format,
                keys_by_report: [(u8::MAX, KeySet::default()); KEY_REPORTS],
                state: BootKeyboard::new(),
                dropped: 0,
                recovery: Recovery::Running,
                failures_in_a_row: 0,
                failed: false,
            });
        }
        self.send_command(
            job,
            EnumerationStep::ConfiguringReportEndpoint,
            configure_endpoint(input, slot),
        )
    }

    fn keyboard_format(job: &Enumeration) -> Option<ReportFormat> {
        job.keyboard
            .as_ref()
            .and_then(|k| k.keyboard.as_ref())
            .map(|k| k.format)
    }

    fn configuring_report_endpoint(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
    ) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let (boot, interface) = job
            .keyboard
            .as_ref()
            .map(|k| (k.boot, k.interface))
            .ok_or(XhciError::Gone)?;
        // SET_PROTOCOL exists only on boot interfaces; the others are
        // always in the report protocol.
        if boot {
            let protocol = match Self::keyboard_format(job) {
                Some(ReportFormat::Described(_)) => PROTOCOL_REPORT,
                _ => PROTOCOL_BOOT,
            };
            return self.request(
                job,
                EnumerationStep::SettingProtocol,
                index,
                (0x21, HID_SET_PROTOCOL, protocol, u16::from(interface)),
            );
        }
        self.request(
            job,
            EnumerationStep::SettingIdle,
            index,
            (0x21, HID_SET_IDLE, 0, u16::from(interface)),
        )
    }

    fn setting_protocol(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        let location = job.location;
        match (done, Self::keyboard_format(job)) {
            (Ok(()), _) => {}
            // Reports are read by the descriptor whatever it answers.
            (Err(e), Some(ReportFormat::Described(_))) => self.hw.log(format_args!(
                "usb: keyboard on port {location}: SET_PROTOCOL refused ({e})"
            )),
            (Err(e), _) => return Err(e),
        }
        let index = Self::device_index(job)?;
        let interface = job.keyboard.as_ref().map_or(0, |k| k.interface);
        // Reports only when something changes; repeat is ours.
        self.request(
            job,
            EnumerationStep::SettingIdle,
            index,
            (0x21, HID_SET_IDLE, 0, u16::from(interface)),
        )
    }

    /// The last step of a keyboard: its reports start.
    fn setting_idle(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        let location = job.location;
        // Some keyboards refuse SET_IDLE; that costs nothing but reports.
        if let Err(e) = done {
            self.hw.log(format_args!(
                "usb: keyboard on port {location}: SET_IDLE refused ({e})"
            ));
        }
        let index = Self::device_index(job)?;
        let Some(mut keyboard) = job.keyboard.as_mut().and_then(|k| k.keyboard.take()) else {
            return Err(XhciError::Gone);
        };
        for _ in 0..QUEUED_REPORTS {
            queue_report(&mut self.hw, &mut keyboard);
        }
        let (dci, format) = (keyboard.dci, keyboard.format);
        let Some(device) = self.devices[index].as_mut() else {
            return Err(XhciError::Gone);
        };
        device.keyboard = Some(keyboard);
        let slot = device.slot;
        self.write(self.doorbells + 4 * u32::from(slot), u32::from(dci));
        match format {
            ReportFormat::Boot => self.hw.log(format_args!(
                "keyboard: USB keyboard, boot protocol, on port {location}"
            )),
            ReportFormat::Described(layout) => self.hw.log(format_args!(
                "keyboard: USB keyboard, read by its report descriptor ({} key fields, {}-byte reports{}), on port {location}",
                layout.fields().count(),
                layout.longest_key_report(),
                if layout.numbered { ", numbered" } else { "" }
            )),
        }
        Ok(Next::Done)
    }

    fn reading_hub_descriptor(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        let mut bytes = [0u8; 12];
        self.read_buffer(index, &mut bytes);
        let described = descriptor::hub(&bytes)?;
        // A route string has four bits a tier: ports past 15 cannot be reached.
        job.hub.ports = described.ports.min(15);
        if described.ports > 15 {
            let location = job.location;
            self.hw.log(format_args!(
                "usb: hub on port {location}: ports past 15 are not supported"
            ));
        }
        job.hub.power_good =
            (u64::from(described.power_on_to_good_2ms) * 2_000).clamp(20_000, 500_000);
        let configuration = job.configuration;
        self.request(
            job,
            EnumerationStep::ConfiguringHub,
            index,
            (0x00, SET_CONFIGURATION, u16::from(configuration), 0),
        )
    }

    /// The hub is configured; a SuperSpeed hub is told its depth (it
    /// picks its nibble of the route string by it), as Linux does.
    fn configuring_hub(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        if job.speed == speed::SUPER {
            let index = Self::device_index(job)?;
            let depth = job.location.depth() as u16;
            return self.request(
                job,
                EnumerationStep::SettingHubDepth,
                index,
                (0x20, SET_HUB_DEPTH, depth, 0),
            );
        }
        self.mark_hub(job)
    }

    fn setting_hub_depth(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        done?;
        self.mark_hub(job)
    }

    /// Tells the controller the slot is a hub (for its transaction
    /// translator) and adds the hub's status change endpoint.
    fn mark_hub(&mut self, job: &mut Enumeration) -> Result<Next> {
        let index = Self::device_index(job)?;
        let (ring_page, buffer) = (self.page()?, self.page()?);
        let layout = self.capabilities.layout;
        let Some(device) = self.devices[index].as_mut() else {
            return Err(XhciError::Gone);
        };
        let ports = job.hub.ports;
        let mut add = 1;
        let mut hub = Hub {
            ports,
            dci: 0,
            ring: ProducerRing::new(ring_page, INTERRUPT_RING_TRBS),
            buffer,
        };
        device.slot_context.hub = true;
        device.slot_context.hub_ports = ports;
        if let Some(endpoint) = job.hub.status_change {
            hub.dci = 2 * endpoint.number + 1;
            add |= 1 << hub.dci;
            device.slot_context.context_entries =
                device.slot_context.context_entries.max(u32::from(hub.dci));
        }
        let (slot, input, speed_id, slot_context) =
            (device.slot, device.input, device.speed, device.slot_context);
        layout.start_input(&mut self.hw, input, add);
        layout.write_slot(&mut self.hw, input, &slot_context);
        if let Some(endpoint) = job.hub.status_change {
            let max_packet = endpoint.max_packet.clamp(1, 8);
            layout.write_endpoint(
                &mut self.hw,
                input,
                hub.dci,
                &EndpointContext {
                    kind: endpoint_type::INTERRUPT_IN,
                    max_packet,
                    interval: interrupt_interval(speed_id, endpoint.interval),
                    dequeue: hub.ring.dequeue_pointer(),
                    average_trb_length: max_packet,
                },
            );
        }
        if let Some(device) = self.devices[index].as_mut() {
            device.hub = Some(hub);
        }
        self.send_command(
            job,
            EnumerationStep::MarkingHub,
            configure_endpoint(input, slot),
        )
    }

    fn marking_hub(&mut self, job: &mut Enumeration, done: Result<()>) -> Result<Next> {
        let index = Self::device_index(job)?;
        if let Err(e) = done {
            let location = job.location;
            self.hw.log(format_args!(
                "usb: hub on port {location}: not marked as a hub ({e}); devices plugged in later are not seen"
            ));
            if let Some(hub) = self.devices[index].as_mut().and_then(|d| d.hub.as_mut()) {
                hub.dci = 0;
            }
        }
        self.power_hub_port(job, 1)
    }

    fn power_hub_port(&mut self, job: &mut Enumeration, port: u8) -> Result<Next> {
        let index = Self::device_index(job)?;
        if port > job.hub.ports {
            let until = self.hw.now_micros() + job.hub.power_good + HUB_CONNECT_MICROS;
            return job.wait(EnumerationStep::WaitingForHubPower, until);
        }
        self.request(
            job,
            EnumerationStep::PoweringHubPort(port),
            index,
            (0x23, SET_FEATURE, HUB_PORT_POWER, u16::from(port)),
        )
    }

    fn powering_hub_port(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
        port: u8,
    ) -> Result<Next> {
        done?;
        self.power_hub_port(job, port + 1)
    }

    fn waiting_for_hub_power(&mut self, job: &mut Enumeration) -> Result<Next> {
        // Every port is looked at once.
        job.hub.to_examine = (((1u32 << (job.hub.ports + 1)) - 2) & 0xFFFF) as u16;
        self.examine_next_hub_port(job)
    }

    /// GET_STATUS of the next hub port to look at; when none is left, the
    /// hub's status change transfer is queued (again).
    fn examine_next_hub_port(&mut self, job: &mut Enumeration) -> Result<Next> {
        let index = Self::device_index(job)?;
        if job.hub.to_examine == 0 {
            self.queue_status_change(index);
            return Ok(Next::Done);
        }
        let port = job.hub.to_examine.trailing_zeros() as u8;
        job.hub.to_examine &= !(1 << port);
        let setup = Setup {
            request_type: 0xA3,
            request: GET_STATUS,
            value: 0,
            index: u16::from(port),
            length: 4,
        };
        self.send_control(
            job,
            EnumerationStep::ReadingHubPortStatus(port),
            index,
            setup,
        )
    }

    fn reading_hub_port_status(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
        port: u8,
    ) -> Result<Next> {
        done?;
        let index = Self::device_index(job)?;
        job.hub.port_status = self.read_port_status(index);
        self.clear_next_hub_port_change(job, port)
    }

    /// Clears the port's next change bit (one request a step); when none is
    /// left, acts on the port's status.
    fn clear_next_hub_port_change(&mut self, job: &mut Enumeration, port: u8) -> Result<Next> {
        let index = Self::device_index(job)?;
        let superspeed = self.devices[index]
            .as_ref()
            .is_some_and(|d| d.speed == speed::SUPER);
        let changes = if superspeed {
            HUB_PORT_CHANGES | SUPERSPEED_HUB_PORT_CHANGES
        } else {
            HUB_PORT_CHANGES
        };
        let pending = job.hub.port_status & changes;
        if pending != 0 {
            let bit = pending.trailing_zeros();
            job.hub.port_status &= !(1 << bit);
            job.hub.connection_changed |= 1 << bit == HUB_C_PORT_CONNECTION;
            // A change up to C_PORT_RESET is cleared by the feature of its
            // bit's number; SuperSpeed's later ones by their own.
            let feature = match bit {
                21 => 29, // C_BH_PORT_RESET
                22 => 25, // C_PORT_LINK_STATE
                23 => 26, // C_PORT_CONFIG_ERROR
                bit => bit as u16,
            };
            return self.request(
                job,
                EnumerationStep::ClearingHubPortChange(port),
                index,
                (0x23, CLEAR_FEATURE, feature, u16::from(port)),
            );
        }
        self.hub_port_examined(job, port)
    }

    fn clearing_hub_port_change(
        &mut self,
        job: &mut Enumeration,
        done: Result<()>,
        port: u8,
    ) -> Result<Next> {
        done?;
        self.clear_next_hub_port_change(job, port)
    }

    /// A hub port's status is known and its changes cleared: a device gone
    /// is let go of, a new one queued.
    fn hub_port_examined(&mut self, job: &mut Enumeration, port: u8) -> Result<Next> {
        let status = job.hub.port_status;
        let connection_changed = job.hub.connection_changed || !job.hub_changes_only;
        job.hub.connection_changed = false;
        let location = job.location.below(port);
        if connection_changed {
            // The poll hands the released keys on once the step is done.
            let mut released = [0u8; RELEASED_BYTES];
            let mut count = 0;
            self.release_under(location, &mut |byte| {
                if let Some(slot) = released.get_mut(count) {
                    *slot = byte;
                    count += 1;
                }
            });
            for &byte in &released[..count] {
                if let Some(slot) = self.released.get_mut(self.released_count) {
                    *slot = byte;
                    self.released_count += 1;
                }
            }
            if status & HUB_PORT_CONNECTION != 0 {
                if job.hub_changes_only {
                    self.hw
                        .log(format_args!("usb: port {location}: device plugged in"));
                }
                // Ports looked at right after the power-on wait have had
                // their connect time.
                self.queue_port(location, !job.hub_changes_only);
            }
        }
        self.examine_next_hub_port(job)
    }

    /// Queues one transfer on a hub's status change endpoint.
    pub(super) fn queue_status_change(&mut self, index: usize) {
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let slot = device.slot;
        let Some(hub) = device.hub.as_mut() else {
            return;
        };
        if hub.dci == 0 {
            return;
        }
        let mut normal = transfer::Normal::new();
        // One bit for the hub and one a port.
        let bytes = (u32::from(hub.ports) + 8) / 8;
        normal
            .set_data_buffer_pointer(hub.buffer)
            .set_trb_transfer_length(bytes)
            .set_interrupt_on_completion()
            .set_interrupt_on_short_packet();
        hub.ring.push(&mut self.hw, Trb(normal.into_raw()));
        let dci = hub.dci;
        self.write(self.doorbells + 4 * u32::from(slot), u32::from(dci));
    }

    /// The work is done: said, with what it took.
    fn finish(&mut self, job: Enumeration) {
        if job.hub_changes_only {
            return;
        }
        let took = self.hw.now_micros().saturating_sub(job.started);
        let location = job.location;
        self.hw.log(format_args!(
            "usb: port {location}: enumerated in {took} us, its longest step {} us",
            job.longest_step
        ));
    }

    /// A step failed or timed out: said; the device's slot disabled and its
    /// pages kept for the next; the next port's turn.
    fn fail(&mut self, job: Enumeration, e: XhciError) {
        let took = self.hw.now_micros().saturating_sub(job.started);
        let (location, step) = (job.location, job.step);
        self.hw.log(format_args!(
            "usb: port {location}: {e} while {step}; left alone after {took} us"
        ));
        if job.hub_changes_only {
            // The hub's port changes are looked at again on its next report.
            if let Some(index) = job.index {
                self.queue_status_change(index);
            }
            return;
        }
        if let Some(keyboard) = job.keyboard.and_then(|k| k.keyboard) {
            self.free_page(keyboard.ring.base());
            self.free_page(keyboard.reports);
        }
        match job.index {
            Some(index) => {
                self.free_pages_of(index);
                self.disable_slot(job.slot);
            }
            None if job.slot != 0 => self.disable_slot(job.slot),
            None => {}
        }
    }

    /// Queues Disable Slot (its completion is not waited for).
    pub(super) fn disable_slot(&mut self, slot: u8) {
        let mut disable = command::DisableSlot::new();
        disable.set_slot_id(slot);
        let _ = self.queue_command(Trb(disable.into_raw()));
    }

    /// Command Abort (CRCR's CA): the command the controller is stuck on is
    /// given up; its completion, should it come, matches no one's.
    fn abort_command(&mut self) {
        let crcr = self.operational + CRCR;
        self.write(crcr, CRCR_COMMAND_ABORT);
    }
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
