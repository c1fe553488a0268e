use super::*;
use proptest::prelude::*;
use std::vec::Vec;

/// The boot keyboard's descriptor (HID 1.11 appendix E.6, as QEMU's usb-kbd).
pub const BOOT: [u8; 63] = crate::model::devices::KEYBOARD_REPORT_DESCRIPTOR;

/// An N-key rollover keyboard in the manner of a Corsair K70: report
/// ID 1, eight modifier bits, then a bitmap of usages 0-151 (21 bytes
/// in all), in the report protocol whatever SET_PROTOCOL says.
pub const NKRO: [u8; 33] = [
    0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x85, 0x01, 0x05, 0x07, 0x19, 0xE0, 0x29, 0xE7, 0x15, 0x00,
    0x25, 0x01, 0x75, 0x01, 0x95, 0x08, 0x81, 0x02, 0x19, 0x00, 0x29, 0x97, 0x95, 0x98, 0x81, 0x02,
    0xC0,
];

/// A keyboard with numbered reports: ID 1 the boot layout, ID 2 a
/// consumer-control (media key) report of one 16-bit usage.
pub const NUMBERED: [u8; 75] = [
    0x05, 0x01, 0x09, 0x06, 0xA1, 0x01, 0x85, 0x01, 0x75, 0x01, 0x95, 0x08, 0x05, 0x07, 0x19, 0xE0,
    0x29, 0xE7, 0x15, 0x00, 0x25, 0x01, 0x81, 0x02, 0x95, 0x01, 0x75, 0x08, 0x81, 0x01, 0x95, 0x05,
    0x75, 0x01, 0x05, 0x08, 0x19, 0x01, 0x29, 0x05, 0x91, 0x02, 0x95, 0x06, 0x75, 0x08, 0x15, 0x00,
    0x26, 0xFF, 0x00, 0x05, 0x07, 0x19, 0x00, 0x29, 0xFF, 0x81, 0x00, 0xC0,
    // Consumer control, report 2.
    0x05, 0x0C, 0x09, 0x01, 0xA1, 0x01, 0x85, 0x02, 0x75, 0x10, 0x95, 0x01, 0x81, 0x00, 0xC0,
];

/// A tablet: buttons and absolute X/Y, no keys.
pub const TABLET: [u8; 46] = [
    0x05, 0x01, 0x09, 0x02, 0xA1, 0x01, 0x09, 0x01, 0xA1, 0x00, 0x05, 0x09, 0x19, 0x01, 0x29, 0x03,
    0x15, 0x00, 0x25, 0x01, 0x95, 0x03, 0x75, 0x01, 0x81, 0x02, 0x95, 0x01, 0x75, 0x05, 0x81, 0x01,
    0x05, 0x01, 0x09, 0x30, 0x09, 0x31, 0x75, 0x10, 0x95, 0x02, 0x81, 0x02, 0xC0, 0xC0,
];

fn keys(usages: &[u8]) -> KeySet {
    let mut set = KeySet::default();
    usages.iter().for_each(|&u| set.insert(u));
    set
}

fn nkro_report(usages: &[u8]) -> [u8; 21] {
    let mut report = [0u8; 21];
    report[0] = 1;
    for &usage in usages {
        if usage >= 0xE0 {
            report[1] |= 1 << (usage - 0xE0);
        } else {
            report[2 + usize::from(usage / 8)] |= 1 << (usage % 8);
        }
    }
    report
}

#[test]
fn the_boot_descriptor_gives_the_boot_report() {
    let layout = parse(&BOOT).unwrap();
    assert!(!layout.numbered && layout.has_keys());
    assert_eq!(layout.longest_key_report(), 8);
    assert_eq!(
        layout.decode(&[0x02, 0, 0x04, 0x50, 0, 0, 0, 0]),
        Decoded::Keys {
            report_id: 0,
            keys: keys(&[0xE1, 0x04, 0x50])
        }
    );
    assert_eq!(layout.decode(&[0, 0, 1, 1, 1, 1, 1, 1]), Decoded::Rollover);
    assert_eq!(layout.decode(&[0, 0, 4]), Decoded::Unreadable);
}

#[test]
fn an_nkro_bitmap_with_a_report_id_is_read_bit_by_bit() {
    let layout = parse(&NKRO).unwrap();
    assert!(layout.numbered);
    assert_eq!(layout.longest_key_report(), 21);
    // Nine keys at once, more than a boot report holds, and the last
    // usage of the bitmap (151).
    let down = [
        0xE0, 0xE6, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0A, 0x50, 0x97,
    ];
    assert_eq!(
        layout.decode(&nkro_report(&down)),
        Decoded::Keys {
            report_id: 1,
            keys: keys(&down)
        }
    );
    // A boot report from it, or another ID, cannot be read.
    assert_eq!(
        layout.decode(&[0, 0, 4, 0, 0, 0, 0, 0]),
        Decoded::Unreadable
    );
    let mut other = nkro_report(&[4]);
    other[0] = 3;
    assert_eq!(layout.decode(&other), Decoded::Unreadable);
    assert_eq!(layout.decode(&nkro_report(&[4])[..20]), Decoded::Unreadable);
    assert_eq!(layout.decode(&[]), Decoded::Unreadable);
}

#[test]
fn numbered_reports_without_keys_are_told_apart() {
    let layout = parse(&NUMBERED).unwrap();
    assert!(layout.numbered);
    assert_eq!(layout.longest_key_report(), 9);
    assert_eq!(
        layout.decode(&[1, 0x01, 0, 0x29, 0, 0, 0, 0, 0]),
        Decoded::Keys {
            report_id: 1,
            keys: keys(&[0xE0, 0x29])
        }
    );
    assert_eq!(layout.decode(&[2, 0xE9, 0x00]), Decoded::NotKeys);
    assert_eq!(layout.decode(&[2, 0xE9]), Decoded::Unreadable);
}

#[test]
fn a_tablet_has_no_keys() {
    let layout = parse(&TABLET).unwrap();
    assert!(!layout.has_keys());
    assert_eq!(layout.decode(&[1, 0, 0, 0, 0]), Decoded::NotKeys);
}

#[test]
fn descriptors_that_lie_are_refused() {
    let cases: [(&str, Vec<u8>, HidError); 11] = [
        (
            "data past the end",
            BOOT[..62].iter().chain(&[0x26, 0xFF]).copied().collect(),
            HidError::Truncated(62),
        ),
        (
            "a long item past the end",
            std::vec![0xFE, 10, 0],
            HidError::Truncated(0),
        ),
        (
            "collection never closed",
            BOOT[..BOOT.len() - 1].to_vec(),
            HidError::Unclosed(1),
        ),
        (
            "end with nothing open",
            std::vec![0xC0],
            HidError::UnbalancedEnd(0),
        ),
        (
            "nesting without end",
            [0xA1, 0x00].repeat(100),
            HidError::TooDeep,
        ),
        (
            "pop with nothing pushed",
            std::vec![0xB4],
            HidError::BadPushPop(0),
        ),
        (
            "push without end",
            [0xA4].repeat(10),
            HidError::BadPushPop(4),
        ),
        (
            "report size 64 bits",
            std::vec![0x75, 64],
            HidError::BadReportSize(64),
        ),
        ("report ID 0", std::vec![0x85, 0], HidError::BadReportId(0)),
        (
            "absurd count",
            std::vec![0x05, 0x07, 0x75, 0x08, 0x97, 0xFF, 0xFF, 0xFF, 0x7F, 0x81, 0x01],
            HidError::ReportTooLong {
                report_id: 0,
                bits: u32::MAX,
            },
        ),
        (
            "usage range backwards",
            std::vec![0x05, 0x07, 0x19, 0x20, 0x29, 0x10],
            HidError::BadRange(4),
        ),
    ];
    for (what, descriptor, error) in cases {
        assert_eq!(parse(&descriptor), Err(error), "{what}");
    }
    // A keyboard report longer than one full-speed packet.
    let mut long = NKRO;
    long[29] = 0xFF; // 255 bits of bitmap, past usage 151
    long[27] = 0xFF;
    assert!(parse(&long).is_ok(), "255 bits fit in 64 bytes");
    let mut longer = NKRO.to_vec();
    longer.splice(28..30, [0x96, 0x00, 0x02]); // 512 bits
    assert!(matches!(
        parse(&longer),
        Err(HidError::ReportTooLong { report_id: 1, .. })
    ));
}

proptest! {
    #[test]
    fn any_bytes_parse_or_fail_without_panicking(
        bytes in proptest::collection::vec(any::<u8>(), 0..300),
        report in proptest::collection::vec(any::<u8>(), 0..70),
    ) {
        if let Ok(layout) = parse(&bytes) {
            let _ = layout.decode(&report);
            prop_assert!(layout.longest_key_report() <= MAX_REPORT_BYTES);
        }
    }

    #[test]
    fn a_keyboard_descriptor_changed_anywhere_never_panics(
        base in 0..3usize,
        changes in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..6),
        report in proptest::collection::vec(any::<u8>(), 0..70),
    ) {
        let mut bytes = [&BOOT[..], &NKRO[..], &NUMBERED[..]][base].to_vec();
        for (at, value) in changes {
            let at = at % bytes.len();
            bytes[at] = value;
        }
        if let Ok(layout) = parse(&bytes) {
            if let Decoded::Keys { report_id, .. } = layout.decode(&report) {
                // Keys come only from a report long enough for its
                // fields, and with the ID it says.
                let needed = layout.report_bytes(report_id);
                prop_assert!(needed.is_some_and(|n| report.len() >= n));
                prop_assert!(!layout.numbered || report[0] == report_id);
            }
        }
    }
}
