//! Whether Secure Boot was on, and who checked the loader (issue 39): the
//! words of the facts row, decided from which firmware booted the machine
//! ([`crate::boot_firmware`]) and the record the UEFI loader hands over in
//! its ramdisk (`loader_logic::secure_boot::Record`, written and validated
//! by the same code). It never says "on" unless the loader read
//! `SecureBoot` as 1; what nobody read is "unknown".
//!
//! ```
//! use firmware::boot_firmware::Firmware;
//! use firmware::secure_boot::{decide, SecureBoot};
//! use loader_logic::secure_boot::{Key, Reading, Record};
//!
//! let record = Record {
//!     secure_boot: Reading::Yes,
//!     setup_mode: Reading::No,
//!     shim: Reading::Yes,
//!     shim_validation_off: Reading::No,
//!     key_in_db: Key::Absent,
//!     key_in_mok: Key::Present,
//! };
//! let state = decide(Firmware::Uefi, Some(&record.encode()));
//! assert_eq!(state.to_string(), "on (shim, your key)");
//! assert_eq!(decide(Firmware::Bios, None).to_string(), "not UEFI");
//! assert_eq!(decide(Firmware::Uefi, None).to_string(), "unknown");
//! ```

use crate::boot_firmware::Firmware;
use core::fmt;
use loader_logic::secure_boot::{Key, Reading, Record};
pub use loader_logic::secure_boot::{RecordError, RECORD_LEN};

/// The Secure Boot state, as the report screen says it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SecureBoot {
    /// A BIOS (or CSM) boot: there is no Secure Boot.
    NotUefi,
    /// Not known: why.
    Unknown(Unknown),
    /// The firmware read `SecureBoot` as 0 and was not in setup mode.
    Off,
    /// No platform key: the firmware checks nothing.
    SetupMode,
    /// `SecureBoot` read as 1: the firmware checked what it started.
    On(CheckedBy),
}

/// Why the state is not known.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unknown {
    /// The machine's firmware itself is not known.
    Firmware,
    /// A UEFI boot handed over no record (an older or other loader).
    NoRecord,
    /// The ramdisk held something that is not a valid record.
    BadRecord(RecordError),
    /// The loader could not read `SecureBoot` (or `SetupMode` when
    /// `SecureBoot` was 0).
    Unread,
}

/// Who checked the loader, when Secure Boot was on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CheckedBy {
    /// Shim, by the user's certificate in its MOK list.
    ShimYourKey,
    /// The firmware (and shim, if it was there) by the user's certificate
    /// in the firmware's `db`.
    YourKeyInDb,
    /// Shim started the loader with its checks switched off (`MokSBState`).
    ShimNotChecking,
    /// Shim, by a key the loader did not find (or could not look for).
    Shim,
    /// The firmware, with no shim, by an entry of `db` that is not the
    /// user's certificate (or that could not be looked for).
    Firmware,
}

/// The state: "not UEFI" only where the memory map says BIOS; a UEFI (or
/// unknown) boot's state comes from `record` (the ramdisk's bytes) alone.
pub fn decide(firmware: Firmware, record: Option<&[u8]>) -> SecureBoot {
    match firmware {
        Firmware::Bios => return SecureBoot::NotUefi,
        Firmware::Unknown if record.is_none() => return SecureBoot::Unknown(Unknown::Firmware),
        _ => {}
    }
    let Some(bytes) = record else {
        return SecureBoot::Unknown(Unknown::NoRecord);
    };
    match Record::decode(bytes) {
        Ok(record) => from_record(&record),
        Err(error) => SecureBoot::Unknown(Unknown::BadRecord(error)),
    }
}

fn from_record(record: &Record) -> SecureBoot {
    match (record.secure_boot, record.setup_mode) {
        (Reading::Unknown, _) => SecureBoot::Unknown(Unknown::Unread),
        (Reading::No, Reading::Yes) => SecureBoot::SetupMode,
        (Reading::No, Reading::No) => SecureBoot::Off,
        (Reading::No, Reading::Unknown) => SecureBoot::Unknown(Unknown::Unread),
        (Reading::Yes, _) => SecureBoot::On(checked_by(record)),
    }
}

fn checked_by(record: &Record) -> CheckedBy {
    if record.key_in_db == Key::Present {
        // Shim too looks in db before its MOK list.
        return CheckedBy::YourKeyInDb;
    }
    match (record.shim, record.shim_validation_off, record.key_in_mok) {
        (Reading::Yes, Reading::Yes, _) => CheckedBy::ShimNotChecking,
        (Reading::Yes, Reading::No, Key::Present) => CheckedBy::ShimYourKey,
        (Reading::Yes, _, _) => CheckedBy::Shim,
        (_, _, _) => CheckedBy::Firmware,
    }
}

impl fmt::Display for SecureBoot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SecureBoot::NotUefi => "not UEFI",
            SecureBoot::Unknown(_) => "unknown",
            SecureBoot::Off => "off",
            SecureBoot::SetupMode => "setup mode",
            SecureBoot::On(CheckedBy::ShimYourKey) => "on (shim, your key)",
            SecureBoot::On(CheckedBy::YourKeyInDb) => "on (your key in db)",
            SecureBoot::On(CheckedBy::ShimNotChecking) => "on (shim, its checks off)",
            SecureBoot::On(CheckedBy::Shim) => "on (shim)",
            SecureBoot::On(CheckedBy::Firmware) => "on (firmware's db)",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    fn record(secure_boot: Reading, setup_mode: Reading) -> Record {
        Record {
            secure_boot,
            setup_mode,
            shim: Reading::No,
            shim_validation_off: Reading::No,
            key_in_db: Key::Absent,
            key_in_mok: Key::Absent,
        }
    }

    fn say(record: Record) -> std::string::String {
        decide(Firmware::Uefi, Some(&record.encode())).to_string()
    }

    #[test]
    fn on_is_said_only_when_secure_boot_read_as_1() {
        use Reading::{No, Unknown, Yes};
        for setup in [No, Yes, Unknown] {
            assert!(say(record(Yes, setup)).starts_with("on"));
            assert!(!say(record(No, setup)).starts_with("on"));
            assert_eq!(say(record(Unknown, setup)), "unknown");
        }
        assert_eq!(say(record(No, No)), "off");
        assert_eq!(say(record(No, Yes)), "setup mode");
        assert_eq!(say(record(No, Unknown)), "unknown");
    }

    #[test]
    fn who_checked_the_loader() {
        let on = |shim, off, db, mok| {
            say(Record {
                shim,
                shim_validation_off: off,
                key_in_db: db,
                key_in_mok: mok,
                ..record(Reading::Yes, Reading::No)
            })
        };
        use Key::{Absent, NotSigned, Present};
        use Reading::{No, Unknown, Yes};
        assert_eq!(on(Yes, No, Absent, Present), "on (shim, your key)");
        assert_eq!(on(Yes, No, Present, Absent), "on (your key in db)");
        assert_eq!(on(No, No, Present, Absent), "on (your key in db)");
        assert_eq!(on(Yes, Yes, Absent, Present), "on (shim, its checks off)");
        assert_eq!(on(Yes, Unknown, Absent, Present), "on (shim)");
        assert_eq!(on(Yes, No, Key::Unknown, Key::Unknown), "on (shim)");
        assert_eq!(on(No, No, Absent, Absent), "on (firmware's db)");
        assert_eq!(on(No, No, NotSigned, NotSigned), "on (firmware's db)");
    }

    #[test]
    fn no_record_or_a_bad_one_is_unknown_and_bios_is_not_uefi() {
        let good = record(Reading::Yes, Reading::No).encode();
        assert_eq!(decide(Firmware::Bios, Some(&good)), SecureBoot::NotUefi);
        assert_eq!(
            decide(Firmware::Uefi, None),
            SecureBoot::Unknown(Unknown::NoRecord)
        );
        assert_eq!(
            decide(Firmware::Unknown, None),
            SecureBoot::Unknown(Unknown::Firmware)
        );
        let mut bad = good;
        bad[12] ^= 1;
        assert_eq!(
            decide(Firmware::Uefi, Some(&bad)),
            SecureBoot::Unknown(Unknown::BadRecord(RecordError::Checksum))
        );
        assert_eq!(
            decide(Firmware::Uefi, Some(b"an initrd")).to_string(),
            "unknown"
        );
    }
}
