//! USB keyboards on every PC host controller, polled: no interrupts, MSI or
//! IOAPIC routing. Everything is written against small traits over the
//! hardware ([`Hardware`] and [`PciHardware`]: the controller's registers,
//! DMA memory, PCI configuration space, a clock and a log), so the same code
//! runs on the machine and on the host against register models.
//!
//! The device layer and the interface below it:
//! - [`host`]: the one polled host-controller trait the device layer drives,
//!   start-up (firmware hand-off, reset, start) included;
//! - [`driver`]: the four drivers as one type under one device layer;
//! - [`bus`]: the device layer over it: debounce, resets, addresses,
//!   descriptors, hubs and their transaction translators, keyboards, stalls
//!   and errors, hot-plug, a step per poll;
//! - [`report`]: boot reports become PS/2 set-1 scancodes, with typematic repeat;
//! - [`descriptor`]: USB descriptors, every length checked;
//! - [`hid`]: HID report descriptors, for keyboards that do not keep to
//!   the boot report (N-key rollover bitmaps, report IDs).
//!
//! - [`pci_power`]: a controller left in D1-D3hot brought to D0 first.
//!
//! The host controller drivers:
//! - [`uhci`]: UHCI (Intel and VIA USB 1.1): I/O registers, the frame list,
//!   queue heads and transfer descriptors;
//! - [`ohci`]: OHCI (AMD, SiS, NEC USB 1.1): the HCCA, endpoint and transfer
//!   descriptors, the control list and the interrupt tree;
//! - [`ehci`]: EHCI (USB 2.0): the asynchronous and periodic schedules, split
//!   transactions through a hub's transaction translator, companions;
//! - [`xhci`]: xHCI (USB 3, SuperSpeed too): its implementation of
//!   [`host::HostController`], with [`xhci::ring`] (the command, transfer
//!   and event rings) and [`xhci::context`] (slot and endpoint contexts).

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod bus;
pub mod descriptor;
pub mod driver;
pub mod ehci;
pub mod hid;
pub mod host;
pub mod ohci;
pub mod pci_power;
pub mod report;
pub mod uhci;
pub mod xhci;

#[cfg(test)]
mod model;
#[cfg(test)]
mod test_memory;
#[cfg(test)]
mod tests;

/// DMA memory, by physical address, a 32-bit word at a time.
pub trait Memory {
    /// Reads the word at `address` (4-byte aligned).
    fn mem_read(&mut self, address: u64) -> u32;
    /// Writes the word at `address` (4-byte aligned).
    fn mem_write(&mut self, address: u64, value: u32);
}

/// The machine's services to every driver and to the device layer: the
/// clock every bound is measured on, and the kernel's log. They reach the
/// device layer through [`host::HostController::hardware`].
pub trait Platform {
    /// A clock for every wait's bound, in microseconds.
    fn now_micros(&mut self) -> u64;
    /// Says something on the kernel's log (one line, no newline).
    fn log(&mut self, message: core::fmt::Arguments<'_>);

    /// Waits `micros` by the clock, touching no device (a reset's hold
    /// time, a power-on delay).
    fn pause(&mut self, micros: u64) {
        let start = self.now_micros();
        while self.now_micros().saturating_sub(start) < micros {
            core::hint::spin_loop();
        }
    }
}

/// Everything the driver needs from the machine.
pub trait Hardware: Memory + Platform {
    /// Reads the controller's register at `offset` in BAR0 (4-byte aligned,
    /// inside the BAR: the driver checks).
    fn mmio_read(&mut self, offset: u32) -> u32;
    /// Writes the controller's register at `offset` in BAR0.
    fn mmio_write(&mut self, offset: u32, value: u32);
}

/// What an EHCI, OHCI or UHCI driver needs beyond [`Hardware`]: UHCI's
/// registers are 16-bit I/O ports, and the EHCI and UHCI firmware hand-offs
/// live in PCI configuration space. `mmio_read`/`mmio_write` reach 32-bit
/// registers (UHCI's FRBASEADD; every OHCI and EHCI register).
pub trait PciHardware: Hardware {
    /// Reads the 16-bit register at `offset` (2-byte aligned).
    fn read16(&mut self, offset: u32) -> u16;
    /// Writes the 16-bit register at `offset`.
    fn write16(&mut self, offset: u32, value: u16);
    /// Reads the controller function's PCI configuration dword at `offset`
    /// (4-byte aligned, below 256).
    fn pci_config_read(&mut self, offset: u8) -> u32;
    /// Writes the controller function's PCI configuration dword at `offset`.
    fn pci_config_write(&mut self, offset: u8, value: u32);
}
