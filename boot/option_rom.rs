//! The worst-case BIOS of `tests/hostile_bios.rs`: an option ROM
//! (`boot/roms/hostile_bios.asm`) that hooks INT 10h, 13h and 15h and hands
//! back junk in the upper halves of the 32-bit registers, and, as a boot
//! device, loads the MBR itself and jumps to it with junk everywhere. Built
//! with NASM into a scratch directory at test time (no binary is kept) and
//! given to QEMU with [`crate::qemu::OptionRom`].

use std::path::{Path, PathBuf};
use std::process::Command;

/// The ROM's source.
pub const HOSTILE_BIOS_SOURCE: &str = include_str!("roms/hostile_bios.asm");

/// Where the ROM counts the calls of its hooks, each a little-endian `u32`
/// in the interrupt table's slots of INT 60h-62h: INT 10h's, 13h's, 15h's.
pub const CALL_COUNTERS: u64 = 0x180;

/// The line the ROM writes to COM1 once its hooks are in.
pub const HOOKED_LINE: &str = "hostile-bios: INT 10h, 13h and 15h hooked";

/// The start of the line the ROM's Boot Entry Vector writes to COM1 just
/// before it jumps to the MBR it loaded.
pub const BEV_JUMP_LINE: &str = "hostile-bios: BEV: MBR read, jumping to ";

/// The line the ROM writes to COM1 when, as [`HostileBoot::NoExtensions`],
/// it refuses INT 13h AH=41h.
pub const NO_EXTENSIONS_LINE: &str = "hostile-bios: INT 13h AH=41h: no extensions (CF set)";

/// What the ROM does besides hooking the BIOS.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HostileBoot {
    /// Nothing: the firmware boots the disk as usual, through the hooks.
    HooksOnly,
    /// As `HooksOnly`, but INT 13h is a BIOS without the extensions (LBA
    /// packet reads): AH=41h returns CF set and AH=01h, never reaching the
    /// BIOS.
    NoExtensions,
    /// The ROM is a boot device (a PnP Boot Entry Vector): it reads sector 0
    /// of drive 80h to 0000:7C00 and jumps to `segment:offset` (0000:7C00 or
    /// 07C0:0000) with `drive` in DL and junk in every other register and in
    /// the upper half of ESP.
    Bev {
        /// The segment of the jump.
        segment: u16,
        /// The offset of the jump.
        offset: u16,
        /// DL at the jump.
        drive: u8,
    },
}

/// The NASM executable, found on PATH.
pub const NASM: &str = "nasm";

/// Assembles the ROM for `boot` into `dir`, with its checksum fixed; returns
/// its path. Fails, saying how to install it, without NASM.
pub fn build_hostile_bios(dir: &Path, boot: HostileBoot) -> Result<PathBuf, String> {
    let source = dir.join("hostile_bios.asm");
    std::fs::write(&source, HOSTILE_BIOS_SOURCE)
        .map_err(|e| format!("cannot write {}: {e}", source.display()))?;
    let name = match boot {
        HostileBoot::HooksOnly => "hostile-hooks.rom".to_owned(),
        HostileBoot::NoExtensions => "hostile-no-extensions.rom".to_owned(),
        HostileBoot::Bev {
            segment,
            offset,
            drive,
        } => format!("hostile-bev-{segment:04x}-{offset:04x}-dl{drive:02x}.rom"),
    };
    let rom = dir.join(name);
    let mut nasm = Command::new(NASM);
    nasm.args(["-f", "bin", "-o"]).arg(&rom);
    if boot == HostileBoot::NoExtensions {
        nasm.arg("-DNO_EXTENSIONS=1");
    }
    if let HostileBoot::Bev {
        segment,
        offset,
        drive,
    } = boot
    {
        nasm.arg("-DBEV=1")
            .arg(format!("-DJUMP_SEG={segment:#06x}"))
            .arg(format!("-DJUMP_OFF={offset:#06x}"))
            .arg(format!("-DBOOT_DRIVE={drive:#04x}"))
            .arg(format!("-DJUMP_TEXT='{segment:04X}:{offset:04X}'"))
            .arg(format!("-DDRIVE_TEXT='{drive:02X}'"));
    }
    nasm.arg(&source);
    let output = nasm.output().map_err(|e| {
        format!(
            "cannot run {NASM} ({e}): install it with `boot/setup.sh` (or `apt-get install nasm`)"
        )
    })?;
    if !output.status.success() {
        return Err(format!(
            "{NASM} failed on {}: {}",
            source.display(),
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let mut bytes =
        std::fs::read(&rom).map_err(|e| format!("cannot read {}: {e}", rom.display()))?;
    fix_checksum(&mut bytes)?;
    std::fs::write(&rom, &bytes).map_err(|e| format!("cannot write {}: {e}", rom.display()))?;
    Ok(rom)
}

/// Sets an option ROM's last byte so that all its bytes add up to zero
/// (modulo 256), as the firmware checks; the ROM must be whole 512-byte
/// blocks, its size byte saying how many.
pub fn fix_checksum(rom: &mut [u8]) -> Result<(), String> {
    if rom.len() < 512 || rom.len() % 512 != 0 || rom[..2] != [0x55, 0xAA] {
        return Err(format!(
            "not an option ROM: {} bytes, starting {:02x?}",
            rom.len(),
            &rom[..rom.len().min(2)]
        ));
    }
    if usize::from(rom[2]) * 512 != rom.len() {
        return Err(format!(
            "the ROM says it is {} blocks of 512 bytes but is {} bytes",
            rom[2],
            rom.len()
        ));
    }
    let last = rom.len() - 1;
    rom[last] = 0;
    let sum = rom.iter().fold(0u8, |sum, &byte| sum.wrapping_add(byte));
    rom[last] = sum.wrapping_neg();
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_checksum_makes_the_sum_zero() {
        let mut rom = vec![0u8; 1024];
        rom[..3].copy_from_slice(&[0x55, 0xAA, 2]);
        rom[100] = 0x37;
        fix_checksum(&mut rom).unwrap();
        assert_eq!(rom.iter().fold(0u8, |s, &b| s.wrapping_add(b)), 0);
        assert_ne!(rom[1023], 0);
    }

    #[test]
    fn a_rom_whose_size_byte_is_wrong_is_refused() {
        let mut rom = vec![0u8; 1024];
        rom[..3].copy_from_slice(&[0x55, 0xAA, 1]);
        assert!(fix_checksum(&mut rom).is_err());
        assert!(fix_checksum(&mut [0u8; 512]).is_err());
    }
}
