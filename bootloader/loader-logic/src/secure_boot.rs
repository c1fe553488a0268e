//! The Secure Boot state the UEFI loader reads from the firmware and hands to
//! the kernel (issue 39), as a small versioned record; and the search of a
//! UEFI signature database (`db`, shim's `MokListRT`) for the certificate
//! whose SHA-256 the signed loader carries.
//!
//! The loader fills a [`Record`] from what each read gave ([`Reading`]: a
//! read that failed is [`Reading::Unknown`], never a guess) and writes it
//! with [`Record::encode`]; the kernel takes it back with [`Record::decode`],
//! which refuses anything that is not exactly such a record.
//!
//! ```
//! use loader_logic::secure_boot::{Key, Reading, Record};
//!
//! let record = Record {
//!     secure_boot: Reading::Yes,
//!     setup_mode: Reading::No,
//!     shim: Reading::No,
//!     shim_validation_off: Reading::No,
//!     key_in_db: Key::Present,
//!     key_in_mok: Key::Absent,
//! };
//! let bytes = record.encode();
//! assert_eq!(Record::decode(&bytes), Ok(record));
//! let mut changed = bytes;
//! changed[10] = 0;
//! assert!(Record::decode(&changed).is_err());
//! ```

/// The record's first bytes.
pub const MAGIC: [u8; 8] = *b"MXSBSTAT";
/// The format's version; a kernel refuses any other.
pub const VERSION: u8 = 1;
/// The payload's length in version 1: one byte a field.
const PAYLOAD_LEN: u8 = 6;
/// The whole record: magic, version, payload length, payload, checksum.
pub const RECORD_LEN: usize = 8 + 1 + 1 + PAYLOAD_LEN as usize + 2;

/// What one read of the firmware gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Reading {
    /// Read, and false (or absent where absence is the answer).
    No,
    /// Read, and true.
    Yes,
    /// Not read: the firmware returned an error, or a value of a wrong size.
    Unknown,
}

/// Where the signed loader's own certificate was looked for, and what was
/// found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    /// The loader carries no certificate hash (not a signed stick's loader).
    NotSigned,
    /// Looked for, and not there (or the variable does not exist).
    Absent,
    /// There.
    Present,
    /// The variable could not be read or parsed.
    Unknown,
}

/// What the loader read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Record {
    /// The `SecureBoot` variable is 1 (the firmware enforces signatures).
    pub secure_boot: Reading,
    /// The `SetupMode` variable is 1 (no platform key: nothing enforced).
    pub setup_mode: Reading,
    /// Shim's lock protocol is installed: shim started the loader.
    pub shim: Reading,
    /// Shim's `MokSBStateRT` says the user switched shim's checks off.
    pub shim_validation_off: Reading,
    /// The firmware's `db` holds the loader's certificate.
    pub key_in_db: Key,
    /// Shim's `MokListRT` holds the loader's certificate.
    pub key_in_mok: Key,
}

/// Why bytes are not a record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordError {
    /// Fewer bytes than a record.
    TooShort,
    /// Not the record's magic.
    NotARecord,
    /// A version this kernel does not know.
    Version(u8),
    /// The payload's length is not the version's.
    Length(u8),
    /// The checksum does not match.
    Checksum,
    /// A field holds no defined value.
    Field(usize),
}

impl Reading {
    fn byte(self) -> u8 {
        match self {
            Reading::No => 0,
            Reading::Yes => 1,
            Reading::Unknown => 2,
        }
    }

    fn from_byte(byte: u8) -> Option<Reading> {
        Some(match byte {
            0 => Reading::No,
            1 => Reading::Yes,
            2 => Reading::Unknown,
            _ => return None,
        })
    }

    /// A UEFI boolean variable's value: one byte, 0 or 1. Anything else
    /// (another size, another value, a failed read) is [`Reading::Unknown`].
    pub fn of_variable(value: Option<&[u8]>) -> Reading {
        match value {
            Some([0]) => Reading::No,
            Some([1]) => Reading::Yes,
            _ => Reading::Unknown,
        }
    }
}

impl Key {
    fn byte(self) -> u8 {
        match self {
            Key::NotSigned => 0,
            Key::Absent => 1,
            Key::Present => 2,
            Key::Unknown => 3,
        }
    }

    fn from_byte(byte: u8) -> Option<Key> {
        Some(match byte {
            0 => Key::NotSigned,
            1 => Key::Absent,
            2 => Key::Present,
            3 => Key::Unknown,
            _ => return None,
        })
    }
}

/// A 16-bit Fletcher sum: a changed or moved byte changes it.
fn checksum(bytes: &[u8]) -> u16 {
    let (mut a, mut b) = (0u16, 0u16);
    for &byte in bytes {
        a = (a + u16::from(byte)) % 255;
        b = (b + a) % 255;
    }
    (b << 8) | a
}

impl Record {
    /// The record's bytes.
    pub fn encode(&self) -> [u8; RECORD_LEN] {
        let mut bytes = [0u8; RECORD_LEN];
        bytes[..8].copy_from_slice(&MAGIC);
        bytes[8] = VERSION;
        bytes[9] = PAYLOAD_LEN;
        bytes[10] = self.secure_boot.byte();
        bytes[11] = self.setup_mode.byte();
        bytes[12] = self.shim.byte();
        bytes[13] = self.shim_validation_off.byte();
        bytes[14] = self.key_in_db.byte();
        bytes[15] = self.key_in_mok.byte();
        let sum = checksum(&bytes[..RECORD_LEN - 2]);
        bytes[RECORD_LEN - 2..].copy_from_slice(&sum.to_le_bytes());
        bytes
    }

    /// The record in `bytes` (trailing bytes, such as a page's rest, are
    /// ignored), or why they hold none.
    pub fn decode(bytes: &[u8]) -> Result<Record, RecordError> {
        let bytes = bytes.get(..RECORD_LEN).ok_or(RecordError::TooShort)?;
        if bytes[..8] != MAGIC {
            return Err(RecordError::NotARecord);
        }
        if bytes[8] != VERSION {
            return Err(RecordError::Version(bytes[8]));
        }
        if bytes[9] != PAYLOAD_LEN {
            return Err(RecordError::Length(bytes[9]));
        }
        let sum = u16::from_le_bytes([bytes[RECORD_LEN - 2], bytes[RECORD_LEN - 1]]);
        if sum != checksum(&bytes[..RECORD_LEN - 2]) {
            return Err(RecordError::Checksum);
        }
        let reading = |at: usize| Reading::from_byte(bytes[at]).ok_or(RecordError::Field(at));
        let key = |at: usize| Key::from_byte(bytes[at]).ok_or(RecordError::Field(at));
        Ok(Record {
            secure_boot: reading(10)?,
            setup_mode: reading(11)?,
            shim: reading(12)?,
            shim_validation_off: reading(13)?,
            key_in_db: key(14)?,
            key_in_mok: key(15)?,
        })
    }
}

/// `EFI_CERT_X509_GUID` (a5c059a1-94e4-4aa7-87b5-ab155c2bf072) as it lies in
/// memory: an X.509 certificate, DER, per signature.
pub const CERT_X509_GUID: [u8; 16] = [
    0xa1, 0x59, 0xc0, 0xa5, 0xe4, 0x94, 0xa7, 0x4a, 0x87, 0xb5, 0xab, 0x15, 0x5c, 0x2b, 0xf0, 0x72,
];

/// A signature database that is not a run of `EFI_SIGNATURE_LIST`s.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MalformedDatabase;

/// Whether the signature database `db` (the bytes of `db` or `MokListRT`: a
/// run of `EFI_SIGNATURE_LIST`s, UEFI 2.10 section 32.4.1) holds an X.509
/// certificate whose SHA-256 (computed by `sha256`) is `wanted`. A list
/// whose sizes do not add up makes the whole answer an error: nothing is
/// guessed from a damaged variable.
pub fn database_holds_cert(
    db: &[u8],
    wanted: &[u8; 32],
    sha256: impl Fn(&[u8]) -> [u8; 32],
) -> Result<bool, MalformedDatabase> {
    let u32_at = |bytes: &[u8], at: usize| -> Result<usize, MalformedDatabase> {
        let field = bytes.get(at..at + 4).ok_or(MalformedDatabase)?;
        Ok(u32::from_le_bytes([field[0], field[1], field[2], field[3]]) as usize)
    };
    let mut found = false;
    let mut rest = db;
    while !rest.is_empty() {
        let list_size = u32_at(rest, 16)?;
        let header_size = u32_at(rest, 20)?;
        let signature_size = u32_at(rest, 24)?;
        let list = rest.get(..list_size).ok_or(MalformedDatabase)?;
        let first = 28usize.checked_add(header_size).ok_or(MalformedDatabase)?;
        let signatures = list.get(first..).ok_or(MalformedDatabase)?;
        if signature_size <= 16 || signatures.len() % signature_size != 0 {
            return Err(MalformedDatabase);
        }
        if list[..16] == CERT_X509_GUID {
            found |= signatures
                .chunks_exact(signature_size)
                .any(|signature| sha256(&signature[16..]) == *wanted);
        }
        rest = &rest[list_size..];
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn record() -> Record {
        Record {
            secure_boot: Reading::Yes,
            setup_mode: Reading::No,
            shim: Reading::Yes,
            shim_validation_off: Reading::Unknown,
            key_in_db: Key::Absent,
            key_in_mok: Key::Present,
        }
    }

    #[test]
    fn a_record_comes_back_as_written_with_trailing_bytes_ignored() {
        let mut page = [0xAAu8; 64];
        page[..RECORD_LEN].copy_from_slice(&record().encode());
        assert_eq!(Record::decode(&page), Ok(record()));
    }

    #[test]
    fn every_changed_byte_is_refused() {
        let bytes = record().encode();
        for at in 0..RECORD_LEN {
            let mut changed = bytes;
            changed[at] ^= 0x01;
            assert!(Record::decode(&changed).is_err(), "byte {at}");
        }
        assert_eq!(
            Record::decode(&bytes[..RECORD_LEN - 1]),
            Err(RecordError::TooShort)
        );
        assert_eq!(Record::decode(&[0u8; 64]), Err(RecordError::NotARecord));
    }

    #[test]
    fn another_version_or_length_or_value_is_named() {
        let with = |at: usize, value: u8| {
            let mut bytes = record().encode();
            bytes[at] = value;
            let sum = checksum(&bytes[..RECORD_LEN - 2]);
            bytes[RECORD_LEN - 2..].copy_from_slice(&sum.to_le_bytes());
            Record::decode(&bytes)
        };
        assert_eq!(with(8, 2), Err(RecordError::Version(2)));
        assert_eq!(with(9, 7), Err(RecordError::Length(7)));
        assert_eq!(with(10, 3), Err(RecordError::Field(10)));
        assert_eq!(with(15, 4), Err(RecordError::Field(15)));
    }

    #[test]
    fn a_variable_is_a_boolean_only_if_it_is_one_byte_0_or_1() {
        assert_eq!(Reading::of_variable(Some(&[1])), Reading::Yes);
        assert_eq!(Reading::of_variable(Some(&[0])), Reading::No);
        assert_eq!(Reading::of_variable(Some(&[2])), Reading::Unknown);
        assert_eq!(Reading::of_variable(Some(&[1, 0])), Reading::Unknown);
        assert_eq!(Reading::of_variable(None), Reading::Unknown);
    }

    /// A stand-in hash for the tests: the first 32 bytes, zero-padded.
    fn head(bytes: &[u8]) -> [u8; 32] {
        let mut out = [0u8; 32];
        let n = bytes.len().min(32);
        out[..n].copy_from_slice(&bytes[..n]);
        out
    }

    fn list(kind: [u8; 16], header: &[u8], signatures: &[&[u8]]) -> Vec<u8> {
        let size = 16 + signatures[0].len();
        let mut bytes = Vec::from(kind);
        let total = 28 + header.len() + size * signatures.len();
        bytes.extend((total as u32).to_le_bytes());
        bytes.extend((header.len() as u32).to_le_bytes());
        bytes.extend((size as u32).to_le_bytes());
        bytes.extend(header);
        for signature in signatures {
            bytes.extend([0x11u8; 16]);
            bytes.extend(*signature);
        }
        bytes
    }

    #[test]
    fn the_certificate_is_found_in_any_x509_list_and_only_there() {
        let ours = [7u8; 40];
        let other = [9u8; 40];
        let sha256_kind = [0x26u8; 16];
        let mut db = list(CERT_X509_GUID, &[], &[&other]);
        db.extend(list(sha256_kind, &[], &[&ours[..32]]));
        assert_eq!(database_holds_cert(&db, &head(&ours), head), Ok(false));
        db.extend(list(CERT_X509_GUID, &[1, 2, 3], &[&other, &ours]));
        assert_eq!(database_holds_cert(&db, &head(&ours), head), Ok(true));
        assert_eq!(database_holds_cert(&[], &head(&ours), head), Ok(false));
    }

    #[test]
    fn a_damaged_database_is_an_error_not_an_answer() {
        let ours = [7u8; 40];
        let db = list(CERT_X509_GUID, &[], &[&ours]);
        assert_eq!(
            database_holds_cert(&db[..db.len() - 1], &head(&ours), head),
            Err(MalformedDatabase)
        );
        let mut wrong_size = db.clone();
        wrong_size[24] = 17;
        assert_eq!(
            database_holds_cert(&wrong_size, &head(&ours), head),
            Err(MalformedDatabase)
        );
        let mut huge_header = db;
        huge_header[20..24].copy_from_slice(&u32::MAX.to_le_bytes());
        assert_eq!(
            database_holds_cert(&huge_header, &head(&ours), head),
            Err(MalformedDatabase)
        );
    }
}
