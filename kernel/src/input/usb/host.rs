//! The drivers as the kernel holds them: `usb`'s one [`Driver`] type over
//! the kernel's registers, under one device layer (`Bus<Host>`). All that
//! is per kind here is PCI's: Intel's switchable ports, routed to an xHCI
//! before it starts and handed back after it halts, as Linux does.

use super::hardware::Registers;
use crate::{pci, serial_println};
use usb::driver::Driver;
use usb::host::HostController;

/// A host controller driver, of whichever kind.
pub type Host = Driver<Registers>;

/// Before an xHCI starts: Intel's switchable ports routed to it.
pub fn route_ports_to_xhci(host: &mut Host) {
    let Driver::Xhci(xhci) = host else {
        return;
    };
    if let Some(routed) = pci::route_intel_ports_to_xhci(xhci.hardware().function) {
        serial_println!(
            "usb: Intel PCH ports switched to the xHCI (XUSB2PR {:#x})",
            routed
        );
    }
}

/// After an xHCI's halt: Intel's switched ports handed back to the EHCI
/// (some 7-series boards otherwise power straight back on).
pub fn hand_ports_back(host: &mut Host) {
    let Driver::Xhci(xhci) = host else {
        return;
    };
    if let Some((usb2, superspeed)) = pci::hand_intel_ports_back_to_ehci(xhci.hardware().function) {
        serial_println!(
            "usb: Intel PCH ports handed back to the EHCI (XUSB2PR {:#x}, USB3_PSSEN {:#x})",
            usb2,
            superspeed
        );
    }
}
