//! PCI configuration space through the legacy ports (mechanism #1): finding
//! the display controller to name its maker, and finding and enabling USB
//! host controllers (UHCI, OHCI, EHCI, xHCI) and reading and writing their
//! configuration registers for the drivers' firmware hand-offs.

use x86_64::instructions::port::Port;

const CONFIG_ADDRESS: u16 = 0xCF8;
const CONFIG_DATA: u16 = 0xCFC;
const ENABLE: u32 = 1 << 31;
/// Class code 0x03: display controller.
const CLASS_DISPLAY: u8 = 0x03;
const NO_DEVICE: u16 = 0xFFFF;
/// Header type bit 7: the device has functions 1-7 too.
const MULTI_FUNCTION: u8 = 0x80;

fn address(bus: u8, device: u8, function: u8, offset: u8) -> u32 {
    ENABLE
        | (u32::from(bus) << 16)
        | (u32::from(device) << 11)
        | (u32::from(function) << 8)
        | u32::from(offset & 0xFC)
}

fn read(bus: u8, device: u8, function: u8, offset: u8) -> u32 {
    let address = address(bus, device, function, offset);
    // SAFETY: CONFIG_ADDRESS/CONFIG_DATA are the chipset's configuration
    // ports; reading configuration space changes no device state.
    unsafe {
        Port::<u32>::new(CONFIG_ADDRESS).write(address);
        Port::<u32>::new(CONFIG_DATA).read()
    }
}

/// The vendor and device IDs of the first display controller found (the one
/// the firmware most likely made the boot display), scanning every bus.
pub fn display_controller() -> Option<(u16, u16)> {
    for bus in 0..=255u8 {
        for device in 0..32u8 {
            let id = read(bus, device, 0, 0x00);
            if id as u16 == NO_DEVICE {
                continue;
            }
            let header_type = (read(bus, device, 0, 0x0C) >> 16) as u8;
            let functions = if header_type & MULTI_FUNCTION != 0 {
                8
            } else {
                1
            };
            for function in 0..functions {
                let id = read(bus, device, function, 0x00);
                let class = (read(bus, device, function, 0x08) >> 24) as u8;
                if id as u16 != NO_DEVICE && class == CLASS_DISPLAY {
                    return Some((id as u16, (id >> 16) as u16));
                }
            }
        }
    }
    None
}

fn write(bus: u8, device: u8, function: u8, offset: u8, value: u32) {
    let address = address(bus, device, function, offset);
    // SAFETY: as in `read`; callers write only registers of a function they
    // found by its class: a USB controller's command, BAR, port-routing
    // and firmware hand-off registers.
    unsafe {
        Port::<u32>::new(CONFIG_ADDRESS).write(address);
        Port::<u32>::new(CONFIG_DATA).write(value);
    }
}

/// Class 0C (serial bus), subclass 03 (USB); the programming interface
/// names the controller kind (`usb::host::ControllerKind::from_prog_if`).
const CLASS_USB: u32 = 0x0C_03;
const COMMAND: u8 = 0x04;
const COMMAND_IO: u32 = 1 << 0;
const COMMAND_MEMORY: u32 = 1 << 1;
const COMMAND_BUS_MASTER: u32 = 1 << 2;
const BAR0: u8 = 0x10;
/// UHCI's I/O registers (USBBASE, PCI config offset 20h).
pub const BAR4: u8 = 0x20;
const BAR_64_BIT: u32 = 0b100;
const BAR_IO: u32 = 1;

/// A PCI function, by its address.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Function {
    pub bus: u8,
    pub device: u8,
    pub function: u8,
    pub vendor: u16,
    pub id: u16,
}

impl core::fmt::Display for Function {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{:04x}:{:04x} at {:02x}:{:02x}.{}",
            self.vendor, self.id, self.bus, self.device, self.function
        )
    }
}

/// A USB host controller found on PCI: where, and its programming
/// interface (class 0C03h), which names its kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsbFunction {
    pub function: Function,
    pub prog_if: u8,
}

/// Every USB host controller (class 0C03h, any programming interface; up
/// to `N`), in bus order, and how many there are.
pub fn usb_controllers<const N: usize>() -> ([Option<UsbFunction>; N], usize) {
    let mut found = [None; N];
    let mut count = 0;
    for bus in 0..=255u8 {
        for device in 0..32u8 {
            if read(bus, device, 0, 0x00) as u16 == NO_DEVICE {
                continue;
            }
            let header_type = (read(bus, device, 0, 0x0C) >> 16) as u8;
            let functions = if header_type & MULTI_FUNCTION != 0 {
                8
            } else {
                1
            };
            for function in 0..functions {
                let id = read(bus, device, function, 0x00);
                let class = read(bus, device, function, 0x08);
                if id as u16 == NO_DEVICE || class >> 16 != CLASS_USB {
                    continue;
                }
                if count < N {
                    found[count] = Some(UsbFunction {
                        function: Function {
                            bus,
                            device,
                            function,
                            vendor: id as u16,
                            id: (id >> 16) as u16,
                        },
                        prog_if: (class >> 8) as u8,
                    });
                }
                count += 1;
            }
        }
    }
    (found, count)
}

/// Reads the function's configuration dword at `offset` (4-aligned).
pub fn config_read(f: Function, offset: u8) -> u32 {
    read(f.bus, f.device, f.function, offset)
}

/// Writes the function's configuration dword at `offset` (4-aligned): for
/// the USB drivers' hand-off registers (UHCI's LEGSUP, EHCI's USBLEGSUP).
pub fn config_write(f: Function, offset: u8, value: u32) {
    write(f.bus, f.device, f.function, offset, value)
}

/// A memory BAR: its physical address and size.
#[derive(Clone, Copy, Debug)]
pub struct MemoryBar {
    pub address: u64,
    pub bytes: u64,
}

/// Sizes BAR0 (with memory decoding off meanwhile; a 64-bit BAR's upper
/// half read too), then turns on memory decoding and bus mastering. `None`
/// if BAR0 is not a memory BAR.
pub fn enable_memory_and_bus_master(f: Function) -> Option<MemoryBar> {
    let command = read(f.bus, f.device, f.function, COMMAND);
    write(
        f.bus,
        f.device,
        f.function,
        COMMAND,
        command & !COMMAND_MEMORY & 0xFFFF,
    );
    let low = read(f.bus, f.device, f.function, BAR0);
    let is_64 = low & 0b110 == BAR_64_BIT;
    let high = if is_64 {
        read(f.bus, f.device, f.function, BAR0 + 4)
    } else {
        0
    };
    write(f.bus, f.device, f.function, BAR0, u32::MAX);
    let size_mask = read(f.bus, f.device, f.function, BAR0) & !0xF;
    write(f.bus, f.device, f.function, BAR0, low);
    write(
        f.bus,
        f.device,
        f.function,
        COMMAND,
        (command | COMMAND_MEMORY | COMMAND_BUS_MASTER) & 0xFFFF,
    );
    if low & BAR_IO != 0 || size_mask == 0 {
        return None;
    }
    Some(MemoryBar {
        address: (u64::from(high) << 32) | u64::from(low & !0xF),
        bytes: u64::from((!size_mask).wrapping_add(1)),
    })
}

/// An I/O BAR: its first port and how many ports.
#[derive(Clone, Copy, Debug)]
pub struct IoBar {
    pub base: u16,
    pub ports: u32,
}

/// Sizes the I/O BAR at `bar` (with I/O decoding off meanwhile), then
/// turns on I/O decoding and bus mastering. `None` if it is not an I/O BAR
/// or it lies beyond the 64 KiB of x86 port space.
pub fn enable_io_and_bus_master(f: Function, bar: u8) -> Option<IoBar> {
    let command = read(f.bus, f.device, f.function, COMMAND);
    write(
        f.bus,
        f.device,
        f.function,
        COMMAND,
        command & !COMMAND_IO & 0xFFFF,
    );
    let original = read(f.bus, f.device, f.function, bar);
    write(f.bus, f.device, f.function, bar, u32::MAX);
    // The upper 16 bits of an I/O BAR may read back zero (16-bit decoding).
    let size_mask = read(f.bus, f.device, f.function, bar) & 0xFFFC;
    write(f.bus, f.device, f.function, bar, original);
    write(
        f.bus,
        f.device,
        f.function,
        COMMAND,
        (command | COMMAND_IO | COMMAND_BUS_MASTER) & 0xFFFF,
    );
    let base = original & !0x3;
    if original & BAR_IO == 0 || size_mask == 0 || base > 0xFFFF {
        return None;
    }
    let ports = (!size_mask & 0xFFFF) + 1;
    (u32::from(base as u16) + ports <= 0x1_0000).then_some(IoBar {
        base: base as u16,
        ports,
    })
}

/// Intel PCHs whose USB 2 and 3 ports start routed to the EHCI (Panther
/// Point, Lynx Point, Wildcat Point), as Linux's `usb_is_intel_switchable_xhci`.
const INTEL_SWITCHABLE_XHCI: [u16; 5] = [0x1E31, 0x8C31, 0x9C31, 0x8CB1, 0x9CB1];
const USB3_PSSEN: u8 = 0xD8;
const USB3PRM: u8 = 0xDC;
const XUSB2PR: u8 = 0xD0;
const XUSB2PRM: u8 = 0xD4;

/// On those PCHs, switches every switchable port to the xHCI (SuperSpeed
/// enabled, USB 2 routed), as the masks the firmware left allow. Returns the
/// ports routed, or `None` for other controllers.
pub fn route_intel_ports_to_xhci(f: Function) -> Option<u32> {
    if f.vendor != 0x8086 || !INTEL_SWITCHABLE_XHCI.contains(&f.id) {
        return None;
    }
    let superspeed = read(f.bus, f.device, f.function, USB3PRM);
    write(f.bus, f.device, f.function, USB3_PSSEN, superspeed);
    let usb2 = read(f.bus, f.device, f.function, XUSB2PRM);
    write(f.bus, f.device, f.function, XUSB2PR, usb2);
    Some(read(f.bus, f.device, f.function, XUSB2PR))
}

/// On those PCHs, hands every port back to the EHCI (USB 2 routing and
/// SuperSpeed both cleared), as Linux's `usb_disable_xhci_ports` does before
/// power-off: some 7-series boards otherwise power straight back on. Returns
/// what the two registers read afterwards, or `None` for other controllers.
pub fn hand_intel_ports_back_to_ehci(f: Function) -> Option<(u32, u32)> {
    if f.vendor != 0x8086 || !INTEL_SWITCHABLE_XHCI.contains(&f.id) {
        return None;
    }
    write(f.bus, f.device, f.function, USB3_PSSEN, 0);
    write(f.bus, f.device, f.function, XUSB2PR, 0);
    Some((
        read(f.bus, f.device, f.function, XUSB2PR),
        read(f.bus, f.device, f.function, USB3_PSSEN),
    ))
}

/// Brings the function to D0 if the firmware left it in D1 to D3hot
/// (`usb::pci_power` decides what to write), waiting what the PCI Power
/// Management specification asks. Gives the state it was in, if it was not
/// D0, and whether it is in D0 now.
pub fn wake_to_d0(f: Function) -> Option<(u8, bool)> {
    let mut read = |offset: u8| config_read(f, offset);
    let mut write = |offset: u8, value: u32| config_write(f, offset, value);
    match usb::pci_power::wake(&mut read, &mut write) {
        usb::pci_power::Wake::NoCapability | usb::pci_power::Wake::AlreadyOn => None,
        usb::pci_power::Wake::Waking {
            pmcsr,
            from,
            wait_micros,
        } => {
            let until = crate::time::micros().saturating_add(wait_micros);
            while crate::time::micros() < until {
                core::hint::spin_loop();
            }
            Some((from, usb::pci_power::is_on(&mut read, pmcsr)))
        }
    }
}
