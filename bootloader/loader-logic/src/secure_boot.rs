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

/// A firmware variable the record is read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Variable {
    /// `SecureBoot` (EFI global variable): 1 while signatures are enforced.
    SecureBoot,
    /// `SetupMode` (EFI global variable): 1 while there is no platform key.
    SetupMode,
    /// Shim's `MokSBStateRT`: set only when the user switched shim's checks
    /// off.
    MokSbStateRt,
    /// The firmware's signature database `db`.
    Db,
    /// Shim's `MokListRT`: the user's keys enrolled through MokManager.
    MokListRt,
}

/// `EFI_GLOBAL_VARIABLE` (8be4df61-93ca-11d2-aa0d-00e098032b8c) as it lies
/// in memory.
const GLOBAL_VARIABLE_GUID: [u8; 16] = [
    0x61, 0xdf, 0xe4, 0x8b, 0xca, 0x93, 0xd2, 0x11, 0xaa, 0x0d, 0x00, 0xe0, 0x98, 0x03, 0x2b, 0x8c,
];
/// `EFI_IMAGE_SECURITY_DATABASE_GUID` (d719b2cb-3d3a-4596-a3bc-dad00e67656f).
const IMAGE_SECURITY_DATABASE_GUID: [u8; 16] = [
    0xcb, 0xb2, 0x19, 0xd7, 0x3a, 0x3d, 0x96, 0x45, 0xa3, 0xbc, 0xda, 0xd0, 0x0e, 0x67, 0x65, 0x6f,
];
/// Shim's variables' vendor, its lock protocol's GUID
/// (605dab50-e046-4300-abb6-3dd810dd8b23).
const SHIM_GUID: [u8; 16] = [
    0x50, 0xab, 0x5d, 0x60, 0x46, 0xe0, 0x00, 0x43, 0xab, 0xb6, 0x3d, 0xd8, 0x10, 0xdd, 0x8b, 0x23,
];

impl Variable {
    /// The variable's name.
    pub fn name(self) -> &'static str {
        match self {
            Variable::SecureBoot => "SecureBoot",
            Variable::SetupMode => "SetupMode",
            Variable::MokSbStateRt => "MokSBStateRT",
            Variable::Db => "db",
            Variable::MokListRt => "MokListRT",
        }
    }

    /// Its vendor GUID, as the bytes lie in memory (`EFI_GUID`).
    pub fn vendor_guid(self) -> [u8; 16] {
        match self {
            Variable::SecureBoot | Variable::SetupMode => GLOBAL_VARIABLE_GUID,
            Variable::Db => IMAGE_SECURITY_DATABASE_GUID,
            Variable::MokSbStateRt | Variable::MokListRt => SHIM_GUID,
        }
    }
}

/// What `GetVariable` gave.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VariableRead<'a> {
    /// The variable's bytes (possibly none).
    Value(&'a [u8]),
    /// `EFI_NOT_FOUND`: the variable does not exist.
    NotFound,
    /// Any other error, or no memory to read it into.
    Failed,
}

/// The firmware calls the record is read with; each loader makes them
/// (`bootloader/uefi/src/secure_boot_state.rs`, shared by both UEFI
/// loaders) and [`read_record`] decides what they mean.
pub trait Firmware {
    /// Reads `variable`, whatever its size, and hands what the read gave to
    /// `then`.
    fn read_variable<R>(
        &mut self,
        variable: Variable,
        then: impl FnOnce(VariableRead<'_>) -> R,
    ) -> R;
    /// Whether shim's lock protocol is installed: `Unknown` if the lookup
    /// failed for another reason than there being none.
    fn shim_lock(&mut self) -> Reading;
}

/// The record, from what `firmware` answers. `cert_sha256` is the SHA-256
/// of the certificate that signs the loader (all zeros: not a signed
/// stick's loader, and no database is read); `sha256` hashes each
/// certificate of a database.
pub fn read_record(
    firmware: &mut impl Firmware,
    cert_sha256: &[u8; 32],
    sha256: impl Fn(&[u8]) -> [u8; 32],
) -> Record {
    // A boolean; `absent` is the answer when it does not exist (`None`: its
    // absence is unknown too).
    let mut boolean = |variable, absent: Option<Reading>| {
        firmware.read_variable(variable, |read| match read {
            VariableRead::Value(value) => Reading::of_variable(Some(value)),
            VariableRead::NotFound => absent.unwrap_or(Reading::Unknown),
            VariableRead::Failed => Reading::Unknown,
        })
    };
    let secure_boot = boolean(Variable::SecureBoot, None);
    let setup_mode = boolean(Variable::SetupMode, None);
    // Shim sets MokSBStateRT only when the user switched its checks off.
    let shim_validation_off = boolean(Variable::MokSbStateRt, Some(Reading::No));
    let signed = *cert_sha256 != [0; 32];
    let mut key_in = |variable| {
        if !signed {
            return Key::NotSigned;
        }
        firmware.read_variable(variable, |read| match read {
            VariableRead::Value(value) => match database_holds_cert(value, cert_sha256, &sha256) {
                Ok(true) => Key::Present,
                Ok(false) => Key::Absent,
                Err(MalformedDatabase) => Key::Unknown,
            },
            VariableRead::NotFound => Key::Absent,
            VariableRead::Failed => Key::Unknown,
        })
    };
    let key_in_db = key_in(Variable::Db);
    let key_in_mok = key_in(Variable::MokListRt);
    Record {
        secure_boot,
        setup_mode,
        shim: firmware.shim_lock(),
        shim_validation_off,
        key_in_db,
        key_in_mok,
    }
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

    /// A firmware of variables: `None` is a failed read, a missing entry is
    /// `EFI_NOT_FOUND`; it counts the variables read.
    struct Variables {
        values: Vec<(Variable, Option<Vec<u8>>)>,
        shim: Reading,
        read: Vec<Variable>,
    }

    impl Firmware for Variables {
        fn read_variable<R>(
            &mut self,
            variable: Variable,
            then: impl FnOnce(VariableRead<'_>) -> R,
        ) -> R {
            self.read.push(variable);
            match self.values.iter().find(|(name, _)| *name == variable) {
                Some((_, Some(value))) => then(VariableRead::Value(value)),
                Some((_, None)) => then(VariableRead::Failed),
                None => then(VariableRead::NotFound),
            }
        }

        fn shim_lock(&mut self) -> Reading {
            self.shim
        }
    }

    fn firmware(values: &[(Variable, Option<&[u8]>)]) -> Variables {
        Variables {
            values: values
                .iter()
                .map(|(name, value)| (*name, value.map(Vec::from)))
                .collect(),
            shim: Reading::No,
            read: Vec::new(),
        }
    }

    #[test]
    fn blank_variables_are_setup_mode_and_an_unsigned_loader_reads_no_database() {
        // OVMF's empty variable store: no platform key, no shim.
        let mut blank = firmware(&[
            (Variable::SecureBoot, Some(&[0])),
            (Variable::SetupMode, Some(&[1])),
        ]);
        let record = read_record(&mut blank, &[0; 32], head);
        assert_eq!(
            record,
            Record {
                secure_boot: Reading::No,
                setup_mode: Reading::Yes,
                shim: Reading::No,
                shim_validation_off: Reading::No,
                key_in_db: Key::NotSigned,
                key_in_mok: Key::NotSigned,
            }
        );
        assert!(!blank.read.contains(&Variable::Db), "{:?}", blank.read);
    }

    #[test]
    fn a_failed_read_is_unknown_and_absence_is_unknown_where_it_means_nothing() {
        let ours = [7u8; 40];
        let mut broken = firmware(&[
            (Variable::SecureBoot, None),
            (Variable::MokSbStateRt, Some(&[1])),
            (Variable::Db, None),
            (
                Variable::MokListRt,
                Some(&list(CERT_X509_GUID, &[], &[&ours])),
            ),
        ]);
        broken.shim = Reading::Unknown;
        let record = read_record(&mut broken, &head(&ours), head);
        assert_eq!(
            record,
            Record {
                secure_boot: Reading::Unknown,
                // Absent: a firmware without `SetupMode` says nothing.
                setup_mode: Reading::Unknown,
                shim: Reading::Unknown,
                shim_validation_off: Reading::Yes,
                key_in_db: Key::Unknown,
                key_in_mok: Key::Present,
            }
        );
        // No db, and a damaged MOK list: absent, and unknown.
        let mut damaged = firmware(&[(Variable::MokListRt, Some(&[1, 2, 3]))]);
        let record = read_record(&mut damaged, &head(&ours), head);
        assert_eq!(
            (record.key_in_db, record.key_in_mok),
            (Key::Absent, Key::Unknown)
        );
    }

    /// An `EFI_GUID`'s bytes from its text form.
    fn guid(text: &str) -> [u8; 16] {
        let hex: Vec<u8> = text
            .split('-')
            .flat_map(|part| {
                (0..part.len())
                    .step_by(2)
                    .map(move |at| u8::from_str_radix(&part[at..at + 2], 16).unwrap())
            })
            .collect();
        let mut bytes = [0u8; 16];
        bytes.copy_from_slice(&hex);
        bytes[..4].reverse();
        bytes[4..6].reverse();
        bytes[6..8].reverse();
        bytes
    }

    #[test]
    fn the_variables_vendors_are_the_specifications_guids() {
        let global = guid("8be4df61-93ca-11d2-aa0d-00e098032b8c");
        assert_eq!(Variable::SecureBoot.vendor_guid(), global);
        assert_eq!(Variable::SetupMode.vendor_guid(), global);
        assert_eq!(
            Variable::Db.vendor_guid(),
            guid("d719b2cb-3d3a-4596-a3bc-dad00e67656f")
        );
        let shim = guid("605dab50-e046-4300-abb6-3dd810dd8b23");
        assert_eq!(Variable::MokSbStateRt.vendor_guid(), shim);
        assert_eq!(Variable::MokListRt.vendor_guid(), shim);
        assert_eq!(CERT_X509_GUID, guid("a5c059a1-94e4-4aa7-87b5-ab155c2bf072"));
    }
}
