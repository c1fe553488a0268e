use anyhow::Context;
use mbrman::BOOT_ACTIVE;
use std::{
    fs::{self, File},
    io::{self, Seek, SeekFrom},
    path::Path,
};

const SECTOR_SIZE: u32 = 512;

/// Patched: partitions start on 1 MiB boundaries (as fdisk, parted and Windows
/// place them) instead of the stage-2 partition at LBA 1, which some BIOSes
/// take for a sign of a floppy or an unformatted disk.
const PARTITION_ALIGNMENT_SECTORS: u32 = 2048;

/// Patched: the first sector at or after `sector` on a partition boundary.
fn align_up(sector: u32) -> anyhow::Result<u32> {
    sector
        .checked_next_multiple_of(PARTITION_ALIGNMENT_SECTORS)
        .context("disk image larger than an MBR can address")
}

/// Patched: a CHS address for `lba` in the usual translation (255 heads, 63
/// sectors a track); past what CHS can address, the LBA-only marker
/// 1023/254/63. Upstream left every CHS field zero, which is not a valid address
/// (sectors count from 1).
fn chs(lba: u32) -> mbrman::CHS {
    const HEADS: u32 = 255;
    const SECTORS_PER_TRACK: u32 = 63;
    let cylinder = lba / (HEADS * SECTORS_PER_TRACK);
    if cylinder > 1023 {
        return mbrman::CHS::new(1023, 254, 63);
    }
    let head = (lba / SECTORS_PER_TRACK) % HEADS;
    let sector = lba % SECTORS_PER_TRACK + 1;
    mbrman::CHS::new(cylinder as u16, head as u8, sector as u8)
}

pub fn create_mbr_disk(
    bootsector_binary: &[u8],
    second_stage_binary: &[u8],
    boot_partition_path: &Path,
    out_mbr_path: &Path,
) -> anyhow::Result<()> {
    use std::io::Cursor;
    let mut boot_sector = Cursor::new(bootsector_binary);
    let mut mbr =
        mbrman::MBR::read_from(&mut boot_sector, SECTOR_SIZE).context("failed to read MBR")?;

    for (index, partition) in mbr.iter() {
        if !partition.is_unused() {
            anyhow::bail!("partition {index} should be unused");
        }
    }

    let mut second_stage = Cursor::new(second_stage_binary);
    let second_stage_size = second_stage_binary.len() as u64;

    let second_stage_start_sector = PARTITION_ALIGNMENT_SECTORS;
    let second_stage_sectors = ((second_stage_size - 1) / u64::from(SECTOR_SIZE) + 1)
        .try_into()
        .context("size of second stage is larger than u32::MAX")?;
    mbr[1] = mbrman::MBRPartitionEntry {
        boot: BOOT_ACTIVE,
        starting_lba: second_stage_start_sector,
        sectors: second_stage_sectors,
        // see BOOTLOADER_SECOND_STAGE_PARTITION_TYPE in `boot_sector` crate
        sys: 0x20,

        first_chs: chs(second_stage_start_sector),
        last_chs: chs(second_stage_start_sector + second_stage_sectors - 1),
    };

    let mut boot_partition =
        File::open(boot_partition_path).context("failed to open FAT boot partition")?;
    let boot_partition_start_sector = align_up(second_stage_start_sector + second_stage_sectors)?;
    let boot_partition_size = boot_partition
        .metadata()
        .context("failed to read file metadata of FAT boot partition")?
        .len();
    let boot_partition_sectors: u32 = ((boot_partition_size - 1) / u64::from(SECTOR_SIZE) + 1)
        .try_into()
        .context("size of FAT partition is larger than u32::MAX")?;
    mbr[2] = mbrman::MBRPartitionEntry {
        // Patched: only the stage-2 entry is active (upstream marked both);
        // some BIOSes refuse a disk with more than one.
        boot: mbrman::BOOT_INACTIVE,
        starting_lba: boot_partition_start_sector,
        sectors: boot_partition_sectors,
        //TODO: is this the correct type?
        sys: 0x0c, // FAT32 with LBA

        first_chs: chs(boot_partition_start_sector),
        last_chs: chs(boot_partition_start_sector + boot_partition_sectors - 1),
    };

    let mut disk = fs::OpenOptions::new()
        .create(true)
        .truncate(true)
        .read(true)
        .write(true)
        .open(out_mbr_path)
        .with_context(|| {
            format!(
                "failed to create MBR disk image at `{}`",
                out_mbr_path.display()
            )
        })?;

    mbr.write_into(&mut disk)
        .context("failed to write MBR header to disk image")?;

    // second stage
    disk.seek(SeekFrom::Start(
        u64::from(second_stage_start_sector) * u64::from(SECTOR_SIZE),
    ))
    .context("seek failed")?;
    io::copy(&mut second_stage, &mut disk)
        .context("failed to copy second stage binary to MBR disk image")?;

    // fat partition
    disk.seek(SeekFrom::Start(
        u64::from(boot_partition_start_sector) * u64::from(SECTOR_SIZE),
    ))
    .context("seek failed")?;
    io::copy(&mut boot_partition, &mut disk)
        .context("failed to copy FAT image to MBR disk image")?;

    Ok(())
}
