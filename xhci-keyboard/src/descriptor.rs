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
    /// Hub descriptor (USB 2.0).
    pub const HUB: u8 = 0x29;
}

/// HID class.
pub const CLASS_HID: u8 = 3;
/// Hub class.
pub const CLASS_HUB: u8 = 9;
/// HID subclass: supports the boot protocol.
pub const SUBCLASS_BOOT: u8 = 1;
/// HID boot protocol: keyboard.
pub const PROTOCOL_KEYBOARD: u8 = 1;

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
    /// A boot keyboard interface and its interrupt IN endpoint.
    BootKeyboard {
        /// `bInterfaceNumber`.
        interface: u8,
        /// The report endpoint.
        endpoint: InterruptIn,
    },
    /// A hub.
    Hub,
}

/// A configuration: its value for SET_CONFIGURATION and what it offers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Configuration {
    /// `bConfigurationValue`.
    pub value: u8,
    /// The first boot keyboard (or a hub), if any.
    pub function: Option<Function>,
}

/// Walks a whole configuration (header, interfaces, endpoints, class
/// descriptors) for a boot keyboard interface with an interrupt IN endpoint,
/// or a hub interface. Stops at the first descriptor whose length is wrong.
pub fn configuration(bytes: &[u8]) -> Result<Configuration, DescriptorError> {
    let total = usize::from(configuration_total_length(bytes)?);
    let bytes = &bytes[..total.min(bytes.len())];
    need(bytes, 9)?;
    let value = bytes[5];
    let mut offset = usize::from(bytes[0]);
    let mut keyboard_interface = None;
    let mut function = None;
    while offset + 2 <= bytes.len() {
        let length = usize::from(bytes[offset]);
        if length < 2 || offset + length > bytes.len() {
            return Err(DescriptorError::BadLength(bytes[offset]));
        }
        let descriptor = &bytes[offset..offset + length];
        match descriptor[1] {
            kind::INTERFACE if length >= 9 => {
                let (class, subclass, protocol) = (descriptor[5], descriptor[6], descriptor[7]);
                keyboard_interface = (class == CLASS_HID
                    && subclass == SUBCLASS_BOOT
                    && protocol == PROTOCOL_KEYBOARD
                    && function.is_none())
                .then_some(descriptor[2]);
                if class == CLASS_HUB && function.is_none() {
                    function = Some(Function::Hub);
                }
            }
            kind::ENDPOINT if length >= 7 => {
                let address = descriptor[2];
                let is_interrupt_in = address & 0x80 != 0 && descriptor[3] & 0x03 == 0x03;
                if let (Some(interface), true) = (keyboard_interface, is_interrupt_in) {
                    let number = address & 0x0F;
                    if number != 0 {
                        function = Some(Function::BootKeyboard {
                            interface,
                            endpoint: InterruptIn {
                                number,
                                max_packet: u16::from_le_bytes([descriptor[4], descriptor[5]])
                                    & 0x7FF,
                                interval: descriptor[6],
                            },
                        });
                        keyboard_interface = None;
                    }
                }
            }
            _ => {}
        }
        offset += length;
    }
    Ok(Configuration { value, function })
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

/// Reads a USB 2.0 hub descriptor.
pub fn hub(bytes: &[u8]) -> Result<HubDescriptor, DescriptorError> {
    need(bytes, 7)?;
    if bytes[1] != kind::HUB {
        return Err(DescriptorError::WrongType(bytes[1]));
    }
    if bytes[0] < 7 {
        return Err(DescriptorError::BadLength(bytes[0]));
    }
    Ok(HubDescriptor {
        ports: bytes[2],
        power_on_to_good_2ms: bytes[5],
        think_time: (bytes[3] >> 5) & 3,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// QEMU's usb-kbd: one configuration, one boot keyboard interface, a
    /// HID descriptor, an 8-byte interrupt IN endpoint 1 every 10 ms.
    const KEYBOARD_CONFIGURATION: [u8; 34] = [
        9, 2, 34, 0, 1, 1, 0, 0xA0, 50, // configuration
        9, 4, 0, 0, 1, 3, 1, 1, 0, // interface: HID, boot, keyboard
        9, 0x21, 0x11, 0x01, 0, 1, 0x22, 63, 0, // HID
        7, 5, 0x81, 3, 8, 0, 10, // endpoint 1 IN, interrupt, 8 bytes, 10 ms
    ];

    #[test]
    fn a_boot_keyboard_is_found_with_its_endpoint() {
        let configuration = configuration(&KEYBOARD_CONFIGURATION).unwrap();
        assert_eq!(configuration.value, 1);
        assert_eq!(
            configuration.function,
            Some(Function::BootKeyboard {
                interface: 0,
                endpoint: InterruptIn {
                    number: 1,
                    max_packet: 8,
                    interval: 10
                }
            })
        );
    }

    #[test]
    fn a_mouse_is_not_a_keyboard_and_a_hub_is_a_hub() {
        let mut mouse = KEYBOARD_CONFIGURATION;
        mouse[16] = 2;
        assert_eq!(configuration(&mouse).unwrap().function, None);
        let mut hub = KEYBOARD_CONFIGURATION;
        hub[14] = CLASS_HUB;
        assert_eq!(configuration(&hub).unwrap().function, Some(Function::Hub));
    }

    #[test]
    fn lengths_that_lie_are_refused_not_followed() {
        // A descriptor of length 0 would loop forever; one running past the
        // end would read past the buffer.
        let mut zero = KEYBOARD_CONFIGURATION;
        zero[9] = 0;
        assert_eq!(configuration(&zero), Err(DescriptorError::BadLength(0)));
        let mut long = KEYBOARD_CONFIGURATION;
        long[27] = 40;
        assert_eq!(configuration(&long), Err(DescriptorError::BadLength(40)));
        // wTotalLength beyond what arrived: only what arrived is read.
        let mut total = KEYBOARD_CONFIGURATION;
        total[2] = 200;
        assert!(configuration(&total).is_ok());
        assert_eq!(
            configuration(&KEYBOARD_CONFIGURATION[..5]),
            Err(DescriptorError::Short { needed: 9, got: 5 })
        );
        assert_eq!(
            configuration(&[9, 4, 0, 0, 0, 0, 0, 0, 0]),
            Err(DescriptorError::WrongType(4))
        );
    }

    #[test]
    fn device_and_hub_descriptors_are_checked() {
        let device_bytes = [
            18, 1, 0, 2, 0, 0, 0, 8, 0x27, 0x06, 0x01, 0x00, 0, 0, 1, 2, 3, 1,
        ];
        let parsed = device(&device_bytes).unwrap();
        assert_eq!(
            (parsed.max_packet_0, parsed.vendor, parsed.product),
            (8, 0x0627, 1)
        );
        assert_eq!(device(&device_bytes[..8]).unwrap().vendor, 0);
        assert!(device(&device_bytes[..7]).is_err());
        assert_eq!(
            device(&[18, 2, 0, 0, 0, 0, 0, 8]),
            Err(DescriptorError::WrongType(2))
        );
        let hub_bytes = [9, 0x29, 8, 0x20, 0, 50, 0, 0, 0xFF];
        assert_eq!(
            hub(&hub_bytes).unwrap(),
            HubDescriptor {
                ports: 8,
                power_on_to_good_2ms: 50,
                think_time: 1
            }
        );
        assert!(hub(&hub_bytes[..6]).is_err());
    }
}
