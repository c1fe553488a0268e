//! The SHA-256 of every file a loader starts, checked before any of it runs
//! (CHANGES.md, issue 48). A firmware may hand back wrong bytes as a good
//! read (OVMF's AHCI driver does, for a sector that keeps failing); a stick
//! may rot. Without a check the loader then fails on those bytes with no
//! word of why.
//!
//! Each loader carries one [`HashSlot`]: a marker, then the SHA-256 of the
//! kernel file and of BIOS stage 4. The loaders are built
//! before the kernel, so the slot is all zeros as built; the image build
//! finds the marker in each loader's file and writes the hashes there
//! ([`patch`]), and the Secure Boot stick's signature then covers them. A
//! loader whose slot was never written refuses every file.
//!
//! The hash is the `sha2` crate's portable code ([`sha256`]), the same in
//! every loader; the words of a mismatch are [`Mismatch`]'s.

use core::fmt;
use sha2::Digest;

/// The 16 bytes before the hashes, found by the build in a loader's file.
/// (The loaders only read the hashes after it, so these bytes are in each
/// loader's file once: in its [`HashSlot`].)
pub const MARKER: [u8; 16] = *b"modex-cube sha\x32\x01";

/// What each loader keeps, patched by the build: the SHA-256 of each file
/// it checks. `repr(C)`: the build writes it by offset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C)]
pub struct HashSlot {
    /// [`MARKER`].
    pub marker: [u8; 16],
    /// The files' hashes, in [`File`]'s order.
    pub hashes: [[u8; 32]; File::COUNT],
}

impl HashSlot {
    /// As built: the marker, and zeros where the hashes go.
    pub const EMPTY: HashSlot = HashSlot {
        marker: MARKER,
        hashes: [[0; 32]; File::COUNT],
    };

    /// The bytes of the slot as they lie in a loader's file.
    pub fn to_bytes(&self) -> [u8; HashSlot::SIZE] {
        let mut bytes = [0; HashSlot::SIZE];
        bytes[..16].copy_from_slice(&self.marker);
        for (at, hash) in self.hashes.iter().enumerate() {
            bytes[16 + 32 * at..][..32].copy_from_slice(hash);
        }
        bytes
    }

    /// The slot's size in a loader's file.
    pub const SIZE: usize = 16 + 32 * File::COUNT;

    /// Checks `found`, the SHA-256 of `file` as read, against this slot.
    pub fn check(&self, file: File, found: [u8; 32]) -> Result<(), Mismatch> {
        let expected = self.hashes[file as usize];
        if found == expected {
            Ok(())
        } else {
            Err(Mismatch {
                file,
                expected,
                found,
            })
        }
    }
}

/// The files the loaders check, and their places in [`HashSlot::hashes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum File {
    /// `kernel-x86_64`, checked by both UEFI loaders and BIOS stage 3.
    Kernel = 0,
    /// `boot-stage-4`, checked by the 32-bit UEFI loader and BIOS stage 3.
    Stage4 = 1,
}

impl File {
    /// How many files a slot holds.
    pub const COUNT: usize = 2;

    /// The file's name on the stick, and which stage it is.
    pub fn name(self) -> &'static str {
        match self {
            File::Kernel => "kernel-x86_64 (the kernel)",
            File::Stage4 => "boot-stage-4 (loader stage 4)",
        }
    }
}

/// A file whose bytes are not the ones the build wrote: the loader's
/// message, on the screen and COM1, before it stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// The file.
    pub file: File,
    /// Its SHA-256 by the loader's slot.
    pub expected: [u8; 32],
    /// Its SHA-256 as read.
    pub found: [u8; 32],
}

/// The first bytes of a hash, in hex: enough to tell two apart by eye.
struct Prefix<'a>(&'a [u8; 32]);

impl fmt::Display for Prefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        for byte in &self.0[..6] {
            write!(f, "{byte:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(
            f,
            "{}{}: SHA-256 expected {}..., read {}.... \
             Write the stick again, or try another USB port. The loader stops here.",
            DAMAGED,
            self.file.name(),
            Prefix(&self.expected),
            Prefix(&self.found),
        )
    }
}

/// The start of [`Mismatch`]'s message, which the tests wait for.
pub const DAMAGED: &str = "loader: damaged file: ";

/// Why [`patch`] could not write a loader's hashes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatchError {
    /// The loader's file has no [`MARKER`]: not this project's loader.
    NoSlot,
    /// The marker is there more than once: which one is the slot?
    SeveralSlots,
}

impl fmt::Display for PatchError {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(match self {
            PatchError::NoSlot => "the loader has no hash slot (not this project's loader)",
            PatchError::SeveralSlots => "the loader's hash slot marker is there more than once",
        })
    }
}

/// Where the slot's bytes are in a loader's file.
pub fn slot_offset(loader: &[u8]) -> Result<usize, PatchError> {
    let mut found = loader
        .windows(MARKER.len())
        .enumerate()
        .filter(|(_, window)| *window == MARKER)
        .map(|(at, _)| at);
    let at = found.next().ok_or(PatchError::NoSlot)?;
    if found.next().is_some() {
        return Err(PatchError::SeveralSlots);
    }
    if loader.len() < at + HashSlot::SIZE {
        return Err(PatchError::NoSlot);
    }
    Ok(at)
}

/// The slot as written in a loader's file.
pub fn slot_of(loader: &[u8]) -> Result<HashSlot, PatchError> {
    let at = slot_offset(loader)?;
    let mut slot = HashSlot::EMPTY;
    for (index, hash) in slot.hashes.iter_mut().enumerate() {
        hash.copy_from_slice(&loader[at + 16 + 32 * index..][..32]);
    }
    Ok(slot)
}

/// Writes `hashes` (in [`File`] order) into `loader`'s slot.
pub fn patch(loader: &mut [u8], hashes: &[[u8; 32]; File::COUNT]) -> Result<(), PatchError> {
    let at = slot_offset(loader)?;
    let slot = HashSlot {
        marker: MARKER,
        hashes: *hashes,
    };
    loader[at..at + HashSlot::SIZE].copy_from_slice(&slot.to_bytes());
    Ok(())
}

/// The SHA-256 of `bytes`: the `sha2` crate's portable code
/// (`force-soft`), with no CPU feature detection, which the 32-bit stages
/// and loaders could not trust.
pub fn sha256(bytes: &[u8]) -> [u8; 32] {
    sha2::Sha256::digest(bytes).into()
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::{format, vec::Vec};

    fn hex(hash: [u8; 32]) -> std::string::String {
        hash.iter().map(|b| format!("{b:02x}")).collect()
    }

    #[test]
    fn the_hash_is_sha256_by_the_published_examples() {
        // FIPS 180-2, appendix B: one block, two blocks, and a million a's.
        assert_eq!(
            hex(sha256(b"abc")),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(
            hex(sha256(
                b"abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"
            )),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"
        );
        assert_eq!(
            hex(sha256(&std::vec![b'a'; 1_000_000])),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"
        );
        assert_eq!(
            hex(sha256(b"")),
            "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
        );
    }

    fn loader_with_slot() -> Vec<u8> {
        let mut loader = std::vec![0x90u8; 100];
        loader.extend_from_slice(&HashSlot::EMPTY.to_bytes());
        loader.extend_from_slice(&[0xCC; 50]);
        loader
    }

    #[test]
    fn the_build_writes_the_hashes_where_the_marker_is() {
        let mut loader = loader_with_slot();
        let hashes = [[1; 32], [2; 32]];
        patch(&mut loader, &hashes).unwrap();
        assert_eq!(slot_offset(&loader), Ok(100));
        assert_eq!(slot_of(&loader).unwrap().hashes, hashes);
        assert_eq!(loader[..100], [0x90; 100]);
        assert_eq!(loader[100 + HashSlot::SIZE..], [0xCC; 50]);
    }

    #[test]
    fn a_file_without_or_with_two_markers_is_refused() {
        assert_eq!(slot_offset(&[0; 500]), Err(PatchError::NoSlot));
        let mut two = loader_with_slot();
        two.extend_from_slice(&loader_with_slot());
        assert_eq!(
            patch(&mut two, &[[0; 32]; 2]),
            Err(PatchError::SeveralSlots)
        );
        // A marker too near the end to hold the hashes is no slot.
        let mut short = std::vec![0u8; 10];
        short.extend_from_slice(&MARKER);
        assert_eq!(slot_offset(&short), Err(PatchError::NoSlot));
    }

    #[test]
    fn a_match_passes_and_a_mismatch_names_the_file_both_prefixes_and_what_to_do() {
        let mut slot = HashSlot::EMPTY;
        slot.hashes[File::Stage4 as usize] = sha256(b"stage 4");
        assert_eq!(slot.check(File::Stage4, sha256(b"stage 4")), Ok(()));
        let mismatch = slot.check(File::Stage4, sha256(b"stage 4!")).unwrap_err();
        let text = format!("{mismatch}");
        assert!(text.starts_with(DAMAGED), "{text}");
        assert!(text.contains("boot-stage-4 (loader stage 4)"), "{text}");
        let hex = |hash: [u8; 32]| -> std::string::String {
            hash[..6].iter().map(|b| format!("{b:02x}")).collect()
        };
        assert!(
            text.contains(&format!("expected {}...", hex(sha256(b"stage 4")))),
            "{text}"
        );
        assert!(
            text.contains(&format!("read {}...", hex(sha256(b"stage 4!")))),
            "{text}"
        );
        assert!(text.contains("Write the stick again, or try another USB port"));
        // A slot never written refuses every file.
        assert!(HashSlot::EMPTY.check(File::Kernel, sha256(b"")).is_err());
    }
}
