//! The controller-independent USB device layer (Linux's usbcore and
//! hub.c, as far as keyboards need them), over any [`HostController`]:
//!
//! - root ports and hub ports watched for devices plugged in and pulled
//!   out, a connection debounced before it is enumerated;
//! - enumeration a step per poll (`bus/enumeration.rs`): reset, address,
//!   descriptors, then a keyboard set up or a hub configured and its ports
//!   powered, to the five hub tiers USB allows, with the transaction
//!   translator a full- or low-speed device behind a high-speed hub needs;
//! - keyboards' reports read through their interrupt pipes, put back
//!   together from their packets where a report is longer than one, and
//!   turned into PS/2 set-1 bytes ([`crate::report`]: typematic repeat too), by the boot
//!   report or by the keyboard's own report descriptor ([`crate::hid`]);
//! - stalls and errors on interrupt pipes recovered, a device that keeps
//!   failing given up, every control transfer bounded by the clock.
//!
//! Nothing here waits: every wait is a deadline a later poll checks. An
//! idle poll costs one [`HostController::anything_happened`] call, and
//! the clock only while a key is held (for its repeat) or work is queued.

use crate::descriptor;
use crate::hid::{Decoded, KeySet, KeyboardLayout, MAX_REPORT_BYTES};
use crate::host::{
    ControllerKind, DeviceId, HostController, PipeId, Setup, Speed, TransactionTranslator,
    Transfer, MAX_CONTROL_DATA, MAX_REPORT,
};
use crate::report::{self, BootKeyboard};
use crate::Platform;
use core::fmt;

mod enumeration;
pub use enumeration::BOOT_ENUMERATION_MICROS;
use enumeration::{Job, WorkQueue};

#[cfg(test)]
mod tests;

/// Devices kept per controller (hubs included); one more is logged as
/// "no room" and its port disabled.
pub const MAX_DEVICES: usize = 32;
/// Hub tiers below the root hub (USB 2.0 4.1.1: five, with the root hub
/// and the device itself seven).
pub const MAX_HUB_TIERS: usize = 5;
/// A hub's ports this layer looks at (a port bitmap is 32 bits, bit 0
/// the hub itself); ports past it are left alone, logged.
pub const MAX_HUB_PORTS: u8 = 31;
/// Failed reports in a row after which an interrupt pipe is given up (a
/// device that fails every transfer is gone or broken; hot-plug finds it
/// again). The same bound as xHCI's.
pub const MAX_RECOVERIES: u32 = 8;
/// Report IDs whose keys are kept apart (a keyboard may split its keys
/// over several numbered reports; the keys down are the union).
const KEY_REPORTS: usize = 4;
/// Reports taken from one pipe in one poll; past it the next poll looks
/// again without waiting for [`HostController::anything_happened`].
const REPORTS_PER_POLL: u32 = 16;
/// How long a control transfer may take: Linux's `USB_CTRL_GET_TIMEOUT`
/// and `USB_CTRL_SET_TIMEOUT` (include/linux/usb.h, 5000 ms).
pub const TRANSFER_MICROS: u64 = 5_000_000;
/// Keyboards are polled every frame (1 ms), however slowly they ask to be
/// (a host may poll an interrupt endpoint more often than its bInterval,
/// USB 2.0 5.7.4), as the xHCI driver does: keys wait at most 1 ms.
const KEYBOARD_INTERVAL_FRAMES: u8 = 1;
/// A hub's status change endpoint is polled at least this often (frames),
/// so that a device plugged in is seen within 32 ms.
const HUB_INTERVAL_FRAMES: u8 = 32;

const GET_STATUS: u8 = 0;
const CLEAR_FEATURE: u8 = 1;
const SET_FEATURE: u8 = 3;
const GET_DESCRIPTOR: u8 = 6;
const SET_CONFIGURATION: u8 = 9;
const SET_INTERFACE: u8 = 11;
/// SET_HUB_DEPTH, a SuperSpeed hub's class request (USB 3.2 10.16.2.9).
const SET_HUB_DEPTH: u8 = 12;
const HID_SET_IDLE: u8 = 0x0A;
const HID_SET_PROTOCOL: u8 = 0x0B;
const PROTOCOL_BOOT: u16 = 0;
const PROTOCOL_REPORT: u16 = 1;
/// The standard feature selector of an endpoint's halt.
const ENDPOINT_HALT: u16 = 0;

/// Where a device hangs: a root port, and the hub port on each tier below.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Location {
    root_port: u8,
    hub_ports: [u8; MAX_HUB_TIERS],
    depth: u8,
}

impl Location {
    /// The device on root port `port` (1-based).
    pub const fn root(port: u8) -> Location {
        Location {
            root_port: port,
            hub_ports: [0; MAX_HUB_TIERS],
            depth: 0,
        }
    }

    /// The root port, 1-based.
    pub fn root_port(&self) -> u8 {
        self.root_port
    }

    /// The hub port on each tier below the root port, the first tier first.
    pub fn hub_ports(&self) -> &[u8] {
        &self.hub_ports[..usize::from(self.depth)]
    }

    /// The hub tiers between the root port and the device.
    pub fn depth(&self) -> usize {
        usize::from(self.depth)
    }

    /// Port `port` of the hub at this location (None past the five tiers).
    pub fn below(&self, port: u8) -> Option<Location> {
        let depth = self.depth();
        if depth >= MAX_HUB_TIERS {
            return None;
        }
        let mut below = *self;
        below.hub_ports[depth] = port;
        below.depth += 1;
        Some(below)
    }

    /// Whether `other` is this location or lies below it.
    pub fn holds(&self, other: Location) -> bool {
        other.root_port == self.root_port
            && other.depth >= self.depth
            && other.hub_ports[..self.depth()] == *self.hub_ports()
    }

    /// The hub this location's port belongs to (None on a root port).
    pub fn hub(&self) -> Option<Location> {
        let depth = self.depth().checked_sub(1)?;
        let mut hub = *self;
        hub.hub_ports[depth] = 0;
        hub.depth -= 1;
        Some(hub)
    }

    /// The port on its hub (the root port on the root hub).
    pub fn port(&self) -> u8 {
        match self.depth() {
            0 => self.root_port,
            depth => self.hub_ports[depth - 1],
        }
    }
}

impl fmt::Display for Location {
    /// `1` for root port 1, `1.3.2` for port 2 of the hub on port 3 of the
    /// hub on root port 1 (as the xHCI driver and Linux's bus IDs write it).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.root_port)?;
        for port in self.hub_ports() {
            write!(f, ".{port}")?;
        }
        Ok(())
    }
}

/// How a keyboard's reports are read.
// The layout lives in the keyboard itself: no allocator to box it in.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Copy, Debug)]
enum ReportFormat {
    /// The boot report, 8 bytes (the keyboard was put in the boot protocol
    /// because its report descriptor could not be read).
    Boot,
    /// As its report descriptor lays them out (report protocol).
    Described(KeyboardLayout),
}

/// Where an interrupt pipe stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PipeState {
    /// Reports are read.
    Running,
    /// Stalled: CLEAR_FEATURE(ENDPOINT_HALT) waits for the device's
    /// endpoint 0 (a hub's may be in use by the enumeration).
    HaltToClear,
    /// CLEAR_FEATURE(ENDPOINT_HALT) sent; the pipe restarts when it ends,
    /// or is given up at `until`.
    ClearingHalt { until: u64 },
    /// Failed past [`MAX_RECOVERIES`], or its recovery did: closed.
    GivenUp,
}

/// An interrupt-in pipe: a keyboard's reports, or a hub's port changes.
#[derive(Clone, Copy, Debug)]
struct Pipe {
    id: PipeId,
    endpoint: u8,
    state: PipeState,
    /// Failed transfers since the last good one.
    failures_in_a_row: u32,
}

impl Pipe {
    fn new(id: PipeId, endpoint: u8) -> Pipe {
        Pipe {
            id,
            endpoint,
            state: PipeState::Running,
            failures_in_a_row: 0,
        }
    }
}

/// A keyboard's report put back together from its interrupt packets: an
/// N-key-rollover report of 16 to 32 bytes comes in 8-byte packets, one
/// per poll on every controller. A report ends when its length (by the
/// report descriptor) has come, or with a short packet (USB 2.0 5.7.3).
#[derive(Clone, Copy, Debug)]
struct Packets {
    /// The endpoint's packet size: a packet shorter than it ends a report.
    max_packet: u16,
    bytes: [u8; MAX_REPORT_BYTES],
    /// Bytes of the report under way so far (past `bytes` too: counted,
    /// not kept).
    received: usize,
    /// The length the report under way has.
    expected: usize,
}

/// What one packet made of the report under way.
enum Assembled {
    /// More packets to come.
    Pending,
    /// A whole report, its first bytes in [`Packets::bytes`].
    Report(usize),
    /// A report longer than [`MAX_REPORT_BYTES`], dropped.
    TooLong(usize),
}

impl Packets {
    fn new(max_packet: u16) -> Packets {
        Packets {
            max_packet,
            bytes: [0; MAX_REPORT_BYTES],
            received: 0,
            expected: 0,
        }
    }

    /// Takes one packet of a keyboard's reports in `format`.
    fn take(&mut self, packet: &[u8], format: &ReportFormat) -> Assembled {
        if self.received == 0 {
            let Some(&first) = packet.first() else {
                // A zero-length packet between reports ends one that
                // filled whole packets: nothing in it.
                return Assembled::Pending;
            };
            self.expected = match format {
                ReportFormat::Boot => report::REPORT_BYTES,
                ReportFormat::Described(layout) => layout.report_length(first),
            };
        }
        let start = self.received;
        self.received += packet.len();
        if let Some(room) = self.bytes.get_mut(start..self.received) {
            room.copy_from_slice(packet);
        }
        if self.received < self.expected && packet.len() >= usize::from(self.max_packet) {
            return Assembled::Pending;
        }
        let length = core::mem::take(&mut self.received);
        if length > MAX_REPORT_BYTES {
            Assembled::TooLong(length)
        } else {
            Assembled::Report(length)
        }
    }
}

/// A configured keyboard.
#[derive(Clone, Debug)]
struct Keyboard {
    pipe: Pipe,
    format: ReportFormat,
    /// The report under way.
    packets: Packets,
    /// The keys each report ID last said are down (`u8::MAX`: unused).
    keys_by_report: [(u8, KeySet); KEY_REPORTS],
    state: BootKeyboard,
    /// Reports that could not be read, dropped.
    dropped: u32,
}

impl Keyboard {
    /// Takes one report: gives the keys now down, or why it changes nothing.
    fn keys(&mut self, report: &[u8]) -> Result<KeySet, Decoded> {
        match &self.format {
            ReportFormat::Boot if report.len() >= report::REPORT_BYTES => {
                report::boot_report_keys(report).ok_or(Decoded::Rollover)
            }
            ReportFormat::Boot => Err(Decoded::Unreadable),
            ReportFormat::Described(layout) => match layout.decode(report) {
                Decoded::Keys { report_id, keys } => {
                    let slot = self
                        .keys_by_report
                        .iter()
                        .position(|&(id, _)| id == report_id)
                        .or_else(|| {
                            self.keys_by_report
                                .iter()
                                .position(|&(id, _)| id == u8::MAX)
                        })
                        .ok_or(Decoded::Unreadable)?;
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

    /// Lets go of every key (breaks for those held) and forgets them.
    fn release_all(&mut self, out: &mut impl FnMut(u8)) {
        self.state.release_all(out);
        // A report cut short by a failure is not finished by the next one.
        self.packets.received = 0;
        self.keys_by_report = [(u8::MAX, KeySet::default()); KEY_REPORTS];
    }
}

/// A configured hub.
#[derive(Clone, Copy, Debug)]
struct Hub {
    /// Downstream ports looked at.
    ports: u8,
    /// Its status change endpoint (None: ports changed later are not seen).
    pipe: Option<Pipe>,
}

/// What a device turned out to be.
// As with ReportFormat: no allocator.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
enum Role {
    /// Being enumerated.
    Enumerating,
    /// Neither a keyboard nor a hub (or one refused): kept addressed, unused.
    Other,
    /// A hub.
    Hub(Hub),
    /// A keyboard.
    Keyboard(Keyboard),
}

/// A device the controller has a handle for.
#[derive(Clone, Debug)]
struct Device {
    id: DeviceId,
    location: Location,
    speed: Speed,
    /// Its USB address (0 until SET_ADDRESS completed).
    address: u8,
    /// The transaction translator it is reached through.
    translator: Option<TransactionTranslator>,
    role: Role,
}

impl Device {
    fn pipe_mut(&mut self) -> Option<&mut Pipe> {
        match &mut self.role {
            Role::Keyboard(keyboard) => Some(&mut keyboard.pipe),
            Role::Hub(Hub {
                pipe: Some(pipe), ..
            }) => Some(pipe),
            _ => None,
        }
    }
}

/// USB addresses 1-127, given out and taken back.
#[derive(Clone, Copy, Debug, Default)]
struct Addresses(u128);

impl Addresses {
    /// The lowest free address.
    fn take(&mut self) -> Option<u8> {
        let free = (1..=127u8).find(|&a| self.0 & (1 << a) == 0)?;
        self.0 |= 1 << free;
        Some(free)
    }

    fn free(&mut self, address: u8) {
        if (1..=127).contains(&address) {
            self.0 &= !(1u128 << address);
        }
    }

    fn in_use(&self) -> u32 {
        self.0.count_ones()
    }
}

/// The device layer over one host controller.
#[derive(Debug)]
pub struct Bus<C: HostController> {
    controller: C,
    kind: ControllerKind,
    /// Every root port the controller has (xHCI's MaxPorts: up to 255,
    /// chipsets' 20 to 30 with USB 2 ports often past 15); nothing is
    /// kept per port, so none is left out.
    root_ports: u8,
    devices: [Option<Device>; MAX_DEVICES],
    addresses: Addresses,
    /// Ports and hubs waiting for their turn to be enumerated.
    queue: WorkQueue,
    /// The enumeration in progress, a step per poll.
    job: Option<Job>,
    /// When the root ports are first looked at.
    scan_at: Option<u64>,
    /// The data stage of the job's control transfer.
    buffer: [u8; MAX_CONTROL_DATA],
    /// Bit n: device n's keyboard holds a key (its repeat needs the clock).
    holding: u32,
    /// Bit n: device n's pipe waits for, or runs, a halt's clearing.
    recovering: u32,
    /// A pipe had more reports than one poll takes.
    more_reports: bool,
    /// [`Bus::shut_down`] ran: the controller is not touched again.
    stopped: bool,
}

impl<C: HostController> Bus<C> {
    /// The device layer over `controller`, which has been reset and
    /// started; nothing is touched until [`Bus::enumerate`] or [`Bus::poll`].
    pub fn new(controller: C) -> Bus<C> {
        let kind = controller.kind();
        let root_ports = controller.root_ports();
        Bus {
            controller,
            kind,
            root_ports,
            devices: [const { None }; MAX_DEVICES],
            addresses: Addresses::default(),
            queue: WorkQueue::default(),
            job: None,
            scan_at: None,
            buffer: [0; MAX_CONTROL_DATA],
            holding: 0,
            recovering: 0,
            more_reports: false,
            stopped: false,
        }
    }

    /// Which kind of controller the bus is on (for the log and the facts
    /// record, beside [`Bus::keyboards`]).
    pub fn kind(&self) -> ControllerKind {
        self.kind
    }

    /// The controller, for the caller's checks and for its driver's own calls.
    pub fn controller(&mut self) -> &mut C {
        &mut self.controller
    }

    /// Boot enumeration: the root ports are looked at once devices have had
    /// time to connect, and [`Bus::poll`] runs until nothing is left to
    /// enumerate or [`BOOT_ENUMERATION_MICROS`] pass by the controller's
    /// clock (keys pressed meanwhile are dropped: nobody listens yet);
    /// what is left carries on from later polls. Gives the keyboards found.
    pub fn enumerate(&mut self) -> usize {
        let start = self.now_micros();
        self.scan_at = Some(start + enumeration::CONNECT_MICROS);
        while !self.enumeration_idle() && !self.stopped {
            if self.now_micros().saturating_sub(start) >= BOOT_ENUMERATION_MICROS {
                match self.job.as_ref().map(|job| (job.location, job.step)) {
                    Some((location, step)) => self.say(format_args!(
                        "boot enumeration cut short after {} ms, port {location} still {step}; it carries on from the frame loop",
                        BOOT_ENUMERATION_MICROS / 1_000
                    )),
                    None => self.say(format_args!(
                        "boot enumeration cut short after {} ms; the ports queued carry on from the frame loop",
                        BOOT_ENUMERATION_MICROS / 1_000
                    )),
                }
                break;
            }
            self.poll(&mut |_| {});
        }
        self.keyboards().count()
    }

    /// Starts enumerating as [`Self::enumerate`] does, leaving every step
    /// to the polls that follow (the host tests' frame-by-frame view).
    #[cfg(test)]
    pub(crate) fn start_enumeration(&mut self) {
        self.scan_at = Some(self.now_micros() + enumeration::CONNECT_MICROS);
    }

    /// Whether nothing is being enumerated or waits to be.
    pub fn enumeration_idle(&self) -> bool {
        self.scan_at.is_none() && self.job.is_none() && self.queue.is_empty()
    }

    /// One step: `out` gets PS/2 set-1 bytes for the keyboards' reports
    /// and repeats; root and hub ports' changes are taken, and at most one
    /// enumeration step runs. When the controller says nothing happened,
    /// nothing is enumerated and no key is held, that one question is all
    /// it costs.
    pub fn poll(&mut self, out: &mut impl FnMut(u8)) {
        if self.stopped {
            return;
        }
        let happened = self.controller.anything_happened();
        let busy = !self.enumeration_idle() || self.recovering != 0 || self.more_reports;
        if !happened && !busy && self.holding == 0 {
            return;
        }
        if happened || self.more_reports {
            self.more_reports = false;
            self.root_ports_changed(out);
            self.read_pipes(out);
        }
        if self.recovering != 0 {
            self.recover_pipes();
        }
        if !self.enumeration_idle() {
            self.advance_enumeration(out);
        }
        if self.holding != 0 {
            let now = self.now_micros();
            for device in self.devices.iter_mut().flatten() {
                if let Role::Keyboard(keyboard) = &mut device.role {
                    keyboard.state.tick(now, out);
                }
            }
        }
    }

    /// The keyboards working, by where they hang.
    pub fn keyboards(&self) -> impl Iterator<Item = Location> + '_ {
        self.devices
            .iter()
            .flatten()
            .filter(|d| matches!(&d.role, Role::Keyboard(k) if k.pipe.state != PipeState::GivenUp))
            .map(|d| d.location)
    }

    /// Reports dropped because they could not be read, over all keyboards.
    pub fn dropped_reports(&self) -> u32 {
        self.devices
            .iter()
            .flatten()
            .filter_map(|d| match &d.role {
                Role::Keyboard(k) => Some(k.dropped),
                _ => None,
            })
            .fold(0, u32::saturating_add)
    }

    /// The devices kept (hubs, keyboards, others, and one being enumerated).
    pub fn devices(&self) -> usize {
        self.devices.iter().flatten().count()
    }

    /// USB addresses given out.
    pub fn addresses_in_use(&self) -> u32 {
        self.addresses.in_use()
    }

    /// Halts the controller before power-off or reset
    /// ([`HostController::halt`]: bounded, shared ports handed back). The
    /// device layer forgets everything and touches the controller no more.
    /// Says whether it halted.
    pub fn shut_down(&mut self) -> bool {
        self.stopped = true;
        self.job = None;
        self.queue = WorkQueue::default();
        self.scan_at = None;
        self.devices = [const { None }; MAX_DEVICES];
        self.addresses = Addresses::default();
        self.holding = 0;
        self.recovering = 0;
        self.controller.halt()
    }

    /// The platform's clock, which bounds every wait.
    fn now_micros(&mut self) -> u64 {
        self.controller.hardware().now_micros()
    }

    /// Says something on the log, naming the controller.
    fn say(&mut self, message: fmt::Arguments<'_>) {
        let kind = self.kind;
        self.controller
            .hardware()
            .log(format_args!("usb: {kind}: {message}"));
    }

    /// Says something about the device or port at `location`.
    fn say_at(&mut self, location: Location, message: fmt::Arguments<'_>) {
        let kind = self.kind;
        self.controller
            .hardware()
            .log(format_args!("usb: {kind} port {location}: {message}"));
    }

    /// Every root port whose connection changed: a device pulled out (or
    /// switched away by a KVM) is let go of with everything behind it; a
    /// device plugged in is enumerated once its connection has settled.
    fn root_ports_changed(&mut self, out: &mut impl FnMut(u8)) {
        for port in 1..=self.root_ports {
            let status = self.controller.port_status(port);
            // A companion's port is its business; a port in reset, the
            // reset's, while the device is still there.
            if !status.connect_changed
                || status.companion_owned
                || (status.connected && self.root_port_in_reset(port))
            {
                continue;
            }
            self.controller.clear_port_change(port);
            self.port_changed(Location::root(port), status.connected, out);
        }
    }

    /// Reads every running interrupt pipe: keyboards' reports become
    /// scancodes, hubs' port changes are queued; a stall or an error
    /// starts the pipe's recovery.
    fn read_pipes(&mut self, out: &mut impl FnMut(u8)) {
        let mut report = [0u8; MAX_REPORT];
        for index in 0..MAX_DEVICES {
            let mut taken = 0;
            while let Some(id) = self.running_pipe(index) {
                if taken == REPORTS_PER_POLL {
                    self.more_reports = true;
                    break;
                }
                taken += 1;
                match self.controller.interrupt_poll(id, &mut report) {
                    Transfer::Pending => break,
                    Transfer::Complete(length) => {
                        let length = length.min(report.len());
                        self.pipe_report(index, &report[..length], out);
                    }
                    Transfer::Stalled => {
                        self.pipe_failed(index, None, out);
                        break;
                    }
                    Transfer::Failed(e) => {
                        self.pipe_failed(index, Some(e), out);
                        break;
                    }
                }
            }
        }
    }

    /// Device `index`'s interrupt pipe, if it is running.
    fn running_pipe(&mut self, index: usize) -> Option<PipeId> {
        let pipe = self.devices[index].as_mut()?.pipe_mut()?;
        (pipe.state == PipeState::Running).then_some(pipe.id)
    }

    /// A report came on device `index`'s pipe.
    fn pipe_report(&mut self, index: usize, report: &[u8], out: &mut impl FnMut(u8)) {
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let location = device.location;
        match &mut device.role {
            Role::Keyboard(keyboard) => {
                keyboard.pipe.failures_in_a_row = 0;
                let mut whole = [0u8; MAX_REPORT_BYTES];
                let report = match keyboard.packets.take(report, &keyboard.format) {
                    Assembled::Pending => return,
                    Assembled::Report(length) => {
                        whole[..length].copy_from_slice(&keyboard.packets.bytes[..length]);
                        &whole[..length]
                    }
                    Assembled::TooLong(length) => {
                        keyboard.dropped = keyboard.dropped.saturating_add(1);
                        self.say_at(
                            location,
                            format_args!(
                                "keyboard: a report of {length} bytes dropped (at most {MAX_REPORT_BYTES} are kept)"
                            ),
                        );
                        return;
                    }
                };
                match keyboard.keys(report) {
                    Ok(keys) => {
                        let now = self.controller.hardware().now_micros();
                        keyboard.state.keys(&keys, now, out);
                        // Its repeat needs the clock while anything is down.
                        if keys == KeySet::default() {
                            self.holding &= !(1 << index);
                        } else {
                            self.holding |= 1 << index;
                        }
                    }
                    Err(Decoded::Unreadable) => {
                        keyboard.dropped = keyboard.dropped.saturating_add(1);
                        let dropped = keyboard.dropped;
                        // The first says what happened; a count says how often.
                        if dropped.is_power_of_two() {
                            self.say_at(
                                location,
                                format_args!(
                                    "keyboard: {dropped} unreadable reports dropped (the last {} bytes)",
                                    report.len()
                                ),
                            );
                        }
                    }
                    Err(_) => {} // rollover, or a report without keys
                }
            }
            Role::Hub(hub) => {
                if let Some(pipe) = hub.pipe.as_mut() {
                    pipe.failures_in_a_row = 0;
                }
                // Bit n: port n changed; bit 0: the hub itself.
                let mut changed = 0u32;
                for (byte, &bits) in report.iter().take(4).enumerate() {
                    changed |= u32::from(bits) << (8 * byte);
                }
                let ports = hub.ports;
                changed &= ((1u64 << (u32::from(ports) + 1)) - 1) as u32;
                if changed != 0 {
                    self.queue_hub_changes(index, changed);
                }
            }
            _ => {}
        }
    }

    /// Device `index`'s pipe stalled (`error` None) or failed: its keys
    /// are let go (their releases may be lost), and it is started again
    /// (after a stall, once the halt is cleared on the device too), or
    /// given up after [`MAX_RECOVERIES`] in a row.
    fn pipe_failed(
        &mut self,
        index: usize,
        error: Option<crate::host::TransferError>,
        out: &mut impl FnMut(u8),
    ) {
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let location = device.location;
        let what = match &mut device.role {
            Role::Keyboard(keyboard) => {
                keyboard.release_all(out);
                "keyboard"
            }
            _ => "hub",
        };
        self.holding &= !(1 << index);
        let Some(pipe) = device.pipe_mut() else {
            return;
        };
        pipe.failures_in_a_row += 1;
        let id = pipe.id;
        if pipe.failures_in_a_row > MAX_RECOVERIES {
            match error {
                Some(e) => self.give_up(index, format_args!("{e}")),
                None => self.give_up(index, format_args!("stalled")),
            }
            return;
        }
        match error {
            None => {
                pipe.state = PipeState::HaltToClear;
                self.recovering |= 1 << index;
                self.say_at(
                    location,
                    format_args!("{what}: interrupt endpoint stalled; clearing the halt"),
                );
            }
            Some(e) => {
                let failures = pipe.failures_in_a_row;
                if failures == 1 {
                    self.say_at(
                        location,
                        format_args!("{what}: report failed ({e}); recovering"),
                    );
                }
                if let Err(e) = self.controller.interrupt_restart(id, false) {
                    self.give_up(index, format_args!("restart refused: {e}"));
                }
            }
        }
    }

    /// Runs the halt clearings due: a pipe whose device's endpoint 0 is
    /// free gets its CLEAR_FEATURE(ENDPOINT_HALT); one that ended restarts
    /// its pipe with the data toggle reset (the device reset its own).
    fn recover_pipes(&mut self) {
        let now = self.now_micros();
        for index in 0..MAX_DEVICES {
            if self.recovering & (1 << index) == 0 {
                continue;
            }
            let in_use = self.job.as_ref().is_some_and(|job| job.uses(index));
            let Some(device) = self.devices[index].as_mut() else {
                self.recovering &= !(1 << index);
                continue;
            };
            let id = device.id;
            let Some(pipe) = device.pipe_mut() else {
                self.recovering &= !(1 << index);
                continue;
            };
            match pipe.state {
                PipeState::HaltToClear if !in_use => {
                    let setup = Setup {
                        request_type: 0x02,
                        request: CLEAR_FEATURE,
                        value: ENDPOINT_HALT,
                        index: u16::from(0x80 | pipe.endpoint),
                        length: 0,
                    };
                    pipe.state = PipeState::ClearingHalt {
                        until: now + TRANSFER_MICROS,
                    };
                    if let Err(e) = self.controller.control_begin(id, setup, &[]) {
                        self.give_up(index, format_args!("CLEAR_FEATURE refused: {e}"));
                    }
                }
                PipeState::ClearingHalt { until } => {
                    let pipe_id = pipe.id;
                    match self.controller.control_poll(id, &mut []) {
                        Transfer::Pending if now < until => {}
                        Transfer::Pending => {
                            self.controller.control_cancel(id);
                            self.give_up(index, format_args!("CLEAR_FEATURE timed out"));
                        }
                        Transfer::Complete(_) => {
                            self.recovering &= !(1 << index);
                            if let Some(pipe) =
                                self.devices[index].as_mut().and_then(Device::pipe_mut)
                            {
                                pipe.state = PipeState::Running;
                            }
                            match self.controller.interrupt_restart(pipe_id, true) {
                                Ok(()) => {
                                    let location = self.devices[index]
                                        .as_ref()
                                        .map_or(Location::root(0), |d| d.location);
                                    self.say_at(location, format_args!("halt cleared; recovered"));
                                }
                                Err(e) => self.give_up(index, format_args!("restart refused: {e}")),
                            }
                        }
                        Transfer::Stalled => {
                            self.give_up(index, format_args!("CLEAR_FEATURE stalled"))
                        }
                        Transfer::Failed(e) => {
                            self.give_up(index, format_args!("CLEAR_FEATURE failed: {e}"))
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// Device `index`'s pipe failed past recovery: closed, its keys let go
    /// (already), said.
    fn give_up(&mut self, index: usize, why: fmt::Arguments<'_>) {
        self.recovering &= !(1 << index);
        self.holding &= !(1 << index);
        let Some(device) = self.devices[index].as_mut() else {
            return;
        };
        let location = device.location;
        let is_keyboard = matches!(device.role, Role::Keyboard(_));
        let Some(pipe) = device.pipe_mut() else {
            return;
        };
        if pipe.state == PipeState::GivenUp {
            return;
        }
        pipe.state = PipeState::GivenUp;
        let id = pipe.id;
        self.controller.interrupt_close(id);
        if is_keyboard {
            self.say_at(
                location,
                format_args!("keyboard not recovered ({why}); keyboard given up"),
            );
        } else {
            self.say_at(
                location,
                format_args!(
                    "hub's status change endpoint not recovered ({why}); its ports are no longer watched"
                ),
            );
        }
    }

    /// The devices at `location` and below are gone: their held keys
    /// released, their pipes closed, their handles and addresses given
    /// back, and the work queued or running for them dropped.
    fn release_under(&mut self, location: Location, out: &mut impl FnMut(u8)) {
        let mut gone = 0u32;
        for (index, device) in self.devices.iter().enumerate() {
            if device.as_ref().is_some_and(|d| location.holds(d.location)) {
                gone |= 1 << index;
            }
        }
        // The job first: its control transfer is cancelled while its
        // device still has a handle.
        self.forget_work_under(location, gone);
        for index in 0..MAX_DEVICES {
            if gone & (1 << index) == 0 {
                continue;
            }
            let Some(device) = self.devices[index].as_mut() else {
                continue;
            };
            let at = device.location;
            let what = match &mut device.role {
                Role::Keyboard(keyboard) => {
                    keyboard.release_all(out);
                    "keyboard gone; its keys released"
                }
                Role::Hub(_) => "hub gone",
                _ => "device gone",
            };
            self.remove_device(index);
            self.say_at(at, format_args!("{what}"));
        }
    }

    /// The device at `location`, by its place in the table.
    fn device_at(&self, location: Location) -> Option<usize> {
        self.devices
            .iter()
            .position(|d| d.as_ref().is_some_and(|d| d.location == location))
    }
}
