//! Starting an xHCI and handing Intel's switchable ports back: the xHCI
//! keeps its own enumeration (`usb::xhci`), and on Intel's 7- to 9-series
//! PCHs its ports are switched from the EHCI to it at start and back at
//! shutdown, as Linux does.

use super::hardware::Registers;
use super::Start;
use crate::{pci, serial_println};
use usb::xhci::Xhci;

impl Start for Xhci<Registers> {
    fn start(&mut self) -> bool {
        let function = self.hardware().function;
        if let Some(routed) = pci::route_intel_ports_to_xhci(function) {
            serial_println!(
                "usb: Intel PCH ports switched to the xHCI (XUSB2PR {:#x})",
                routed
            );
        }
        if let Err(problem) = self.reset_and_start() {
            serial_println!(
                "usb: xHCI {}: {}; USB keyboards not used",
                function,
                problem
            );
            return false;
        }
        if let Err(problem) = self.no_op() {
            serial_println!(
                "usb: xHCI {}: command ring: {}; USB keyboards not used",
                function,
                problem
            );
            return false;
        }
        // Boot enumeration: at most `BOOT_ENUMERATION_MICROS`, then it carries
        // on from the frame loop's polls (the driver says so).
        if self.enumerate() == 0 {
            serial_println!(
                "usb: no USB keyboard on the xHCI {} at boot; its ports stay watched",
                function
            );
        }
        true
    }
}

/// After the xHCI's shutdown: Intel's switched ports handed back to the
/// EHCI (some 7-series boards otherwise power straight back on).
pub fn hand_ports_back(function: pci::Function) {
    if let Some((usb2, superspeed)) = pci::hand_intel_ports_back_to_ehci(function) {
        serial_println!(
            "usb: Intel PCH ports handed back to the EHCI (XUSB2PR {:#x}, USB3_PSSEN {:#x})",
            usb2,
            superspeed
        );
    }
}
