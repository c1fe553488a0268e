//! A worst-case BIOS (issue 38): SeaBIOS with an option ROM
//! (`boot/roms/hostile_bios.asm`, built by `boot::option_rom`) that hooks
//! INT 10h, 13h and 15h and returns from each with junk in the upper 16 bits
//! of EAX, EBX, ECX, EDX, ESI, EDI and EBP (E820's 32-bit outputs kept), and
//! BP changed by INT 10h. With the hooks alone SeaBIOS boots the disk; as a
//! boot device (`bootindex=0`) the ROM loads the MBR itself and jumps to it
//! at 0000:7C00 or 07C0:0000, with junk in the upper half of ESP and in every
//! register but DL (80h, or 00h which the loader must not take for a disk).
//!
//! Each boot must reach the cube; with DL=80h the cube test's keys must give
//! the software VGA's pictures and Esc must power off with success. The
//! hooks must have run: the ROM says so on COM1 and counts its calls in the
//! interrupt table (`boot::option_rom::CALL_COUNTERS`), read through QMP.
//!
//! A BIOS without the INT 13h extensions (issue 48): the ROM's variant that
//! fails AH=41h gets the boot sector's message on the screen (the VGA text
//! buffer, read through QMP) and COM1, and no stage 2.

mod common;

use boot::option_rom::{self, HostileBoot};
use boot::qemu::EXIT_SUCCESS;
use boot::{line, OptionRom, Qemu, QemuOptions};
use common::{assert_same_picture, BOOT_TIMEOUT};

/// Starts SeaBIOS with the hostile ROM built for `boot`; the scratch
/// directory holds the ROM and must outlive QEMU.
fn start(boot: HostileBoot) -> (Qemu, tempfile::TempDir) {
    let dir = tempfile::Builder::new()
        .prefix("modex-cube-rom-")
        .tempdir()
        .expect("a scratch directory");
    let rom = option_rom::build_hostile_bios(dir.path(), boot).unwrap_or_else(|e| panic!("{e}"));
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.option_roms.push(OptionRom {
        path: rom,
        bootindex: match boot {
            HostileBoot::HooksOnly | HostileBoot::NoExtensions => None,
            HostileBoot::Bev { .. } => Some(0),
        },
    });
    (Qemu::start(&options).unwrap_or_else(|e| panic!("{e}")), dir)
}

/// The ROM's call counters: INT 10h, 13h, 15h.
fn call_counts(qemu: &mut Qemu) -> [u32; 3] {
    let bytes = qemu.read_physical(option_rom::CALL_COUNTERS, 12).unwrap();
    [0, 1, 2].map(|i| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap()))
}

/// Boots through the hostile ROM to the cube, checks the hooks ran (and, as
/// a boot device, that the ROM's own jump started the loader), then runs
/// the cube test's keys unless `keys` is false, and Esc.
fn cube_through(boot: HostileBoot, keys: bool) {
    let (mut qemu, _rom) = start(boot);
    let console = qemu
        .wait_for_serial(line::READY, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{boot:?}: {e}"));
    let hooked = console
        .find(option_rom::HOOKED_LINE)
        .unwrap_or_else(|| panic!("the ROM did not hook the BIOS:\n{console}"));
    let loader = console
        .find(line::LOADER_START)
        .unwrap_or_else(|| panic!("no loader line:\n{console}"));
    assert!(hooked < loader, "{console}");
    if let HostileBoot::Bev {
        segment,
        offset,
        drive,
    } = boot
    {
        let jump = format!(
            "{}{segment:04X}:{offset:04X} with DL={drive:02X}",
            option_rom::BEV_JUMP_LINE
        );
        let jumped = console.find(&jump).unwrap_or_else(|| {
            panic!("the ROM's BEV did not start the loader ({jump}):\n{console}")
        });
        assert!(hooked < jumped && jumped < loader, "{console}");
    }
    // The loader read the disk (INT 13h), the memory map (INT 15h) and wrote
    // on the screen (INT 10h) through the hooks.
    let [int10, int13, int15] = call_counts(&mut qemu);
    assert!(
        int10 > 0 && int13 > 0 && int15 > 0,
        "the hooks were not called: INT 10h {int10}, 13h {int13}, 15h {int15} times"
    );
    if keys {
        common::after_each_key_on(&mut qemu, &common::CUBE_KEYS, |screen, model, _, what| {
            assert_same_picture(screen, model, what)
        });
    }
    qemu.send_key("esc").unwrap();
    qemu.wait_for_serial(line::GOODBYE, BOOT_TIMEOUT).unwrap();
    let status = qemu.wait_for_exit(BOOT_TIMEOUT).unwrap();
    assert_eq!(status.code(), Some(EXIT_SUCCESS), "{}", qemu.serial());
}

#[test]
fn seabios_with_junk_in_the_upper_halves_boots_the_cube() {
    cube_through(HostileBoot::HooksOnly, true);
}

#[test]
fn a_boot_rom_jumping_to_0000_7c00_with_junk_boots_the_cube() {
    cube_through(
        HostileBoot::Bev {
            segment: 0x0000,
            offset: 0x7C00,
            drive: 0x80,
        },
        true,
    );
}

#[test]
fn a_boot_rom_jumping_to_07c0_0000_with_junk_boots_the_cube() {
    cube_through(
        HostileBoot::Bev {
            segment: 0x07C0,
            offset: 0x0000,
            drive: 0x80,
        },
        true,
    );
}

#[test]
fn a_boot_rom_giving_drive_00_boots_the_cube_from_80() {
    cube_through(
        HostileBoot::Bev {
            segment: 0x0000,
            offset: 0x7C00,
            drive: 0x00,
        },
        false,
    );
}

/// The boot sector's words for a BIOS without the INT 13h extensions
/// (`bootloader/bios/boot_sector/src/boot.s`).
const NO_EXTENSIONS_MESSAGE: &str = "loader: no INT 13h extensions";

#[test]
fn a_bios_without_int_13h_extensions_gets_the_boot_sectors_message_on_screen() {
    let (mut qemu, _rom) = start(HostileBoot::NoExtensions);
    let console = qemu
        .wait_for_serial(NO_EXTENSIONS_MESSAGE, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e}"));
    let refused = console
        .find(option_rom::NO_EXTENSIONS_LINE)
        .unwrap_or_else(|| panic!("the ROM did not refuse AH=41h:\n{console}"));
    assert!(
        refused < console.find(NO_EXTENSIONS_MESSAGE).unwrap(),
        "{console}"
    );
    // On the screen: the boot sector prints through INT 10h's teletype.
    let screen = qemu.text_screen().unwrap();
    assert!(
        screen
            .lines()
            .any(|row| row.trim() == NO_EXTENSIONS_MESSAGE),
        "not on the screen:\n{screen}"
    );
    // The boot sector stops there: no stage 2, and no reset (-no-reboot
    // would end QEMU).
    assert!(!console.contains(line::LOADER_START), "{console}");
    assert!(qemu.is_running(), "QEMU ended:\n{console}");
}

#[test]
fn the_rom_builds_with_a_valid_checksum_and_pnp_header() {
    let dir = tempfile::tempdir().unwrap();
    for boot in [
        HostileBoot::HooksOnly,
        HostileBoot::NoExtensions,
        HostileBoot::Bev {
            segment: 0x07C0,
            offset: 0,
            drive: 0x80,
        },
    ] {
        let rom = std::fs::read(option_rom::build_hostile_bios(dir.path(), boot).unwrap()).unwrap();
        assert_eq!(rom[..2], [0x55, 0xAA]);
        assert_eq!(usize::from(rom[2]) * 512, rom.len());
        assert_eq!(rom.iter().fold(0u8, |s, &b| s.wrapping_add(b)), 0);
        let pnp = usize::from(u16::from_le_bytes([rom[0x1A], rom[0x1B]]));
        assert_eq!(&rom[pnp..pnp + 4], b"$PnP");
        let bev = u16::from_le_bytes([rom[pnp + 0x1A], rom[pnp + 0x1B]]);
        let booted = matches!(boot, HostileBoot::Bev { .. });
        assert_eq!(bev != 0, booted, "{boot:?}");
    }
}
