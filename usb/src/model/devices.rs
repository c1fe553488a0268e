//! The device side of the bus, shared by the EHCI, OHCI and UHCI register
//! models: a tree of USB devices (keyboards, hubs with transaction
//! translators, devices that misbehave) that answers packets the way real
//! devices do. A controller model turns its transfer descriptors into
//! [`Packet`]s, hands them to [`UsbTree::transact`], and writes the
//! [`Reply`] back into its descriptors.
//!
//! The devices keep to USB 2.0 chapters 8 (control transfers, data
//! toggles), 9 (device states and standard requests) and 11 (hubs and
//! transaction translators), and HID 1.11 (the boot keyboard's class
//! requests). Time does not pass here: a hub's port reset and port power
//! complete at once. What a correct host never does (a SETUP with DATA1, a
//! token to an endpoint the device does not have, two devices answering at
//! one address, a status stage with the wrong toggle) is answered as the
//! device would and also noted in [`UsbTree::errors`], which the
//! controllers' tests check is empty.
//!
//! The shared descriptors (QEMU's usb-kbd and usb-hub, and the high-speed
//! and low-speed variants) live here too; the xHCI model uses them.
//!
//! INTERFACE FIXED BY THE LEAD: the signatures of the items below that
//! came with the file are what the controller models are written against.

#![allow(dead_code)]

use crate::host::{Setup, Speed};
use std::collections::VecDeque;
use std::format;
use std::string::String;
use std::vec;
use std::vec::Vec;

// ---------------------------------------------------------------------------
// Descriptors.

/// QEMU's usb-kbd device descriptor (full speed, an 8-byte endpoint 0).
pub const KEYBOARD_DEVICE: [u8; 18] = [
    18, 1, 0x00, 0x02, 0, 0, 0, 8, 0x27, 0x06, 0x01, 0x00, 0, 0, 1, 2, 3, 1,
];
/// A low-speed boot keyboard's device descriptor: USB 1.1, and endpoint 0
/// of 8 bytes, the only size low speed allows (USB 2.0 5.5.3).
pub const LOW_SPEED_KEYBOARD_DEVICE: [u8; 18] = [
    18, 1, 0x10, 0x01, 0, 0, 0, 8, 0x27, 0x06, 0x01, 0x00, 0, 0, 1, 2, 3, 1,
];
/// A high-speed keyboard's device descriptor: endpoint 0 of 64 bytes, the
/// only size high speed allows (USB 2.0 5.5.3).
pub const HIGH_SPEED_KEYBOARD_DEVICE: [u8; 18] = [
    18, 1, 0x00, 0x02, 0, 0, 0, 64, 0x27, 0x06, 0x01, 0x00, 0, 0, 1, 2, 3, 1,
];
/// QEMU's usb-kbd configuration: one boot keyboard interface, its HID
/// descriptor, an 8-byte interrupt IN endpoint 1 polled every 10 ms.
pub const KEYBOARD_CONFIGURATION: [u8; 34] = [
    9, 2, 34, 0, 1, 1, 0, 0xA0, 50, 9, 4, 0, 0, 1, 3, 1, 1, 0, 9, 0x21, 0x11, 0x01, 0, 1, 0x22, 63,
    0, 7, 5, 0x81, 3, 8, 0, 10,
];
/// The same at high speed: bInterval 7 is 2^6 microframes, 8 ms.
pub const HIGH_SPEED_KEYBOARD_CONFIGURATION: [u8; 34] = [
    9, 2, 34, 0, 1, 1, 0, 0xA0, 50, 9, 4, 0, 0, 1, 3, 1, 1, 0, 9, 0x21, 0x11, 0x01, 0, 1, 0x22, 63,
    0, 7, 5, 0x81, 3, 8, 0, 7,
];
/// A keyboard's configuration whose lengths lie: wTotalLength says 64 bytes
/// where there are 34, and the HID descriptor's bLength is 0 (a parser that
/// trusted it would loop for ever).
pub const LYING_KEYBOARD_CONFIGURATION: [u8; 34] = [
    9, 2, 64, 0, 1, 1, 0, 0xA0, 50, 9, 4, 0, 0, 1, 3, 1, 1, 0, 0, 0x21, 0x11, 0x01, 0, 1, 0x22, 63,
    0, 7, 5, 0x81, 3, 8, 0, 10,
];
/// QEMU's usb-kbd report descriptor: the boot report (HID 1.11 appendix
/// E.6): modifier bits, a constant byte, LED outputs, six key bytes.
pub const KEYBOARD_REPORT_DESCRIPTOR: [u8; 63] = [
    0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x75, 0x01, 0x95, 0x08, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7,
    0x15, 0x00, 0x25, 0x01, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01, 0x95, 0x05, 0x75, 0x01,
    0x05, 0x08, 0x19, 0x01, 0x29, 0x05, 0x91, 0x02, 0x95, 0x01, 0x75, 0x03, 0x91, 0x01, 0x95, 0x06,
    0x75, 0x08, 0x15, 0x00, 0x25, 0xFF, 0x05, 0x07, 0x19, 0x00, 0x29, 0xFF, 0x81, 0x00, 0xC0,
];
/// An N-key-rollover keyboard's report descriptor: modifier bits, a
/// constant byte, then a bit for each of usages 0-143: 20-byte reports,
/// sent in 8-byte packets (its endpoint's wMaxPacketSize).
pub const ROLLOVER_REPORT_DESCRIPTOR: [u8; 45] = [
    0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7, 0x15, 0x00, 0x25, 0x01,
    0x75, 0x01, 0x95, 0x08, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01, 0x05, 0x07, 0x19, 0x00,
    0x29, 0x8F, 0x15, 0x00, 0x25, 0x01, 0x75, 0x01, 0x95, 0x90, 0x81, 0x02, 0xC0,
];
/// The length of the rollover keyboard's report.
pub const ROLLOVER_REPORT_BYTES: usize = 20;
/// The rollover keyboard's report with `usages` down.
pub fn rollover_report(usages: &[u8]) -> [u8; ROLLOVER_REPORT_BYTES] {
    let mut report = [0; ROLLOVER_REPORT_BYTES];
    for &usage in usages {
        report[2 + usize::from(usage / 8)] |= 1 << (usage % 8);
    }
    report
}
/// A full-speed hub's device descriptor (class 9, protocol 0: no
/// transaction translator), an 8-byte endpoint 0.
pub const HUB_DEVICE: [u8; 18] = [
    18, 1, 0x00, 0x02, 9, 0, 0, 8, 0x09, 0x04, 0x11, 0x11, 0, 0, 0, 0, 0, 1,
];
/// A high-speed hub with one transaction translator for all its ports
/// (bDeviceProtocol 1, USB 2.0 11.23.1), a 64-byte endpoint 0.
pub const HIGH_SPEED_HUB_DEVICE: [u8; 18] = [
    18, 1, 0x00, 0x02, 9, 0, 1, 64, 0x09, 0x04, 0x11, 0x11, 0, 0, 0, 0, 0, 1,
];
/// A high-speed hub with a transaction translator per port
/// (bDeviceProtocol 2).
pub const HIGH_SPEED_MULTI_TT_HUB_DEVICE: [u8; 18] = [
    18, 1, 0x00, 0x02, 9, 0, 2, 64, 0x09, 0x04, 0x11, 0x11, 0, 0, 0, 0, 0, 1,
];
/// A hub's configuration (self-powered, remote wake-up): one interface of
/// class 9 and its 1-byte status change endpoint 0x81 (ports 1-7).
pub const HUB_CONFIGURATION: [u8; 25] = [
    9, 2, 25, 0, 1, 1, 0, 0xE0, 0, 9, 4, 0, 0, 1, 9, 0, 0, 0, 7, 5, 0x81, 3, 1, 0, 12,
];
/// A single-TT high-speed hub's configuration: interface protocol 0
/// (USB 2.0 11.23.1); bInterval 12 is 2^11 microframes, 256 ms.
pub const HIGH_SPEED_HUB_CONFIGURATION: [u8; 25] = HUB_CONFIGURATION;
/// A multi-TT high-speed hub's configuration: interface 0 alternate 0 is
/// protocol 1 (one translator), alternate 1 protocol 2 (one per port),
/// chosen with SET_INTERFACE (USB 2.0 11.23.1).
pub const HIGH_SPEED_MULTI_TT_HUB_CONFIGURATION: [u8; 41] = [
    9, 2, 41, 0, 1, 1, 0, 0xE0, 0, 9, 4, 0, 0, 1, 9, 0, 1, 0, 7, 5, 0x81, 3, 1, 0, 12, 9, 4, 0, 1,
    1, 9, 0, 2, 0, 7, 5, 0x81, 3, 1, 0, 12,
];
/// The xHCI model's 4-port hub descriptor (ganged power switching, 100 ms
/// from power on to power good).
pub const HUB_DESCRIPTOR: [u8; 9] = [9, 0x29, 4, 0, 0, 50, 0, 0, 0xFF];
/// String descriptor 0: the one language, US English (0x0409).
pub const LANGUAGES: [u8; 4] = [4, 3, 0x09, 0x04];
/// The keyboard's strings 1 (manufacturer), 2 (product), 3 (serial).
pub const KEYBOARD_STRINGS: [&str; 3] = ["QEMU", "QEMU USB Keyboard", "42"];

/// The hub descriptor (USB 2.0 11.23.2.1) of the tree's hubs: `ports`
/// ports, each with its own power switch and over-current report,
/// 100 ms from power on to power good, every device removable.
pub fn hub_descriptor(ports: u8) -> Vec<u8> {
    // One bit per port and bit 0 reserved, in whole bytes.
    let bitmap_bytes = (usize::from(ports) + 1).div_ceil(8);
    let mut bytes = vec![0, 0x29, ports, 0x09, 0x00, 50, 0];
    bytes.extend(core::iter::repeat_n(0x00, bitmap_bytes)); // DeviceRemovable
    bytes.extend(core::iter::repeat_n(0xFF, bitmap_bytes)); // PortPwrCtrlMask
    bytes[0] = bytes.len() as u8;
    bytes
}

/// A string descriptor holding `text` in UTF-16LE.
fn string_descriptor(text: &str) -> Vec<u8> {
    let mut bytes = vec![0, 3];
    for unit in text.encode_utf16() {
        bytes.extend(unit.to_le_bytes());
    }
    bytes[0] = bytes.len() as u8;
    bytes
}

// ---------------------------------------------------------------------------
// The fixed interface.
/// A token's packet identifier.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pid {
    /// SETUP (always DATA0, 8 bytes).
    Setup,
    /// IN: the device sends up to `max_packet` bytes.
    In,
    /// OUT: the host sends `data`.
    Out,
}

/// One transaction as the controller puts it on the wire.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packet {
    /// The device address (0: the default address).
    pub address: u8,
    /// The endpoint number (0-15).
    pub endpoint: u8,
    /// SETUP, IN or OUT.
    pub pid: Pid,
    /// The data PID the host sends with (false: DATA0, true: DATA1). For
    /// IN it is the toggle the host expects.
    pub toggle: bool,
    /// The bytes of a SETUP or OUT.
    pub data: Vec<u8>,
    /// The most bytes the host takes for an IN.
    pub max_packet: usize,
    /// The speed the controller sends at (low-speed packets go with PRE
    /// on UHCI/OHCI, or through a translator on EHCI).
    pub speed: Speed,
}

/// What came back.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// IN: a data packet with the device's toggle (the host accepts it only
    /// if it is the toggle it expected; the device flips its toggle when
    /// the host's ACK arrives, which the tree models as every accepted
    /// packet).
    Data {
        /// The bytes.
        bytes: Vec<u8>,
        /// The device's data PID (false: DATA0).
        toggle: bool,
    },
    /// SETUP/OUT accepted.
    Ack,
    /// Not now (no new report; a busy device).
    Nak,
    /// The endpoint is halted, or the request is not supported.
    Stall,
    /// No answer at all: nothing at that address, a port not enabled, a
    /// device that is dead. The controller counts an error (CERR).
    Timeout,
}

/// Where a full- or low-speed device's split transaction went (EHCI): the
/// controller model gives the hub address and port from its queue head,
/// and the tree checks them against the real topology.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Split {
    /// The high-speed hub's address (QH Hub Addr).
    pub hub_address: u8,
    /// The hub's port (QH Port Number).
    pub hub_port: u8,
}

/// A device's place: the root port, then each hub port down (1-based).
pub type Path = Vec<u8>;

/// A device kind to plug in.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum UsbDevice {
    /// QEMU's `usb-kbd`: a boot keyboard at this speed.
    Keyboard(Speed),
    /// A hub with this many ports at this speed (high speed: one
    /// transaction translator for all ports, or one per port if `multi_tt`).
    Hub {
        /// Its speed.
        speed: Speed,
        /// Downstream ports.
        ports: u8,
        /// A translator per port.
        multi_tt: bool,
    },
    /// Answers nothing after the reset.
    Dead(Speed),
    /// A keyboard whose device descriptor says bLength 18 but whose
    /// configuration's wTotalLength is larger than what it sends.
    LyingKeyboard(Speed),
    /// An N-key-rollover keyboard: 20-byte reports
    /// ([`ROLLOVER_REPORT_DESCRIPTOR`]) in 8-byte packets.
    RolloverKeyboard(Speed),
}

// ---------------------------------------------------------------------------
// Request codes and feature selectors.

/// Standard requests (USB 2.0 table 9-4).
const GET_STATUS: u8 = 0;
const CLEAR_FEATURE: u8 = 1;
const SET_FEATURE: u8 = 3;
const SET_ADDRESS: u8 = 5;
const GET_DESCRIPTOR: u8 = 6;
const GET_CONFIGURATION: u8 = 8;
const SET_CONFIGURATION: u8 = 9;
const GET_INTERFACE: u8 = 10;
const SET_INTERFACE: u8 = 11;
/// HID class requests (HID 1.11 7.2).
const GET_REPORT: u8 = 0x01;
const GET_IDLE: u8 = 0x02;
const GET_PROTOCOL: u8 = 0x03;
const SET_REPORT: u8 = 0x09;
const SET_IDLE: u8 = 0x0A;
const SET_PROTOCOL: u8 = 0x0B;
/// Hub class requests for the transaction translator (USB 2.0 table 11-16).
const CLEAR_TT_BUFFER: u8 = 8;
const RESET_TT: u8 = 9;
const STOP_TT: u8 = 11;
/// Standard feature selectors (USB 2.0 table 9-6).
const ENDPOINT_HALT: u16 = 0;
const DEVICE_REMOTE_WAKEUP: u16 = 1;
/// Hub port feature selectors (USB 2.0 table 11-17).
const PORT_ENABLE: u16 = 1;
const PORT_SUSPEND: u16 = 2;
const PORT_RESET: u16 = 4;
const PORT_POWER: u16 = 8;
const C_PORT_CONNECTION: u16 = 16;
const C_PORT_ENABLE: u16 = 17;
const C_PORT_SUSPEND: u16 = 18;
const C_PORT_OVER_CURRENT: u16 = 19;
const C_PORT_RESET: u16 = 20;
const PORT_TEST: u16 = 21;
const PORT_INDICATOR: u16 = 22;

/// A hub port's GET_STATUS bits: wPortStatus (USB 2.0 table 11-21) in the
/// low half, wPortChange (table 11-22) in the high half.
pub mod port_bits {
    /// A device is attached.
    pub const CONNECTION: u32 = 1 << 0;
    /// The port is enabled (after a reset).
    pub const ENABLE: u32 = 1 << 1;
    /// The port is suspended.
    pub const SUSPEND: u32 = 1 << 2;
    /// The port is in reset (never seen: resets end at once here).
    pub const RESET: u32 = 1 << 4;
    /// The port is powered.
    pub const POWER: u32 = 1 << 8;
    /// The attached device is low speed.
    pub const LOW_SPEED: u32 = 1 << 9;
    /// The attached device is high speed (known after the reset).
    pub const HIGH_SPEED: u32 = 1 << 10;
    /// C_PORT_CONNECTION: the connection changed.
    pub const C_CONNECTION: u32 = 1 << 16;
    /// C_PORT_ENABLE: the port was disabled by an error.
    pub const C_ENABLE: u32 = 1 << 17;
    /// C_PORT_SUSPEND: a resume finished.
    pub const C_SUSPEND: u32 = 1 << 18;
    /// C_PORT_RESET: a reset finished.
    pub const C_RESET: u32 = 1 << 20;
}

/// Hubs in a chain below a root port at most (USB 2.0 4.1.1: tier 7 is the
/// last, for a device below five hubs).
pub const MAX_HUB_TIERS: usize = 5;
/// Boot reports a keyboard holds before [`UsbTree::send_report`] says no.
pub const REPORT_QUEUE: usize = 16;
/// Ports a hub of the tree may have (the status change bitmap stays 2 bytes).
pub const MAX_HUB_PORTS: u8 = 15;
/// The idle rate HID 1.11 7.2.4 recommends for keyboards: 500 ms in 4 ms units.
const DEFAULT_IDLE: u8 = 125;

// ---------------------------------------------------------------------------
// The devices.

impl UsbDevice {
    /// The fastest speed the device can run at (a high-speed device below a
    /// full-speed hub runs at full speed).
    pub fn speed(&self) -> Speed {
        match self {
            UsbDevice::Keyboard(speed)
            | UsbDevice::Dead(speed)
            | UsbDevice::LyingKeyboard(speed)
            | UsbDevice::RolloverKeyboard(speed) => *speed,
            UsbDevice::Hub { speed, .. } => *speed,
        }
    }

    fn is_keyboard(&self) -> bool {
        matches!(
            self,
            UsbDevice::Keyboard(_) | UsbDevice::LyingKeyboard(_) | UsbDevice::RolloverKeyboard(_)
        )
    }

    /// A keyboard's report descriptor.
    fn report_descriptor(&self) -> &'static [u8] {
        match self {
            UsbDevice::RolloverKeyboard(_) => &ROLLOVER_REPORT_DESCRIPTOR,
            _ => &KEYBOARD_REPORT_DESCRIPTOR,
        }
    }
}

/// The device and configuration descriptors `device` gives when running
/// at `speed` (a high-speed hub at full speed is a plain full-speed hub,
/// USB 2.0 11.23.1).
fn descriptors(device: &UsbDevice, speed: Speed) -> (Vec<u8>, Vec<u8>) {
    match (device, speed) {
        (UsbDevice::Keyboard(_), Speed::Low) => (
            LOW_SPEED_KEYBOARD_DEVICE.to_vec(),
            KEYBOARD_CONFIGURATION.to_vec(),
        ),
        (UsbDevice::Keyboard(_), Speed::Full) => {
            (KEYBOARD_DEVICE.to_vec(), KEYBOARD_CONFIGURATION.to_vec())
        }
        // The USB 2 models have no SuperSpeed (the xHCI model does its own).
        (UsbDevice::Keyboard(_), Speed::High | Speed::Super) => (
            HIGH_SPEED_KEYBOARD_DEVICE.to_vec(),
            HIGH_SPEED_KEYBOARD_CONFIGURATION.to_vec(),
        ),
        (UsbDevice::RolloverKeyboard(_), speed) => {
            let (device, mut configuration) = descriptors(&UsbDevice::Keyboard(speed), speed);
            // The HID descriptor's wDescriptorLength of the report descriptor.
            configuration[25] = ROLLOVER_REPORT_DESCRIPTOR.len() as u8;
            (device, configuration)
        }
        (UsbDevice::LyingKeyboard(_), Speed::Low) => (
            LOW_SPEED_KEYBOARD_DEVICE.to_vec(),
            LYING_KEYBOARD_CONFIGURATION.to_vec(),
        ),
        (UsbDevice::LyingKeyboard(_), _) => (
            KEYBOARD_DEVICE.to_vec(),
            LYING_KEYBOARD_CONFIGURATION.to_vec(),
        ),
        (
            UsbDevice::Hub {
                ports, multi_tt, ..
            },
            speed,
        ) => {
            let (device, mut configuration) = match (speed, multi_tt) {
                (Speed::High, true) => (
                    HIGH_SPEED_MULTI_TT_HUB_DEVICE.to_vec(),
                    HIGH_SPEED_MULTI_TT_HUB_CONFIGURATION.to_vec(),
                ),
                (Speed::High, false) => (
                    HIGH_SPEED_HUB_DEVICE.to_vec(),
                    HIGH_SPEED_HUB_CONFIGURATION.to_vec(),
                ),
                _ => (HUB_DEVICE.to_vec(), HUB_CONFIGURATION.to_vec()),
            };
            // The status change endpoints carry a bit per port and bit 0.
            let bitmap_bytes = (usize::from(*ports) + 1).div_ceil(8) as u8;
            let mut offset = 0;
            while offset + 7 <= configuration.len() && configuration[offset] >= 2 {
                if configuration[offset + 1] == 5 {
                    configuration[offset + 4] = bitmap_bytes;
                }
                offset += usize::from(configuration[offset]);
            }
            (device, configuration)
        }
        (UsbDevice::Dead(_), _) => (Vec::new(), Vec::new()),
    }
}

/// Where endpoint 0 stands in a control transfer (USB 2.0 8.5.3).
#[derive(Clone, Debug, Default)]
enum Control {
    /// No transfer: only a SETUP is answered.
    #[default]
    Idle,
    /// The request was refused (or the host broke the protocol): every IN
    /// and OUT stalls until the next SETUP.
    Stalled,
    /// A control read's data stage; an OUT is its status stage.
    DataIn {
        /// The reply, cut to wLength.
        bytes: Vec<u8>,
        /// Bytes sent so far.
        sent: usize,
        /// wLength.
        length: usize,
        /// The next data packet's PID.
        toggle: bool,
        /// A short packet, or wLength bytes, went: the data stage is over.
        ended: bool,
    },
    /// A control write's data stage; an IN is its status stage.
    DataOut {
        /// What to do with the bytes.
        request: OutRequest,
        /// wLength.
        expected: usize,
        /// Bytes taken so far.
        received: Vec<u8>,
        /// The data PID the next new packet comes with.
        toggle: bool,
    },
    /// A no-data request's status stage (a zero-length IN).
    StatusIn {
        /// SET_ADDRESS's address, which takes effect when this stage ends
        /// (USB 2.0 9.4.6).
        new_address: Option<u8>,
    },
}

/// A request with an OUT data stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum OutRequest {
    /// HID SET_REPORT(output): the LEDs.
    SetReport,
}

/// What a SETUP's request leads to.
#[derive(Debug)]
enum Response {
    /// A data stage of these bytes (cut to wLength), then a status OUT.
    In(Vec<u8>),
    /// Only a status IN; the request is done.
    NoData,
    /// Only a status IN, after which the device takes this address.
    SetAddress(u8),
    /// A data stage of wLength bytes from the host, then a status IN.
    Out(OutRequest),
}

/// A boot keyboard's own state.
#[derive(Clone, Debug)]
struct Keyboard {
    /// 0 boot, 1 report (HID 1.11 7.2.6: report after a reset).
    protocol: u8,
    /// SET_IDLE's duration, in 4 ms units.
    idle: u8,
    /// SET_REPORT's LED byte.
    leds: u8,
    /// Interrupt packets not sent yet (a report of more than 8 bytes is
    /// several).
    reports: VecDeque<Vec<u8>>,
    /// The last packet sent.
    last: Option<Vec<u8>>,
    /// The knob: send `last` again with its old toggle.
    repeat_next: bool,
}

impl Default for Keyboard {
    fn default() -> Keyboard {
        Keyboard {
            protocol: 1,
            idle: DEFAULT_IDLE,
            leds: 0,
            reports: VecDeque::new(),
            last: None,
            repeat_next: false,
        }
    }
}

/// A hub's downstream port (USB 2.0 11.5).
#[derive(Clone, Copy, Debug, Default)]
struct HubPort {
    powered: bool,
    enabled: bool,
    suspended: bool,
    connect_change: bool,
    enable_change: bool,
    suspend_change: bool,
    reset_change: bool,
    /// The device plugged in (a handle), powered or not.
    child: Option<usize>,
}

/// One device, plugged in or (once unplugged) kept so that handles stay.
#[derive(Debug)]
struct Node {
    device: UsbDevice,
    /// The hub and its port above, or none on a root port.
    parent: Option<(usize, u8)>,
    /// The root port the device is below.
    root_port: u8,
    /// Still plugged in.
    attached: bool,
    /// Reset since power came (USB 2.0 9.1.1: a device answers nothing
    /// before its first reset).
    reset: bool,
    address: u8,
    configuration: u8,
    alternate: u8,
    remote_wakeup: bool,
    control: Control,
    /// Endpoint 0x81's data PID.
    interrupt_toggle: bool,
    /// Endpoint 0x81 is halted.
    interrupt_halted: bool,
    keyboard: Keyboard,
    /// A hub's ports (none for the rest).
    ports: Vec<HubPort>,
    /// GET_DESCRIPTOR(DEVICE) requests still to be stalled (a device that
    /// fails its first enumerations, as real ones often do).
    descriptor_stalls: u32,
}

impl Node {
    fn new(device: UsbDevice, parent: Option<(usize, u8)>, root_port: u8) -> Node {
        let ports = match device {
            UsbDevice::Hub { ports, .. } => vec![HubPort::default(); usize::from(ports)],
            _ => Vec::new(),
        };
        Node {
            device,
            parent,
            root_port,
            attached: true,
            reset: false,
            address: 0,
            configuration: 0,
            alternate: 0,
            remote_wakeup: false,
            control: Control::Idle,
            interrupt_toggle: false,
            interrupt_halted: false,
            keyboard: Keyboard::default(),
            ports,
            descriptor_stalls: 0,
        }
    }

    /// Back to the state power-on leaves (its ports are the tree's business).
    fn power_on_state(&mut self) {
        self.reset = false;
        self.address = 0;
        self.configuration = 0;
        self.alternate = 0;
        self.remote_wakeup = false;
        self.control = Control::Idle;
        self.interrupt_toggle = false;
        self.interrupt_halted = false;
        self.keyboard = Keyboard::default();
    }
}

/// The tree of devices on a controller's root ports.
#[derive(Debug, Default)]
pub struct UsbTree {
    /// Every device ever plugged in; a handle is an index.
    nodes: Vec<Node>,
    /// Each root port's device.
    root: Vec<Option<usize>>,
    splits: Vec<(Split, Packet)>,
    errors: Vec<String>,
    /// The root ports are USB 1.1 (UHCI, OHCI): high-speed devices on
    /// them run at full speed.
    full_speed_root: bool,
}

impl UsbTree {
    /// A tree with `root_ports` empty root ports.
    pub fn new(root_ports: u8) -> UsbTree {
        UsbTree {
            root: vec![None; usize::from(root_ports)],
            ..UsbTree::default()
        }
    }

    /// Makes the root ports USB 1.1 ones (a UHCI or OHCI controller's):
    /// a high-speed device there runs at full speed, as does everything
    /// below it. Without this a root port takes a device at its own speed.
    pub fn set_root_ports_full_speed(&mut self) {
        self.full_speed_root = true;
    }

    /// Plugs `device` in at `path` (the parent hub must be there). Gives
    /// the new device's handle for the knobs below. The device is powered
    /// if its port is, and answers nothing until it has been reset; a hub
    /// port it is plugged into reports C_PORT_CONNECTION.
    ///
    /// Panics (the test is wrong) if the place is taken or not there, if a
    /// hub would be a sixth tier, or a hub is low speed or has 0 or more
    /// than [`MAX_HUB_PORTS`] ports.
    pub fn plug(&mut self, path: &[u8], device: UsbDevice) -> usize {
        let (&port, parent_path) = path.split_last().expect("a path names a root port");
        let hubs_above = parent_path.len();
        if let UsbDevice::Hub { speed, ports, .. } = device {
            assert!(speed != Speed::Low, "there are no low-speed hubs");
            assert!(
                (1..=MAX_HUB_PORTS).contains(&ports),
                "a hub with {ports} ports"
            );
            assert!(
                hubs_above < MAX_HUB_TIERS,
                "a hub at {path:?} would be tier {}",
                hubs_above + 1
            );
        }
        assert!(hubs_above <= MAX_HUB_TIERS, "{path:?} is too deep");
        let index = self.nodes.len();
        if parent_path.is_empty() {
            let slot = usize::from(port)
                .checked_sub(1)
                .and_then(|i| self.root.get_mut(i))
                .unwrap_or_else(|| panic!("no root port {port}"));
            assert!(slot.is_none(), "root port {port} is taken");
            *slot = Some(index);
            self.nodes.push(Node::new(device, None, port));
        } else {
            let hub = self
                .node_at(parent_path)
                .unwrap_or_else(|| panic!("no hub at {parent_path:?}"));
            let root_port = self.nodes[hub].root_port;
            let hub_port = usize::from(port)
                .checked_sub(1)
                .and_then(|i| self.nodes[hub].ports.get_mut(i))
                .unwrap_or_else(|| panic!("no hub port at {path:?}"));
            assert!(hub_port.child.is_none(), "{path:?} is taken");
            hub_port.child = Some(index);
            if hub_port.powered {
                hub_port.connect_change = true;
            }
            self.nodes
                .push(Node::new(device, Some((hub, port)), root_port));
        }
        index
    }

    /// Pulls out whatever is at `path`, with everything below it (nothing
    /// there: nothing happens). A hub port it was in loses its connection
    /// and enable and reports C_PORT_CONNECTION.
    pub fn unplug(&mut self, path: &[u8]) {
        let Some(index) = self.node_at(path) else {
            return;
        };
        self.detach(index);
        match self.nodes[index].parent {
            None => self.root[usize::from(path[0]) - 1] = None,
            Some((hub, port)) => {
                let hub_port = &mut self.nodes[hub].ports[usize::from(port) - 1];
                hub_port.child = None;
                if hub_port.powered {
                    hub_port.connect_change = true;
                }
                hub_port.enabled = false;
                hub_port.suspended = false;
            }
        }
    }

    /// Whether a device is attached to root port `port`, and its speed.
    pub fn root_device(&self, port: u8) -> Option<Speed> {
        self.root_node(port).map(|i| self.speed_of(i))
    }

    /// Resets the device on root port `port`: it goes back to the default
    /// address, unconfigured (a hub's ports with it are disabled).
    pub fn reset_root_port(&mut self, port: u8) {
        if let Some(index) = self.root_node(port) {
            self.bus_reset(index);
        }
    }

    /// One transaction on root port `port`. `split` is set when the
    /// controller sent it as a split transaction (EHCI); the tree answers
    /// [`Reply::Timeout`] if the split names the wrong hub or port, or if a
    /// full/low-speed device behind a high-speed hub is addressed without
    /// one, and records every split for the tests ([`Self::splits`]).
    ///
    /// The packet reaches the devices below the root port through powered,
    /// enabled, not suspended hub ports. The one device that answers is the
    /// one reset since power-on, at `packet.address`, running at
    /// `packet.speed`, and reached with exactly the split its place needs
    /// (none unless a high-speed hub's translator is above it).
    ///
    /// An IN's data packet is as long as the device's endpoint sends (up
    /// to its wMaxPacketSize), whatever `packet.max_packet` says: a reply
    /// longer than that is babble for the controller model to report.
    pub fn transact(&mut self, port: u8, packet: &Packet, split: Option<Split>) -> Reply {
        if let Some(split) = split {
            self.splits.push((split, packet.clone()));
        }
        let Some(root) = self.root_node(port) else {
            return Reply::Timeout;
        };
        let mut hearers = Vec::new();
        // Each device reached, with the translator above it (the nearest
        // high-speed hub and the port of it the subtree hangs from).
        let mut reached: Vec<(usize, Option<(usize, u8)>)> = vec![(root, None)];
        while let Some((index, translator)) = reached.pop() {
            let node = &self.nodes[index];
            if !node.reset {
                continue;
            }
            let speed = self.speed_of(index);
            // A dead device drives nothing onto the wire: it cannot collide.
            let silent = matches!(node.device, UsbDevice::Dead(_));
            if node.address == packet.address && !silent {
                let needed = translator.map(|(hub, hub_port)| Split {
                    hub_address: self.nodes[hub].address,
                    hub_port,
                });
                if split == needed && packet.speed == speed {
                    hearers.push(index);
                }
            }
            for (i, hub_port) in node.ports.iter().enumerate() {
                let Some(child) = hub_port.child else {
                    continue;
                };
                if !hub_port.powered || !hub_port.enabled || hub_port.suspended {
                    continue;
                }
                let port_number = i as u8 + 1;
                let below = match translator {
                    None if speed == Speed::High && self.speed_of(child) != Speed::High => {
                        Some((index, port_number))
                    }
                    other => other,
                };
                reached.push((child, below));
            }
        }
        match hearers[..] {
            [] => Reply::Timeout,
            [index] => self.answer(index, packet),
            _ => {
                let where_ = hearers
                    .iter()
                    .map(|&i| self.describe(i))
                    .collect::<Vec<_>>()
                    .join(", ");
                self.errors.push(format!(
                    "address {} answered by {} devices at once: {where_}",
                    packet.address,
                    hearers.len()
                ));
                Reply::Timeout
            }
        }
    }

    /// Every split transaction seen, with the packet, in order.
    pub fn splits(&self) -> &[(Split, Packet)] {
        &self.splits
    }

    /// Queues an 8-byte boot report on keyboard `device` (a handle from
    /// [`Self::plug`]); false if its queue is full, or the keyboard is
    /// unplugged or not configured (a keyboard reports only once
    /// configured; its queue empties at every reset).
    pub fn send_report(&mut self, device: usize, report: [u8; 8]) -> bool {
        let node = &mut self.nodes[device];
        assert!(node.device.is_keyboard(), "device {device} is no keyboard");
        if !node.attached || node.configuration == 0 || node.keyboard.reports.len() >= REPORT_QUEUE
        {
            return false;
        }
        node.keyboard.reports.push_back(report.to_vec());
        true
    }

    /// Queues a report of any length on keyboard `device`, cut into
    /// packets of 8 bytes (its endpoint's wMaxPacketSize), the last short
    /// (a zero-length one if the report fills whole packets and `end_with_empty`);
    /// false, with nothing queued, where [`Self::send_report`] would be.
    pub fn send_packets(&mut self, device: usize, report: &[u8], end_with_empty: bool) -> bool {
        let node = &mut self.nodes[device];
        assert!(node.device.is_keyboard(), "device {device} is no keyboard");
        let mut packets: Vec<Vec<u8>> = report.chunks(8).map(<[u8]>::to_vec).collect();
        if end_with_empty && report.len() % 8 == 0 {
            packets.push(Vec::new());
        }
        if !node.attached
            || node.configuration == 0
            || node.keyboard.reports.len() + packets.len() > REPORT_QUEUE
        {
            return false;
        }
        node.keyboard.reports.extend(packets);
        true
    }

    /// Makes keyboard `device` send its next report with the wrong toggle
    /// (as if the host's ACK of the previous one was lost): the host must
    /// drop the repeat and keep in step. The repeat is the last report
    /// sent, before any queued one; with none sent yet since the reset, the
    /// knob waits for one.
    pub fn repeat_next_toggle(&mut self, device: usize) {
        let node = &mut self.nodes[device];
        assert!(node.device.is_keyboard(), "device {device} is no keyboard");
        node.keyboard.repeat_next = true;
    }

    /// Makes `device` stall its next `times` GET_DESCRIPTOR(DEVICE)
    /// requests, whatever its address.
    pub fn stall_device_descriptor(&mut self, device: usize, times: u32) {
        self.nodes[device].descriptor_stalls = times;
    }

    /// Makes keyboard `device` stall its interrupt endpoint until a
    /// CLEAR_FEATURE(ENDPOINT_HALT).
    pub fn stall_interrupt(&mut self, device: usize) {
        let node = &mut self.nodes[device];
        assert!(node.device.is_keyboard(), "device {device} is no keyboard");
        node.interrupt_halted = true;
    }

    /// The protocol keyboard `device` is in (0 boot, 1 report), its
    /// configuration value (0: unconfigured) and its address.
    pub fn keyboard_state(&self, device: usize) -> (u8, u8, u8) {
        let node = &self.nodes[device];
        (node.keyboard.protocol, node.configuration, node.address)
    }

    // -----------------------------------------------------------------------
    // More for the tests.

    /// What the host did that a correct host never does, one line each.
    pub fn errors(&self) -> &[String] {
        &self.errors
    }

    /// The handle of the device at `path`, if one is plugged in there.
    pub fn handle_at(&self, path: &[u8]) -> Option<usize> {
        self.node_at(path)
    }

    /// Whether device `device` is still plugged in.
    pub fn is_attached(&self, device: usize) -> bool {
        self.nodes[device].attached
    }

    /// The speed device `device` runs at where it is.
    pub fn speed(&self, device: usize) -> Speed {
        self.speed_of(device)
    }

    /// Hub `hub`'s port `port` as GET_STATUS(port) gives it (see
    /// [`port_bits`]); `None` if there is no such port.
    pub fn port_status(&self, hub: usize, port: u8) -> Option<u32> {
        let hub_port = usize::from(port)
            .checked_sub(1)
            .and_then(|i| self.nodes[hub].ports.get(i))?;
        let connected = hub_port.powered && hub_port.child.is_some();
        let child_speed = hub_port.child.map(|child| self.speed_of(child));
        let bit = |on: bool, bit: u32| if on { bit } else { 0 };
        Some(
            bit(connected, port_bits::CONNECTION)
                | bit(hub_port.enabled, port_bits::ENABLE)
                | bit(hub_port.suspended, port_bits::SUSPEND)
                | bit(hub_port.powered, port_bits::POWER)
                | bit(
                    connected && child_speed == Some(Speed::Low),
                    port_bits::LOW_SPEED,
                )
                | bit(
                    hub_port.enabled && child_speed == Some(Speed::High),
                    port_bits::HIGH_SPEED,
                )
                | bit(hub_port.connect_change, port_bits::C_CONNECTION)
                | bit(hub_port.enable_change, port_bits::C_ENABLE)
                | bit(hub_port.suspend_change, port_bits::C_SUSPEND)
                | bit(hub_port.reset_change, port_bits::C_RESET),
        )
    }

    /// Whether the hub at USB address `address` runs a transaction
    /// translator per port (a multi-TT hub at high speed, its alternate
    /// setting 1 chosen); false for any other device or address.
    pub fn translator_per_port(&self, address: u8) -> bool {
        self.nodes.iter().enumerate().any(|(index, node)| {
            node.attached
                && node.reset
                && node.address == address
                && matches!(node.device, UsbDevice::Hub { multi_tt: true, .. })
                && self.speed_of(index) == Speed::High
                && node.alternate == 1
        })
    }

    /// The LED byte keyboard `device` was last given with SET_REPORT.
    pub fn leds(&self, device: usize) -> u8 {
        self.nodes[device].keyboard.leds
    }

    /// The idle rate keyboard `device` was given with SET_IDLE (4 ms units;
    /// 125 after a reset). Idle repeats are not modelled: a keyboard sends
    /// only the reports queued.
    pub fn idle(&self, device: usize) -> u8 {
        self.nodes[device].keyboard.idle
    }

    /// Reports queued on keyboard `device` and not sent yet.
    pub fn reports_queued(&self, device: usize) -> usize {
        self.nodes[device].keyboard.reports.len()
    }

    // -----------------------------------------------------------------------
    // The topology.

    fn root_node(&self, port: u8) -> Option<usize> {
        let slot = usize::from(port).checked_sub(1)?;
        *self.root.get(slot)?
    }

    fn node_at(&self, path: &[u8]) -> Option<usize> {
        let (&first, rest) = path.split_first()?;
        let mut node = self.root_node(first)?;
        for &port in rest {
            let slot = usize::from(port).checked_sub(1)?;
            node = self.nodes[node].ports.get(slot)?.child?;
        }
        Some(node)
    }

    /// The device's path, for messages.
    fn describe(&self, index: usize) -> String {
        let mut ports = Vec::new();
        let mut at = index;
        while let Some((hub, port)) = self.nodes[at].parent {
            ports.push(port);
            at = hub;
        }
        ports.push(self.nodes[index].root_port);
        let path: Vec<String> = ports.iter().rev().map(|p| format!("{p}")).collect();
        format!("device at {}", path.join("."))
    }

    fn error(&mut self, index: usize, what: &str) {
        let message = format!("{}: {what}", self.describe(index));
        self.errors.push(message);
    }

    /// The speed the device runs at: a high-speed device below a hub that
    /// is not high speed (or on a USB 1.1 root port) chirps in vain and
    /// stays at full speed.
    fn speed_of(&self, index: usize) -> Speed {
        let own = self.nodes[index].device.speed();
        let port_is_high_speed = match self.nodes[index].parent {
            Some((hub, _)) => self.speed_of(hub) == Speed::High,
            None => !self.full_speed_root,
        };
        if own == Speed::High && !port_is_high_speed {
            Speed::Full
        } else {
            own
        }
    }

    fn detach(&mut self, index: usize) {
        self.nodes[index].attached = false;
        let children: Vec<usize> = self.nodes[index]
            .ports
            .iter()
            .filter_map(|p| p.child)
            .collect();
        for child in children {
            self.detach(child);
        }
    }

    /// A bus reset (USB 2.0 9.1.1.3): the Default state, address 0; a
    /// hub's ports lose power (11.5.1.1), and the devices below with them.
    fn bus_reset(&mut self, index: usize) {
        self.nodes[index].power_on_state();
        self.nodes[index].reset = true;
        self.power_off_ports(index);
    }

    fn power_off(&mut self, index: usize) {
        self.nodes[index].power_on_state();
        self.power_off_ports(index);
    }

    fn power_off_ports(&mut self, index: usize) {
        for slot in 0..self.nodes[index].ports.len() {
            let child = self.nodes[index].ports[slot].child;
            self.nodes[index].ports[slot] = HubPort {
                child,
                ..HubPort::default()
            };
            if let Some(child) = child {
                self.power_off(child);
            }
        }
    }

    // -----------------------------------------------------------------------
    // One device's answers.

    fn answer(&mut self, index: usize, packet: &Packet) -> Reply {
        match (packet.endpoint, packet.pid) {
            (0, Pid::Setup) => self.setup_stage(index, packet),
            (0, Pid::In) => self.control_in(index, packet),
            (0, Pid::Out) => self.control_out(index, packet),
            (1, Pid::In) if self.nodes[index].configuration != 0 => {
                self.interrupt_in(index, packet)
            }
            (endpoint, pid) => {
                let state = if self.nodes[index].configuration == 0 {
                    " (not configured)"
                } else {
                    ""
                };
                self.error(
                    index,
                    &format!("{pid:?} to endpoint {endpoint}, which it does not have{state}"),
                );
                Reply::Timeout
            }
        }
    }

    fn ep0_max_packet(&self, index: usize) -> usize {
        let (device, _) = descriptors(&self.nodes[index].device, self.speed_of(index));
        usize::from(device.get(7).copied().unwrap_or(8))
    }

    /// A SETUP: always DATA0 and 8 bytes, always taken, and it ends
    /// whatever control transfer was under way (USB 2.0 8.5.3).
    fn setup_stage(&mut self, index: usize, packet: &Packet) -> Reply {
        if packet.toggle || packet.data.len() != 8 {
            self.error(
                index,
                &format!(
                    "a SETUP of {} bytes with DATA{}",
                    packet.data.len(),
                    u8::from(packet.toggle)
                ),
            );
            return Reply::Timeout;
        }
        let d = &packet.data;
        let setup = Setup {
            request_type: d[0],
            request: d[1],
            value: u16::from_le_bytes([d[2], d[3]]),
            index: u16::from_le_bytes([d[4], d[5]]),
            length: u16::from_le_bytes([d[6], d[7]]),
        };
        self.nodes[index].control = Control::Idle;
        let length = usize::from(setup.length);
        let out_data = setup.request_type == 0x21 && setup.request == SET_REPORT;
        let control = if !setup.is_in() && !out_data && length != 0 {
            self.error(
                index,
                &format!("request {setup:?}: an OUT data stage it has no use for"),
            );
            Control::Stalled
        } else {
            match self.request(index, setup) {
                None => Control::Stalled,
                Some(Response::In(mut bytes)) if length > 0 => {
                    bytes.truncate(length);
                    Control::DataIn {
                        bytes,
                        sent: 0,
                        length,
                        toggle: true,
                        ended: false,
                    }
                }
                Some(Response::Out(request)) if length > 0 => Control::DataOut {
                    request,
                    expected: length,
                    received: Vec::new(),
                    toggle: true,
                },
                Some(Response::SetAddress(address)) => Control::StatusIn {
                    new_address: Some(address),
                },
                Some(_) => Control::StatusIn { new_address: None },
            }
        };
        self.nodes[index].control = control;
        Reply::Ack
    }

    fn control_in(&mut self, index: usize, packet: &Packet) -> Reply {
        let max_packet = self.ep0_max_packet(index);
        match core::mem::take(&mut self.nodes[index].control) {
            Control::Idle => {
                self.error(index, "IN on endpoint 0 with no control transfer");
                Reply::Stall
            }
            Control::Stalled => {
                self.nodes[index].control = Control::Stalled;
                Reply::Stall
            }
            Control::DataIn {
                bytes,
                sent,
                length,
                toggle,
                ended,
            } => {
                if ended {
                    self.error(index, "IN past the end of the data stage");
                    self.nodes[index].control = Control::Stalled;
                    return Reply::Stall;
                }
                if packet.toggle != toggle {
                    self.error(
                        index,
                        &format!(
                            "data stage IN expects DATA{}, the device sends DATA{}",
                            u8::from(packet.toggle),
                            u8::from(toggle)
                        ),
                    );
                }
                let end = (sent + max_packet).min(bytes.len());
                let chunk = bytes[sent..end].to_vec();
                let ended = chunk.len() < max_packet || end == length;
                self.nodes[index].control = Control::DataIn {
                    bytes,
                    sent: end,
                    length,
                    toggle: !toggle,
                    ended,
                };
                Reply::Data {
                    bytes: chunk,
                    toggle,
                }
            }
            Control::DataOut {
                request,
                expected,
                received,
                toggle: _,
            } => {
                if received.len() < expected {
                    self.error(
                        index,
                        &format!(
                            "status IN after {} of {expected} data bytes",
                            received.len()
                        ),
                    );
                    self.nodes[index].control = Control::Stalled;
                    return Reply::Stall;
                }
                if !packet.toggle {
                    self.error(index, "status IN expects DATA0");
                }
                self.apply_out(index, request, &received);
                Reply::Data {
                    bytes: Vec::new(),
                    toggle: true,
                }
            }
            Control::StatusIn { new_address } => {
                if !packet.toggle {
                    self.error(index, "status IN expects DATA0");
                }
                if let Some(address) = new_address {
                    self.nodes[index].address = address;
                }
                Reply::Data {
                    bytes: Vec::new(),
                    toggle: true,
                }
            }
        }
    }

    fn control_out(&mut self, index: usize, packet: &Packet) -> Reply {
        let max_packet = self.ep0_max_packet(index);
        match core::mem::take(&mut self.nodes[index].control) {
            Control::Idle => {
                self.error(index, "OUT on endpoint 0 with no control transfer");
                Reply::Stall
            }
            Control::Stalled => {
                self.nodes[index].control = Control::Stalled;
                Reply::Stall
            }
            state @ Control::DataIn { .. } => {
                // The status stage (the host may end the data stage early).
                if !packet.data.is_empty() {
                    self.error(index, "status OUT with data");
                    self.nodes[index].control = Control::Stalled;
                    Reply::Stall
                } else if !packet.toggle {
                    // A DATA0 looks like a repeat of an earlier packet:
                    // taken and dropped, and the transfer goes on.
                    self.error(index, "status OUT with DATA0");
                    self.nodes[index].control = state;
                    Reply::Ack
                } else {
                    Reply::Ack
                }
            }
            Control::DataOut {
                request,
                expected,
                mut received,
                toggle,
            } => {
                if packet.toggle != toggle {
                    self.error(index, "data stage OUT repeats the previous toggle");
                    self.nodes[index].control = Control::DataOut {
                        request,
                        expected,
                        received,
                        toggle,
                    };
                    return Reply::Ack;
                }
                if packet.data.len() > max_packet || received.len() + packet.data.len() > expected {
                    self.error(
                        index,
                        &format!(
                            "data stage OUT of {} bytes after {} of {expected} (packets of {max_packet})",
                            packet.data.len(),
                            received.len()
                        ),
                    );
                    self.nodes[index].control = Control::Stalled;
                    return Reply::Stall;
                }
                received.extend_from_slice(&packet.data);
                self.nodes[index].control = Control::DataOut {
                    request,
                    expected,
                    received,
                    toggle: !toggle,
                };
                Reply::Ack
            }
            Control::StatusIn { .. } => {
                self.error(index, "OUT where the status stage is IN");
                self.nodes[index].control = Control::Stalled;
                Reply::Stall
            }
        }
    }

    fn apply_out(&mut self, index: usize, request: OutRequest, bytes: &[u8]) {
        match request {
            OutRequest::SetReport => {
                self.nodes[index].keyboard.leds = bytes.first().copied().unwrap_or(0);
            }
        }
    }

    fn interrupt_in(&mut self, index: usize, packet: &Packet) -> Reply {
        if self.nodes[index].interrupt_halted {
            return Reply::Stall;
        }
        let bytes = if self.nodes[index].device.is_keyboard() {
            let keyboard = &mut self.nodes[index].keyboard;
            if let (true, Some(last)) = (keyboard.repeat_next, keyboard.last.clone()) {
                // The ACK of `last` was lost: it comes again with the old
                // toggle, and this ACK flips the device's toggle back to
                // where the host already is.
                keyboard.repeat_next = false;
                return Reply::Data {
                    bytes: last,
                    toggle: !self.nodes[index].interrupt_toggle,
                };
            }
            let Some(report) = keyboard.reports.pop_front() else {
                return Reply::Nak;
            };
            keyboard.last = Some(report.clone());
            report
        } else {
            let bitmap = self.change_bitmap(index);
            if bitmap.iter().all(|&b| b == 0) {
                return Reply::Nak;
            }
            bitmap
        };
        let toggle = self.nodes[index].interrupt_toggle;
        if packet.toggle != toggle {
            self.error(
                index,
                &format!(
                    "interrupt IN expects DATA{}, the device sends DATA{}: the data is lost",
                    u8::from(packet.toggle),
                    u8::from(toggle)
                ),
            );
        }
        // The host ACKs every good data packet, whatever its toggle.
        self.nodes[index].interrupt_toggle = !toggle;
        Reply::Data { bytes, toggle }
    }

    /// A hub's status change bitmap (USB 2.0 11.12.4): bit n for port n,
    /// set while any of its change bits is.
    fn change_bitmap(&self, index: usize) -> Vec<u8> {
        let ports = self.nodes[index].ports.len();
        let mut bitmap = vec![0u8; (ports + 1).div_ceil(8)];
        for port in 1..=ports {
            let status = self.port_status(index, port as u8).unwrap_or(0);
            if status >> 16 != 0 {
                bitmap[port / 8] |= 1 << (port % 8);
            }
        }
        bitmap
    }

    // -----------------------------------------------------------------------
    // Requests. `None`: a request error, answered with STALL.

    fn request(&mut self, index: usize, setup: Setup) -> Option<Response> {
        match (setup.request_type >> 5) & 3 {
            0 => self.standard_request(index, setup),
            1 if matches!(self.nodes[index].device, UsbDevice::Hub { .. }) => {
                self.hub_request(index, setup)
            }
            1 if self.nodes[index].device.is_keyboard() => self.hid_request(index, setup),
            _ => None,
        }
    }

    fn standard_request(&mut self, index: usize, setup: Setup) -> Option<Response> {
        let speed = self.speed_of(index);
        let (device_descriptor, configuration) = descriptors(&self.nodes[index].device, speed);
        let multi_tt = matches!(
            self.nodes[index].device,
            UsbDevice::Hub { multi_tt: true, .. }
        ) && speed == Speed::High;
        let node = &mut self.nodes[index];
        let configured = node.configuration != 0;
        let attributes = configuration.get(7).copied().unwrap_or(0);
        match (setup.request_type, setup.request) {
            (0x80, GET_STATUS) => {
                let self_powered = attributes & 0x40 != 0;
                Some(Response::In(vec![
                    u8::from(self_powered) | u8::from(node.remote_wakeup) << 1,
                    0,
                ]))
            }
            (0x81, GET_STATUS) if configured && setup.index == 0 => Some(Response::In(vec![0, 0])),
            (0x82, GET_STATUS) => match setup.index {
                0x00 | 0x80 => Some(Response::In(vec![0, 0])),
                0x81 if configured => Some(Response::In(vec![u8::from(node.interrupt_halted), 0])),
                _ => None,
            },
            (0x00, CLEAR_FEATURE) if setup.value == DEVICE_REMOTE_WAKEUP => {
                node.remote_wakeup = false;
                Some(Response::NoData)
            }
            (0x00, SET_FEATURE)
                if setup.value == DEVICE_REMOTE_WAKEUP && attributes & 0x20 != 0 =>
            {
                node.remote_wakeup = true;
                Some(Response::NoData)
            }
            (0x02, CLEAR_FEATURE | SET_FEATURE) if setup.value == ENDPOINT_HALT => {
                match setup.index {
                    // Endpoint 0's stall clears at the next SETUP anyway.
                    0x00 | 0x80 => Some(Response::NoData),
                    0x81 if configured => {
                        node.interrupt_halted = setup.request == SET_FEATURE;
                        if setup.request == CLEAR_FEATURE {
                            // USB 2.0 9.4.5: the toggle goes back to DATA0.
                            node.interrupt_toggle = false;
                        }
                        Some(Response::NoData)
                    }
                    _ => None,
                }
            }
            (0x00, SET_ADDRESS) if setup.value <= 127 && setup.index == 0 && !configured => {
                Some(Response::SetAddress(setup.value as u8))
            }
            (0x80, GET_DESCRIPTOR) => {
                let has_strings = node.device.is_keyboard();
                let [number, kind] = setup.value.to_le_bytes();
                match (kind, number) {
                    (1, 0) if node.descriptor_stalls > 0 => {
                        node.descriptor_stalls -= 1;
                        None
                    }
                    (1, 0) => Some(Response::In(device_descriptor)),
                    (2, 0) => Some(Response::In(configuration)),
                    (3, 0) if has_strings => Some(Response::In(LANGUAGES.to_vec())),
                    (3, 1..=3) if has_strings => Some(Response::In(string_descriptor(
                        KEYBOARD_STRINGS[usize::from(number) - 1],
                    ))),
                    (6, 0) if node.device.speed() == Speed::High => {
                        // The device qualifier: how it would be at the
                        // other speed (USB 2.0 9.6.2).
                        let other = if speed == Speed::High {
                            Speed::Full
                        } else {
                            Speed::High
                        };
                        let (other_device, _) = descriptors(&node.device, other);
                        let mut qualifier = vec![10, 6];
                        qualifier.extend_from_slice(&other_device[2..8]);
                        qualifier.extend_from_slice(&[other_device[17], 0]);
                        Some(Response::In(qualifier))
                    }
                    _ => None,
                }
            }
            (0x81, GET_DESCRIPTOR) if node.device.is_keyboard() && setup.index == 0 => {
                match setup.value >> 8 {
                    0x21 => Some(Response::In(configuration[18..27].to_vec())),
                    0x22 => Some(Response::In(node.device.report_descriptor().to_vec())),
                    _ => None,
                }
            }
            (0x80, GET_CONFIGURATION) => Some(Response::In(vec![node.configuration])),
            // In the Default state SET_CONFIGURATION is not defined (9.4.7).
            (0x00, SET_CONFIGURATION) if node.address != 0 && setup.value <= 1 => {
                node.configuration = setup.value as u8;
                node.alternate = 0;
                node.interrupt_toggle = false;
                node.interrupt_halted = false;
                if setup.value == 0 {
                    self.power_off_ports(index);
                }
                Some(Response::NoData)
            }
            (0x81, GET_INTERFACE) if configured && setup.index == 0 => {
                Some(Response::In(vec![node.alternate]))
            }
            (0x01, SET_INTERFACE)
                if configured
                    && setup.index == 0
                    && (setup.value == 0 || (multi_tt && setup.value == 1)) =>
            {
                node.alternate = setup.value as u8;
                node.interrupt_toggle = false;
                node.interrupt_halted = false;
                Some(Response::NoData)
            }
            _ => None,
        }
    }

    fn hid_request(&mut self, index: usize, setup: Setup) -> Option<Response> {
        let node = &mut self.nodes[index];
        // HID class requests go to the one interface, once configured.
        if node.configuration == 0 || setup.index != 0 {
            return None;
        }
        let keyboard = &mut node.keyboard;
        match (setup.request_type, setup.request) {
            (0xA1, GET_REPORT) if setup.value == 0x0100 => Some(Response::In(
                keyboard.last.clone().unwrap_or_else(|| vec![0; 8]),
            )),
            (0xA1, GET_IDLE) if setup.value & 0xFF == 0 => Some(Response::In(vec![keyboard.idle])),
            (0xA1, GET_PROTOCOL) => Some(Response::In(vec![keyboard.protocol])),
            (0x21, SET_REPORT) if setup.value >> 8 == 2 => {
                Some(Response::Out(OutRequest::SetReport))
            }
            (0x21, SET_IDLE) => {
                keyboard.idle = (setup.value >> 8) as u8;
                Some(Response::NoData)
            }
            (0x21, SET_PROTOCOL) if setup.value <= 1 => {
                keyboard.protocol = setup.value as u8;
                Some(Response::NoData)
            }
            _ => None,
        }
    }

    fn hub_request(&mut self, index: usize, setup: Setup) -> Option<Response> {
        let configured = self.nodes[index].configuration != 0;
        let ports = self.nodes[index].ports.len();
        let high_speed = self.speed_of(index) == Speed::High;
        let port = usize::from(setup.index & 0xFF);
        let port_valid = configured && (1..=ports).contains(&port);
        match (setup.request_type, setup.request) {
            (0xA0, GET_DESCRIPTOR) if setup.value >> 8 == 0x29 => {
                Some(Response::In(hub_descriptor(ports as u8)))
            }
            (0xA0, GET_STATUS) => Some(Response::In(vec![0; 4])),
            // C_HUB_LOCAL_POWER, C_HUB_OVER_CURRENT: never set here.
            (0x20, CLEAR_FEATURE) if setup.value <= 1 => Some(Response::NoData),
            (0xA3, GET_STATUS) if port_valid => {
                let status = self.port_status(index, port as u8).unwrap_or(0);
                Some(Response::In(status.to_le_bytes().to_vec()))
            }
            (0x23, SET_FEATURE) if port_valid => self.set_port_feature(index, port, setup.value),
            (0x23, CLEAR_FEATURE) if port_valid => {
                self.clear_port_feature(index, port, setup.value)
            }
            (0x23, CLEAR_TT_BUFFER | RESET_TT | STOP_TT) if configured && high_speed => {
                Some(Response::NoData)
            }
            _ => None,
        }
    }

    fn set_port_feature(&mut self, index: usize, port: usize, feature: u16) -> Option<Response> {
        let hub_port = &mut self.nodes[index].ports[port - 1];
        match feature {
            PORT_SUSPEND => {
                if hub_port.enabled {
                    hub_port.suspended = true;
                }
            }
            PORT_RESET => {
                // On a port with nothing attached, or no power, the reset
                // is a no-op (USB 2.0 11.24.2.13).
                if let (true, Some(child)) = (hub_port.powered, hub_port.child) {
                    hub_port.enabled = true;
                    hub_port.suspended = false;
                    hub_port.reset_change = true;
                    self.bus_reset(child);
                }
            }
            PORT_POWER => {
                if !hub_port.powered {
                    hub_port.powered = true;
                    // The device there now sees power: a connection.
                    hub_port.connect_change = hub_port.child.is_some();
                }
            }
            PORT_TEST | PORT_INDICATOR => {}
            _ => return None,
        }
        Some(Response::NoData)
    }

    fn clear_port_feature(&mut self, index: usize, port: usize, feature: u16) -> Option<Response> {
        let hub_port = &mut self.nodes[index].ports[port - 1];
        match feature {
            PORT_ENABLE => {
                hub_port.enabled = false;
                hub_port.suspended = false;
            }
            PORT_SUSPEND => {
                if hub_port.suspended {
                    hub_port.suspended = false;
                    hub_port.suspend_change = true;
                }
            }
            PORT_POWER => {
                let child = hub_port.child;
                *hub_port = HubPort {
                    child,
                    ..HubPort::default()
                };
                if let Some(child) = child {
                    self.power_off(child);
                }
            }
            PORT_INDICATOR | C_PORT_OVER_CURRENT => {}
            C_PORT_CONNECTION => hub_port.connect_change = false,
            C_PORT_ENABLE => hub_port.enable_change = false,
            C_PORT_SUSPEND => hub_port.suspend_change = false,
            C_PORT_RESET => hub_port.reset_change = false,
            _ => return None,
        }
        Some(Response::NoData)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::descriptor;

    /// How the test's packets travel: the root port, the speed, the split.
    #[derive(Clone, Copy, Debug)]
    struct Route {
        port: u8,
        speed: Speed,
        split: Option<Split>,
    }

    const FULL_ON_1: Route = Route {
        port: 1,
        speed: Speed::Full,
        split: None,
    };

    fn setup(request_type: u8, request: u8, value: u16, index: u16, length: u16) -> Setup {
        Setup {
            request_type,
            request,
            value,
            index,
            length,
        }
    }

    fn get_descriptor(kind: u8, length: u16) -> Setup {
        setup(0x80, GET_DESCRIPTOR, u16::from(kind) << 8, 0, length)
    }

    /// One packet to `address` endpoint `endpoint`.
    fn send(
        tree: &mut UsbTree,
        route: Route,
        address: u8,
        endpoint: u8,
        pid: Pid,
        toggle: bool,
        data: &[u8],
    ) -> Reply {
        let packet = Packet {
            address,
            endpoint,
            pid,
            toggle,
            data: data.to_vec(),
            max_packet: 64,
            speed: route.speed,
        };
        tree.transact(route.port, &packet, route.split)
    }

    /// A control transfer as a controller runs it: the SETUP, data packets
    /// of at most `max_packet` bytes with alternating toggles from DATA1,
    /// the zero-length DATA1 status the other way. The bytes read, or the
    /// reply that ended it.
    fn control(
        tree: &mut UsbTree,
        route: Route,
        address: u8,
        request: Setup,
        out: &[u8],
        max_packet: usize,
    ) -> Result<Vec<u8>, Reply> {
        let mut send = |pid, toggle, data: &[u8]| send(tree, route, address, 0, pid, toggle, data);
        match send(Pid::Setup, false, &request.bytes()) {
            Reply::Ack => {}
            other => return Err(other),
        }
        let mut got = Vec::new();
        let mut toggle = true;
        if request.is_in() && request.length > 0 {
            loop {
                match send(Pid::In, toggle, &[]) {
                    Reply::Data {
                        bytes,
                        toggle: sent,
                    } => {
                        assert_eq!(sent, toggle, "data stage toggle");
                        assert!(bytes.len() <= max_packet, "babble: {} bytes", bytes.len());
                        let short = bytes.len() < max_packet;
                        got.extend(bytes);
                        toggle = !toggle;
                        if short || got.len() >= usize::from(request.length) {
                            break;
                        }
                    }
                    other => return Err(other),
                }
            }
            match send(Pid::Out, true, &[]) {
                Reply::Ack => Ok(got),
                other => Err(other),
            }
        } else {
            for chunk in out.chunks(max_packet) {
                match send(Pid::Out, toggle, chunk) {
                    Reply::Ack => toggle = !toggle,
                    other => return Err(other),
                }
            }
            match send(Pid::In, true, &[]) {
                Reply::Data {
                    bytes,
                    toggle: true,
                } if bytes.is_empty() => Ok(got),
                other => Err(other),
            }
        }
    }

    /// Enumerates the device at address 0 as a driver does: the first 8
    /// bytes of its device descriptor, SET_ADDRESS, the whole descriptor,
    /// the configuration's header then all of it, SET_CONFIGURATION(1).
    /// Gives the device and configuration descriptors.
    fn enumerate(tree: &mut UsbTree, route: Route, address: u8) -> (Vec<u8>, Vec<u8>) {
        let first = control(tree, route, 0, get_descriptor(1, 8), &[], 8).unwrap();
        let max_packet = usize::from(descriptor::device(&first).unwrap().max_packet_0);
        control(
            tree,
            route,
            0,
            setup(0, SET_ADDRESS, address.into(), 0, 0),
            &[],
            8,
        )
        .unwrap();
        let device = control(tree, route, address, get_descriptor(1, 18), &[], max_packet).unwrap();
        let header = control(tree, route, address, get_descriptor(2, 9), &[], max_packet).unwrap();
        let total = descriptor::configuration_total_length(&header).unwrap();
        let configuration = control(
            tree,
            route,
            address,
            get_descriptor(2, total),
            &[],
            max_packet,
        )
        .unwrap();
        control(
            tree,
            route,
            address,
            setup(0, SET_CONFIGURATION, 1, 0, 0),
            &[],
            max_packet,
        )
        .unwrap();
        (device, configuration)
    }

    fn interrupt(tree: &mut UsbTree, route: Route, address: u8, toggle: bool) -> Reply {
        send(tree, route, address, 1, Pid::In, toggle, &[])
    }

    #[test]
    fn a_keyboard_is_enumerated_by_hand_through_packets() {
        let mut tree = UsbTree::new(2);
        let keyboard = tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        assert_eq!(tree.root_device(1), Some(Speed::Full));
        assert_eq!(tree.root_device(2), None);
        // Before its reset a device answers nothing.
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        tree.reset_root_port(1);
        let (device, configuration) = enumerate(&mut tree, FULL_ON_1, 5);
        assert_eq!(device, KEYBOARD_DEVICE);
        assert_eq!(configuration, KEYBOARD_CONFIGURATION);
        let parsed = descriptor::configuration(&configuration).unwrap();
        assert!(matches!(
            parsed.function,
            Some(descriptor::Function::Keyboard { boot: true, .. })
        ));
        let report = control(
            &mut tree,
            FULL_ON_1,
            5,
            setup(0x81, GET_DESCRIPTOR, 0x2200, 0, 63),
            &[],
            8,
        );
        assert_eq!(report.unwrap(), KEYBOARD_REPORT_DESCRIPTOR);
        for request in [
            setup(0x21, SET_PROTOCOL, 0, 0, 0),
            setup(0x21, SET_IDLE, 0, 0, 0),
        ] {
            control(&mut tree, FULL_ON_1, 5, request, &[], 8).unwrap();
        }
        control(
            &mut tree,
            FULL_ON_1,
            5,
            setup(0x21, SET_REPORT, 0x0200, 0, 1),
            &[0b010],
            8,
        )
        .unwrap();
        assert_eq!(tree.keyboard_state(keyboard), (0, 1, 5));
        assert_eq!((tree.leds(keyboard), tree.idle(keyboard)), (0b010, 0));
        // The interrupt endpoint: NAK until a report, then DATA0, DATA1.
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 5, false), Reply::Nak);
        let reports = [[0, 0, 4, 0, 0, 0, 0, 0], [0, 0, 0, 0, 0, 0, 0, 0]];
        for report in reports {
            assert!(tree.send_report(keyboard, report));
        }
        for (i, report) in reports.iter().enumerate() {
            assert_eq!(
                interrupt(&mut tree, FULL_ON_1, 5, i == 1),
                Reply::Data {
                    bytes: report.to_vec(),
                    toggle: i == 1
                }
            );
        }
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 5, false), Reply::Nak);
        assert_eq!(tree.errors(), &[] as &[String]);
    }

    #[test]
    fn set_address_takes_effect_after_the_status_stage() {
        let mut tree = UsbTree::new(1);
        let keyboard = tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        let set_address = setup(0, SET_ADDRESS, 7, 0, 0).bytes();
        let r = FULL_ON_1;
        assert_eq!(
            send(&mut tree, r, 0, 0, Pid::Setup, false, &set_address),
            Reply::Ack
        );
        // Until the status stage ends the device is still at 0.
        let get = get_descriptor(1, 8).bytes();
        assert_eq!(
            send(&mut tree, r, 7, 0, Pid::Setup, false, &get),
            Reply::Timeout
        );
        assert_eq!(tree.keyboard_state(keyboard).2, 0);
        assert_eq!(
            send(&mut tree, r, 0, 0, Pid::In, true, &[]),
            Reply::Data {
                bytes: Vec::new(),
                toggle: true
            }
        );
        assert_eq!(tree.keyboard_state(keyboard).2, 7);
        assert_eq!(
            send(&mut tree, r, 0, 0, Pid::Setup, false, &get),
            Reply::Timeout
        );
        assert_eq!(
            control(&mut tree, r, 7, get_descriptor(1, 8), &[], 8).unwrap(),
            KEYBOARD_DEVICE[..8]
        );
        // A SET_ADDRESS whose status stage never comes changes nothing.
        let again = setup(0, SET_ADDRESS, 9, 0, 0).bytes();
        assert_eq!(
            send(&mut tree, r, 7, 0, Pid::Setup, false, &again),
            Reply::Ack
        );
        assert_eq!(
            send(&mut tree, r, 7, 0, Pid::Setup, false, &get),
            Reply::Ack
        );
        assert_eq!(tree.keyboard_state(keyboard).2, 7);
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn control_stages_keep_to_chapter_8() {
        let mut tree = UsbTree::new(1);
        tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        let r = FULL_ON_1;
        enumerate(&mut tree, r, 3);
        // wLength cuts the reply; packets are 8 bytes, toggles alternate
        // (the helper checks both).
        let cut = control(&mut tree, r, 3, get_descriptor(2, 20), &[], 8).unwrap();
        assert_eq!(cut, KEYBOARD_CONFIGURATION[..20]);
        // A request the device does not know: the SETUP is taken, the
        // data stage stalls, and stays stalled until the next SETUP.
        let unknown = setup(0x80, 0x33, 0, 0, 4).bytes();
        assert_eq!(
            send(&mut tree, r, 3, 0, Pid::Setup, false, &unknown),
            Reply::Ack
        );
        assert_eq!(send(&mut tree, r, 3, 0, Pid::In, true, &[]), Reply::Stall);
        assert_eq!(send(&mut tree, r, 3, 0, Pid::In, true, &[]), Reply::Stall);
        assert_eq!(send(&mut tree, r, 3, 0, Pid::Out, true, &[]), Reply::Stall);
        assert_eq!(
            control(&mut tree, r, 3, setup(0x80, GET_STATUS, 0, 0, 2), &[], 8).unwrap(),
            [0, 0]
        );
        // A SETUP in the middle of a data stage starts afresh at DATA1.
        let config = get_descriptor(2, 34).bytes();
        assert_eq!(
            send(&mut tree, r, 3, 0, Pid::Setup, false, &config),
            Reply::Ack
        );
        assert!(matches!(
            send(&mut tree, r, 3, 0, Pid::In, true, &[]),
            Reply::Data { toggle: true, .. }
        ));
        assert!(matches!(
            send(&mut tree, r, 3, 0, Pid::In, false, &[]),
            Reply::Data { toggle: false, .. }
        ));
        let device = control(&mut tree, r, 3, get_descriptor(1, 18), &[], 8).unwrap();
        assert_eq!(device, KEYBOARD_DEVICE);
        // An IN past wLength stalls: the data stage is over.
        let eight = get_descriptor(1, 8).bytes();
        assert_eq!(
            send(&mut tree, r, 3, 0, Pid::Setup, false, &eight),
            Reply::Ack
        );
        assert!(matches!(
            send(&mut tree, r, 3, 0, Pid::In, true, &[]),
            Reply::Data { .. }
        ));
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
        assert_eq!(send(&mut tree, r, 3, 0, Pid::In, false, &[]), Reply::Stall);
        assert_eq!(tree.errors().len(), 1, "{:?}", tree.errors());
        // A SETUP with DATA1 is not a SETUP: no answer, and it is noted.
        assert_eq!(
            send(&mut tree, r, 3, 0, Pid::Setup, true, &eight),
            Reply::Timeout
        );
        assert_eq!(tree.errors().len(), 2, "{:?}", tree.errors());
        // The strings: 0 the languages, 2 the product in UTF-16LE.
        assert_eq!(
            control(&mut tree, r, 3, get_descriptor(3, 255), &[], 8).unwrap(),
            LANGUAGES
        );
        let product = control(
            &mut tree,
            r,
            3,
            setup(0x80, GET_DESCRIPTOR, 0x0302, 0x0409, 255),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(usize::from(product[0]), product.len());
        let text: Vec<u16> = product[2..]
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        assert_eq!(String::from_utf16(&text).unwrap(), KEYBOARD_STRINGS[1]);
        // SET_CONFIGURATION to a configuration it does not have stalls in
        // the status stage.
        assert_eq!(
            control(
                &mut tree,
                r,
                3,
                setup(0, SET_CONFIGURATION, 2, 0, 0),
                &[],
                8
            ),
            Err(Reply::Stall)
        );
        // A status OUT with data stalls.
        assert_eq!(
            send(&mut tree, r, 3, 0, Pid::Setup, false, &eight),
            Reply::Ack
        );
        assert!(matches!(
            send(&mut tree, r, 3, 0, Pid::In, true, &[]),
            Reply::Data { .. }
        ));
        assert_eq!(send(&mut tree, r, 3, 0, Pid::Out, true, &[1]), Reply::Stall);
        // Endpoint 1 OUT does not exist.
        assert_eq!(
            send(&mut tree, r, 3, 1, Pid::Out, false, &[0]),
            Reply::Timeout
        );
        assert_eq!(tree.errors().len(), 4, "{:?}", tree.errors());
    }

    /// Configures the hub at `address` and powers and resets its `port`,
    /// clearing the changes that brings: the device there is at address 0.
    fn bring_up_port(tree: &mut UsbTree, route: Route, address: u8, max_packet: usize, port: u16) {
        for request in [
            setup(0x23, SET_FEATURE, PORT_POWER, port, 0),
            setup(0x23, CLEAR_FEATURE, C_PORT_CONNECTION, port, 0),
            setup(0x23, SET_FEATURE, PORT_RESET, port, 0),
            setup(0x23, CLEAR_FEATURE, C_PORT_RESET, port, 0),
        ] {
            control(tree, route, address, request, &[], max_packet).unwrap();
        }
    }

    fn hub_port_status(
        tree: &mut UsbTree,
        route: Route,
        address: u8,
        max_packet: usize,
        port: u16,
    ) -> u32 {
        let bytes = control(
            tree,
            route,
            address,
            setup(0xA3, GET_STATUS, 0, port, 4),
            &[],
            max_packet,
        )
        .unwrap();
        u32::from_le_bytes(bytes.try_into().unwrap())
    }

    #[test]
    fn a_hub_port_reset_enables_the_port_and_resets_the_device() {
        use port_bits::*;
        let mut tree = UsbTree::new(1);
        let hub = tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let keyboard = tree.plug(&[1, 3], UsbDevice::Keyboard(Speed::Full));
        tree.plug(&[1, 4], UsbDevice::Keyboard(Speed::Low));
        tree.reset_root_port(1);
        let r = FULL_ON_1;
        let (device, configuration) = enumerate(&mut tree, r, 1);
        assert_eq!(device, HUB_DEVICE);
        assert!(matches!(
            descriptor::configuration(&configuration).unwrap().function,
            Some(descriptor::Function::Hub {
                status_change: Some(_)
            })
        ));
        let hub_descriptor = control(
            &mut tree,
            r,
            1,
            setup(0xA0, GET_DESCRIPTOR, 0x2900, 0, 71),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(descriptor::hub(&hub_descriptor).unwrap().ports, 4);
        // Unpowered ports say nothing, and their devices are not reached.
        assert_eq!(hub_port_status(&mut tree, r, 1, 8, 3), 0);
        assert_eq!(interrupt(&mut tree, r, 1, false), Reply::Nak);
        for port in 1..=4 {
            control(
                &mut tree,
                r,
                1,
                setup(0x23, SET_FEATURE, PORT_POWER, port, 0),
                &[],
                8,
            )
            .unwrap();
        }
        assert_eq!(hub_port_status(&mut tree, r, 1, 8, 1), POWER);
        assert_eq!(
            hub_port_status(&mut tree, r, 1, 8, 3),
            POWER | CONNECTION | C_CONNECTION
        );
        assert_eq!(
            hub_port_status(&mut tree, r, 1, 8, 4),
            POWER | CONNECTION | LOW_SPEED | C_CONNECTION
        );
        // The status change endpoint: bits 3 and 4.
        assert_eq!(
            interrupt(&mut tree, r, 1, false),
            Reply::Data {
                bytes: vec![0b1_1000],
                toggle: false
            }
        );
        // Connected but not enabled: the keyboard is not reached.
        assert_eq!(
            control(&mut tree, r, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        control(
            &mut tree,
            r,
            1,
            setup(0x23, SET_FEATURE, PORT_RESET, 3, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(
            hub_port_status(&mut tree, r, 1, 8, 3),
            POWER | CONNECTION | ENABLE | C_CONNECTION | C_RESET
        );
        for change in [C_PORT_CONNECTION, C_PORT_RESET] {
            control(
                &mut tree,
                r,
                1,
                setup(0x23, CLEAR_FEATURE, change, 3, 0),
                &[],
                8,
            )
            .unwrap();
        }
        control(
            &mut tree,
            r,
            1,
            setup(0x23, CLEAR_FEATURE, C_PORT_CONNECTION, 4, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(
            hub_port_status(&mut tree, r, 1, 8, 3),
            POWER | CONNECTION | ENABLE
        );
        assert_eq!(interrupt(&mut tree, r, 1, true), Reply::Nak);
        enumerate(&mut tree, r, 2);
        assert_eq!(tree.keyboard_state(keyboard), (1, 1, 2));
        // A second reset puts the keyboard back at address 0, unconfigured.
        control(
            &mut tree,
            r,
            1,
            setup(0x23, SET_FEATURE, PORT_RESET, 3, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(tree.keyboard_state(keyboard), (1, 0, 0));
        assert_eq!(
            interrupt(&mut tree, r, 1, true),
            Reply::Data {
                bytes: vec![0b1000],
                toggle: true
            }
        );
        assert_eq!(
            control(&mut tree, r, 2, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        assert_eq!(
            control(&mut tree, r, 0, get_descriptor(1, 8), &[], 8).unwrap(),
            KEYBOARD_DEVICE[..8]
        );
        // The hub's own reset powers its ports off (USB 2.0 11.5.1.1).
        tree.reset_root_port(1);
        assert_eq!(tree.port_status(hub, 3), Some(0));
        assert_eq!(tree.keyboard_state(keyboard), (1, 0, 0));
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn port_requests_out_of_range_or_before_configuration_stall() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 2,
                multi_tt: false,
            },
        );
        tree.reset_root_port(1);
        let r = FULL_ON_1;
        control(&mut tree, r, 0, setup(0, SET_ADDRESS, 1, 0, 0), &[], 8).unwrap();
        let power = setup(0x23, SET_FEATURE, PORT_POWER, 1, 0);
        assert_eq!(control(&mut tree, r, 1, power, &[], 8), Err(Reply::Stall));
        control(
            &mut tree,
            r,
            1,
            setup(0, SET_CONFIGURATION, 1, 0, 0),
            &[],
            8,
        )
        .unwrap();
        control(&mut tree, r, 1, power, &[], 8).unwrap();
        for port in [0, 3] {
            let status = setup(0xA3, GET_STATUS, 0, port, 4);
            assert_eq!(control(&mut tree, r, 1, status, &[], 8), Err(Reply::Stall));
        }
        let enable = setup(0x23, SET_FEATURE, PORT_ENABLE, 1, 0);
        assert_eq!(control(&mut tree, r, 1, enable, &[], 8), Err(Reply::Stall));
        // A full-speed hub has no translator to clear.
        let clear_tt = setup(0x23, CLEAR_TT_BUFFER, 0, 1, 0);
        assert_eq!(
            control(&mut tree, r, 1, clear_tt, &[], 8),
            Err(Reply::Stall)
        );
    }

    /// A high-speed hub on root port 1 at address 1 with a full-speed hub
    /// (address 2) on its port 2, a low-speed keyboard (address 3) on
    /// that hub's port 4, and a full-speed keyboard (address 4) on the
    /// high-speed hub's port 3, all enumerated. Gives the handles.
    fn translated_tree() -> (UsbTree, [usize; 4]) {
        let mut tree = UsbTree::new(1);
        let high = Route {
            port: 1,
            speed: Speed::High,
            split: None,
        };
        let hs_hub = tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::High,
                ports: 4,
                multi_tt: false,
            },
        );
        let fs_hub = tree.plug(
            &[1, 2],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let low_keyboard = tree.plug(&[1, 2, 4], UsbDevice::Keyboard(Speed::Low));
        let full_keyboard = tree.plug(&[1, 3], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        let (device, _) = enumerate(&mut tree, high, 1);
        assert_eq!(device, HIGH_SPEED_HUB_DEVICE);
        let below_2 = Route {
            speed: Speed::Full,
            split: Some(Split {
                hub_address: 1,
                hub_port: 2,
            }),
            ..high
        };
        let below_3 = Route {
            speed: Speed::Full,
            split: Some(Split {
                hub_address: 1,
                hub_port: 3,
            }),
            ..high
        };
        bring_up_port(&mut tree, high, 1, 64, 2);
        enumerate(&mut tree, below_2, 2);
        bring_up_port(&mut tree, below_2, 2, 8, 4);
        enumerate(
            &mut tree,
            Route {
                speed: Speed::Low,
                ..below_2
            },
            3,
        );
        bring_up_port(&mut tree, high, 1, 64, 3);
        enumerate(&mut tree, below_3, 4);
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
        (tree, [hs_hub, fs_hub, low_keyboard, full_keyboard])
    }

    #[test]
    fn splits_must_name_the_nearest_high_speed_hub_and_port() {
        let (mut tree, [hs_hub, _, low_keyboard, full_keyboard]) = translated_tree();
        assert_eq!(tree.keyboard_state(low_keyboard), (1, 1, 3));
        assert_eq!(tree.keyboard_state(full_keyboard), (1, 1, 4));
        assert_eq!(
            tree.port_status(hs_hub, 3).unwrap() & (port_bits::HIGH_SPEED | port_bits::LOW_SPEED),
            0
        );
        let split = |hub_address, hub_port| {
            Some(Split {
                hub_address,
                hub_port,
            })
        };
        let get = get_descriptor(1, 8);
        let splits_before = tree.splits().len();
        let mut expected = Vec::new();
        for (speed, address, split, answers) in [
            (Speed::Full, 4, split(1, 3), true),
            (Speed::Full, 4, None, false),
            (Speed::High, 4, None, false),
            (Speed::Full, 4, split(1, 2), false),
            (Speed::Full, 4, split(2, 3), false),
            (Speed::Low, 4, split(1, 3), false),
            (Speed::Low, 3, split(1, 2), true),
            // The nearest high-speed hub, not the full-speed one above it.
            (Speed::Low, 3, split(2, 4), false),
            (Speed::Full, 3, split(1, 2), false),
            (Speed::Full, 2, split(1, 2), true),
            // The high-speed hub itself takes no split.
            (Speed::High, 1, None, true),
            (Speed::High, 1, split(1, 1), false),
            (Speed::Full, 1, split(1, 1), false),
        ] {
            let route = Route {
                port: 1,
                speed,
                split,
            };
            let reply = control(&mut tree, route, address, get, &[], 8);
            assert_eq!(
                reply.is_ok(),
                answers,
                "{speed:?} to {address} with {split:?}: {reply:?}"
            );
            // Every split packet is recorded: SETUP, IN, OUT when the
            // device answered, the SETUP alone when not.
            if let Some(split) = split {
                let pids: &[Pid] = if answers {
                    &[Pid::Setup, Pid::In, Pid::Out]
                } else {
                    &[Pid::Setup]
                };
                expected.extend(pids.iter().map(|&pid| (split, address, pid, speed)));
            }
        }
        let recorded: Vec<_> = tree.splits()[splits_before..]
            .iter()
            .map(|(split, packet)| (*split, packet.address, packet.pid, packet.speed))
            .collect();
        assert_eq!(recorded, expected);
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn a_split_to_a_device_with_no_translator_above_times_out() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        tree.plug(&[1, 1], UsbDevice::Keyboard(Speed::Low));
        tree.reset_root_port(1);
        let get = get_descriptor(1, 8);
        let split = Route {
            split: Some(Split {
                hub_address: 0,
                hub_port: 1,
            }),
            ..FULL_ON_1
        };
        assert_eq!(
            control(&mut tree, split, 0, get, &[], 8),
            Err(Reply::Timeout)
        );
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        // Below a full-speed hub a low-speed device takes low-speed
        // packets (PRE), and nothing else.
        let low = Route {
            speed: Speed::Low,
            ..FULL_ON_1
        };
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get, &[], 8),
            Err(Reply::Timeout)
        );
        let split_low = Route {
            split: Some(Split {
                hub_address: 1,
                hub_port: 1,
            }),
            ..low
        };
        assert_eq!(
            control(&mut tree, split_low, 0, get, &[], 8),
            Err(Reply::Timeout)
        );
        assert_eq!(
            control(&mut tree, low, 0, get, &[], 8).unwrap(),
            LOW_SPEED_KEYBOARD_DEVICE[..8]
        );
        assert_eq!(tree.splits().len(), 2);
    }

    #[test]
    fn a_high_speed_hub_below_a_full_speed_hub_runs_at_full_speed() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let inner = tree.plug(
            &[1, 2],
            UsbDevice::Hub {
                speed: Speed::High,
                ports: 4,
                multi_tt: true,
            },
        );
        let keyboard = tree.plug(&[1, 2, 1], UsbDevice::Keyboard(Speed::High));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 2);
        let (device, configuration) = enumerate(&mut tree, FULL_ON_1, 2);
        assert_eq!(
            device, HUB_DEVICE,
            "protocol 0: no translator at full speed"
        );
        assert_eq!(configuration, HUB_CONFIGURATION);
        assert_eq!(tree.speed(inner), Speed::Full);
        // Its qualifier tells how it would be at high speed: multi TT.
        let qualifier = control(&mut tree, FULL_ON_1, 2, get_descriptor(6, 10), &[], 8).unwrap();
        assert_eq!(qualifier, [10, 6, 0, 2, 9, 0, 2, 64, 1, 0]);
        bring_up_port(&mut tree, FULL_ON_1, 2, 8, 1);
        assert_eq!(
            tree.port_status(inner, 1).unwrap() & port_bits::HIGH_SPEED,
            0
        );
        let (device, _) = enumerate(&mut tree, FULL_ON_1, 3);
        assert_eq!(device, KEYBOARD_DEVICE);
        assert_eq!(tree.keyboard_state(keyboard), (1, 1, 3));
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn a_multi_tt_hub_offers_its_second_alternate_setting() {
        let mut tree = UsbTree::new(1);
        let high = Route {
            port: 1,
            speed: Speed::High,
            split: None,
        };
        let hub = tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::High,
                ports: 9,
                multi_tt: true,
            },
        );
        let keyboard = tree.plug(&[1, 9], UsbDevice::Keyboard(Speed::High));
        tree.reset_root_port(1);
        let (device, configuration) = enumerate(&mut tree, high, 1);
        assert_eq!(device, HIGH_SPEED_MULTI_TT_HUB_DEVICE);
        assert_eq!(
            configuration.len(),
            HIGH_SPEED_MULTI_TT_HUB_CONFIGURATION.len()
        );
        // Nine ports and bit 0: a 2-byte bitmap on both alternates' endpoints.
        assert_eq!((configuration[22], configuration[38]), (2, 2));
        let hub_descriptor = control(
            &mut tree,
            high,
            1,
            setup(0xA0, GET_DESCRIPTOR, 0x2900, 0, 71),
            &[],
            64,
        )
        .unwrap();
        assert_eq!(hub_descriptor.len(), 11);
        assert_eq!(descriptor::hub(&hub_descriptor).unwrap().ports, 9);
        for alternate in [1, 0, 1] {
            control(
                &mut tree,
                high,
                1,
                setup(1, SET_INTERFACE, alternate, 0, 0),
                &[],
                64,
            )
            .unwrap();
            let got = control(
                &mut tree,
                high,
                1,
                setup(0x81, GET_INTERFACE, 0, 0, 1),
                &[],
                64,
            )
            .unwrap();
            assert_eq!(got, [alternate as u8]);
        }
        assert_eq!(
            control(
                &mut tree,
                high,
                1,
                setup(1, SET_INTERFACE, 2, 0, 0),
                &[],
                64
            ),
            Err(Reply::Stall)
        );
        for request in [
            setup(0x23, CLEAR_TT_BUFFER, 0, 9, 0),
            setup(0x23, RESET_TT, 0, 9, 0),
        ] {
            control(&mut tree, high, 1, request, &[], 64).unwrap();
        }
        bring_up_port(&mut tree, high, 1, 64, 9);
        assert_ne!(tree.port_status(hub, 9).unwrap() & port_bits::HIGH_SPEED, 0);
        // A high-speed keyboard below a high-speed hub: no split.
        let (device, configuration) = enumerate(&mut tree, high, 2);
        assert_eq!(
            (device, configuration),
            (
                HIGH_SPEED_KEYBOARD_DEVICE.to_vec(),
                HIGH_SPEED_KEYBOARD_CONFIGURATION.to_vec()
            )
        );
        assert_eq!(tree.keyboard_state(keyboard), (1, 1, 2));
        // Bitmap bit 9 sits in the second byte.
        control(
            &mut tree,
            high,
            1,
            setup(0x23, CLEAR_FEATURE, PORT_POWER, 9, 0),
            &[],
            64,
        )
        .unwrap();
        tree.unplug(&[1, 9]);
        control(
            &mut tree,
            high,
            1,
            setup(0x23, SET_FEATURE, PORT_POWER, 9, 0),
            &[],
            64,
        )
        .unwrap();
        tree.plug(&[1, 9], UsbDevice::Keyboard(Speed::Full));
        assert_eq!(
            interrupt(&mut tree, high, 1, false),
            Reply::Data {
                bytes: vec![0, 0b10],
                toggle: false
            }
        );
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    /// A full-speed keyboard on root port 1, enumerated at `address` and
    /// in the boot protocol.
    fn boot_keyboard(address: u8) -> (UsbTree, usize) {
        let mut tree = UsbTree::new(1);
        let keyboard = tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, address);
        control(
            &mut tree,
            FULL_ON_1,
            address,
            setup(0x21, SET_PROTOCOL, 0, 0, 0),
            &[],
            8,
        )
        .unwrap();
        (tree, keyboard)
    }

    #[test]
    fn a_repeated_toggle_is_dropped_and_the_keyboard_stays_in_step() {
        let (mut tree, keyboard) = boot_keyboard(1);
        let a = [0, 0, 4, 0, 0, 0, 0, 0];
        let b = [0, 0, 5, 0, 0, 0, 0, 0];
        // The knob waits for a report to repeat.
        tree.repeat_next_toggle(keyboard);
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, false), Reply::Nak);
        assert!(tree.send_report(keyboard, a));
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, false),
            Reply::Data {
                bytes: a.to_vec(),
                toggle: false
            }
        );
        assert!(tree.send_report(keyboard, b));
        // The repeat of A comes with DATA0 where the host expects DATA1:
        // the host drops it and still expects DATA1, which B comes with.
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, true),
            Reply::Data {
                bytes: a.to_vec(),
                toggle: false
            }
        );
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, true),
            Reply::Data {
                bytes: b.to_vec(),
                toggle: true
            }
        );
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, false), Reply::Nak);
        assert_eq!(tree.reports_queued(keyboard), 0);
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
        // A host out of step loses the report, and the tree says so.
        assert!(tree.send_report(keyboard, a));
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, true),
            Reply::Data {
                bytes: a.to_vec(),
                toggle: false
            }
        );
        assert_eq!(tree.errors().len(), 1);
    }

    #[test]
    fn the_report_queue_is_bounded_and_needs_a_configured_keyboard() {
        let mut tree = UsbTree::new(1);
        let keyboard = tree.plug(&[1], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        assert!(!tree.send_report(keyboard, [0; 8]), "not configured yet");
        enumerate(&mut tree, FULL_ON_1, 1);
        for _ in 0..REPORT_QUEUE {
            assert!(tree.send_report(keyboard, [0; 8]));
        }
        assert!(!tree.send_report(keyboard, [0; 8]));
        tree.reset_root_port(1);
        assert_eq!(tree.reports_queued(keyboard), 0);
    }

    #[test]
    fn a_stalled_interrupt_endpoint_clears_to_data0() {
        let (mut tree, keyboard) = boot_keyboard(1);
        let report = [0, 0, 4, 0, 0, 0, 0, 0];
        assert!(tree.send_report(keyboard, report));
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, false),
            Reply::Data {
                bytes: report.to_vec(),
                toggle: false
            }
        );
        tree.stall_interrupt(keyboard);
        assert!(tree.send_report(keyboard, report));
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, true), Reply::Stall);
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, true), Reply::Stall);
        let status = setup(0x82, GET_STATUS, 0, 0x81, 2);
        assert_eq!(
            control(&mut tree, FULL_ON_1, 1, status, &[], 8).unwrap(),
            [1, 0]
        );
        // The endpoint's halt, not ep0's: a SETUP does not clear it.
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x02, CLEAR_FEATURE, ENDPOINT_HALT, 0x81, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(
            control(&mut tree, FULL_ON_1, 1, status, &[], 8).unwrap(),
            [0, 0]
        );
        // DATA0 again, though DATA1 was next before the stall.
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, false),
            Reply::Data {
                bytes: report.to_vec(),
                toggle: false
            }
        );
        // SET_FEATURE(ENDPOINT_HALT) halts it from the host's side too.
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x02, SET_FEATURE, ENDPOINT_HALT, 0x81, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, true), Reply::Stall);
        // A halt on an endpoint it does not have is a request error.
        let other = setup(0x02, CLEAR_FEATURE, ENDPOINT_HALT, 0x82, 0);
        assert_eq!(
            control(&mut tree, FULL_ON_1, 1, other, &[], 8),
            Err(Reply::Stall)
        );
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn unplugging_below_a_hub_reports_a_connection_change() {
        use port_bits::*;
        let mut tree = UsbTree::new(1);
        let hub = tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let first = tree.plug(&[1, 2], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 2);
        enumerate(&mut tree, FULL_ON_1, 2);
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, false), Reply::Nak);
        tree.unplug(&[1, 2]);
        assert!(!tree.is_attached(first));
        assert_eq!(tree.handle_at(&[1, 2]), None);
        assert!(!tree.send_report(first, [0; 8]));
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, false),
            Reply::Data {
                bytes: vec![0b100],
                toggle: false
            }
        );
        assert_eq!(
            hub_port_status(&mut tree, FULL_ON_1, 1, 8, 2),
            POWER | C_CONNECTION
        );
        assert_eq!(
            control(&mut tree, FULL_ON_1, 2, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x23, CLEAR_FEATURE, C_PORT_CONNECTION, 2, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(interrupt(&mut tree, FULL_ON_1, 1, true), Reply::Nak);
        // Plugged in again: a new device, in its power-on state.
        let second = tree.plug(&[1, 2], UsbDevice::Keyboard(Speed::Low));
        assert_ne!(first, second);
        assert_eq!(
            tree.port_status(hub, 2),
            Some(POWER | CONNECTION | LOW_SPEED | C_CONNECTION)
        );
        assert_eq!(
            interrupt(&mut tree, FULL_ON_1, 1, true),
            Reply::Data {
                bytes: vec![0b100],
                toggle: true
            }
        );
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 2);
        enumerate(
            &mut tree,
            Route {
                speed: Speed::Low,
                ..FULL_ON_1
            },
            2,
        );
        assert_eq!(tree.keyboard_state(second), (1, 1, 2));
        // Pulling the hub pulls everything below it.
        tree.unplug(&[1]);
        assert_eq!(tree.root_device(1), None);
        assert!(!tree.is_attached(second));
        assert_eq!(
            control(&mut tree, FULL_ON_1, 1, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn powering_a_hub_port_off_and_on_needs_a_new_reset() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        let keyboard = tree.plug(&[1, 1], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        enumerate(&mut tree, FULL_ON_1, 2);
        let power = |set| {
            setup(
                0x23,
                if set { SET_FEATURE } else { CLEAR_FEATURE },
                PORT_POWER,
                1,
                0,
            )
        };
        control(&mut tree, FULL_ON_1, 1, power(false), &[], 8).unwrap();
        assert_eq!(tree.keyboard_state(keyboard), (1, 0, 0));
        assert_eq!(hub_port_status(&mut tree, FULL_ON_1, 1, 8, 1), 0);
        control(&mut tree, FULL_ON_1, 1, power(true), &[], 8).unwrap();
        assert_eq!(
            hub_port_status(&mut tree, FULL_ON_1, 1, 8, 1),
            port_bits::POWER | port_bits::CONNECTION | port_bits::C_CONNECTION
        );
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        // Disabled: not reached even after the reset.
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x23, CLEAR_FEATURE, PORT_ENABLE, 1, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        // Suspended: not reached until resumed (C_PORT_SUSPEND then).
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x23, SET_FEATURE, PORT_SUSPEND, 1, 0),
            &[],
            8,
        )
        .unwrap();
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        control(
            &mut tree,
            FULL_ON_1,
            1,
            setup(0x23, CLEAR_FEATURE, PORT_SUSPEND, 1, 0),
            &[],
            8,
        )
        .unwrap();
        assert_ne!(
            hub_port_status(&mut tree, FULL_ON_1, 1, 8, 1) & port_bits::C_SUSPEND,
            0
        );
        assert!(control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8).is_ok());
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn five_tiers_of_hubs_reach_a_keyboard() {
        let mut tree = UsbTree::new(1);
        let high = Route {
            port: 1,
            speed: Speed::High,
            split: None,
        };
        let mut path = vec![1];
        for _ in 0..MAX_HUB_TIERS {
            tree.plug(
                &path,
                UsbDevice::Hub {
                    speed: Speed::High,
                    ports: 4,
                    multi_tt: false,
                },
            );
            path.push(4);
        }
        let keyboard = tree.plug(&path, UsbDevice::Keyboard(Speed::Low));
        tree.reset_root_port(1);
        for tier in 1..=MAX_HUB_TIERS as u8 {
            enumerate(&mut tree, high, tier);
            bring_up_port(&mut tree, high, tier, 64, 4);
        }
        // The translator is the last hub's, port 4.
        let low = Route {
            speed: Speed::Low,
            split: Some(Split {
                hub_address: 5,
                hub_port: 4,
            }),
            ..high
        };
        enumerate(&mut tree, low, 6);
        assert_eq!(tree.keyboard_state(keyboard), (1, 1, 6));
        assert!(tree.send_report(keyboard, [1; 8]));
        assert_eq!(
            interrupt(&mut tree, low, 6, false),
            Reply::Data {
                bytes: vec![1; 8],
                toggle: false
            }
        );
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    #[should_panic(expected = "tier 6")]
    fn a_sixth_tier_of_hubs_is_refused() {
        let mut tree = UsbTree::new(1);
        let mut path = vec![1];
        for _ in 0..=MAX_HUB_TIERS {
            tree.plug(
                &path,
                UsbDevice::Hub {
                    speed: Speed::Full,
                    ports: 4,
                    multi_tt: false,
                },
            );
            path.push(1);
        }
    }

    #[test]
    fn two_devices_at_address_0_collide() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        tree.plug(&[1, 1], UsbDevice::Keyboard(Speed::Full));
        tree.plug(&[1, 2], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 2);
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        assert_eq!(tree.errors().len(), 1, "{:?}", tree.errors());
        assert!(
            tree.errors()[0].contains("device at 1.1, device at 1.2")
                || tree.errors()[0].contains("device at 1.2, device at 1.1"),
            "{:?}",
            tree.errors()
        );
    }

    #[test]
    fn a_dead_device_answers_nothing() {
        let mut tree = UsbTree::new(2);
        tree.plug(&[2], UsbDevice::Dead(Speed::Full));
        assert_eq!(tree.root_device(2), Some(Speed::Full));
        tree.reset_root_port(2);
        let route = Route {
            port: 2,
            ..FULL_ON_1
        };
        assert_eq!(
            control(&mut tree, route, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        assert_eq!(
            send(&mut tree, route, 0, 0, Pid::In, true, &[]),
            Reply::Timeout
        );
        assert_eq!(
            send(&mut tree, route, 0, 1, Pid::In, false, &[]),
            Reply::Timeout
        );
        // Nor does an empty root port.
        assert_eq!(
            control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 8), &[], 8),
            Err(Reply::Timeout)
        );
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn the_lying_keyboard_is_refused_by_the_parser() {
        let mut tree = UsbTree::new(1);
        tree.plug(&[1], UsbDevice::LyingKeyboard(Speed::Full));
        tree.reset_root_port(1);
        let device = control(&mut tree, FULL_ON_1, 0, get_descriptor(1, 18), &[], 8).unwrap();
        assert_eq!(device, KEYBOARD_DEVICE);
        let header = control(&mut tree, FULL_ON_1, 0, get_descriptor(2, 9), &[], 8).unwrap();
        let total = descriptor::configuration_total_length(&header).unwrap();
        let all = control(&mut tree, FULL_ON_1, 0, get_descriptor(2, total), &[], 8).unwrap();
        assert!(all.len() < usize::from(total), "{} of {total}", all.len());
        assert_eq!(
            descriptor::configuration(&all),
            Err(descriptor::DescriptorError::BadLength(0))
        );
    }

    #[test]
    fn the_descriptors_are_what_they_say() {
        for (name, device) in [
            ("keyboard", &KEYBOARD_DEVICE),
            ("low-speed keyboard", &LOW_SPEED_KEYBOARD_DEVICE),
            ("high-speed keyboard", &HIGH_SPEED_KEYBOARD_DEVICE),
            ("hub", &HUB_DEVICE),
            ("high-speed hub", &HIGH_SPEED_HUB_DEVICE),
            ("multi-TT hub", &HIGH_SPEED_MULTI_TT_HUB_DEVICE),
        ] {
            let parsed = descriptor::device(device).unwrap();
            assert_eq!(usize::from(device[0]), device.len(), "{name}");
            assert_eq!(parsed.configurations, 1, "{name}");
        }
        for (name, configuration, hub) in [
            ("keyboard", &KEYBOARD_CONFIGURATION[..], false),
            (
                "high-speed keyboard",
                &HIGH_SPEED_KEYBOARD_CONFIGURATION[..],
                false,
            ),
            ("hub", &HUB_CONFIGURATION[..], true),
            ("high-speed hub", &HIGH_SPEED_HUB_CONFIGURATION[..], true),
            (
                "multi-TT hub",
                &HIGH_SPEED_MULTI_TT_HUB_CONFIGURATION[..],
                true,
            ),
        ] {
            let total = descriptor::configuration_total_length(configuration).unwrap();
            assert_eq!(usize::from(total), configuration.len(), "{name}");
            let function = descriptor::configuration(configuration).unwrap().function;
            assert_eq!(
                matches!(function, Some(descriptor::Function::Hub { .. })),
                hub,
                "{name}"
            );
        }
        assert_eq!(hub_descriptor(7).len(), 9);
        assert_eq!(hub_descriptor(8).len(), 11);
        assert_eq!(descriptor::hub(&hub_descriptor(4)).unwrap().ports, 4);
        assert_eq!(descriptor::hub(&HUB_DESCRIPTOR).unwrap().ports, 4);
        assert_eq!(
            (
                LOW_SPEED_KEYBOARD_DEVICE[7],
                HIGH_SPEED_KEYBOARD_DEVICE[7],
                HIGH_SPEED_HUB_DEVICE[7]
            ),
            (8, 64, 64)
        );
        assert_eq!(
            (
                HIGH_SPEED_HUB_DEVICE[6],
                HIGH_SPEED_MULTI_TT_HUB_DEVICE[6],
                HUB_DEVICE[6]
            ),
            (1, 2, 0)
        );
        assert_eq!(
            descriptor::configuration_total_length(&LYING_KEYBOARD_CONFIGURATION),
            Ok(64)
        );
    }

    #[test]
    fn a_high_speed_hub_on_a_usb_1_1_root_port_runs_at_full_speed() {
        let mut tree = UsbTree::new(1);
        tree.set_root_ports_full_speed();
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::High,
                ports: 4,
                multi_tt: false,
            },
        );
        let keyboard = tree.plug(&[1, 1], UsbDevice::Keyboard(Speed::Full));
        assert_eq!(tree.root_device(1), Some(Speed::Full));
        tree.reset_root_port(1);
        let (device, _) = enumerate(&mut tree, FULL_ON_1, 1);
        assert_eq!(device, HUB_DEVICE);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        enumerate(&mut tree, FULL_ON_1, 2);
        assert_eq!(tree.keyboard_state(keyboard), (1, 1, 2));
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }

    #[test]
    fn a_dead_device_at_address_0_does_not_collide() {
        let mut tree = UsbTree::new(1);
        tree.plug(
            &[1],
            UsbDevice::Hub {
                speed: Speed::Full,
                ports: 4,
                multi_tt: false,
            },
        );
        tree.plug(&[1, 1], UsbDevice::Dead(Speed::Full));
        tree.plug(&[1, 2], UsbDevice::Keyboard(Speed::Full));
        tree.reset_root_port(1);
        enumerate(&mut tree, FULL_ON_1, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 1);
        bring_up_port(&mut tree, FULL_ON_1, 1, 8, 2);
        enumerate(&mut tree, FULL_ON_1, 2);
        assert!(tree.errors().is_empty(), "{:?}", tree.errors());
    }
}
