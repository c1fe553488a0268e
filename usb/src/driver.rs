//! The four drivers as one type, [`Driver`], so that one device layer
//! (`Bus<Driver<H>>`) serves every kind: the device layer is generic over
//! its controller, and one copy of it for the four kinds instead of four
//! keeps the kernel file inside its budget (`tests/size.rs`). Each call is
//! passed to the driver inside; the match costs a compare.

use crate::ehci::{Ehci, EhciError};
use crate::host::{
    ControllerKind, DeviceId, DeviceInfo, Handoff, HostController, HostError, PipeId, PortStatus,
    ResetOutcome, Setup, Transfer,
};
use crate::ohci::{Ohci, OhciError};
use crate::uhci::{Uhci, UhciError};
use crate::xhci::{Xhci, XhciError};
use crate::PciHardware;
use core::fmt;

/// A host controller driver, of whichever kind.
// The drivers live in the kernel's controller table (no heap): an xHCI's
// device table is the largest, and every place has room for it.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum Driver<H: PciHardware> {
    /// An EHCI (USB 2.0).
    Ehci(Ehci<H>),
    /// An OHCI (USB 1.1).
    Ohci(Ohci<H>),
    /// A UHCI (USB 1.1).
    Uhci(Uhci<H>),
    /// An xHCI (every speed).
    Xhci(Xhci<H>),
}

/// Why a driver would not be made or started, whichever it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriverError {
    /// The EHCI driver's reason.
    Ehci(EhciError),
    /// The OHCI driver's reason.
    Ohci(OhciError),
    /// The UHCI driver's reason.
    Uhci(UhciError),
    /// The xHCI driver's reason.
    Xhci(XhciError),
}

impl fmt::Display for DriverError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DriverError::Ehci(problem) => problem.fmt(f),
            DriverError::Ohci(problem) => problem.fmt(f),
            DriverError::Uhci(problem) => problem.fmt(f),
            DriverError::Xhci(problem) => problem.fmt(f),
        }
    }
}

/// Runs `$body` with `$driver` bound to the driver inside `$host`.
macro_rules! each {
    ($host:expr, |$driver:ident| $body:expr) => {
        match $host {
            Driver::Ehci($driver) => $body,
            Driver::Ohci($driver) => $body,
            Driver::Uhci($driver) => $body,
            Driver::Xhci($driver) => $body,
        }
    };
}

/// The [`HostController`] methods that only pass their call on.
macro_rules! pass_on {
    ($($(#[$attribute:meta])* fn $name:ident(&mut self $(, $argument:ident: $type:ty)*) $(-> $result:ty)?;)*) => {
        $($(#[$attribute])* fn $name(&mut self $(, $argument: $type)*) $(-> $result)? {
            each!(self, |driver| driver.$name($($argument),*))
        })*
    };
}

impl<H: PciHardware> Driver<H> {
    /// The driver of `kind` over `hardware`: `mmio_bytes` of registers (an
    /// EHCI's, OHCI's or xHCI's BAR0; a UHCI's registers are I/O ports) and
    /// the DMA memory `dma_base` to `dma_base + dma_bytes`.
    #[optimize(size)] // run once at start-up: small beats fast
    pub fn new(
        kind: ControllerKind,
        hardware: H,
        mmio_bytes: u32,
        dma_base: u64,
        dma_bytes: u64,
    ) -> Result<Driver<H>, DriverError> {
        Ok(match kind {
            ControllerKind::Ehci => Driver::Ehci(
                Ehci::new(hardware, mmio_bytes, dma_base, dma_bytes).map_err(DriverError::Ehci)?,
            ),
            ControllerKind::Ohci => Driver::Ohci(
                Ohci::new(hardware, mmio_bytes, dma_base, dma_bytes).map_err(DriverError::Ohci)?,
            ),
            ControllerKind::Uhci => {
                Driver::Uhci(Uhci::new(hardware, dma_base, dma_bytes).map_err(DriverError::Uhci)?)
            }
            ControllerKind::Xhci => Driver::Xhci(
                Xhci::new(hardware, mmio_bytes, dma_base, dma_bytes).map_err(DriverError::Xhci)?,
            ),
        })
    }
}

impl<H: PciHardware> HostController for Driver<H> {
    type Hardware = H;
    type StartError = DriverError;

    #[optimize(size)] // run once at start-up: small beats fast
    fn reset_and_start(&mut self) -> Result<(), DriverError> {
        match self {
            Driver::Ehci(ehci) => ehci.reset_and_start().map_err(DriverError::Ehci),
            Driver::Ohci(ohci) => ohci.reset_and_start().map_err(DriverError::Ohci),
            Driver::Uhci(uhci) => uhci.reset_and_start().map_err(DriverError::Uhci),
            Driver::Xhci(xhci) => xhci.reset_and_start().map_err(DriverError::Xhci),
        }
    }

    fn kind(&self) -> ControllerKind {
        each!(self, |driver| driver.kind())
    }

    fn root_ports(&self) -> u8 {
        each!(self, |driver| driver.root_ports())
    }

    pass_on! {
        fn hardware(&mut self) -> &mut H;
        fn take_ownership(&mut self) -> Handoff;
        fn port_status(&mut self, port: u8) -> PortStatus;
        fn clear_port_change(&mut self, port: u8);
        fn port_reset_begin(&mut self, port: u8);
        fn port_reset_poll(&mut self, port: u8) -> Option<ResetOutcome>;
        fn port_disable(&mut self, port: u8);
        fn device_new(&mut self, info: DeviceInfo) -> Result<DeviceId, HostError>;
        fn address_begin(&mut self, device: DeviceId, address: u8) -> Result<(), HostError>;
        fn address_poll(&mut self, device: DeviceId, address: u8) -> Transfer;
        fn device_set_address(&mut self, device: DeviceId, address: u8) -> Result<(), HostError>;
        fn device_set_max_packet(&mut self, device: DeviceId, max_packet: u16) -> Result<(), HostError>;
        fn device_is_hub(&mut self, device: DeviceId, ports: u8, multi_tt: bool) -> Result<(), HostError>;
        fn device_remove(&mut self, device: DeviceId);
        fn control_begin(&mut self, device: DeviceId, setup: Setup, out: &[u8]) -> Result<(), HostError>;
        fn control_poll(&mut self, device: DeviceId, into: &mut [u8]) -> Transfer;
        fn control_cancel(&mut self, device: DeviceId);
        fn interrupt_open(&mut self, device: DeviceId, endpoint: u8, max_packet: u16, interval: u8) -> Result<PipeId, HostError>;
        fn interrupt_poll(&mut self, pipe: PipeId, into: &mut [u8]) -> Transfer;
        fn interrupt_restart(&mut self, pipe: PipeId, reset_toggle: bool) -> Result<(), HostError>;
        fn interrupt_close(&mut self, pipe: PipeId);
        #[inline]
        fn anything_happened(&mut self) -> bool;
        fn halt(&mut self) -> bool;
    }
}

#[cfg(test)]
mod tests;
