//! Junk RAM (issue 38): a real PC's memory holds whatever it held at power-on,
//! not QEMU's zeros. Before the firmware runs, QEMU's generic loader device
//! (`boot::RamFile`) fills low memory from 0x500 up to the EBDA's page
//! (0x9F000) and everything from 1 MiB up to near the top of the guest's RAM
//! with deterministic pseudo-random bytes (a fixed seed). The firmware sets up
//! its own areas; the loader and the kernel must not take anything else for
//! zeros (a `.bss`, a page table, a structure's padding). SeaBIOS (`-M pc`)
//! and OVMF (`-M q35`): the cube must come up, the cube test's keys must give
//! the software VGA's pictures, Esc must power off with success.

mod common;

use boot::qemu::{DEFAULT_MEMORY_MIB, EXIT_SUCCESS};
use boot::{line, Board, Firmware, Qemu, QemuOptions, RamFile};
use common::BOOT_TIMEOUT;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is
/// slow (as `tests/loader.rs`).
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);

/// Low memory's junk: from the end of the BIOS data area to the page of
/// SeaBIOS's EBDA (0x9FC00 at 256 MiB).
const LOW: (u64, u64) = (0x500, 0x9_F000);
/// High memory's junk: from 1 MiB to 1 MiB short of the top of RAM.
const HIGH: (u64, u64) = (0x10_0000, (DEFAULT_MEMORY_MIB as u64 - 1) << 20);

/// Writes `len` pseudo-random bytes to `path`: xorshift64* from `seed`, so
/// every run puts the same junk in the same places.
fn write_junk(path: &Path, len: u64, seed: u64) {
    let mut state = seed;
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut block = vec![0u8; 1 << 16];
    let mut left = len;
    while left > 0 {
        for chunk in block.chunks_mut(8) {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            let word = state.wrapping_mul(0x2545_F491_4F6C_DD1D);
            chunk.copy_from_slice(&word.to_le_bytes()[..chunk.len()]);
        }
        let n = left.min(block.len() as u64) as usize;
        out.write_all(&block[..n]).unwrap();
        left -= n as u64;
    }
    out.flush().unwrap();
}

/// Starts `firmware` with RAM full of junk; the directory holds the junk
/// files and must outlive QEMU.
fn start(firmware: Firmware) -> (Qemu, tempfile::TempDir) {
    let dir = tempfile::Builder::new()
        .prefix("modex-cube-junk-")
        .tempdir()
        .unwrap();
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    if firmware == Firmware::Uefi {
        options.board = Board::Q35;
    }
    options.firmware = firmware;
    for (n, (start, end)) in [LOW, HIGH].into_iter().enumerate() {
        let path = dir.path().join(format!("junk-{start:#x}.bin"));
        write_junk(&path, end - start, 0x5EED_0000_0000_0001 + n as u64);
        options.ram_files.push(RamFile {
            path,
            address: start,
        });
    }
    (Qemu::start(&options).unwrap_or_else(|e| panic!("{e}")), dir)
}

fn cube_on_junk(firmware: Firmware) {
    let (mut qemu, junk) = start(firmware);
    let timeout = match firmware {
        Firmware::Bios => BOOT_TIMEOUT,
        Firmware::Uefi | Firmware::Uefi32 => UEFI_BOOT_TIMEOUT,
    };
    let console = qemu
        .wait_for_serial(line::READY, timeout)
        .unwrap_or_else(|e| panic!("{firmware:?} with junk in RAM: {e}"));
    assert!(console.contains(line::LOADER_START), "{console}");
    // The junk really was put there: of a few pages well inside high RAM,
    // at least one still holds it after the firmware, loader and kernel ran.
    let high_junk = std::fs::read(junk.path().join(format!("junk-{:#x}.bin", HIGH.0))).unwrap();
    let still_junk = [100u64, 150, 200, 250]
        .into_iter()
        .filter(|mib| {
            let address = mib << 20;
            let offset = (address - HIGH.0) as usize;
            qemu.read_physical(address, 4096).unwrap() == high_junk[offset..offset + 4096]
        })
        .count();
    assert!(
        still_junk > 0,
        "no junk found in RAM: the loader device did not fill it"
    );
    common::after_each_key_on(&mut qemu, &common::CUBE_KEYS, |screen, model, _, what| {
        common::assert_cube_picture(firmware, screen, model, what)
    });
    qemu.send_key("esc").unwrap();
    qemu.wait_for_serial(line::GOODBYE, BOOT_TIMEOUT).unwrap();
    let status = qemu.wait_for_exit(BOOT_TIMEOUT).unwrap();
    assert_eq!(status.code(), Some(EXIT_SUCCESS), "{}", qemu.serial());
}

#[test]
fn seabios_with_junk_in_ram_runs_the_cube() {
    cube_on_junk(Firmware::Bios);
}

#[test]
fn ovmf_with_junk_in_ram_runs_the_cube() {
    cube_on_junk(Firmware::Uefi);
}
