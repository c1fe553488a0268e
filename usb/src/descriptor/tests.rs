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
        Some(Function::Keyboard {
            interface: 0,
            endpoint: InterruptIn {
                number: 1,
                max_packet: 8,
                interval: 10
            },
            boot: true,
            report_descriptor_bytes: 63,
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
    assert_eq!(
        configuration(&hub).unwrap().function,
        Some(Function::Hub {
            status_change: Some(InterruptIn {
                number: 1,
                max_packet: 8,
                interval: 10
            })
        })
    );
}

#[test]
fn a_stick_is_named_by_its_first_interface_and_offers_nothing() {
    // QEMU's usb-storage: one bulk-only SCSI interface, two bulk endpoints.
    let stick: [u8; 32] = [
        9, 2, 32, 0, 1, 1, 0, 0x80, 50, // configuration
        9, 4, 0, 0, 2, 8, 6, 0x50, 0, // interface: mass storage, SCSI, bulk-only
        7, 5, 0x81, 2, 0, 2, 0, // endpoint 1 IN, bulk
        7, 5, 0x02, 2, 0, 2, 0, // endpoint 2 OUT, bulk
    ];
    let offered = configuration(&stick).unwrap();
    assert_eq!(offered.function, None);
    let class = offered.first_interface.unwrap();
    assert_eq!(std::format!("{class}"), "mass storage, class 08/06/50");
    let keyboard = configuration(&KEYBOARD_CONFIGURATION).unwrap();
    assert_eq!(keyboard.first_interface.unwrap().name(), "HID");
}

#[test]
fn a_hid_interface_without_boot_protocol_may_be_a_keyboard_but_boot_comes_first() {
    // A tablet or an N-key rollover interface: subclass 0, protocol 0.
    let mut other = KEYBOARD_CONFIGURATION;
    other[15] = 0;
    other[16] = 0;
    let Some(Function::Keyboard {
        boot,
        report_descriptor_bytes,
        ..
    }) = configuration(&other).unwrap().function
    else {
        panic!("not a candidate");
    };
    assert!(!boot);
    assert_eq!(report_descriptor_bytes, 63);
    // Both: the boot interface (the second here) is the one taken.
    let mut both = std::vec::Vec::from(other);
    both.extend_from_slice(&KEYBOARD_CONFIGURATION[9..]);
    both[2] = both.len() as u8;
    both[9 + 25 + 2] = 1; // the second interface's number
    both[9 + 25 + 18 + 2] = 0x82; // and its endpoint
    let function = configuration(&both).unwrap().function;
    assert!(
        matches!(
            function,
            Some(Function::Keyboard {
                interface: 1,
                boot: true,
                endpoint: InterruptIn { number: 2, .. },
                ..
            })
        ),
        "{function:?}"
    );
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
