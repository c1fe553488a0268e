//! USB descriptors as a device sends them, read with every length checked:
//! nothing here trusts a `bLength` or `wTotalLength` to fit the bytes that
//! actually arrived.

/// Descriptor types.
pub mod kind {
    /// Device descriptor.
    pub const DEVICE: u8 = 1;
    /// Configuration descriptor.
    pub const CONFIGURATION: u8 = 2;
    /// Interface descriptor.
    pub const INTERFACE: u8 = 4;
    /// Endpoint descriptor.
    pub const ENDPOINT: u8 = 5;
    /// HID class descriptor (in a configuration, after its interface).
    pub const HID: u8 = 0x21;
    /// HID report descriptor (read from the interface).
    pub const REPORT: u8 = 0x22;
    /// Hub descriptor (USB 2.0).
    pub const HUB: u8 = 0x29;
    /// SuperSpeed hub descriptor (USB 3.2 10.15.2.1).
    pub const SUPERSPEED_HUB: u8 = 0x2A;
}

/// HID class.
pub const CLASS_HID: u8 = 3;
/// Hub class.
pub const CLASS_HUB: u8 = 9;
/// HID subclass: supports the boot protocol.
pub const SUBCLASS_BOOT: u8 = 1;
/// HID boot protocol: keyboard.
pub const PROTOCOL_KEYBOARD: u8 = 1;
/// HID subclass and protocol of an interface with no boot protocol (a
/// keyboard may still be one, if its report descriptor says so).
const NO_BOOT: u8 = 0;

/// What a descriptor failed on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DescriptorError {
    /// Fewer bytes than the descriptor needs.
    Short {
        /// Bytes needed.
        needed: usize,
        /// Bytes there.
        got: usize,
    },
    /// The type byte is not the one asked for.
    WrongType(u8),
    /// A length field that cannot be right (under 2, or past the end).
    BadLength(u8),
}

impl core::fmt::Display for DescriptorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DescriptorError::Short { needed, got } => {
                write!(f, "descriptor too short ({got} of {needed} bytes)")
            }
            DescriptorError::WrongType(t) => write!(f, "unexpected descriptor type {t:#04x}"),
            DescriptorError::BadLength(l) => write!(f, "descriptor length {l} is impossible"),
        }
    }
}

fn need(bytes: &[u8], needed: usize) -> Result<(), DescriptorError> {
    if bytes.len() < needed {
        return Err(DescriptorError::Short {
            needed,
            got: bytes.len(),
        });
    }
    Ok(())
}

/// The fields of a device descriptor this driver uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DeviceDescriptor {
    /// Device class (0: per interface; 9: hub).
    pub class: u8,
    /// Largest packet on endpoint 0 (a power of two for USB 3: 2^n).
    pub max_packet_0: u8,
    /// Vendor ID.
    pub vendor: u16,
    /// Product ID.
    pub product: u16,
    /// Configurations.
    pub configurations: u8,
}

/// Reads the first 8 bytes of a device descriptor (all that is needed to
/// learn endpoint 0's packet size), or the whole 18.
pub fn device(bytes: &[u8]) -> Result<DeviceDescriptor, DescriptorError> {
    need(bytes, 8)?;
    if bytes[1] != kind::DEVICE {
        return Err(DescriptorError::WrongType(bytes[1]));
    }
    if bytes[0] < 8 {
        return Err(DescriptorError::BadLength(bytes[0]));
    }
    let full = bytes.len() >= 18 && bytes[0] >= 18;
    Ok(DeviceDescriptor {
        class: bytes[4],
        max_packet_0: bytes[7],
        vendor: if full {
            u16::from_le_bytes([bytes[8], bytes[9]])
        } else {
            0
        },
        product: if full {
            u16::from_le_bytes([bytes[10], bytes[11]])
        } else {
            0
        },
        configurations: if full { bytes[17] } else { 0 },
    })
}

/// The total length a configuration descriptor's header announces.
pub fn configuration_total_length(bytes: &[u8]) -> Result<u16, DescriptorError> {
    need(bytes, 9)?;
    if bytes[1] != kind::CONFIGURATION {
        return Err(DescriptorError::WrongType(bytes[1]));
    }
    if bytes[0] < 9 {
        return Err(DescriptorError::BadLength(bytes[0]));
    }
    Ok(u16::from_le_bytes([bytes[2], bytes[3]]))
}

/// An interrupt IN endpoint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterruptIn {
    /// The endpoint number (1-15).
    pub number: u8,
    /// Largest packet.
    pub max_packet: u16,
    /// `bInterval` as the device gave it.
    pub interval: u8,
}

/// What a configuration offers this driver.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    /// A HID interface that is or may be a keyboard, and its interrupt IN
    /// endpoint: a boot keyboard, or (when there is none) a HID interface
    /// without the boot protocol, which is a keyboard only if its report
    /// descriptor says so.
    Keyboard {
        /// `bInterfaceNumber`.
        interface: u8,
        /// The report endpoint.
        endpoint: InterruptIn,
        /// The interface does the boot protocol (subclass 1, protocol 1).
        boot: bool,
        /// The report descriptor's length its HID descriptor announces (0: none).
        report_descriptor_bytes: u16,
    },
    /// A hub, and its status change endpoint (the interrupt IN endpoint
    /// of its interface) if the configuration names one.
    Hub {
        /// The endpoint that says which ports changed.
        status_change: Option<InterruptIn>,
    },
}

/// A configuration: its value for SET_CONFIGURATION and what it offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Configuration {
    /// `bConfigurationValue`.
    pub value: u8,
    /// The first boot keyboard, else the first other HID interface that
    /// may be a keyboard (or a hub), if any.
    pub function: Option<Function>,
    /// The first interface's class, subclass and protocol, to say what a
    /// device that is not ours is.
    pub first_interface: Option<InterfaceClass>,
}

/// An interface's `bInterfaceClass`, `bInterfaceSubClass` and
/// `bInterfaceProtocol`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterfaceClass {
    /// `bInterfaceClass`.
    pub class: u8,
    /// `bInterfaceSubClass`.
    pub subclass: u8,
    /// `bInterfaceProtocol`.
    pub protocol: u8,
}

impl InterfaceClass {
    /// The class's name in the USB-IF's list of class codes.
    pub fn name(self) -> &'static str {
        match self.class {
            0x01 => "audio",
            0x02 => "communications",
            0x03 => "HID",
            0x06 => "still image",
            0x07 => "printer",
            0x08 => "mass storage",
            0x09 => "hub",
            0x0A => "CDC data",
            0x0B => "smart card",
            0x0E => "video",
            0xE0 => "wireless controller",
            0xEF => "miscellaneous",
            0xFE => "application specific",
            0xFF => "vendor specific",
            _ => "other",
        }
    }
}

impl core::fmt::Display for InterfaceClass {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}, class {:02x}/{:02x}/{:02x}",
            self.name(),
            self.class,
            self.subclass,
            self.protocol
        )
    }
}

/// A HID interface being walked: its number, whether it is a boot
/// keyboard, and its report descriptor's length once its HID descriptor
/// has been seen.
#[derive(Clone, Copy, Debug)]
struct HidInterface {
    number: u8,
    boot: bool,
    report_descriptor_bytes: u16,
}

/// The report descriptor's length a HID class descriptor announces
/// (bNumDescriptors entries of type and length, from byte 6), or 0.
fn report_descriptor_length(hid: &[u8]) -> u16 {
    let count = usize::from(hid.get(5).copied().unwrap_or(0));
    hid.get(6..)
        .unwrap_or(&[])
        .as_chunks::<3>()
        .0
        .iter()
        .take(count)
        .find(|entry| entry[0] == kind::REPORT)
        .map_or(0, |entry| u16::from_le_bytes([entry[1], entry[2]]))
}

/// Walks a whole configuration (header, interfaces, endpoints, class
/// descriptors) for a HID interface with an interrupt IN endpoint that is or
/// may be a keyboard (a boot keyboard first), or a hub interface. Stops at
/// the first descriptor whose length is wrong.
pub fn configuration(bytes: &[u8]) -> Result<Configuration, DescriptorError> {
    let total = usize::from(configuration_total_length(bytes)?);
    let bytes = &bytes[..total.min(bytes.len())];
    need(bytes, 9)?;
    let value = bytes[5];
    let mut offset = usize::from(bytes[0]);
    let mut interface: Option<HidInterface> = None;
    let mut boot_keyboard = None;
    let mut other_hid = None;
    let mut hub = false;
    let mut in_hub_interface = false;
    let mut status_change = None;
    let mut first_interface = None;
    while offset + 2 <= bytes.len() {
        let length = usize::from(bytes[offset]);
        if length < 2 || offset + length > bytes.len() {
            return Err(DescriptorError::BadLength(bytes[offset]));
        }
        let descriptor = &bytes[offset..offset + length];
        match descriptor[1] {
            kind::INTERFACE if length >= 9 => {
                let (class, subclass, protocol) = (descriptor[5], descriptor[6], descriptor[7]);
                first_interface = first_interface.or(Some(InterfaceClass {
                    class,
                    subclass,
                    protocol,
                }));
                let boot = subclass == SUBCLASS_BOOT && protocol == PROTOCOL_KEYBOARD;
                let maybe = subclass == NO_BOOT && protocol == NO_BOOT;
                interface = (class == CLASS_HID && (boot || maybe)).then_some(HidInterface {
                    number: descriptor[2],
                    boot,
                    report_descriptor_bytes: 0,
                });
                hub |= class == CLASS_HUB;
                in_hub_interface = class == CLASS_HUB;
            }
            kind::HID => {
                if let Some(interface) = interface.as_mut() {
                    interface.report_descriptor_bytes = report_descriptor_length(descriptor);
                }
            }
            kind::ENDPOINT if length >= 7 => {
                let address = descriptor[2];
                let is_interrupt_in = address & 0x80 != 0 && descriptor[3] & 0x03 == 0x03;
                let number = address & 0x0F;
                let endpoint = InterruptIn {
                    number,
                    max_packet: u16::from_le_bytes([descriptor[4], descriptor[5]]) & 0x7FF,
                    interval: descriptor[6],
                };
                if in_hub_interface && is_interrupt_in && number != 0 {
                    status_change = status_change.or(Some(endpoint));
                }
                if let (Some(found), true, true) = (interface, is_interrupt_in, number != 0) {
                    let function = Function::Keyboard {
                        interface: found.number,
                        endpoint,
                        boot: found.boot,
                        report_descriptor_bytes: found.report_descriptor_bytes,
                    };
                    if found.boot {
                        boot_keyboard = boot_keyboard.or(Some(function));
                    } else {
                        other_hid = other_hid.or(Some(function));
                    }
                    interface = None;
                }
            }
            _ => {}
        }
        offset += length;
    }
    let function = if hub {
        Some(Function::Hub { status_change })
    } else {
        boot_keyboard.or(other_hid)
    };
    Ok(Configuration {
        value,
        function,
        first_interface,
    })
}

/// The fields of a hub descriptor this driver uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HubDescriptor {
    /// Downstream ports.
    pub ports: u8,
    /// Time from power on to power good, in 2 ms units.
    pub power_on_to_good_2ms: u8,
    /// Transaction translator think time (wHubCharacteristics bits 5-6).
    pub think_time: u8,
}

/// Reads a USB 2.0 hub descriptor, or a SuperSpeed one (12 bytes, the
/// ports and power-on time where USB 2.0 has them, no transaction
/// translator).
pub fn hub(bytes: &[u8]) -> Result<HubDescriptor, DescriptorError> {
    need(bytes, 7)?;
    let shortest = match bytes[1] {
        kind::HUB => 7,
        kind::SUPERSPEED_HUB => 12,
        other => return Err(DescriptorError::WrongType(other)),
    };
    if bytes[0] < shortest {
        return Err(DescriptorError::BadLength(bytes[0]));
    }
    Ok(HubDescriptor {
        ports: bytes[2],
        power_on_to_good_2ms: bytes[5],
        think_time: if bytes[1] == kind::HUB {
            (bytes[3] >> 5) & 3
        } else {
            0
        },
    })
}

#[cfg(test)]
mod tests;
