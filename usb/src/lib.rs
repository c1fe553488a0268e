//! A polled xHCI driver for USB boot keyboards, written against a small
//! trait over the hardware ([`Hardware`]: the controller's registers, DMA
//! memory, a clock and a log) so that the same code runs on the machine and
//! on the host against a register model of the controller.
//!
//! - [`report`]: boot reports become PS/2 set-1 scancodes, with typematic repeat;
//! - [`descriptor`]: USB descriptors, every length checked;
//! - [`hid`]: HID report descriptors, for keyboards that do not keep to
//!   the boot report (N-key rollover bitmaps, report IDs);
//! - [`ring`]: the command, transfer and event rings and their cycle bits;
//! - [`context`]: slot and endpoint contexts, 32- or 64-byte (CSZ);
//! - [`xhci`]: the controller: taking it from the firmware, resetting it,
//!   enumerating keyboards and hubs (USB 2 and USB 3, five tiers) a step
//!   per poll, hot-plug at root and hub ports, and polling the reports.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod bus;
pub mod context;
pub mod descriptor;
pub mod hid;
pub mod host;
pub mod report;
pub mod ring;
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

/// Everything the driver needs from the machine.
pub trait Hardware: Memory {
    /// Reads the controller's register at `offset` in BAR0 (4-byte aligned,
    /// inside the BAR: the driver checks).
    fn mmio_read(&mut self, offset: u32) -> u32;
    /// Writes the controller's register at `offset` in BAR0.
    fn mmio_write(&mut self, offset: u32, value: u32);
    /// A clock for every wait's bound, in microseconds.
    fn now_micros(&mut self) -> u64;
    /// Says something on the kernel's log (one line, no newline).
    fn log(&mut self, message: core::fmt::Arguments<'_>);
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
