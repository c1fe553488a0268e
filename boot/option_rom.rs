//! The worst-case BIOS of `tests/hostile_bios.rs`: an option ROM
//! (`boot/roms/hostile_bios.asm`) that hooks INT 10h, 13h and 15h and hands
//! back junk in the upper halves of the 32-bit registers, and, as a boot
//! device, loads the MBR itself and jumps to it with junk everywhere. Built
//! with NASM into a scratch directory at test time (no binary is kept) and
//! given to QEMU with [`crate::qemu::OptionRom`].
//!
//! Also the E820 ROM of `tests/memory_map.rs` (`boot/roms/e820_map.asm`,
//! issue 66): it answers the BIOS memory map call from the BIOS's own list
//! with a reserved range laid inside the top of RAM, an entry twice, the
//! entries reversed, or no usable RAM above 1 MiB.

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

/// Where the ROM counts the waits of [`HostileBoot::VideoBiosWaits`]: those
/// begun, then those ended, each a little-endian `u32` (the interrupt
/// table's slots of INT 68h and 69h).
pub const VIDEO_WAITS: u64 = 0x1A0;

/// The start of the line the ROM writes to COM1 as a wait of
/// [`HostileBoot::VideoBiosWaits`] begins.
pub const VIDEO_WAIT_LINE: &str = "hostile-bios: INT 10h AX=0013h: ";

/// How a video BIOS's mode set waits (issue 66), as real video BIOSes and
/// CSMs do inside INT 10h AH=00h.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VideoWait {
    /// 1 ms through INT 15h AH=86h, which SeaBIOS times on the RTC's IRQ 8.
    Int15Delay,
    /// `sti`, then until the BIOS tick at 0040:006C moves (IRQ 0).
    BiosTick,
    /// `sti`, then `hlt` for ever: the call never returns.
    Forever,
}

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
    /// As `HooksOnly`, but INT 10h AX=0013h (mode 13h, which only the
    /// kernel sets) waits first, as [`VideoWait`] says.
    VideoBiosWaits(VideoWait),
}

/// The NASM executable, found on PATH.
pub const NASM: &str = "nasm";

/// Assembles the ROM for `boot` into `dir`, with its checksum fixed; returns
/// its path. Fails, saying how to install it, without NASM.
pub fn build_hostile_bios(dir: &Path, boot: HostileBoot) -> Result<PathBuf, String> {
    let (name, defines) = match boot {
        HostileBoot::HooksOnly => ("hostile-hooks.rom".to_owned(), vec![]),
        HostileBoot::NoExtensions => (
            "hostile-no-extensions.rom".to_owned(),
            vec!["-DNO_EXTENSIONS=1".to_owned()],
        ),
        HostileBoot::VideoBiosWaits(wait) => {
            let (name, number) = match wait {
                VideoWait::Int15Delay => ("int15-delay", 1),
                VideoWait::BiosTick => ("bios-tick", 2),
                VideoWait::Forever => ("forever", 3),
            };
            (
                format!("hostile-video-wait-{name}.rom"),
                vec![format!("-DVIDEO_WAIT={number}")],
            )
        }
        HostileBoot::Bev {
            segment,
            offset,
            drive,
        } => (
            format!("hostile-bev-{segment:04x}-{offset:04x}-dl{drive:02x}.rom"),
            vec![
                "-DBEV=1".to_owned(),
                format!("-DJUMP_SEG={segment:#06x}"),
                format!("-DJUMP_OFF={offset:#06x}"),
                format!("-DBOOT_DRIVE={drive:#04x}"),
                format!("-DJUMP_TEXT='{segment:04X}:{offset:04X}'"),
                format!("-DDRIVE_TEXT='{drive:02X}'"),
            ],
        ),
    };
    assemble(
        dir,
        "hostile_bios.asm",
        HOSTILE_BIOS_SOURCE,
        &name,
        &defines,
    )
}

/// The E820 ROM's source (issue 66): it answers INT 15h E820 from the
/// BIOS's own list, changed as [`E820Changes`] says.
pub const E820_MAP_SOURCE: &str = include_str!("roms/e820_map.asm");

/// The line the E820 ROM writes to COM1 once its hook is in.
pub const E820_HOOKED_LINE: &str = "e820-rom: INT 15h E820 hooked";

/// Where the E820 ROM leaves the reserved range it added
/// ([`E820Changes::reserve_top`]): its start, then its end, each a
/// little-endian `u32`, in the interrupt table's slots of INT 64h and 65h
/// (0 when it added none). The E820 calls it answered follow, at 0x198.
pub const E820_RESERVED_RANGE: u64 = 0x190;

/// What the E820 ROM wrote over the whole reserved range it added, one
/// little-endian `u32` after another.
pub const E820_PATTERN: u32 = 0xE820_C0DE;

/// How the E820 ROM changes the BIOS's list; any together.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct E820Changes {
    /// Adds a reserved entry [top - 4 MiB, top - 2 MiB), where top is the
    /// end of the usable entry ending highest below 4 GiB, and fills it
    /// with [`E820_PATTERN`].
    pub reserve_top: bool,
    /// Lists that usable entry twice.
    pub twice: bool,
    /// Answers the entries last first.
    pub reverse: bool,
    /// Makes every usable entry at or above 1 MiB reserved.
    pub no_high_ram: bool,
}

/// Assembles the E820 ROM for `changes` into `dir`; as
/// [`build_hostile_bios`].
pub fn build_e820_rom(dir: &Path, changes: E820Changes) -> Result<PathBuf, String> {
    let flags = [
        (changes.reserve_top, "RESERVE_TOP"),
        (changes.twice, "TWICE"),
        (changes.reverse, "REVERSE"),
        (changes.no_high_ram, "NO_HIGH_RAM"),
    ];
    let defines: Vec<String> = flags
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, name)| format!("-D{name}=1"))
        .collect();
    let name = flags
        .iter()
        .filter(|(on, _)| *on)
        .fold("e820".to_owned(), |name, (_, flag)| {
            format!("{name}-{}", flag.to_lowercase())
        })
        + ".rom";
    assemble(dir, "e820_map.asm", E820_MAP_SOURCE, &name, &defines)
}

/// What the ROMs share (the header, the checksum fix, the COM1 writer):
/// NASM macros each ROM `%include`s.
const PNP_ROM_INCLUDE: &str = include_str!("roms/pnp_rom.inc");

/// Writes `source` into `dir` as `source_name`, beside the shared include,
/// assembles it with NASM and `defines` into `dir/rom_name`, and fixes its
/// checksum; returns its path.
fn assemble(
    dir: &Path,
    source_name: &str,
    source: &str,
    rom_name: &str,
    defines: &[String],
) -> Result<PathBuf, String> {
    let source_path = dir.join(source_name);
    let include_path = dir.join("pnp_rom.inc");
    for (path, text) in [(&source_path, source), (&include_path, PNP_ROM_INCLUDE)] {
        std::fs::write(path, text).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    let rom = dir.join(rom_name);
    // NASM finds `%include`s from its working directory and `-i` paths.
    let mut include_dir = dir.as_os_str().to_owned();
    include_dir.push("/");
    let output = Command::new(NASM)
        .arg("-i")
        .arg(include_dir)
        .args(["-f", "bin", "-o"])
        .arg(&rom)
        .args(defines)
        .arg(&source_path)
        .output()
        .map_err(|e| {
            format!(
                "cannot run {NASM} ({e}): install it with `boot/setup.sh` (or `apt-get install nasm`)"
            )
        })?;
    if !output.status.success() {
        return Err(format!(
            "{NASM} failed on {}: {}",
            source_path.display(),
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
