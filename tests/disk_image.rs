//! The disk images read back on the host, with the field's own readers (the
//! `gpt` crate, `fatfs`, `crc32fast`) rather than the code that wrote them.
//!
//! The one image (`modex-cube.img`): its MBR has exactly one active entry
//! (stage 2, the first, where the boot sector looks), real CHS values or the
//! LBA-only marker, a FAT entry right after stage 2's (where stage 2 looks),
//! and a protective 0xEE entry from LBA 1 covering the primary GPT; the GPT's
//! headers and CRCs are valid, the backup at the disk's end; MBR and GPT
//! describe the same partitions, inside the disk and not overlapping; the
//! ESP holds the UEFI loader, BIOS stages 3 and 4 and one kernel for both,
//! and the 32-bit UEFI loader (`EFI/BOOT/BOOTIA32.EFI`, a PE32 for i386).
//! `bios.img`'s MBR (the patched bootloader's) keeps the same MBR rules.
//! In both, the boot sector's stack ends on a page boundary below its own
//! 4 KiB page, off the loader's code (issue 61).
//! `--write-usb` moves the backup GPT to a larger stick's end: the moved GPT
//! reads back valid, at the disk's real end, with the same partitions.
//! And the layout refuses inputs it cannot boot (an empty or oversized
//! kernel, a missing stage 2, a bad boot sector, an ESP that is not a FAT),
//! naming what is wrong.

use boot::disk_layout::{self, FatType, LayoutError, SECTOR};
use std::io::{Read, Seek};

const SECTORS_PER_TRACK: u64 = 63;
const HEADS: u64 = 255;

/// A used MBR entry, as read.
#[derive(Debug, Clone, Copy)]
struct MbrEntry {
    index: usize,
    boot: u8,
    kind: u8,
    first_chs: [u8; 3],
    last_chs: [u8; 3],
    start: u64,
    sectors: u64,
}

impl MbrEntry {
    fn end(&self) -> u64 {
        self.start + self.sectors
    }
}

fn mbr_entries(disk: &[u8]) -> Vec<MbrEntry> {
    assert_eq!(disk[510..512], [0x55, 0xAA], "no MBR boot signature");
    (0..4)
        .map(|index| {
            let raw = &disk[446 + 16 * index..][..16];
            MbrEntry {
                index,
                boot: raw[0],
                kind: raw[4],
                first_chs: [raw[1], raw[2], raw[3]],
                last_chs: [raw[5], raw[6], raw[7]],
                start: u64::from(u32::from_le_bytes(raw[8..12].try_into().unwrap())),
                sectors: u64::from(u32::from_le_bytes(raw[12..16].try_into().unwrap())),
            }
        })
        .filter(|entry| {
            if entry.kind == 0 {
                assert_eq!(
                    disk[446 + 16 * entry.index..][..16],
                    [0; 16],
                    "unused entry {} is not all zeros",
                    entry.index
                );
            }
            entry.kind != 0
        })
        .collect()
}

/// A CHS field must address `lba` in the 255-head, 63-sector translation,
/// or be the LBA-only marker 1023/254/63 where CHS cannot reach.
fn assert_chs_addresses(chs: [u8; 3], lba: u64, what: &str) {
    let head = u64::from(chs[0]);
    let sector = u64::from(chs[1] & 0x3F);
    let cylinder = (u64::from(chs[1] & 0xC0) << 2) | u64::from(chs[2]);
    if lba >= 1024 * HEADS * SECTORS_PER_TRACK {
        assert_eq!(
            (cylinder, head, sector),
            (1023, 254, 63),
            "{what}: LBA {lba} is past CHS, so the LBA-only marker"
        );
        return;
    }
    assert!(
        (1..=SECTORS_PER_TRACK).contains(&sector) && head < HEADS,
        "{what}: CHS {cylinder}/{head}/{sector} is not a valid address"
    );
    assert_eq!(
        (cylinder * HEADS + head) * SECTORS_PER_TRACK + sector - 1,
        lba,
        "{what}: CHS {cylinder}/{head}/{sector} is not LBA {lba}"
    );
}

/// The MBR rules of both BIOS-bootable images: one active entry, the first,
/// of stage 2's type; the next a FAT type stage 2 accepts; CHS valid;
/// entries inside the disk and not overlapping.
fn assert_mbr_boots_bios(disk: &[u8]) -> Vec<MbrEntry> {
    let total_sectors = (disk.len() / SECTOR) as u64;
    let entries = mbr_entries(disk);
    let active: Vec<_> = entries.iter().filter(|e| e.boot != 0).collect();
    assert_eq!(active.len(), 1, "exactly one active entry: {entries:?}");
    assert_eq!(active[0].boot, 0x80, "{entries:?}");
    assert_eq!(active[0].index, 0, "the boot sector loads entry 0");
    assert_eq!(active[0].kind, disk_layout::MBR_TYPE_STAGE_2);
    assert!(active[0].start > 1, "stage 2 no longer at LBA 1");
    let fat = entries
        .iter()
        .find(|e| e.index == 1)
        .expect("stage 2 reads the FAT from the entry after its own");
    assert!(
        [0x01, 0x04, 0x06, 0x0E, 0x0B, 0x0C, 0x1B, 0x1C].contains(&fat.kind),
        "entry 1 is of type {:#x}, not a FAT stage 2 accepts",
        fat.kind
    );
    for entry in &entries {
        assert!(entry.sectors > 0 && entry.start > 0, "{entry:?}");
        assert!(entry.end() <= total_sectors, "outside the disk: {entry:?}");
        let what = format!("entry {}", entry.index);
        assert_chs_addresses(entry.first_chs, entry.start, &format!("{what} first"));
        assert_chs_addresses(entry.last_chs, entry.end() - 1, &format!("{what} last"));
        for other in entries.iter().filter(|o| o.index > entry.index) {
            assert!(
                entry.end() <= other.start || other.end() <= entry.start,
                "{entry:?} overlaps {other:?}"
            );
        }
    }
    entries
}

fn one_image() -> (std::path::PathBuf, Vec<u8>) {
    let images = boot::images::publish().expect("the build script made the images");
    let bytes = std::fs::read(&images.hybrid).unwrap();
    (images.hybrid, bytes)
}

#[test]
fn the_one_image_has_a_hybrid_mbr_the_bios_route_can_boot() {
    let (_, disk) = one_image();
    let entries = assert_mbr_boots_bios(&disk);
    let protective: Vec<_> = entries
        .iter()
        .filter(|e| e.kind == disk_layout::MBR_TYPE_GPT_PROTECTIVE)
        .collect();
    assert_eq!(protective.len(), 1, "{entries:?}");
    let protective = protective[0];
    assert_eq!(protective.boot, 0, "the protective entry is never active");
    assert_eq!(protective.start, 1, "UEFI looks for 0xEE starting at LBA 1");
    assert!(
        protective.end() >= 2 + disk_layout::GPT_ENTRY_SECTORS,
        "the protective entry covers the primary GPT: {protective:?}"
    );
    assert_eq!(entries.len(), 3, "{entries:?}");
}

#[test]
fn the_one_image_has_a_valid_gpt_matching_the_mbr() {
    let (path, disk) = one_image();
    let total_sectors = (disk.len() / SECTOR) as u64;
    assert_eq!(disk.len() % SECTOR, 0);
    // The `gpt` crate checks both headers' CRCs, the backup at the last LBA.
    let gpt = gpt::GptConfig::new()
        .writable(false)
        .open(&path)
        .unwrap_or_else(|e| panic!("the gpt crate cannot read {}: {e}", path.display()));
    let primary = gpt.primary_header().expect("primary header");
    let backup = gpt.backup_header().expect("backup header");
    assert_eq!(
        (primary.current_lba, primary.backup_lba),
        (1, total_sectors - 1)
    );
    assert_eq!(
        (backup.current_lba, backup.backup_lba),
        (total_sectors - 1, 1)
    );
    assert_eq!(primary.disk_guid, backup.disk_guid);
    for header in [primary, backup] {
        assert_eq!(header.signature, "EFI PART");
        assert_eq!(header.header_size_le, 92);
        assert_eq!(header.part_size, 128);
        assert!(header.num_parts >= 128);
        assert!(header.first_usable >= 2 + disk_layout::GPT_ENTRY_SECTORS);
        assert!(header.last_usable < total_sectors - disk_layout::GPT_ENTRY_SECTORS - 1);
        // The entry array's CRC, computed here, not by the crate.
        let table = &disk[header.part_start as usize * SECTOR..]
            [..(header.num_parts * header.part_size) as usize];
        assert_eq!(
            crc32fast::hash(table),
            header.crc32_parts,
            "entry array CRC at LBA {}",
            header.part_start
        );
    }
    // The backup entries sit between the last usable sector and the backup header.
    assert!(backup.part_start > primary.last_usable);
    assert_eq!(
        backup.part_start + disk_layout::GPT_ENTRY_SECTORS,
        total_sectors - 1
    );

    let partitions: Vec<_> = gpt.partitions().values().collect();
    assert_eq!(partitions.len(), 2, "{partitions:?}");
    for (n, partition) in partitions.iter().enumerate() {
        assert!(partition.first_lba >= primary.first_usable, "{partition:?}");
        assert!(partition.last_lba <= primary.last_usable, "{partition:?}");
        assert!(partition.first_lba <= partition.last_lba, "{partition:?}");
        for other in &partitions[n + 1..] {
            assert!(
                partition.last_lba < other.first_lba || other.last_lba < partition.first_lba,
                "{partition:?} overlaps {other:?}"
            );
        }
    }
    let bios_boot = partitions
        .iter()
        .find(|p| p.part_type_guid == gpt::partition_types::BIOS)
        .expect("a BIOS boot partition for stage 2");
    let esp = partitions
        .iter()
        .find(|p| p.part_type_guid == gpt::partition_types::EFI)
        .expect("an EFI system partition");
    assert_ne!(bios_boot.part_guid, esp.part_guid);
    assert_ne!(esp.part_guid, primary.disk_guid);

    // The MBR's stage-2 and FAT entries are these same two partitions.
    let entries = mbr_entries(&disk);
    let span = |p: &gpt::partition::Partition| (p.first_lba, p.last_lba - p.first_lba + 1);
    assert_eq!((entries[0].start, entries[0].sectors), span(bios_boot));
    assert_eq!((entries[1].start, entries[1].sectors), span(esp));
    // And the protective entry ends before the first partition.
    let protective = entries.iter().find(|e| e.kind == 0xEE).unwrap();
    assert!(protective.end() <= bios_boot.first_lba.min(esp.first_lba));
}

#[test]
fn the_esp_holds_both_loaders_and_one_kernel() {
    let (_, disk) = one_image();
    let entries = mbr_entries(&disk);
    let esp = &disk[entries[1].start as usize * SECTOR..entries[1].end() as usize * SECTOR];
    assert_eq!(
        FatType::of_volume(esp).unwrap().mbr_type(),
        entries[1].kind,
        "the MBR type says the FAT it is"
    );
    let fs = fatfs::FileSystem::new(std::io::Cursor::new(esp.to_vec()), fatfs::FsOptions::new())
        .expect("the ESP is a FAT fatfs can read");
    let root = fs.root_dir();
    let read = |path: &str| {
        let mut file = root
            .open_file(path)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes).unwrap();
        bytes
    };
    let kernel = read("kernel-x86_64");
    let elf = std::fs::read(env!("KERNEL_ELF")).unwrap();
    assert!(kernel == elf, "the ESP's kernel is the kernel just built");
    for loader in [
        "efi/boot/bootx64.efi",
        "boot-stage-3",
        "boot-stage-4",
        "boot.json",
    ] {
        assert!(!read(loader).is_empty(), "{loader} is empty");
    }
    // Issue 48: every loader that checks what it starts carries the hashes
    // of these very files, written by the image build.
    use loader_logic::file_hash::{sha256, slot_of, File};
    let mut expected = [[0; 32]; File::COUNT];
    expected[File::Kernel as usize] = sha256(&kernel);
    expected[File::Stage4 as usize] = sha256(&read("boot-stage-4"));
    for checker in [
        "efi/boot/bootx64.efi",
        "efi/boot/bootia32.efi",
        "boot-stage-3",
    ] {
        let slot = slot_of(&read(checker)).unwrap_or_else(|e| panic!("{checker}: {e}"));
        assert_eq!(slot.hashes, expected, "{checker}'s hashes");
    }
    // Stage 2 sits whole in its partition, and is what the boot sector loads.
    let stage_2 = &disk[entries[0].start as usize * SECTOR..entries[0].end() as usize * SECTOR];
    assert!(stage_2.iter().any(|&b| b != 0), "stage 2 is there");
}

/// A PE image's COFF machine, optional-header magic and subsystem, read by
/// the PE/COFF specification's offsets; `None` if it is no PE image.
fn pe_header(image: &[u8]) -> Option<(u16, u16, u16)> {
    let u16_at = |at: usize| Some(u16::from_le_bytes(image.get(at..at + 2)?.try_into().ok()?));
    let u32_at = |at: usize| Some(u32::from_le_bytes(image.get(at..at + 4)?.try_into().ok()?));
    if image.get(..2)? != b"MZ" {
        return None;
    }
    let pe = usize::try_from(u32_at(0x3C)?).ok()?;
    if image.get(pe..pe + 4)? != b"PE\0\0" {
        return None;
    }
    let optional = pe + 24;
    // The subsystem is 68 bytes into the optional header, PE32 and PE32+.
    Some((u16_at(pe + 4)?, u16_at(optional)?, u16_at(optional + 68)?))
}

/// Issue 38: PCs with a 32-bit UEFI look for `EFI/BOOT/BOOTIA32.EFI`; it must
/// be there, a PE32 EFI application for the i386 (machine 0x14c), beside the
/// 64-bit loader (PE32+ for x86-64, 0x8664), with stage 4 and the kernel it
/// loads.
#[test]
fn the_esp_holds_a_32_bit_uefi_loader() {
    let (_, disk) = one_image();
    let entries = mbr_entries(&disk);
    let esp = &disk[entries[1].start as usize * SECTOR..entries[1].end() as usize * SECTOR];
    let fs = fatfs::FileSystem::new(std::io::Cursor::new(esp.to_vec()), fatfs::FsOptions::new())
        .expect("the ESP is a FAT fatfs can read");
    let read = |path: &str| {
        let mut bytes = Vec::new();
        fs.root_dir()
            .open_file(path)
            .unwrap_or_else(|e| panic!("the ESP has no {path}: {e}"))
            .read_to_end(&mut bytes)
            .unwrap();
        bytes
    };
    const EFI_APPLICATION: u16 = 10;
    let ia32 = read("EFI/BOOT/BOOTIA32.EFI");
    assert_eq!(
        pe_header(&ia32),
        Some((0x14c, 0x10b, EFI_APPLICATION)),
        "BOOTIA32.EFI: i386, PE32, an EFI application"
    );
    let x64 = read("EFI/BOOT/BOOTX64.EFI");
    assert_eq!(
        pe_header(&x64),
        Some((0x8664, 0x20b, EFI_APPLICATION)),
        "BOOTX64.EFI: x86-64, PE32+, an EFI application"
    );
    assert_ne!(ia32, x64);
    for needed in ["boot-stage-4", "kernel-x86_64"] {
        assert!(!read(needed).is_empty(), "{needed} is empty");
    }
}

#[test]
fn the_bios_image_mbr_has_one_active_entry_and_valid_chs() {
    let images = boot::images::publish().expect("the build script made the images");
    let disk = std::fs::read(&images.bios).unwrap();
    let entries = assert_mbr_boots_bios(&disk);
    assert_eq!(entries.len(), 2, "{entries:?}");
    assert_eq!(entries[0].start % 2048, 0, "stage 2 is MiB-aligned");
    assert_eq!(entries[1].start % 2048, 0, "the FAT is MiB-aligned");
}

/// The boot sector's `mov esp, imm32` (operand-size prefix 66h, then BCh), in
/// the code before the partition table: the top of the stack stages 2 and 3
/// run on. One, or none where the sector sets its stack another way.
fn boot_sector_stack_tops(sector: &[u8]) -> Vec<u32> {
    sector[..446]
        .windows(6)
        .filter(|bytes| bytes[..2] == [0x66, 0xBC])
        .map(|bytes| u32::from_le_bytes(bytes[2..].try_into().unwrap()))
        .collect()
}

/// Issue 61: the stack stages 2 and 3 run on ends on a 4 KiB page boundary
/// at or below the boot sector's page (0x7C00; stage 2 follows at 0x7E00), so
/// no push lands in a page of the loader's code. QEMU's TCG sends every write
/// to a page it has translated code from through its self-modifying-code
/// check; with the stack at 0x7C00 that was every push of stage 3's SHA-256,
/// and the BIOS boot took twice as long. The instruction count under icount
/// did not change, so only the layout can be checked deterministically.
#[test]
fn the_bios_stack_shares_no_page_with_the_loaders_code() {
    let images = boot::images::publish().expect("the build script made the images");
    for image in [&images.hybrid, &images.bios] {
        let disk = std::fs::read(image).unwrap();
        let tops = boot_sector_stack_tops(&disk[..SECTOR]);
        let [top] = tops[..] else {
            panic!(
                "{}: not one `mov esp, imm32` in the boot sector: {tops:x?}",
                image.display()
            );
        };
        let boot_sector_page = 0x7C00 & !0xFFF;
        assert!(
            top % 0x1000 == 0 && top <= boot_sector_page && top > 0x500,
            "{}: the boot sector's stack ends at {top:#x}, not on a page boundary at or \
             below {boot_sector_page:#x}, the page the boot sector and stage 2 run from",
            image.display()
        );
    }
}

#[test]
fn the_one_image_is_the_same_bytes_from_the_same_parts() {
    // The build's GUIDs come from the contents, not a random source: laying
    // out the published image's own parts again gives its bytes back.
    let (_, disk) = one_image();
    let entries = mbr_entries(&disk);
    let part = |e: &MbrEntry| &disk[e.start as usize * SECTOR..e.end() as usize * SECTOR];
    let stage_2 = part(&entries[0]);
    // Stage 2's partition is its binary padded to a whole sector; its last
    // byte is the 0xdead end marker's high byte, so it ends there.
    let stage_2_len = stage_2.iter().rposition(|&b| b != 0).unwrap() + 1;
    let mut boot_sector = disk[..SECTOR].to_vec();
    boot_sector[446..510].fill(0);
    let again = disk_layout::hybrid_image(&boot_sector, &stage_2[..stage_2_len], part(&entries[1]))
        .unwrap();
    assert!(again == disk, "the layout is not reproducible");
}

fn tiny_fat() -> Vec<u8> {
    let mut volume = std::io::Cursor::new(vec![0u8; 2 * 1024 * 1024]);
    fatfs::format_volume(&mut volume, fatfs::FormatVolumeOptions::new()).unwrap();
    volume.rewind().unwrap();
    volume.into_inner()
}

fn boot_sector() -> Vec<u8> {
    let mut sector = vec![0x90u8; SECTOR];
    sector[446..510].fill(0);
    sector[510] = 0x55;
    sector[511] = 0xAA;
    sector
}

#[test]
fn the_layout_names_what_it_cannot_boot() {
    let fat = tiny_fat();
    let stage_2 = vec![0xF4u8; 1000];
    assert!(disk_layout::hybrid_image(&boot_sector(), &stage_2, &fat).is_ok());
    assert_eq!(
        disk_layout::hybrid_image(&boot_sector(), &[], &fat),
        Err(LayoutError::MissingStage2)
    );
    let too_large = vec![1u8; disk_layout::MAX_STAGE_2_BYTES + 1];
    assert_eq!(
        disk_layout::hybrid_image(&boot_sector(), &too_large, &fat),
        Err(LayoutError::Stage2TooLarge {
            bytes: too_large.len()
        })
    );
    assert!(matches!(
        disk_layout::hybrid_image(&boot_sector()[..511], &stage_2, &fat),
        Err(LayoutError::BootSector(_))
    ));
    let mut used_table = boot_sector();
    used_table[450] = 0x0C;
    assert!(matches!(
        disk_layout::hybrid_image(&used_table, &stage_2, &fat),
        Err(LayoutError::BootSector(_))
    ));
    assert!(matches!(
        disk_layout::hybrid_image(&boot_sector(), &stage_2, &vec![0u8; 4096]),
        Err(LayoutError::NotFat(_))
    ));
    assert_eq!(
        disk_layout::check_kernel_size(0),
        Err(LayoutError::EmptyKernel)
    );
    assert_eq!(disk_layout::check_kernel_size(1 << 20), Ok(()));
    let huge = disk_layout::MAX_KERNEL_BYTES + 1;
    assert_eq!(
        disk_layout::check_kernel_size(huge),
        Err(LayoutError::KernelTooLarge { bytes: huge })
    );
    assert!(LayoutError::KernelTooLarge { bytes: huge }
        .to_string()
        .contains("kernel is too large"));
    let message = LayoutError::MissingStage2.to_string();
    assert!(message.contains("stage 2"), "{message}");
}

#[test]
fn chs_is_the_usual_translation_then_the_lba_marker() {
    assert_eq!(disk_layout::chs(0), [0, 1, 0]);
    assert_eq!(disk_layout::chs(62), [0, 63, 0]);
    assert_eq!(disk_layout::chs(63), [1, 1, 0]);
    for lba in [1, 2047, 2048, 16_064, 16_065, 1_000_000, 16_450_559] {
        assert_chs_addresses(disk_layout::chs(lba), lba, "chs()");
    }
    assert_eq!(disk_layout::chs(16_450_560), [0xFE, 0xFF, 0xFF]);
    assert_eq!(disk_layout::chs(u64::from(u32::MAX)), [0xFE, 0xFF, 0xFF]);
}

#[test]
fn crc32_is_ieee() {
    assert_eq!(disk_layout::crc32(b"123456789"), 0xCBF4_3926);
    let bytes: Vec<u8> = (0..=255u8).cycle().take(10_000).collect();
    assert_eq!(disk_layout::crc32(&bytes), crc32fast::hash(&bytes));
}

/// The image's first sectors and last sector, as `backup_gpt_to_disk_end` takes them.
fn head_and_last(disk: &[u8]) -> (&[u8], &[u8]) {
    let head = &disk[..disk_layout::GPT_HEAD_SECTORS as usize * SECTOR];
    (head, &disk[disk.len() - SECTOR..])
}

/// `--write-usb`'s GPT move (`boot/usb.rs` makes these writes): on disks 1,
/// 33, 34 and 2048 sectors larger than the image (the first two put the new
/// entries over the old backup header), the `gpt` crate reads both headers
/// at the disk's real end, with the same partitions.
#[test]
fn the_backup_gpt_moves_to_the_end_of_any_larger_disk() {
    let (_, image) = one_image();
    let image_sectors = (image.len() / SECTOR) as u64;
    let (head, last) = head_and_last(&image);
    let original = gpt::GptConfig::new()
        .writable(false)
        .open(one_image().0)
        .unwrap();
    for extra in [1u64, 33, 34, 2048] {
        let disk_sectors = image_sectors + extra;
        let writes = disk_layout::backup_gpt_to_disk_end(head, last, image_sectors, disk_sectors)
            .unwrap()
            .expect("the image has a GPT");
        let mut disk = image.clone();
        disk.resize(disk_sectors as usize * SECTOR, 0);
        for write in &writes {
            assert_eq!(write.bytes.len() % SECTOR, 0);
            disk[write.lba as usize * SECTOR..][..write.bytes.len()].copy_from_slice(&write.bytes);
        }
        let path =
            std::env::temp_dir().join(format!("modex-gpt-move-{}-{extra}.img", std::process::id()));
        std::fs::write(&path, &disk).unwrap();
        let moved = gpt::GptConfig::new().writable(false).open(&path);
        std::fs::remove_file(&path).unwrap();
        let moved = moved.unwrap_or_else(|e| panic!("+{extra} sectors: {e}"));
        let (primary, backup) = (
            moved.primary_header().unwrap(),
            moved.backup_header().unwrap(),
        );
        let end = disk_sectors - 1;
        assert_eq!(
            (primary.backup_lba, backup.current_lba),
            (end, end),
            "+{extra}"
        );
        assert_eq!(backup.backup_lba, 1);
        assert_eq!(backup.part_start, end - disk_layout::GPT_ENTRY_SECTORS);
        assert_eq!(primary.last_usable, backup.part_start - 1);
        assert_eq!(moved.partitions(), original.partitions(), "+{extra}");
        if extra > disk_layout::GPT_ENTRY_SECTORS {
            let old = &disk[(image_sectors as usize - 1) * SECTOR..][..SECTOR];
            assert!(
                old.iter().all(|&b| b == 0),
                "+{extra}: old backup header left"
            );
        }
        assert_eq!(mbr_entries(&disk).len(), 3);
        assert_mbr_boots_bios(&disk);
    }
}

#[test]
fn the_gpt_move_refuses_what_it_cannot_move_and_leaves_what_it_need_not() {
    let (_, image) = one_image();
    let sectors = (image.len() / SECTOR) as u64;
    let (head, last) = head_and_last(&image);
    let refused = |head: &[u8], last: &[u8], disk: u64| {
        disk_layout::backup_gpt_to_disk_end(head, last, sectors, disk)
            .expect_err("must be refused")
            .to_string()
    };
    // Already at the disk's end: nothing to write.
    assert_eq!(
        disk_layout::backup_gpt_to_disk_end(head, last, sectors, sectors),
        Ok(Some(Vec::new()))
    );
    // No GPT at all (an MBR-only image): nothing to move.
    let mut no_gpt = head.to_vec();
    no_gpt[SECTOR..2 * SECTOR].fill(0);
    assert_eq!(
        disk_layout::backup_gpt_to_disk_end(&no_gpt, last, sectors, sectors + 64),
        Ok(None)
    );
    assert!(refused(head, last, sectors - 1).contains("fewer than the image's"));
    let mut bad_entries = head.to_vec();
    bad_entries[2 * SECTOR + 32] ^= 1;
    assert!(refused(&bad_entries, last, sectors + 64).contains("entry-array CRC"));
    let mut bad_backup = last.to_vec();
    bad_backup[0] = b'X';
    let error = refused(head, &bad_backup, sectors + 64);
    assert!(
        error.contains("backup GPT header has no EFI PART"),
        "{error}"
    );
}
