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
//! The hash is this module's own [`Sha256`], the same code in every loader; its words on a mismatch are
//! [`Mismatch`]'s.

use core::fmt;

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
    /// `kernel-x86_64`, checked by both UEFI loaders.
    Kernel = 0,
    /// `boot-stage-4`, checked by the 32-bit UEFI loader.
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

/// SHA-256 (FIPS 180-4), fed in pieces: the loaders hash a file as it is
/// read, a buffer at a time.
#[derive(Clone)]
pub struct Sha256 {
    state: [u32; 8],
    block: [u8; 64],
    in_block: usize,
    bytes: u64,
}

const ROUND_CONSTANTS: [u32; 64] = [
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2,
];

impl Default for Sha256 {
    fn default() -> Self {
        Self::new()
    }
}

impl Sha256 {
    /// A hash of nothing yet.
    pub const fn new() -> Self {
        Sha256 {
            state: [
                0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab,
                0x5be0cd19,
            ],
            block: [0; 64],
            in_block: 0,
            bytes: 0,
        }
    }

    /// Adds `bytes` to what is hashed.
    pub fn update(&mut self, mut bytes: &[u8]) {
        self.bytes = self.bytes.wrapping_add(bytes.len() as u64);
        if self.in_block > 0 {
            let take = (64 - self.in_block).min(bytes.len());
            self.block[self.in_block..self.in_block + take].copy_from_slice(&bytes[..take]);
            self.in_block += take;
            bytes = &bytes[take..];
            if self.in_block < 64 {
                return;
            }
            let block = self.block;
            self.compress(&block);
            self.in_block = 0;
        }
        let (blocks, rest) = bytes.as_chunks::<64>();
        for block in blocks {
            self.compress(block);
        }
        self.block[..rest.len()].copy_from_slice(rest);
        self.in_block = rest.len();
    }

    /// The hash of everything added.
    pub fn finish(mut self) -> [u8; 32] {
        let bits = self.bytes.wrapping_mul(8);
        // 0x80, zeros to 56 bytes into a block, the length in bits.
        let zeros = (55 + 64 - self.in_block) % 64;
        let mut padding = [0u8; 72];
        padding[0] = 0x80;
        padding[1 + zeros..9 + zeros].copy_from_slice(&bits.to_be_bytes());
        self.update(&padding[..9 + zeros]);
        let mut out = [0; 32];
        for (chunk, word) in out.as_chunks_mut::<4>().0.iter_mut().zip(self.state) {
            *chunk = word.to_be_bytes();
        }
        out
    }

    fn compress(&mut self, block: &[u8; 64]) {
        let mut schedule = [0u32; 64];
        for (word, bytes) in schedule.iter_mut().zip(block.as_chunks::<4>().0) {
            *word = u32::from_be_bytes(*bytes);
        }
        for at in 16..64 {
            let a = schedule[at - 15];
            let b = schedule[at - 2];
            let s0 = a.rotate_right(7) ^ a.rotate_right(18) ^ (a >> 3);
            let s1 = b.rotate_right(17) ^ b.rotate_right(19) ^ (b >> 10);
            schedule[at] = schedule[at - 16]
                .wrapping_add(s0)
                .wrapping_add(schedule[at - 7])
                .wrapping_add(s1);
        }
        let mut v = self.state;
        for (constant, word) in ROUND_CONSTANTS.iter().zip(schedule) {
            let s1 = v[4].rotate_right(6) ^ v[4].rotate_right(11) ^ v[4].rotate_right(25);
            let choose = (v[4] & v[5]) ^ (!v[4] & v[6]);
            let t1 = v[7]
                .wrapping_add(s1)
                .wrapping_add(choose)
                .wrapping_add(*constant)
                .wrapping_add(word);
            let s0 = v[0].rotate_right(2) ^ v[0].rotate_right(13) ^ v[0].rotate_right(22);
            let majority = (v[0] & v[1]) ^ (v[0] & v[2]) ^ (v[1] & v[2]);
            let t2 = s0.wrapping_add(majority);
            v = [
                t1.wrapping_add(t2),
                v[0],
                v[1],
                v[2],
                v[3].wrapping_add(t1),
                v[4],
                v[5],
                v[6],
            ];
        }
        for (state, value) in self.state.iter_mut().zip(v) {
            *state = state.wrapping_add(value);
        }
    }
}

/// The SHA-256 of `bytes`.
pub fn sha256(bytes: &[u8]) -> [u8; 32] {
    let mut hash = Sha256::new();
    hash.update(bytes);
    hash.finish()
}

#[cfg(test)]
mod tests {
    use super::*;
    use sha2::Digest;
    use std::{format, vec::Vec};

    fn reference(bytes: &[u8]) -> [u8; 32] {
        sha2::Sha256::digest(bytes).into()
    }

    #[test]
    fn the_hash_is_sha256_at_every_length_around_the_block_ends() {
        let bytes: Vec<u8> = (0..300u32).map(|i| (i * 7 + 3) as u8).collect();
        for len in 0..bytes.len() {
            assert_eq!(
                sha256(&bytes[..len]),
                reference(&bytes[..len]),
                "{len} bytes"
            );
        }
        // FIPS 180-2's "abc".
        assert_eq!(
            sha256(b"abc")[..4],
            [0xba, 0x78, 0x16, 0xbf],
            "the published hash of abc"
        );
    }

    #[test]
    fn the_hash_fed_in_pieces_is_the_hash_of_the_whole() {
        let bytes: Vec<u8> = (0..5000u32).map(|i| (i ^ (i >> 3)) as u8).collect();
        for piece in [1, 3, 63, 64, 65, 512, 4096] {
            let mut hash = Sha256::new();
            for chunk in bytes.chunks(piece) {
                hash.update(chunk);
            }
            assert_eq!(hash.finish(), reference(&bytes), "pieces of {piece}");
        }
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
