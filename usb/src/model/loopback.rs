//! A host controller that is no controller: [`HostController`] implemented
//! straight on the device tree ([`UsbTree`]), a transaction at a time, with
//! a simulated clock, for the device layer's tests ([`crate::bus`]). It
//! does what every driver must: control transfers as SETUP, data and
//! status stages with their data toggles; interrupt pipes that keep their
//! toggle and drop a repeated packet; three errors in a row before a
//! transfer fails; split transactions through the translator a device was
//! made with; an EHCI-like hand-over of full- and low-speed root devices.
//! It checks what the device layer asks of it (the reset's 50 ms, handles
//! it gave, one control transfer per device at a time) and writes every
//! breach into [`Loopback::errors`].

use super::devices::{Packet, Pid, Reply, Split, UsbTree};
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, Setup, Speed, Transfer, TransferError, MAX_CONTROL_DATA, MAX_REPORT,
    ROOT_RESET_MICROS,
};
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// Model time each clock read takes, so that a loop that polls the clock
/// ends.
pub const MICROS_PER_CLOCK_READ: u64 = 10;
/// Devices the loopback's own table keeps (as a driver's pool would).
pub const LOOPBACK_DEVICES: usize = 40;
/// Errors in a row before a transfer fails (the controllers' CERR of 3).
const ERRORS_BEFORE_FAILING: u32 = 3;

/// A root port.
#[derive(Clone, Copy, Debug, Default)]
struct RootPort {
    /// Whether a device was attached when last looked at.
    connected: bool,
    enabled: bool,
    connect_changed: bool,
    companion_owned: bool,
    /// When a reset began.
    reset_began: Option<u64>,
}

/// Where a control transfer stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Setup,
    /// The data stage: bytes moved so far, and the next toggle.
    Data {
        done: usize,
        toggle: bool,
    },
    Status,
}

#[derive(Clone, Debug)]
struct Control {
    setup: Setup,
    out: Vec<u8>,
    stage: Stage,
    received: Vec<u8>,
    errors: u32,
    /// The test stalls this request at its SETUP.
    stall: bool,
    /// Ended (its bytes kept for the copy): another may begin.
    finished: bool,
}

#[derive(Clone, Debug)]
struct Device {
    info: DeviceInfo,
    address: u8,
    max_packet: u16,
    control: Option<Control>,
    /// When a SET_ADDRESS to it completed, and the address it gave.
    set_address: Option<(u64, u8)>,
    hub: Option<(u8, bool)>,
}

#[derive(Clone, Debug)]
struct Pipe {
    device: usize,
    endpoint: u8,
    max_packet: u16,
    /// The toggle the next packet must have.
    toggle: bool,
    errors: u32,
    /// Stalled or failed: waits for a restart.
    halted: bool,
    /// A transfer done in the background, waiting for `interrupt_poll`.
    done: Option<(Transfer, Vec<u8>)>,
}

/// The loopback controller.
#[derive(Debug)]
pub struct Loopback {
    /// The devices.
    pub tree: UsbTree,
    /// The kind it says it is (EHCI: full- and low-speed root devices go
    /// to the companion).
    pub kind: ControllerKind,
    /// The simulated clock, in microseconds.
    pub now: u64,
    /// Every log line.
    pub log: Vec<String>,
    /// What the device layer did wrong.
    pub errors: Vec<String>,
    /// Every trait call by name, in order (tests clear it).
    pub calls: Vec<&'static str>,
    /// Control transfers never end (a wedged controller).
    pub wedged: bool,
    /// Control requests (bmRequestType, bRequest) answered with a stall
    /// without reaching the device.
    pub stall_requests: Vec<(u8, u8)>,
    /// The next this many interrupt INs get no answer (CRC errors on the
    /// wire), whatever device they go to.
    pub interrupt_errors: u32,
    /// Transactions sent through each root port (index 0: port 1).
    pub transactions: Vec<u32>,
    /// Whether `halt` was called.
    pub halted: bool,
    ports: Vec<RootPort>,
    devices: Vec<Option<Device>>,
    pipes: Vec<Option<Pipe>>,
    /// Something finished or changed since `anything_happened` last said.
    happened: bool,
}

impl Loopback {
    /// A loopback of `kind` with `root_ports` empty root ports.
    pub fn new(kind: ControllerKind, root_ports: u8) -> Loopback {
        Loopback {
            tree: UsbTree::new(root_ports),
            kind,
            now: 0,
            log: Vec::new(),
            errors: Vec::new(),
            calls: Vec::new(),
            wedged: false,
            stall_requests: Vec::new(),
            interrupt_errors: 0,
            transactions: vec![0; usize::from(root_ports)],
            halted: false,
            ports: vec![RootPort::default(); usize::from(root_ports)],
            devices: vec![None; LOOPBACK_DEVICES],
            pipes: vec![None; LOOPBACK_DEVICES],
            happened: false,
        }
    }

    /// Devices with a handle.
    pub fn devices_open(&self) -> usize {
        self.devices.iter().flatten().count()
    }

    /// Whether root port `port` is enabled.
    pub fn port_enabled(&self, port: u8) -> bool {
        usize::from(port)
            .checked_sub(1)
            .and_then(|i| self.ports.get(i))
            .is_some_and(|p| p.enabled)
    }

    /// Interrupt pipes open.
    pub fn pipes_open(&self) -> usize {
        self.pipes.iter().flatten().count()
    }

    /// The transaction translator each device was made with, by its address.
    pub fn translators(&self) -> Vec<(u8, Option<crate::host::TransactionTranslator>)> {
        self.devices
            .iter()
            .flatten()
            .map(|d| (d.address, d.info.translator))
            .collect()
    }

    /// The hubs the layer marked: (address, ports, multi_tt).
    pub fn hubs(&self) -> Vec<(u8, u8, bool)> {
        self.devices
            .iter()
            .flatten()
            .filter_map(|d| d.hub.map(|(ports, multi)| (d.address, ports, multi)))
            .collect()
    }

    fn error(&mut self, what: String) {
        self.errors.push(what);
    }

    fn port(&mut self, port: u8) -> Option<&mut RootPort> {
        usize::from(port)
            .checked_sub(1)
            .and_then(|i| self.ports.get_mut(i))
    }

    /// Whether a root port's reset has begun and not been polled to its end.
    pub fn resetting(&self, port: u8) -> bool {
        self.ports
            .get(usize::from(port).wrapping_sub(1))
            .is_some_and(|state| state.reset_began.is_some())
    }

    /// Looks at the tree: a device attached or gone sets the change.
    fn refresh_port(&mut self, port: u8) {
        let connected = self.tree.root_device(port).is_some();
        let Some(state) = self.port(port) else {
            return;
        };
        if connected != state.connected {
            state.connected = connected;
            state.connect_changed = true;
            if !connected {
                state.enabled = false;
                state.companion_owned = false;
            }
            self.happened = true;
        }
    }

    fn device_index(&self, device: DeviceId) -> Option<usize> {
        let index = usize::from(device.0);
        self.devices.get(index)?.as_ref()?;
        Some(index)
    }

    /// One transaction through the device's root port, as a split when
    /// the device has a translator.
    fn transact(&mut self, index: usize, packet: Packet) -> Reply {
        let Some(device) = self.devices[index].as_ref() else {
            return Reply::Timeout;
        };
        let port = device.info.root_port;
        let split = device.info.translator.map(|tt| Split {
            hub_address: tt.hub_address,
            hub_port: tt.hub_port,
        });
        if let Some(count) = usize::from(port)
            .checked_sub(1)
            .and_then(|i| self.transactions.get_mut(i))
        {
            *count += 1;
        }
        let enabled = self.port(port).is_some_and(|p| p.enabled);
        if !enabled {
            return Reply::Timeout;
        }
        self.tree.transact(port, &packet, split)
    }

    fn packet(&self, index: usize, pid: Pid, endpoint: u8, toggle: bool, data: Vec<u8>) -> Packet {
        let device = self.devices[index].as_ref();
        Packet {
            address: device.map_or(0, |d| d.address),
            endpoint,
            pid,
            toggle,
            data,
            max_packet: device.map_or(8, |d| usize::from(d.max_packet)),
            speed: device.map_or(Speed::Full, |d| d.info.speed),
        }
    }

    /// Runs device `index`'s control transfer as far as it goes now.
    fn run_control(&mut self, index: usize) -> Transfer {
        let Some(mut control) = self.devices[index].as_mut().and_then(|d| d.control.take()) else {
            return Transfer::Failed(TransferError::Controller);
        };
        let result = loop {
            let setup = control.setup;
            let length = usize::from(setup.length);
            let (packet, stage) = match control.stage {
                Stage::Setup => (
                    self.packet(index, Pid::Setup, 0, false, setup.bytes().to_vec()),
                    control.stage,
                ),
                Stage::Data { done, toggle } if setup.is_in() => (
                    self.packet(index, Pid::In, 0, toggle, Vec::new()),
                    Stage::Data { done, toggle },
                ),
                Stage::Data { done, toggle } => {
                    let max = self.devices[index]
                        .as_ref()
                        .map_or(8, |d| usize::from(d.max_packet));
                    let end = (done + max).min(length);
                    let data = control.out[done..end].to_vec();
                    (
                        self.packet(index, Pid::Out, 0, toggle, data),
                        Stage::Data { done, toggle },
                    )
                }
                // The status stage goes the other way from the data (IN if none).
                Stage::Status if setup.is_in() && length > 0 => (
                    self.packet(index, Pid::Out, 0, true, Vec::new()),
                    control.stage,
                ),
                Stage::Status => (
                    self.packet(index, Pid::In, 0, true, Vec::new()),
                    control.stage,
                ),
            };
            let max_packet = packet.max_packet;
            let pid = packet.pid;
            let reply = self.transact(index, packet);
            match reply {
                Reply::Stall => break Transfer::Stalled,
                Reply::Nak => {
                    // Tried again at the next poll, as a controller would.
                    if let Some(device) = self.devices[index].as_mut() {
                        device.control = Some(control);
                    }
                    return Transfer::Pending;
                }
                Reply::Timeout => {
                    control.errors += 1;
                    if control.errors >= ERRORS_BEFORE_FAILING {
                        break Transfer::Failed(TransferError::NoResponse);
                    }
                    continue;
                }
                Reply::Ack if pid != Pid::In => {
                    control.errors = 0;
                    control.stage = match stage {
                        Stage::Setup if length == 0 => Stage::Status,
                        Stage::Setup => Stage::Data {
                            done: 0,
                            toggle: true,
                        },
                        Stage::Data { done, toggle } => {
                            let done = (done + max_packet).min(length);
                            if done == length {
                                Stage::Status
                            } else {
                                Stage::Data {
                                    done,
                                    toggle: !toggle,
                                }
                            }
                        }
                        Stage::Status => break Transfer::Complete(control.received.len()),
                    };
                }
                Reply::Data { bytes, toggle } if pid == Pid::In => {
                    control.errors = 0;
                    match stage {
                        Stage::Data {
                            done,
                            toggle: expected,
                        } => {
                            if toggle != expected {
                                // A repeat of a packet already taken: dropped.
                                continue;
                            }
                            if bytes.len() > max_packet || done + bytes.len() > length {
                                break Transfer::Failed(TransferError::Babble);
                            }
                            control.received.extend_from_slice(&bytes);
                            let done = done + bytes.len();
                            control.stage = if bytes.len() < max_packet || done == length {
                                Stage::Status
                            } else {
                                Stage::Data {
                                    done,
                                    toggle: !expected,
                                }
                            };
                        }
                        Stage::Status => {
                            if !bytes.is_empty() {
                                break Transfer::Failed(TransferError::Babble);
                            }
                            break Transfer::Complete(control.received.len());
                        }
                        Stage::Setup => break Transfer::Failed(TransferError::Controller),
                    }
                }
                other => {
                    self.error(format!("device answered {other:?} to a {pid:?}"));
                    break Transfer::Failed(TransferError::Controller);
                }
            }
        };
        // A SET_ADDRESS done: its time kept, to check the recovery interval.
        if result == Transfer::Complete(0)
            && control.setup.request_type == 0
            && control.setup.request == 5
        {
            let now = self.now;
            if let Some(device) = self.devices[index].as_mut() {
                device.set_address = Some((now, control.setup.value as u8));
            }
        }
        if let Some(device) = self.devices[index].as_mut() {
            // Kept, finished, for control_poll to copy from.
            control.finished = true;
            device.control = Some(control);
        }
        result
    }

    /// One IN on pipe `pipe`, as the controller polls it in the background.
    fn run_pipe(&mut self, pipe: usize) -> Option<(Transfer, Vec<u8>)> {
        let (device, endpoint, max_packet, toggle) = {
            let p = self.pipes[pipe].as_ref()?;
            if p.halted || p.done.is_some() {
                return None;
            }
            (p.device, p.endpoint, p.max_packet, p.toggle)
        };
        let mut packet = self.packet(device, Pid::In, endpoint, toggle, Vec::new());
        packet.max_packet = usize::from(max_packet);
        let reply = if self.interrupt_errors > 0 {
            self.interrupt_errors -= 1;
            Reply::Timeout
        } else {
            self.transact(device, packet)
        };
        let p = self.pipes[pipe].as_mut()?;
        match reply {
            Reply::Data { bytes, toggle } => {
                p.errors = 0;
                if toggle != p.toggle {
                    // The device missed our ACK and sent the last one again.
                    return None;
                }
                if bytes.len() > usize::from(p.max_packet) {
                    p.halted = true;
                    return Some((Transfer::Failed(TransferError::Babble), Vec::new()));
                }
                p.toggle = !p.toggle;
                Some((Transfer::Complete(bytes.len()), bytes))
            }
            Reply::Nak => {
                p.errors = 0;
                None
            }
            Reply::Stall => {
                p.halted = true;
                Some((Transfer::Stalled, Vec::new()))
            }
            Reply::Timeout => {
                p.errors += 1;
                if p.errors >= ERRORS_BEFORE_FAILING {
                    p.halted = true;
                    p.errors = 0;
                    return Some((Transfer::Failed(TransferError::NoResponse), Vec::new()));
                }
                None
            }
            Reply::Ack => {
                p.halted = true;
                Some((Transfer::Failed(TransferError::Controller), Vec::new()))
            }
        }
    }
}

impl crate::Platform for Loopback {
    fn now_micros(&mut self) -> u64 {
        self.calls.push("now_micros");
        self.now += MICROS_PER_CLOCK_READ;
        self.now
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        self.log.push(format!("{message}"));
    }
}

impl HostController for Loopback {
    fn kind(&self) -> ControllerKind {
        self.kind
    }

    type Hardware = Loopback;

    fn hardware(&mut self) -> &mut Loopback {
        self
    }

    type StartError = HostError;

    /// The device layer's tests start with the controller running.
    fn take_ownership(&mut self) -> Handoff {
        Handoff::NotOwned
    }

    fn reset_and_start(&mut self) -> Result<(), HostError> {
        Ok(())
    }

    fn root_ports(&self) -> u8 {
        self.ports.len() as u8
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        self.calls.push("port_status");
        self.refresh_port(port);
        let low_speed = self.tree.root_device(port) == Some(Speed::Low);
        match self.port(port) {
            Some(state) => PortStatus {
                connected: state.connected && !state.companion_owned,
                enabled: state.enabled,
                low_speed,
                connect_changed: state.connect_changed && !state.companion_owned,
                companion_owned: state.companion_owned,
            },
            None => {
                self.error(format!("port_status of port {port}"));
                PortStatus::default()
            }
        }
    }

    fn clear_port_change(&mut self, port: u8) {
        self.calls.push("clear_port_change");
        match self.port(port) {
            Some(state) => state.connect_changed = false,
            None => self.error(format!("clear_port_change of port {port}")),
        }
    }

    fn port_reset_begin(&mut self, port: u8) {
        self.calls.push("port_reset_begin");
        let now = self.now;
        match self.port(port) {
            Some(state) => {
                state.reset_began = Some(now);
                state.enabled = false;
            }
            None => self.error(format!("port_reset_begin of port {port}")),
        }
    }

    /// The reset ends [`ROOT_RESET_MICROS`] after it began, as a driver
    /// times it.
    fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome> {
        self.calls.push("port_reset_poll");
        let now = self.now;
        let kind = self.kind;
        let speed = self.tree.root_device(port);
        let Some(state) = self.port(port) else {
            self.error(format!("port_reset_poll of port {port}"));
            return Some(ResetOutcome::Failed);
        };
        let Some(began) = state.reset_began else {
            self.error(format!("port_reset_poll of port {port} without a reset"));
            return Some(ResetOutcome::Failed);
        };
        if now - began < ROOT_RESET_MICROS {
            return None;
        }
        state.reset_began = None;
        let Some(speed) = speed else {
            return Some(ResetOutcome::Failed);
        };
        if kind == ControllerKind::Ehci && speed != Speed::High {
            if let Some(state) = self.port(port) {
                state.companion_owned = true;
            }
            return Some(ResetOutcome::HandedToCompanion);
        }
        if let Some(state) = self.port(port) {
            state.enabled = true;
        }
        self.tree.reset_root_port(port);
        Some(ResetOutcome::Enabled(speed))
    }

    fn port_disable(&mut self, port: u8) {
        self.calls.push("port_disable");
        match self.port(port) {
            Some(state) => state.enabled = false,
            None => self.error(format!("port_disable of port {port}")),
        }
    }

    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError> {
        self.calls.push("device_new");
        if self.port(info.root_port).is_none() {
            self.error(format!("device_new on port {}", info.root_port));
            return Err(HostError::Invalid);
        }
        let Some(index) = self.devices.iter().position(Option::is_none) else {
            return Err(HostError::NoRoom);
        };
        self.devices[index] = Some(Device {
            info,
            address: 0,
            max_packet: 8,
            control: None,
            set_address: None,
            hub: None,
        });
        Ok(DeviceId(index as u8))
    }

    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        self.calls.push("device_set_address");
        let Some(index) = self.device_index(device) else {
            self.error(format!("device_set_address of unknown {device:?}"));
            return Err(HostError::UnknownHandle);
        };
        let Some(d) = self.devices[index].as_mut() else {
            return Err(HostError::UnknownHandle);
        };
        if !d.set_address.is_some_and(|(_, given)| given == address) {
            self.error(format!(
                "device_set_address({address}) without its SET_ADDRESS"
            ));
        }
        if let Some(d) = self.devices[index].as_mut() {
            d.address = address;
        }
        Ok(())
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> Result<(), HostError> {
        self.calls.push("device_set_max_packet");
        let Some(index) = self.device_index(device) else {
            self.error(format!("device_set_max_packet of unknown {device:?}"));
            return Err(HostError::UnknownHandle);
        };
        if !matches!(max_packet, 8 | 16 | 32 | 64) {
            return Err(HostError::Invalid);
        }
        if let Some(d) = self.devices[index].as_mut() {
            d.max_packet = max_packet;
        }
        Ok(())
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        ports: u8,
        multi_tt: bool,
    ) -> Result<(), HostError> {
        self.calls.push("device_is_hub");
        let Some(index) = self.device_index(device) else {
            self.error(format!("device_is_hub of unknown {device:?}"));
            return Err(HostError::UnknownHandle);
        };
        if let Some(d) = self.devices[index].as_mut() {
            d.hub = Some((ports, multi_tt));
        }
        Ok(())
    }

    fn device_remove(&mut self, device: DeviceId) {
        self.calls.push("device_remove");
        let Some(index) = self.device_index(device) else {
            self.error(format!("device_remove of unknown {device:?}"));
            return;
        };
        if self.pipes.iter().flatten().any(|p| p.device == index) {
            self.error(format!("device_remove of {device:?} with a pipe open"));
            for pipe in self.pipes.iter_mut() {
                if pipe.as_ref().is_some_and(|p| p.device == index) {
                    *pipe = None;
                }
            }
        }
        self.devices[index] = None;
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError> {
        self.calls.push("control_begin");
        let Some(index) = self.device_index(device) else {
            self.error(format!("control_begin on unknown {device:?}"));
            return Err(HostError::UnknownHandle);
        };
        if usize::from(setup.length) > MAX_CONTROL_DATA
            || (!setup.is_in() && out.len() != usize::from(setup.length))
        {
            self.error(format!(
                "control_begin with {setup:?} and {} bytes",
                out.len()
            ));
            return Err(HostError::Invalid);
        }
        let Some(d) = self.devices[index].as_mut() else {
            return Err(HostError::UnknownHandle);
        };
        if d.control.as_ref().is_some_and(|c| !c.finished) {
            self.error(format!("control_begin on busy {device:?}"));
            return Err(HostError::Busy);
        }
        let now = self.now;
        if let Some((at, address)) = d.set_address.filter(|&(_, given)| given == d.address) {
            if now - at < 2_000 {
                let after = now - at;
                self.error(format!(
                    "address {address} used {after} us after SET_ADDRESS"
                ));
            }
        }
        let Some(d) = self.devices[index].as_mut() else {
            return Err(HostError::UnknownHandle);
        };
        let stalled = self
            .stall_requests
            .contains(&(setup.request_type, setup.request));
        d.control = Some(Control {
            setup,
            out: out.to_vec(),
            stage: Stage::Setup,
            received: Vec::new(),
            errors: 0,
            stall: stalled,
            finished: false,
        });
        self.happened = true;
        Ok(())
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        self.calls.push("control_poll");
        let Some(index) = self.device_index(device) else {
            self.error(format!("control_poll on unknown {device:?}"));
            return Transfer::Failed(TransferError::Controller);
        };
        let Some(control) = self.devices[index]
            .as_ref()
            .and_then(|d| d.control.as_ref())
        else {
            self.error(format!("control_poll on {device:?} with no transfer"));
            return Transfer::Failed(TransferError::Controller);
        };
        if control.finished {
            self.error(format!("control_poll on {device:?} after its end"));
            return Transfer::Failed(TransferError::Controller);
        }
        if control.stall {
            // A request the test stalls.
            if let Some(c) = self.devices[index]
                .as_mut()
                .and_then(|d| d.control.as_mut())
            {
                c.finished = true;
            }
            return Transfer::Stalled;
        }
        if self.wedged {
            return Transfer::Pending;
        }
        let result = self.run_control(index);
        if let Transfer::Complete(n) = result {
            if let Some(control) = self.devices[index]
                .as_ref()
                .and_then(|d| d.control.as_ref())
            {
                if n > into.len() {
                    let room = into.len();
                    self.errors
                        .push(format!("control_poll into {room} bytes for {n}"));
                }
                let n = n.min(into.len());
                into[..n].copy_from_slice(&control.received[..n]);
            }
        }
        result
    }

    fn control_cancel(&mut self, device: DeviceId) {
        self.calls.push("control_cancel");
        let Some(index) = self.device_index(device) else {
            self.error(format!("control_cancel on unknown {device:?}"));
            return;
        };
        if let Some(d) = self.devices[index].as_mut() {
            d.control = None;
        }
    }

    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> Result<PipeId, HostError> {
        self.calls.push("interrupt_open");
        let Some(index) = self.device_index(device) else {
            self.error(format!("interrupt_open on unknown {device:?}"));
            return Err(HostError::UnknownHandle);
        };
        if !(1..=15).contains(&endpoint)
            || !(1..=MAX_REPORT as u16).contains(&max_packet)
            || interval == 0
            || !interval.is_power_of_two()
        {
            self.error(format!(
                "interrupt_open of endpoint {endpoint}, {max_packet} bytes, every {interval}"
            ));
            return Err(HostError::Invalid);
        }
        let Some(slot) = self.pipes.iter().position(Option::is_none) else {
            return Err(HostError::NoRoom);
        };
        self.pipes[slot] = Some(Pipe {
            device: index,
            endpoint,
            max_packet,
            toggle: false,
            errors: 0,
            halted: false,
            done: None,
        });
        Ok(PipeId(slot as u8))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        self.calls.push("interrupt_poll");
        let slot = usize::from(pipe.0);
        if self.pipes.get(slot).is_none_or(Option::is_none) {
            self.error(format!("interrupt_poll of unknown {pipe:?}"));
            return Transfer::Failed(TransferError::Controller);
        }
        let done = match self.pipes[slot].as_mut().and_then(|p| p.done.take()) {
            Some(done) => Some(done),
            None => self.run_pipe(slot),
        };
        match done {
            Some((Transfer::Complete(n), bytes)) => {
                let n = n.min(into.len());
                into[..n].copy_from_slice(&bytes[..n]);
                Transfer::Complete(n)
            }
            Some((result, _)) => result,
            None => Transfer::Pending,
        }
    }

    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError> {
        self.calls.push("interrupt_restart");
        let Some(p) = self
            .pipes
            .get_mut(usize::from(pipe.0))
            .and_then(Option::as_mut)
        else {
            self.error(format!("interrupt_restart of unknown {pipe:?}"));
            return Err(HostError::UnknownHandle);
        };
        if !p.halted {
            self.errors
                .push(format!("interrupt_restart of running {pipe:?}"));
        }
        p.halted = false;
        p.errors = 0;
        if reset_toggle {
            p.toggle = false;
        }
        Ok(())
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        self.calls.push("interrupt_close");
        match self.pipes.get_mut(usize::from(pipe.0)) {
            Some(p @ Some(_)) => *p = None,
            _ => self.error(format!("interrupt_close of unknown {pipe:?}")),
        }
    }

    fn anything_happened(&mut self) -> bool {
        self.calls.push("anything_happened");
        // A frame goes by: root ports looked at, every pipe polled once.
        for port in 1..=self.ports.len() as u8 {
            self.refresh_port(port);
        }
        for slot in 0..self.pipes.len() {
            if let Some(done) = self.run_pipe(slot) {
                if let Some(p) = self.pipes[slot].as_mut() {
                    p.done = Some(done);
                }
                self.happened = true;
            }
        }
        core::mem::take(&mut self.happened)
    }

    fn halt(&mut self) -> bool {
        self.calls.push("halt");
        self.halted = true;
        true
    }
}
