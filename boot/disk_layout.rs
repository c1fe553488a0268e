//! The one disk image that boots under BIOS (and CSM) and under UEFI, from
//! the same bytes: a GPT disk with a hybrid MBR. Used by the build script
//! (`boot/build.rs` includes this file) and by the host tests that read the
//! image back.
//!
//! Layout, in 512-byte sectors:
//!
//! | LBA                  | what                                                   |
//! |----------------------|--------------------------------------------------------|
//! | 0                    | MBR: the bootloader's boot sector code, hybrid table   |
//! | 1                    | primary GPT header                                     |
//! | 2..=33               | primary GPT entries (128 of 128 bytes)                 |
//! | 2048..               | BIOS stage 2 (GPT "BIOS boot" partition)               |
//! | next MiB boundary..  | the EFI system partition: one FAT with the UEFI loader,|
//! |                      | BIOS stages 3 and 4, the kernel and its config         |
//! | last 33              | backup GPT entries, then the backup header             |
//!
//! The MBR's entries are what the BIOS route reads: the boot sector loads the
//! first entry (stage 2, type 0x20, the one active entry), and stage 2 reads
//! its files from the FAT in the next entry. The third entry is the GPT's
//! protective one (type 0xEE from LBA 1, up to stage 2), which is how UEFI
//! firmware knows to read the GPT. No entry overlaps another; every CHS field
//! is a real address in the usual 255-head, 63-sector translation, or the
//! LBA-only marker past its reach.
//!
//! Nothing here is random: GUIDs are derived from the contents, so one build
//! gives the same bytes every time.

use std::fmt;

/// Bytes in a sector; the image is laid out for 512-byte-sector disks (USB
/// sticks and QEMU's disks both are).
pub const SECTOR: usize = 512;
/// Partitions start on 1 MiB boundaries, as partitioning tools place them.
pub const ALIGNMENT_SECTORS: u64 = 2048;
/// GPT entries in each table, the minimum the UEFI specification allows.
pub const GPT_ENTRIES: usize = 128;
/// Bytes in a GPT entry.
pub const GPT_ENTRY_SIZE: usize = 128;
/// Sectors the GPT entry array takes (128 × 128 bytes = 32 sectors).
pub const GPT_ENTRY_SECTORS: u64 = (GPT_ENTRIES * GPT_ENTRY_SIZE / SECTOR) as u64;
/// MBR partition type of the BIOS stage 2, as the bootloader's stage 2 looks for it.
pub const MBR_TYPE_STAGE_2: u8 = 0x20;
/// MBR partition type of the GPT's protective entry.
pub const MBR_TYPE_GPT_PROTECTIVE: u8 = 0xEE;
/// MBR boot indicator of the active entry.
pub const MBR_ACTIVE: u8 = 0x80;
/// GPT type of the EFI system partition, C12A7328-F81F-11D2-BA4B-00A0C93EC93B.
pub const GPT_TYPE_EFI_SYSTEM: Guid = Guid::from_fields(
    0xC12A_7328,
    0xF81F,
    0x11D2,
    [0xBA, 0x4B, 0x00, 0xA0, 0xC9, 0x3E, 0xC9, 0x3B],
);
/// GPT type of a BIOS boot partition, 21686148-6449-6E6F-744E-656564454649:
/// raw boot code that no file system should claim.
pub const GPT_TYPE_BIOS_BOOT: Guid = Guid::from_fields(
    0x2168_6148,
    0x6449,
    0x6E6F,
    [0x74, 0x4E, 0x65, 0x65, 0x64, 0x45, 0x46, 0x49],
);

/// A GUID in the byte order GPT stores it (the first three fields little-endian).
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Guid(pub [u8; 16]);

impl Guid {
    /// From the fields of its text form `AAAAAAAA-BBBB-CCCC-DDDD-DDDDDDDDDDDD`.
    pub const fn from_fields(a: u32, b: u16, c: u16, d: [u8; 8]) -> Guid {
        let a = a.to_le_bytes();
        let b = b.to_le_bytes();
        let c = c.to_le_bytes();
        Guid([
            a[0], a[1], a[2], a[3], b[0], b[1], c[0], c[1], d[0], d[1], d[2], d[3], d[4], d[5],
            d[6], d[7],
        ])
    }

    /// A version-4-shaped GUID from 128 bits of hash: unique per content,
    /// yet the same for the same content.
    fn from_hash(bits: u128) -> Guid {
        let mut bytes = bits.to_le_bytes();
        bytes[7] = (bytes[7] & 0x0F) | 0x40; // version 4 (top of the third field)
        bytes[8] = (bytes[8] & 0x3F) | 0x80; // RFC 4122 variant
        Guid(bytes)
    }
}

impl fmt::Debug for Guid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let b = &self.0;
        write!(
            f,
            "{:08X}-{:04X}-{:04X}-{:02X}{:02X}-",
            u32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            u16::from_le_bytes([b[4], b[5]]),
            u16::from_le_bytes([b[6], b[7]]),
            b[8],
            b[9]
        )?;
        b[10..].iter().try_for_each(|byte| write!(f, "{byte:02X}"))
    }
}

/// Why the image could not be laid out. Each names what is missing or wrong.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LayoutError {
    /// The BIOS boot sector is not one 512-byte sector ending in 55 AA.
    BootSector(&'static str),
    /// The BIOS stage 2 is missing (empty).
    MissingStage2,
    /// The BIOS stage 2 is larger than the boot sector can load below the
    /// EBDA (it loads it at 0x7E00, and 0x80000 is where low memory may end).
    Stage2TooLarge {
        /// Its size.
        bytes: usize,
    },
    /// The EFI system partition's contents are not a FAT file system.
    NotFat(&'static str),
    /// The kernel file is empty.
    EmptyKernel,
    /// The kernel is larger than the BIOS stage 2 can place.
    KernelTooLarge {
        /// Its size.
        bytes: u64,
    },
    /// The disk would need more sectors than an MBR entry can describe.
    TooLarge {
        /// The sectors it would need.
        sectors: u64,
    },
}

impl fmt::Display for LayoutError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LayoutError::BootSector(why) => write!(f, "the BIOS boot sector is unusable: {why}"),
            LayoutError::MissingStage2 => write!(f, "the BIOS stage 2 is missing (empty)"),
            LayoutError::Stage2TooLarge { bytes } => write!(
                f,
                "the BIOS stage 2 is {bytes} bytes, more than the {} the boot sector can load",
                MAX_STAGE_2_BYTES
            ),
            LayoutError::NotFat(why) => {
                write!(
                    f,
                    "the EFI system partition is not a FAT file system: {why}"
                )
            }
            LayoutError::EmptyKernel => write!(f, "the kernel is empty"),
            LayoutError::KernelTooLarge { bytes } => write!(
                f,
                "the kernel is too large: {bytes} bytes, at most {MAX_KERNEL_BYTES} fit \
                 (the BIOS stage 2 loads it at 16 MiB with 32-bit addresses)"
            ),
            LayoutError::TooLarge { sectors } => write!(
                f,
                "the disk would be {sectors} sectors, more than an MBR can address"
            ),
        }
    }
}

impl std::error::Error for LayoutError {}

/// The BIOS stage 2 copies the kernel to 16 MiB with 32-bit addresses: it
/// must end below 4 GiB (and, as a FAT file, be under 4 GiB too).
pub const MAX_KERNEL_BYTES: u64 = (1 << 32) - 0x0100_0000;

/// Whether a kernel of `bytes` can go on the image.
pub fn check_kernel_size(bytes: u64) -> Result<(), LayoutError> {
    match bytes {
        0 => Err(LayoutError::EmptyKernel),
        bytes if bytes > MAX_KERNEL_BYTES => Err(LayoutError::KernelTooLarge { bytes }),
        _ => Ok(()),
    }
}

/// Stage 2 is loaded at 0x7E00 and must end by 0x80000.
pub const MAX_STAGE_2_BYTES: usize = 0x8_0000 - 0x7E00;

/// The FAT variant a file system is, by its cluster count (the FAT
/// specification's rule).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FatType {
    /// Under 4085 clusters.
    Fat12,
    /// Under 65525 clusters.
    Fat16,
    /// The rest.
    Fat32,
}

impl FatType {
    /// Reads the FAT boot sector (BPB) at the start of `volume`.
    pub fn of_volume(volume: &[u8]) -> Result<FatType, LayoutError> {
        let sector = volume
            .get(..SECTOR)
            .ok_or(LayoutError::NotFat("shorter than a sector"))?;
        if sector[510..] != [0x55, 0xAA] {
            return Err(LayoutError::NotFat("no 55 AA boot signature"));
        }
        let u16_at = |at: usize| u64::from(u16::from_le_bytes([sector[at], sector[at + 1]]));
        let u32_at = |at: usize| {
            u64::from(u32::from_le_bytes([
                sector[at],
                sector[at + 1],
                sector[at + 2],
                sector[at + 3],
            ]))
        };
        let bytes_per_sector = u16_at(11);
        let sectors_per_cluster = u64::from(sector[13]);
        let reserved = u16_at(14);
        let fats = u64::from(sector[16]);
        let root_entries = u16_at(17);
        let total = match u16_at(19) {
            0 => u32_at(32),
            small => small,
        };
        let fat_size = match u16_at(22) {
            0 => u32_at(36),
            small => small,
        };
        if bytes_per_sector != SECTOR as u64 {
            return Err(LayoutError::NotFat("sectors are not 512 bytes"));
        }
        if sectors_per_cluster == 0 || fats == 0 || fat_size == 0 {
            return Err(LayoutError::NotFat("no clusters or no FAT in the BPB"));
        }
        let root_dir_sectors = (root_entries * 32).div_ceil(bytes_per_sector);
        let data = total
            .checked_sub(reserved + fats * fat_size + root_dir_sectors)
            .ok_or(LayoutError::NotFat("the BPB's areas exceed the volume"))?;
        if total * bytes_per_sector > volume.len() as u64 {
            return Err(LayoutError::NotFat(
                "the BPB's volume is larger than the data",
            ));
        }
        Ok(match data / sectors_per_cluster {
            clusters if clusters < 4085 => FatType::Fat12,
            clusters if clusters < 65525 => FatType::Fat16,
            _ => FatType::Fat32,
        })
    }

    /// Its MBR partition type, with LBA addressing where there is one.
    pub fn mbr_type(self) -> u8 {
        match self {
            FatType::Fat12 => 0x01,
            FatType::Fat16 => 0x0E,
            FatType::Fat32 => 0x0C,
        }
    }
}

/// A CHS address in the MBR's 3-byte form, for `lba` in the usual translation
/// (255 heads, 63 sectors a track); past cylinder 1023, the LBA-only marker
/// 1023/254/63 (FE FF FF).
pub fn chs(lba: u64) -> [u8; 3] {
    const HEADS: u64 = 255;
    const SECTORS_PER_TRACK: u64 = 63;
    let cylinder = lba / (HEADS * SECTORS_PER_TRACK);
    if cylinder > 1023 {
        return [0xFE, 0xFF, 0xFF];
    }
    let head = (lba / SECTORS_PER_TRACK) % HEADS;
    let sector = lba % SECTORS_PER_TRACK + 1;
    [
        head as u8,
        (sector as u8) | (((cylinder >> 8) as u8) << 6),
        cylinder as u8,
    ]
}

/// CRC-32 (IEEE 802.3, reflected), as GPT's header and entry checksums use.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0xEDB8_8320
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// 128-bit FNV-1a: a stable hash for the GUIDs (not for security).
fn fnv1a_128(parts: &[&[u8]]) -> u128 {
    const OFFSET: u128 = 0x6C62_272E_07BB_0142_62B8_2175_6295_C58D;
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013B;
    let mut hash = OFFSET;
    for part in parts {
        for &byte in part.iter() {
            hash ^= u128::from(byte);
            hash = hash.wrapping_mul(PRIME);
        }
        // Separate the parts, so ("ab", "c") and ("a", "bc") differ.
        hash ^= 0xFF;
        hash = hash.wrapping_mul(PRIME);
    }
    hash
}

/// Where each piece lands, in sectors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layout {
    /// First sector of stage 2.
    pub stage_2_start: u64,
    /// Sectors of stage 2 (exactly what the boot sector loads).
    pub stage_2_sectors: u64,
    /// First sector of the EFI system partition.
    pub esp_start: u64,
    /// Sectors of the EFI system partition.
    pub esp_sectors: u64,
    /// Sectors of the whole disk.
    pub total_sectors: u64,
}

impl Layout {
    /// The layout for a stage 2 and an ESP of these sizes, in bytes.
    pub fn new(stage_2_bytes: usize, esp_bytes: usize) -> Result<Layout, LayoutError> {
        let sectors = |bytes: usize| (bytes as u64).div_ceil(SECTOR as u64);
        let stage_2_start = ALIGNMENT_SECTORS;
        let stage_2_sectors = sectors(stage_2_bytes);
        let esp_start = (stage_2_start + stage_2_sectors).next_multiple_of(ALIGNMENT_SECTORS);
        let esp_sectors = sectors(esp_bytes);
        // The backup entries and header follow the ESP.
        let total_sectors = esp_start + esp_sectors + GPT_ENTRY_SECTORS + 1;
        if total_sectors > u64::from(u32::MAX) {
            return Err(LayoutError::TooLarge {
                sectors: total_sectors,
            });
        }
        Ok(Layout {
            stage_2_start,
            stage_2_sectors,
            esp_start,
            esp_sectors,
            total_sectors,
        })
    }

    /// The first sector a GPT partition may use.
    pub fn first_usable(&self) -> u64 {
        2 + GPT_ENTRY_SECTORS
    }

    /// The last sector a GPT partition may use.
    pub fn last_usable(&self) -> u64 {
        self.total_sectors - GPT_ENTRY_SECTORS - 2
    }
}

/// Lays out the one image: `boot_sector` (the bootloader's MBR code with an
/// empty partition table), `stage_2` (its BIOS second stage) and `esp` (a FAT
/// volume holding the UEFI loader, BIOS stages 3 and 4, the kernel and its
/// config). Returns the whole disk.
pub fn hybrid_image(
    boot_sector: &[u8],
    stage_2: &[u8],
    esp: &[u8],
) -> Result<Vec<u8>, LayoutError> {
    if boot_sector.len() != SECTOR {
        return Err(LayoutError::BootSector("not 512 bytes"));
    }
    if boot_sector[510..] != [0x55, 0xAA] {
        return Err(LayoutError::BootSector("no 55 AA boot signature"));
    }
    if boot_sector[446..510].iter().any(|&b| b != 0) {
        return Err(LayoutError::BootSector("its partition table is not empty"));
    }
    if stage_2.is_empty() {
        return Err(LayoutError::MissingStage2);
    }
    if stage_2.len() > MAX_STAGE_2_BYTES {
        return Err(LayoutError::Stage2TooLarge {
            bytes: stage_2.len(),
        });
    }
    let fat_type = FatType::of_volume(esp)?;
    let layout = Layout::new(stage_2.len(), esp.len())?;
    let total_bytes =
        usize::try_from(layout.total_sectors).expect("checked against u32::MAX") * SECTOR;
    let mut disk = vec![0u8; total_bytes];
    let at = |sector: u64| sector as usize * SECTOR;

    // The GUIDs: from the contents, so that the same build gives the same disk.
    let guid = |salt: &str| Guid::from_hash(fnv1a_128(&[salt.as_bytes(), stage_2, esp]));
    let disk_guid = guid("disk");

    // MBR: the boot code, then the hybrid table.
    disk[..446].copy_from_slice(&boot_sector[..446]);
    let entries = [
        mbr_entry(
            MBR_ACTIVE,
            MBR_TYPE_STAGE_2,
            layout.stage_2_start,
            layout.stage_2_sectors,
        ),
        mbr_entry(0, fat_type.mbr_type(), layout.esp_start, layout.esp_sectors),
        mbr_entry(0, MBR_TYPE_GPT_PROTECTIVE, 1, layout.stage_2_start - 1),
        [0; 16],
    ];
    for (index, entry) in entries.iter().enumerate() {
        disk[446 + 16 * index..][..16].copy_from_slice(entry);
    }
    disk[510..512].copy_from_slice(&[0x55, 0xAA]);

    // The GPT's entries, the same array in both copies.
    let mut gpt_entries = vec![0u8; GPT_ENTRIES * GPT_ENTRY_SIZE];
    let partitions = [
        (
            GPT_TYPE_BIOS_BOOT,
            guid("stage 2"),
            layout.stage_2_start,
            layout.stage_2_sectors,
            "BIOS boot",
        ),
        (
            GPT_TYPE_EFI_SYSTEM,
            guid("esp"),
            layout.esp_start,
            layout.esp_sectors,
            "EFI system partition",
        ),
    ];
    for (index, (kind, unique, start, sectors, name)) in partitions.into_iter().enumerate() {
        let entry = &mut gpt_entries[index * GPT_ENTRY_SIZE..][..GPT_ENTRY_SIZE];
        entry[0..16].copy_from_slice(&kind.0);
        entry[16..32].copy_from_slice(&unique.0);
        entry[32..40].copy_from_slice(&start.to_le_bytes());
        entry[40..48].copy_from_slice(&(start + sectors - 1).to_le_bytes());
        for (slot, unit) in entry[56..128]
            .as_chunks_mut::<2>()
            .0
            .iter_mut()
            .zip(name.encode_utf16())
        {
            *slot = unit.to_le_bytes();
        }
    }
    let entries_crc = crc32(&gpt_entries);
    let backup_header = layout.total_sectors - 1;
    let backup_entries = backup_header - GPT_ENTRY_SECTORS;
    disk[at(2)..][..gpt_entries.len()].copy_from_slice(&gpt_entries);
    disk[at(backup_entries)..][..gpt_entries.len()].copy_from_slice(&gpt_entries);
    let header = |this: u64, other: u64, entries_at: u64| {
        let mut header = [0u8; 92];
        header[0..8].copy_from_slice(b"EFI PART");
        header[8..12].copy_from_slice(&0x0001_0000u32.to_le_bytes());
        header[12..16].copy_from_slice(&92u32.to_le_bytes());
        header[24..32].copy_from_slice(&this.to_le_bytes());
        header[32..40].copy_from_slice(&other.to_le_bytes());
        header[40..48].copy_from_slice(&layout.first_usable().to_le_bytes());
        header[48..56].copy_from_slice(&layout.last_usable().to_le_bytes());
        header[56..72].copy_from_slice(&disk_guid.0);
        header[72..80].copy_from_slice(&entries_at.to_le_bytes());
        header[80..84].copy_from_slice(&(GPT_ENTRIES as u32).to_le_bytes());
        header[84..88].copy_from_slice(&(GPT_ENTRY_SIZE as u32).to_le_bytes());
        header[88..92].copy_from_slice(&entries_crc.to_le_bytes());
        let crc = crc32(&header);
        header[16..20].copy_from_slice(&crc.to_le_bytes());
        header
    };
    disk[at(1)..][..92].copy_from_slice(&header(1, backup_header, 2));
    disk[at(backup_header)..][..92].copy_from_slice(&header(backup_header, 1, backup_entries));

    // The partitions' contents.
    disk[at(layout.stage_2_start)..][..stage_2.len()].copy_from_slice(stage_2);
    disk[at(layout.esp_start)..][..esp.len()].copy_from_slice(esp);
    Ok(disk)
}

/// One 16-byte MBR partition entry.
fn mbr_entry(boot: u8, kind: u8, start: u64, sectors: u64) -> [u8; 16] {
    let mut entry = [0u8; 16];
    entry[0] = boot;
    entry[1..4].copy_from_slice(&chs(start));
    entry[4] = kind;
    entry[5..8].copy_from_slice(&chs(start + sectors - 1));
    // `Layout::new` keeps every sector number within u32.
    entry[8..12].copy_from_slice(&(start as u32).to_le_bytes());
    entry[12..16].copy_from_slice(&(sectors as u32).to_le_bytes());
    entry
}

/// The sectors at the image's start that hold the MBR, the primary GPT header
/// and the primary entries: what [`backup_gpt_to_disk_end`] reads.
pub const GPT_HEAD_SECTORS: u64 = 2 + GPT_ENTRY_SECTORS;

/// Sectors to write to a disk, from `lba` on (`bytes` is whole sectors).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SectorWrite {
    /// The first sector.
    pub lba: u64,
    /// What to write there.
    pub bytes: Vec<u8>,
}

/// Why the image's GPT could not be moved to the disk's end: the image is
/// not the one [`hybrid_image`] lays out, or the disk is too small for it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum GptMoveError {
    /// The primary header (LBA 1) is not one this layout writes.
    Primary(&'static str),
    /// The backup header (the image's last sector) is not the primary's twin.
    Backup(&'static str),
    /// The disk has fewer sectors than the image.
    DiskTooSmall {
        /// The image's sectors.
        image_sectors: u64,
        /// The disk's sectors.
        disk_sectors: u64,
    },
}

impl fmt::Display for GptMoveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GptMoveError::Primary(why) => write!(f, "the image's primary GPT header {why}"),
            GptMoveError::Backup(why) => write!(f, "the image's backup GPT header {why}"),
            GptMoveError::DiskTooSmall {
                image_sectors,
                disk_sectors,
            } => write!(
                f,
                "the disk has {disk_sectors} sectors, fewer than the image's {image_sectors}"
            ),
        }
    }
}

impl std::error::Error for GptMoveError {}

fn u32_at(bytes: &[u8], offset: usize) -> u32 {
    u32::from_le_bytes(bytes[offset..offset + 4].try_into().expect("4 bytes"))
}

fn u64_at(bytes: &[u8], offset: usize) -> u64 {
    u64::from_le_bytes(bytes[offset..offset + 8].try_into().expect("8 bytes"))
}

/// The header's CRC field recomputed over its `header size` bytes.
fn seal_gpt_header(sector: &mut [u8]) {
    let size = u32_at(sector, 12) as usize;
    sector[16..20].fill(0);
    let crc = crc32(&sector[..size]);
    sector[16..20].copy_from_slice(&crc.to_le_bytes());
}

/// Checks a GPT header sector: signature, size, CRC, and where it says it is.
fn check_gpt_header(sector: &[u8], this: u64, other: u64) -> Result<(), &'static str> {
    if &sector[..8] != b"EFI PART" {
        return Err("has no EFI PART signature");
    }
    let size = u32_at(sector, 12) as usize;
    if !(92..=SECTOR).contains(&size) {
        return Err("has a header size outside 92..=512");
    }
    let mut copy = sector[..size].to_vec();
    copy[16..20].fill(0);
    if crc32(&copy) != u32_at(sector, 16) {
        return Err("has a wrong CRC");
    }
    if u64_at(sector, 24) != this || u64_at(sector, 32) != other {
        return Err("is not where it says it is, or names the other header elsewhere");
    }
    Ok(())
}

/// What `sgdisk -e` does after an image is written to a larger disk: the
/// backup GPT entries and header moved to the disk's last 33 sectors, both
/// headers fixed (the primary's backup LBA and last usable LBA, the backup's
/// own LBA and entries LBA) with their CRCs, and the image's old backup
/// header sector zeroed. The MBR is left as it is: its protective entry
/// covers only LBA 1 up to stage 2 (a hybrid MBR), so the disk's size is
/// not in it, and its one active entry stays.
///
/// `head` is the image's first [`GPT_HEAD_SECTORS`] sectors, `last` its last
/// sector. `Ok(None)`: the image has no GPT (nothing to move). An empty list:
/// the disk is the image's size, the backup is already at its end. The
/// writes are in the order to make them (the old header's zeros first, in
/// case the new entries overlap it).
pub fn backup_gpt_to_disk_end(
    head: &[u8],
    last: &[u8],
    image_sectors: u64,
    disk_sectors: u64,
) -> Result<Option<Vec<SectorWrite>>, GptMoveError> {
    assert_eq!(head.len(), GPT_HEAD_SECTORS as usize * SECTOR, "head size");
    assert_eq!(last.len(), SECTOR, "last sector size");
    let primary = &head[SECTOR..2 * SECTOR];
    if &primary[..8] != b"EFI PART" {
        return Ok(None);
    }
    if disk_sectors < image_sectors {
        return Err(GptMoveError::DiskTooSmall {
            image_sectors,
            disk_sectors,
        });
    }
    let old_backup = image_sectors - 1;
    check_gpt_header(primary, 1, old_backup).map_err(GptMoveError::Primary)?;
    check_gpt_header(last, old_backup, 1).map_err(GptMoveError::Backup)?;
    let entries_bytes = u64::from(u32_at(primary, 80)) * u64::from(u32_at(primary, 84));
    let entry_sectors = entries_bytes.div_ceil(SECTOR as u64);
    if u64_at(primary, 72) != 2 || 2 + entry_sectors > GPT_HEAD_SECTORS {
        return Err(GptMoveError::Primary(
            "does not put its entries in LBA 2..=33",
        ));
    }
    let entries = &head[2 * SECTOR..][..entry_sectors as usize * SECTOR];
    if crc32(&entries[..entries_bytes as usize]) != u32_at(primary, 88) {
        return Err(GptMoveError::Primary("has a wrong entry-array CRC"));
    }
    if last[40..56] != primary[40..56] || last[56..72] != primary[56..72] {
        return Err(GptMoveError::Backup(
            "differs from the primary in usable sectors or disk GUID",
        ));
    }
    if disk_sectors == image_sectors {
        return Ok(Some(Vec::new()));
    }

    let new_backup = disk_sectors - 1;
    let new_entries = new_backup - entry_sectors;
    let last_usable = new_entries - 1;
    let mut new_primary = primary.to_vec();
    new_primary[32..40].copy_from_slice(&new_backup.to_le_bytes());
    new_primary[48..56].copy_from_slice(&last_usable.to_le_bytes());
    seal_gpt_header(&mut new_primary);
    let mut backup = new_primary.clone();
    backup[24..32].copy_from_slice(&new_backup.to_le_bytes());
    backup[32..40].copy_from_slice(&1u64.to_le_bytes());
    backup[72..80].copy_from_slice(&new_entries.to_le_bytes());
    seal_gpt_header(&mut backup);
    Ok(Some(vec![
        SectorWrite {
            lba: old_backup,
            bytes: vec![0; SECTOR],
        },
        SectorWrite {
            lba: new_entries,
            bytes: entries.to_vec(),
        },
        SectorWrite {
            lba: new_backup,
            bytes: backup,
        },
        SectorWrite {
            lba: 1,
            bytes: new_primary,
        },
    ]))
}
