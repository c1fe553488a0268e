//! Disk reads that fail, as on a worn disk or a cheap stick (issue 38):
//! QEMU's blkdebug driver under the image (`boot::ReadError`) fails the reads
//! that cover one sector with EIO, on SeaBIOS's IDE path (`-M pc`). (The
//! UEFI loader's retries are in `tests/loader.rs`, on OVMF's virtio disk:
//! OVMF's AHCI driver retries by itself and, for a sector that keeps failing,
//! returns wrong bytes as a success.) The sectors are found in the image itself: stage 2
//! from the MBR's first entry, the files from the FAT that the MBR's second
//! entry holds (read with `fatfs`, then located by their contents).
//!
//! A read that fails once must be tried again (the loader says
//! `line::LOADER_READ_RETRIED`) and the cube must come up; a sector that never
//! reads must be named on COM1 and on the screen (`line::LOADER_CANNOT_READ`),
//! and the machine must stay up and do nothing more: no reset (QEMU runs with
//! `-no-reboot`, so a reset would end it), no kernel.
//!
//! Wrong bytes taken as a good read (issue 48): OVMF's AHCI driver returns
//! them for a kernel sector that always fails, and a byte changed in the
//! image file stands for a stick that rots. The UEFI loaders and BIOS
//! stage 3 check the SHA-256 of what they start (`loader_logic::file_hash`),
//! and must say which file is damaged, on COM1 and the screen, and stay up
//! without a reset. (SeaBIOS reports a sector that always fails as a failed
//! read, which stage 2 names before any hash is taken: the test above.)

mod common;

use boot::disk_layout::SECTOR;
use boot::{line, Board, Firmware, Graphics, Qemu, QemuOptions, ReadError, ReadFailures};
use common::{stays_up_and_quiet, BOOT_TIMEOUT};
use loader_logic::file_hash::DAMAGED;
use std::io::{Cursor, Read};
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is
/// slow (as `tests/loader.rs`).
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);

/// The image's kernel file, as the BIOS stage 2 and the UEFI loader read it.
const KERNEL: &str = boot::secure_boot::KERNEL_FILE_NAME;
/// BIOS stage 4, a file on the FAT that stage 2 loads before the kernel.
const STAGE_4: &str = "boot-stage-4";

/// The sectors of the one image that the tests make fail.
#[derive(Debug)]
struct Sectors {
    stage_2_first: u64,
    stage_2_middle: u64,
    stage_4_middle: u64,
    kernel_middle: u64,
}

fn image() -> Vec<u8> {
    let images = boot::images::publish().expect("the build script made the images");
    std::fs::read(&images.hybrid).expect("the one image reads")
}

/// (first LBA, sectors) of MBR entry `index`.
fn mbr_entry(disk: &[u8], index: usize) -> (u64, u64) {
    assert_eq!(disk[510..512], [0x55, 0xAA], "no MBR");
    let raw = &disk[446 + 16 * index..][..16];
    let start = u32::from_le_bytes(raw[8..12].try_into().unwrap());
    let sectors = u32::from_le_bytes(raw[12..16].try_into().unwrap());
    (u64::from(start), u64::from(sectors))
}

/// The LBA of the sector holding the first byte of the cluster-aligned
/// chunk in the middle of file `name` on the FAT at `fat_start`: the file is
/// read with `fatfs`, and its chunk must be found exactly once in the volume,
/// at a sector boundary.
fn middle_of_file(disk: &[u8], fat_start: u64, fat_sectors: u64, name: &str) -> u64 {
    let volume = &disk[(fat_start as usize * SECTOR)..][..(fat_sectors as usize * SECTOR)];
    let fs = fatfs::FileSystem::new(Cursor::new(volume.to_vec()), fatfs::FsOptions::new())
        .expect("the ESP is a FAT");
    let cluster = fs.cluster_size() as usize;
    let mut contents = Vec::new();
    fs.root_dir()
        .open_file(name)
        .unwrap_or_else(|e| panic!("no {name} on the ESP: {e}"))
        .read_to_end(&mut contents)
        .unwrap();
    assert!(
        contents.len() >= 2 * cluster,
        "{name} is {} bytes, less than two clusters of {cluster}",
        contents.len()
    );
    let offset = contents.len() / 2 / cluster * cluster;
    let chunk = &contents[offset..offset + cluster];
    let found: Vec<usize> = (0..volume.len() - cluster)
        .step_by(SECTOR)
        .filter(|&at| &volume[at..at + cluster] == chunk)
        .collect();
    assert_eq!(
        found.len(),
        1,
        "{name}'s bytes {offset}..+{cluster} are found at {found:?} in the FAT volume"
    );
    fat_start + (found[0] / SECTOR) as u64
}

fn sectors() -> Sectors {
    let disk = image();
    // The boot sector loads the first entry (stage 2); stage 2 reads its
    // files from the FAT in the next.
    let (stage_2, stage_2_sectors) = mbr_entry(&disk, 0);
    let (fat, fat_sectors) = mbr_entry(&disk, 1);
    assert!(stage_2_sectors > 2, "stage 2 is {stage_2_sectors} sectors");
    Sectors {
        stage_2_first: stage_2,
        stage_2_middle: stage_2 + stage_2_sectors / 2,
        stage_4_middle: middle_of_file(&disk, fat, fat_sectors, STAGE_4),
        kernel_middle: middle_of_file(&disk, fat, fat_sectors, KERNEL),
    }
}

fn start(firmware: Firmware, error: ReadError) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    start_image(firmware, &images.hybrid, Some(error))
}

fn start_image(firmware: Firmware, image: &std::path::Path, error: Option<ReadError>) -> Qemu {
    let mut options = QemuOptions::new(image);
    if firmware == Firmware::Uefi {
        options.board = Board::Q35;
    }
    options.firmware = firmware;
    options.read_errors.extend(error);
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

/// A read of `sector` fails `times` times: the loader must say it tried
/// again, and the cube must come up.
fn retried_and_ready(firmware: Firmware, sector: u64, times: u32, what: &str) {
    let mut qemu = start(
        firmware,
        ReadError {
            sector,
            failures: ReadFailures::Times(times),
        },
    );
    let timeout = match firmware {
        Firmware::Bios => BOOT_TIMEOUT,
        Firmware::Uefi | Firmware::Uefi32 => UEFI_BOOT_TIMEOUT,
    };
    let console = qemu
        .wait_for_serial(line::READY, timeout)
        .unwrap_or_else(|e| panic!("{what} (LBA {sector:#x}) failed {times} time(s): {e}"));
    let retried = console.find(line::LOADER_READ_RETRIED).unwrap_or_else(|| {
        panic!("{what} (LBA {sector:#x}) failed {times} time(s), yet no retry was said:\n{console}")
    });
    let banner = console
        .find(line::KERNEL_BANNER)
        .unwrap_or_else(|| panic!("no kernel banner:\n{console}"));
    assert!(
        retried < banner,
        "the retry is said by the loader:\n{console}"
    );
    assert!(!console.contains(line::LOADER_CANNOT_READ), "{console}");
}

#[test]
fn bios_stage_2s_first_sector_failing_once_is_read_again() {
    retried_and_ready(
        Firmware::Bios,
        sectors().stage_2_first,
        1,
        "stage 2's first sector",
    );
}

#[test]
fn bios_a_sector_in_the_middle_of_stage_2_failing_once_is_read_again() {
    retried_and_ready(
        Firmware::Bios,
        sectors().stage_2_middle,
        1,
        "stage 2's middle",
    );
}

#[test]
fn bios_a_sector_of_stage_4_failing_once_is_read_again() {
    retried_and_ready(Firmware::Bios, sectors().stage_4_middle, 1, STAGE_4);
}

#[test]
fn bios_a_sector_of_the_kernel_failing_once_is_read_again() {
    retried_and_ready(Firmware::Bios, sectors().kernel_middle, 1, KERNEL);
}

#[test]
fn bios_a_kernel_sector_that_never_reads_is_named_on_com1_and_screen() {
    let sector = sectors().kernel_middle;
    let mut qemu = start(
        Firmware::Bios,
        ReadError {
            sector,
            failures: ReadFailures::Always,
        },
    );
    let console = qemu
        .wait_for_serial(line::LOADER_CANNOT_READ, BOOT_TIMEOUT)
        .unwrap();
    // The message names the LBA of the read that failed: one that covers the
    // bad sector (a transfer is at most 127 sectors).
    const AT_LBA: &str = "cannot read the disk at LBA 0x";
    let at = console
        .find(AT_LBA)
        .unwrap_or_else(|| panic!("no LBA named:\n{console}"))
        + AT_LBA.len();
    let hex = &console[at..at + 8];
    let lba = u64::from_str_radix(hex, 16)
        .unwrap_or_else(|e| panic!("{hex:?} is not 8 hex digits ({e}):\n{console}"));
    assert!(
        lba <= sector && sector < lba + 128,
        "the message names LBA {lba:#x}, not a read covering {sector:#x}:\n{console}"
    );
    let screen = qemu.text_screen().unwrap();
    assert!(
        screen.contains(&format!("{AT_LBA}{hex}")),
        "not on the screen:\n{screen}"
    );
    assert!(!console.contains(line::KERNEL_BANNER), "{console}");
    stays_up_and_quiet(&mut qemu, &console);
}

/// Waits for the damaged-file message naming `file` on COM1 (`copies`
/// times); no kernel may have started. Returns the console.
fn damaged_said(qemu: &mut Qemu, file: &str, copies: usize, budget: Duration) -> String {
    let message = format!("{DAMAGED}{file}: SHA-256 expected ");
    let console = qemu
        .wait_for_serial_count(&message, copies, budget)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        console.contains("Write the stick again, or try another USB port"),
        "{console}"
    );
    assert!(!console.contains(line::KERNEL_BANNER), "{console}");
    console
}

/// OVMF on its AHCI disk (`-M q35`), one kernel sector failing every time:
/// OVMF's driver retries, then hands back wrong bytes as a good read. The
/// loader's hash check must catch them, say so on the UEFI console (the
/// screen, which OVMF copies to COM1: one copy there, issue 48), and wait
/// without a reset.
#[test]
fn ovmf_ahci_a_kernel_sector_that_never_reads_is_caught_by_its_hash() {
    let sector = sectors().kernel_middle;
    let mut qemu = start(
        Firmware::Uefi,
        ReadError {
            sector,
            failures: ReadFailures::Always,
        },
    );
    let console = damaged_said(
        &mut qemu,
        "kernel-x86_64 (the kernel)",
        1,
        UEFI_BOOT_TIMEOUT,
    );
    stays_up_and_quiet(&mut qemu, &console);
}

/// The image with `change` made, written to a file in `dir`.
fn changed_image(
    dir: &std::path::Path,
    change: impl FnOnce(&[u8]) -> Vec<u8>,
) -> std::path::PathBuf {
    let path = dir.join("changed.img");
    std::fs::write(&path, change(&image())).unwrap();
    path
}

/// 32-bit OVMF: a byte of stage 4 changed in the image file (a stick that
/// rots); the 32-bit loader, which starts stage 4, must name stage 4 on COM1
/// and the UEFI console (copied to serial: one copy, issue 48), and wait.
#[test]
fn ovmf32_a_changed_stage_4_byte_is_caught_and_named_stage_4() {
    let scratch = tempfile::tempdir().unwrap();
    let image = changed_image(scratch.path(), |disk| {
        common::with_a_file_byte_changed(disk, STAGE_4)
    });
    let mut qemu = start_image(Firmware::Uefi32, &image, None);
    let console = damaged_said(
        &mut qemu,
        "boot-stage-4 (loader stage 4)",
        1,
        UEFI_BOOT_TIMEOUT,
    );
    stays_up_and_quiet(&mut qemu, &console);
}

/// The one image with a byte of `file` changed, booted by SeaBIOS on
/// `graphics`: stage 3 must name `file` on COM1 and stop. Returns the QEMU
/// and the console.
fn bios_damaged(file: &str, named: &str, graphics: Graphics) -> (Qemu, String) {
    let scratch = tempfile::tempdir().unwrap();
    let image = changed_image(scratch.path(), |disk| {
        common::with_a_file_byte_changed(disk, file)
    });
    let mut options = QemuOptions::new(&image);
    options.firmware = Firmware::Bios;
    options.graphics = graphics;
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    // The kernel's banner ends the wait too: a kernel that starts prints on
    // for good, and the message will never come.
    let message = format!("{DAMAGED}{named}: SHA-256 expected ");
    let console = qemu
        .wait_for_console(&message, BOOT_TIMEOUT, |text| {
            text.contains(&message) || text.contains(line::KERNEL_BANNER)
        })
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        console.contains(&message),
        "the kernel started, unchecked:\n{console}"
    );
    let console = damaged_said(&mut qemu, named, 1, BOOT_TIMEOUT);
    (qemu, console)
}

/// SeaBIOS on an adapter without VBE linear modes (so stage 2 leaves the
/// VGA in text mode), a byte of the kernel changed in the image file:
/// stage 3 must name the kernel on COM1 and on the VGA text screen, and
/// stay up without a reset.
#[test]
fn bios_a_changed_kernel_byte_is_caught_by_its_hash_on_com1_and_the_text_screen() {
    let (mut qemu, console) =
        bios_damaged(KERNEL, "kernel-x86_64 (the kernel)", Graphics::IsaCirrus);
    let screen = qemu.text_screen().unwrap();
    // The screen wraps the message at 80 columns and its rows lose their
    // trailing blanks: compare without any white space.
    let squeezed = |text: &str| -> String { text.split_whitespace().collect() };
    let line = console
        .lines()
        .find(|line| line.starts_with(DAMAGED))
        .unwrap_or_else(|| panic!("no message line:\n{console}"));
    assert!(
        squeezed(&screen).contains(&squeezed(line)),
        "not on the screen: {line:?}\n{screen}"
    );
    stays_up_and_quiet(&mut qemu, &console);
}

/// SeaBIOS on the standard VGA (stage 2 sets a VESA mode), a byte of stage
/// 4 changed in the image file: stage 3 must name stage 4 on COM1, and stay
/// up without a reset.
#[test]
fn bios_a_changed_stage_4_byte_is_caught_and_named_stage_4() {
    let (mut qemu, console) =
        bios_damaged(STAGE_4, "boot-stage-4 (loader stage 4)", Graphics::StdVga);
    stays_up_and_quiet(&mut qemu, &console);
}

#[test]
fn the_sectors_are_where_the_image_says() {
    let disk = image();
    let found = sectors();
    eprintln!("the sectors made to fail: {found:?}");
    let (stage_2, count) = mbr_entry(&disk, 0);
    let (fat, fat_sectors) = mbr_entry(&disk, 1);
    assert_eq!(found.stage_2_first, stage_2);
    assert!((stage_2..stage_2 + count).contains(&found.stage_2_middle));
    for lba in [found.stage_4_middle, found.kernel_middle] {
        assert!((fat..fat + fat_sectors).contains(&lba), "{found:?}");
    }
    assert_ne!(found.stage_4_middle, found.kernel_middle);
    let kernel_sector = &disk[found.kernel_middle as usize * SECTOR..][..SECTOR];
    assert!(kernel_sector.iter().any(|&b| b != 0), "{found:?}");
}
