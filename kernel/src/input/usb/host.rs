//! The four drivers as one type, [`Host`], under one device layer
//! (`Bus<Host>`): the device layer is generic over its controller, and one
//! copy of its code for the four kinds instead of four keeps the kernel
//! file inside its budget (`tests/size.rs`). Each call is passed to the
//! driver inside; the match costs a compare.

use super::hardware::Registers;
use crate::{pci, serial_println};
use core::fmt;
use usb::ehci::Ehci;
use usb::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, Setup, Transfer,
};
use usb::ohci::Ohci;
use usb::uhci::Uhci;
use usb::xhci::Xhci;

/// A host controller driver, of whichever kind.
// The drivers live in the controller table (no heap): an xHCI's device
// table is the largest, and every place has room for it.
#[allow(clippy::large_enum_variant)]
pub enum Host {
    Ehci(Ehci<Registers>),
    Ohci(Ohci<Registers>),
    Uhci(Uhci<Registers>),
    Xhci(Xhci<Registers>),
}

/// Runs `$body` with `$driver` bound to the driver inside `$host`.
macro_rules! each {
    ($host:expr, |$driver:ident| $body:expr) => {
        match $host {
            Host::Ehci($driver) => $body,
            Host::Ohci($driver) => $body,
            Host::Uhci($driver) => $body,
            Host::Xhci($driver) => $body,
        }
    };
}

/// Why a driver would not start, whichever it is.
pub struct StartProblem(StartError);

enum StartError {
    Ehci(usb::ehci::EhciError),
    Ohci(usb::ohci::OhciError),
    Uhci(usb::uhci::UhciError),
    Xhci(usb::xhci::XhciError),
}

impl fmt::Display for StartProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.0 {
            StartError::Ehci(problem) => write!(f, "{problem}"),
            StartError::Ohci(problem) => write!(f, "{problem}"),
            StartError::Uhci(problem) => write!(f, "{problem}"),
            StartError::Xhci(problem) => write!(f, "{problem}"),
        }
    }
}

impl Host {
    /// Takes the controller from the firmware (bounded). An xHCI the
    /// firmware never lets go of is taken anyway after 1 s, as Linux does.
    pub fn take_ownership(&mut self) -> Handoff {
        match self {
            Host::Ehci(driver) => driver.take_ownership(),
            Host::Ohci(driver) => driver.take_ownership(),
            Host::Uhci(driver) => driver.take_ownership(),
            Host::Xhci(xhci) => {
                let capabilities = xhci.capabilities();
                serial_println!(
                    "usb: xHCI {}, {} ports, {}-byte contexts, {} scratchpad pages",
                    xhci.hardware().function,
                    capabilities.ports,
                    capabilities.layout.context_bytes,
                    capabilities.scratchpads
                );
                match xhci.take_ownership() {
                    usb::xhci::Handoff::Forced => {
                        serial_println!(
                            "usb: the firmware did not let go of the xHCI within 1 s; taken anyway"
                        );
                        Handoff::NotOwned
                    }
                    usb::xhci::Handoff::Released(micros) => Handoff::Released { micros },
                    usb::xhci::Handoff::NoLegacyCapability | usb::xhci::Handoff::NotOwned => {
                        Handoff::NotOwned
                    }
                }
            }
        }
    }

    /// Resets and starts the controller (bounded waits).
    pub fn reset_and_start(&mut self) -> Result<(), StartProblem> {
        match self {
            Host::Ehci(ehci) => ehci
                .reset_and_start()
                .map_err(|e| StartProblem(StartError::Ehci(e))),
            Host::Ohci(ohci) => ohci
                .reset_and_start()
                .map_err(|e| StartProblem(StartError::Ohci(e))),
            Host::Uhci(uhci) => uhci
                .reset_and_start()
                .map_err(|e| StartProblem(StartError::Uhci(e))),
            Host::Xhci(xhci) => {
                // Intel's switchable ports routed to the xHCI first, as Linux does.
                if let Some(routed) = pci::route_intel_ports_to_xhci(xhci.hardware().function) {
                    serial_println!(
                        "usb: Intel PCH ports switched to the xHCI (XUSB2PR {:#x})",
                        routed
                    );
                }
                // The No Op proves the command and event rings work.
                xhci.reset_and_start()
                    .and_then(|()| xhci.no_op())
                    .map_err(|e| StartProblem(StartError::Xhci(e)))
            }
        }
    }

    /// After an xHCI's halt: Intel's switched ports handed back to the
    /// EHCI (some 7-series boards otherwise power straight back on).
    pub fn hand_ports_back(&mut self) {
        let Host::Xhci(xhci) = self else {
            return;
        };
        if let Some((usb2, superspeed)) =
            pci::hand_intel_ports_back_to_ehci(xhci.hardware().function)
        {
            serial_println!(
                "usb: Intel PCH ports handed back to the EHCI (XUSB2PR {:#x}, USB3_PSSEN {:#x})",
                usb2,
                superspeed
            );
        }
    }
}

impl HostController for Host {
    fn kind(&self) -> ControllerKind {
        each!(self, |driver| driver.kind())
    }

    type Hardware = Registers;

    fn hardware(&mut self) -> &mut Registers {
        each!(self, |driver| driver.hardware())
    }

    fn root_ports(&self) -> u8 {
        each!(self, |driver| driver.root_ports())
    }

    fn port_status(&mut self, port: u8) -> PortStatus {
        each!(self, |driver| driver.port_status(port))
    }

    fn clear_port_change(&mut self, port: u8) {
        each!(self, |driver| driver.clear_port_change(port))
    }

    fn port_reset_begin(&mut self, port: u8) {
        each!(self, |driver| driver.port_reset_begin(port))
    }

    fn port_reset_end(&mut self, port: u8) -> ResetOutcome {
        each!(self, |driver| driver.port_reset_end(port))
    }

    fn port_disable(&mut self, port: u8) {
        each!(self, |driver| driver.port_disable(port))
    }

    fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError> {
        each!(self, |driver| driver.device_new(info))
    }

    fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError> {
        each!(self, |driver| driver.device_set_address(device, address))
    }

    fn device_set_max_packet(
        &mut self,
        device: DeviceId,
        max_packet: u16,
    ) -> Result<(), HostError> {
        each!(self, |driver| driver
            .device_set_max_packet(device, max_packet))
    }

    fn device_is_hub(
        &mut self,
        device: DeviceId,
        ports: u8,
        multi_tt: bool,
    ) -> Result<(), HostError> {
        each!(self, |driver| driver.device_is_hub(device, ports, multi_tt))
    }

    fn device_remove(&mut self, device: DeviceId) {
        each!(self, |driver| driver.device_remove(device))
    }

    fn control_begin(
        &mut self,
        device: DeviceId,
        setup: Setup,
        out: &[u8],
    ) -> Result<(), HostError> {
        each!(self, |driver| driver.control_begin(device, setup, out))
    }

    fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer {
        each!(self, |driver| driver.control_poll(device, into))
    }

    fn control_cancel(&mut self, device: DeviceId) {
        each!(self, |driver| driver.control_cancel(device))
    }

    fn interrupt_open(
        &mut self,
        device: DeviceId,
        endpoint: u8,
        max_packet: u16,
        interval: u8,
    ) -> Result<PipeId, HostError> {
        each!(self, |driver| driver
            .interrupt_open(device, endpoint, max_packet, interval))
    }

    fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer {
        each!(self, |driver| driver.interrupt_poll(pipe, into))
    }

    fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError> {
        each!(self, |driver| driver.interrupt_restart(pipe, reset_toggle))
    }

    fn interrupt_close(&mut self, pipe: PipeId) {
        each!(self, |driver| driver.interrupt_close(pipe))
    }

    #[inline]
    fn anything_happened(&mut self) -> bool {
        each!(self, |driver| driver.anything_happened())
    }

    /// An xHCI is also reset and its ports switched off (`Xhci::shut_down`).
    fn halt(&mut self) -> bool {
        each!(self, |driver| driver.halt())
    }
}
