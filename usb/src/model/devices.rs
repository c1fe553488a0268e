//! The device side of the bus, shared by the EHCI, OHCI and UHCI register
//! models: a tree of USB devices (keyboards, hubs with transaction
//! translators, devices that misbehave) that answers packets the way real
//! devices do. A controller model turns its transfer descriptors into
//! [`Packet`]s, hands them to [`UsbTree::transact`], and writes the
//! [`Reply`] back into its descriptors.
//!
//! INTERFACE FIXED BY THE LEAD: the signatures below are what the controller
//! models are written against. The bodies are filled in by the device-model
//! work; add methods freely, change these only with the lead.

#![allow(dead_code)]

use crate::host::Speed;
use std::vec::Vec;

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
pub enum Device {
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
}

/// The tree of devices on a controller's root ports.
#[derive(Debug, Default)]
pub struct UsbTree {
    // Filled in by the device-model work.
}

impl UsbTree {
    /// A tree with `root_ports` empty root ports.
    pub fn new(root_ports: u8) -> UsbTree {
        let _ = root_ports;
        todo!()
    }

    /// Plugs `device` in at `path` (the parent hub must be there). Gives
    /// the new device's handle for the knobs below.
    pub fn plug(&mut self, path: &[u8], device: Device) -> usize {
        let _ = (path, device);
        todo!()
    }

    /// Pulls out whatever is at `path`, with everything below it.
    pub fn unplug(&mut self, path: &[u8]) {
        let _ = path;
        todo!()
    }

    /// Whether a device is attached to root port `port`, and its speed.
    pub fn root_device(&self, port: u8) -> Option<Speed> {
        let _ = port;
        todo!()
    }

    /// Resets the device on root port `port`: it goes back to the default
    /// address, unconfigured (a hub's ports with it are disabled).
    pub fn reset_root_port(&mut self, port: u8) {
        let _ = port;
        todo!()
    }

    /// One transaction on root port `port`. `split` is set when the
    /// controller sent it as a split transaction (EHCI); the tree answers
    /// [`Reply::Timeout`] if the split names the wrong hub or port, or if a
    /// full/low-speed device behind a high-speed hub is addressed without
    /// one, and records every split for the tests ([`Self::splits`]).
    pub fn transact(&mut self, port: u8, packet: &Packet, split: Option<Split>) -> Reply {
        let _ = (port, packet, split);
        todo!()
    }

    /// Every split transaction seen, with the packet, in order.
    pub fn splits(&self) -> &[(Split, Packet)] {
        todo!()
    }

    /// Queues an 8-byte boot report on keyboard `device` (a handle from
    /// [`Self::plug`]); false if its queue is full.
    pub fn send_report(&mut self, device: usize, report: [u8; 8]) -> bool {
        let _ = (device, report);
        todo!()
    }

    /// Makes keyboard `device` send its next report with the wrong toggle
    /// (as if the host's ACK of the previous one was lost): the host must
    /// drop the repeat and keep in step.
    pub fn repeat_next_toggle(&mut self, device: usize) {
        let _ = device;
        todo!()
    }

    /// Makes keyboard `device` stall its interrupt endpoint until a
    /// CLEAR_FEATURE(ENDPOINT_HALT).
    pub fn stall_interrupt(&mut self, device: usize) {
        let _ = device;
        todo!()
    }

    /// The protocol keyboard `device` is in (0 boot, 1 report), its
    /// configuration value (0: unconfigured) and its address.
    pub fn keyboard_state(&self, device: usize) -> (u8, u8, u8) {
        let _ = device;
        todo!()
    }
}
