//! QEMU's fw_cfg device as the kernel reads it: check the signature, walk
//! the file directory for a file by name, and copy the file into a buffer.
//! The kernel supplies the two port operations ([`FwCfg`]); everything that
//! decides what the bytes mean lives here, so the host can test it.
//!
//! The layout (QEMU's `docs/specs/fw_cfg.rst`): selecting a key rewinds its
//! item to the start; each read of the data port gives the next byte, and 0
//! past the end. The file directory is a big-endian 32-bit count of entries,
//! each a big-endian 32-bit size, a big-endian 16-bit key to select, two
//! reserved bytes and a 56-byte NUL-padded name.

use protocol::BOOT_OPTION_FILE;

/// The selector key of the signature, `QEMU` on QEMU.
pub const SIGNATURE_KEY: u16 = 0x0000;
/// The selector key of the file directory.
pub const FILE_DIR_KEY: u16 = 0x0019;
/// The bytes of a file name in a directory entry, NUL padding included.
pub const FILE_NAME_LEN: usize = 56;
const SIGNATURE: [u8; 4] = *b"QEMU";

/// The device: the kernel's implementation writes the selector port and
/// reads the data port.
pub trait FwCfg {
    /// Selects the item `key` and rewinds it to its first byte.
    fn select(&mut self, key: u16);
    /// The selected item's next byte.
    fn read_byte(&mut self) -> u8;
}

/// A file found in the directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileEntry {
    /// The key that selects it.
    pub key: u16,
    /// Its length in bytes.
    pub size: usize,
}

fn read_array<const N: usize>(fw_cfg: &mut impl FwCfg) -> [u8; N] {
    let mut bytes = [0; N];
    for byte in &mut bytes {
        *byte = fw_cfg.read_byte();
    }
    bytes
}

/// The directory entry named exactly `name` (the first, if several are),
/// or `None` when the device's signature is not QEMU's or no entry is.
/// A name filling all 56 bytes, with no NUL, is compared whole.
pub fn find_file(fw_cfg: &mut impl FwCfg, name: &[u8]) -> Option<FileEntry> {
    fw_cfg.select(SIGNATURE_KEY);
    if read_array(fw_cfg) != SIGNATURE {
        return None;
    }
    fw_cfg.select(FILE_DIR_KEY);
    let count = u32::from_be_bytes(read_array(fw_cfg));
    for _ in 0..count {
        let size = u32::from_be_bytes(read_array(fw_cfg)) as usize;
        let key = u16::from_be_bytes(read_array(fw_cfg));
        let _reserved: [u8; 2] = read_array(fw_cfg);
        let entry_name: [u8; FILE_NAME_LEN] = read_array(fw_cfg);
        let len = entry_name
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(FILE_NAME_LEN);
        if &entry_name[..len] == name {
            return Some(FileEntry { key, size });
        }
    }
    None
}

/// The file `name` as text: at most `buffer.len()` bytes of it (a longer
/// file is cut short there), without trailing NULs or surrounding white
/// space. `None` if there is no such file, or the bytes kept are not UTF-8
/// (which a cut through a character makes them).
pub fn read_text_file<'b>(
    fw_cfg: &mut impl FwCfg,
    name: &[u8],
    buffer: &'b mut [u8],
) -> Option<&'b str> {
    let file = find_file(fw_cfg, name)?;
    fw_cfg.select(file.key);
    let len = file.size.min(buffer.len());
    for byte in &mut buffer[..len] {
        *byte = fw_cfg.read_byte();
    }
    core::str::from_utf8(&buffer[..len])
        .ok()
        .map(|text| text.trim_end_matches('\0').trim())
}

/// The boot option the runner passed (`-fw_cfg name=opt/modex/boot,string=...`).
pub fn boot_option<'b>(fw_cfg: &mut impl FwCfg, buffer: &'b mut [u8]) -> Option<&'b str> {
    read_text_file(fw_cfg, BOOT_OPTION_FILE.as_bytes(), buffer)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// QEMU's fw_cfg as the kernel sees it: items by key, a cursor into the
    /// selected one, 0 past its end; and every byte read, counted.
    struct FakeFwCfg {
        items: Vec<(u16, Vec<u8>)>,
        selected: Option<u16>,
        at: usize,
        selects: Vec<u16>,
        reads: usize,
    }

    impl FwCfg for FakeFwCfg {
        fn select(&mut self, key: u16) {
            self.selected = Some(key);
            self.at = 0;
            self.selects.push(key);
        }

        fn read_byte(&mut self) -> u8 {
            self.reads += 1;
            let item = self
                .items
                .iter()
                .find(|(key, _)| Some(*key) == self.selected);
            let byte = item.and_then(|(_, bytes)| bytes.get(self.at).copied());
            self.at += 1;
            byte.unwrap_or(0)
        }
    }

    /// A directory entry's name: `name` padded with NULs to 56 bytes.
    fn padded(name: &[u8]) -> [u8; FILE_NAME_LEN] {
        let mut bytes = [0; FILE_NAME_LEN];
        bytes[..name.len()].copy_from_slice(name);
        bytes
    }

    /// A device with QEMU's signature and these files (name, contents), at
    /// keys from 0x20 on; each directory entry's size is its contents' length.
    fn device(files: &[([u8; FILE_NAME_LEN], &[u8])]) -> FakeFwCfg {
        let mut directory = (files.len() as u32).to_be_bytes().to_vec();
        let mut items = std::vec![(SIGNATURE_KEY, b"QEMU".to_vec())];
        for (n, (name, contents)) in files.iter().enumerate() {
            let key = 0x20 + n as u16;
            directory.extend_from_slice(&(contents.len() as u32).to_be_bytes());
            directory.extend_from_slice(&key.to_be_bytes());
            directory.extend_from_slice(&[0xAA, 0x55]); // reserved: ignored
            directory.extend_from_slice(name);
            items.push((key, contents.to_vec()));
        }
        items.push((FILE_DIR_KEY, directory));
        FakeFwCfg {
            items,
            selected: None,
            at: 0,
            selects: Vec::new(),
            reads: 0,
        }
    }

    fn option(fw_cfg: &mut FakeFwCfg) -> Option<std::string::String> {
        let mut buffer = [0u8; 64];
        boot_option(fw_cfg, &mut buffer).map(Into::into)
    }

    #[test]
    fn the_option_is_found_among_several_files() {
        let mut fw_cfg = device(&[
            (padded(b"etc/boot-menu-wait"), b"\x00\x00"),
            (padded(b"opt/other"), b"no"),
            (padded(b"opt/modex/boot"), b"fault=page"),
            (padded(b"genroms/kvmvapic.bin"), &[0xFF; 8]),
        ]);
        assert_eq!(option(&mut fw_cfg).as_deref(), Some("fault=page"));
        assert_eq!(
            find_file(&mut fw_cfg, b"opt/modex/boot"),
            Some(FileEntry {
                key: 0x22,
                size: 10
            })
        );
    }

    #[test]
    fn trailing_nuls_and_white_space_are_dropped() {
        let mut fw_cfg = device(&[(padded(b"opt/modex/boot"), b" bench \n\0\0")]);
        assert_eq!(option(&mut fw_cfg).as_deref(), Some("bench"));
    }

    #[test]
    fn similar_names_are_not_the_option() {
        let similar = [
            padded(b"opt/modex/boot2"),
            padded(b"opt/modex/boo"),
            padded(b"opt/modex/boot/x"),
            padded(b"Opt/modex/boot"),
            padded(b"/opt/modex/boot"),
        ];
        let files: Vec<_> = similar.iter().map(|name| (*name, &b"wrong"[..])).collect();
        assert_eq!(option(&mut device(&files)), None);
        // And after all of them, the real one is still found.
        let mut files = files;
        files.push((padded(b"opt/modex/boot"), b"bench"));
        assert_eq!(option(&mut device(&files)).as_deref(), Some("bench"));
    }

    #[test]
    fn no_such_file_is_none() {
        assert_eq!(option(&mut device(&[(padded(b"opt/other"), b"x")])), None);
        assert_eq!(option(&mut device(&[])), None);
    }

    #[test]
    fn a_name_without_a_nul_is_compared_whole() {
        // All 56 bytes used: "opt/modex/boot" and then more, no NUL.
        let mut name = [b'x'; FILE_NAME_LEN];
        name[..14].copy_from_slice(b"opt/modex/boot");
        assert_eq!(option(&mut device(&[(name, b"bench")])), None);
        // A 56-byte name is found by its 56 bytes.
        let long = [b'n'; FILE_NAME_LEN];
        let mut fw_cfg = device(&[(long, b"yes")]);
        let mut buffer = [0u8; 8];
        assert_eq!(read_text_file(&mut fw_cfg, &long, &mut buffer), Some("yes"));
    }

    #[test]
    fn a_longer_option_is_cut_at_the_buffer() {
        let long = [b'a'; 100];
        let mut fw_cfg = device(&[(padded(b"opt/modex/boot"), &long)]);
        let read_before = {
            let mut probe = device(&[(padded(b"opt/modex/boot"), &long)]);
            find_file(&mut probe, b"opt/modex/boot");
            probe.reads
        };
        let mut buffer = [0u8; 64];
        let text = boot_option(&mut fw_cfg, &mut buffer).unwrap();
        assert_eq!(text, core::str::from_utf8(&long[..64]).unwrap());
        // Not a byte of the file past the buffer is read.
        assert_eq!(fw_cfg.reads, read_before + 64);
    }

    #[test]
    fn bytes_that_are_not_utf8_are_no_option() {
        let mut fw_cfg = device(&[(padded(b"opt/modex/boot"), b"bench\xFF")]);
        assert_eq!(option(&mut fw_cfg), None);
        // A cut through a character counts the same: "é" is two bytes, the
        // buffer holds the first.
        let mut text = [b'a'; 64].to_vec();
        text[63..].copy_from_slice(&[0xC3]);
        text.push(0xA9);
        let mut fw_cfg = device(&[(padded(b"opt/modex/boot"), &text)]);
        assert_eq!(option(&mut fw_cfg), None);
    }

    #[test]
    fn without_qemus_signature_the_directory_is_never_read() {
        let mut fw_cfg = device(&[(padded(b"opt/modex/boot"), b"bench")]);
        fw_cfg.items[0].1 = b"QEMX".to_vec();
        assert_eq!(option(&mut fw_cfg), None);
        assert_eq!(fw_cfg.selects, [SIGNATURE_KEY]);
        // No device at all reads as zeros (an unassigned port reads 0xFF,
        // also not "QEMU").
        fw_cfg.items.clear();
        assert_eq!(option(&mut fw_cfg), None);
    }
}
