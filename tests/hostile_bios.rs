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
//! A video BIOS whose mode set waits (issue 66): the ROM's variants make
//! INT 10h AX=0013h wait 1 ms through INT 15h AH=86h (SeaBIOS times it on
//! the RTC's IRQ 8), wait for the BIOS tick (IRQ 0), or halt for ever. The
//! kernel's call runs in the BIOS's world (PICs at 08h/70h, the firmware's
//! masks, the PIT at 18.2 Hz, interrupts on): the first two return and the
//! cube is set from the BIOS's mode 13h; the third is abandoned by the
//! watchdog, said on COM1, and Mode X is set by registers.
//!
//! A BIOS without the INT 13h extensions (issue 48): the ROM's variant that
//! fails AH=41h gets the boot sector's message on the screen (the VGA text
//! buffer, read through QMP) and COM1, and no stage 2.

mod common;

use boot::option_rom::{self, HostileBoot, VideoWait};
use boot::{line, Qemu};
use common::BOOT_TIMEOUT;

/// Starts SeaBIOS with the hostile ROM built for `boot`; the scratch
/// directory holds the ROM and must outlive QEMU.
fn start(boot: HostileBoot) -> (Qemu, tempfile::TempDir) {
    let bootindex = match boot {
        HostileBoot::Bev { .. } => Some(0),
        _ => None,
    };
    common::start_with_option_rom(
        |dir| option_rom::build_hostile_bios(dir, boot),
        bootindex,
        |_| {},
    )
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
        common::cube_keys_then_escape_powers_off(&mut qemu);
    } else {
        common::escape_powers_off(&mut qemu);
    }
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

/// The ROM's counts of its video waits: begun, ended.
fn video_waits(qemu: &mut Qemu) -> [u32; 2] {
    let bytes = qemu.read_physical(option_rom::VIDEO_WAITS, 8).unwrap();
    [0, 1].map(|i| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap()))
}

/// Boots with a video BIOS whose mode 13h waits as `wait` says, to the
/// ready line; checks the kernel's call reached the wait; returns the
/// console.
fn boot_with_a_video_bios_that_waits(wait: VideoWait) -> (Qemu, tempfile::TempDir, String) {
    let (mut qemu, rom) = start(HostileBoot::VideoBiosWaits(wait));
    let console = qemu
        .wait_for_serial(line::READY, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{wait:?}: {e}"));
    let waited = console
        .find(option_rom::VIDEO_WAIT_LINE)
        .unwrap_or_else(|| panic!("the kernel's INT 10h never reached the wait:\n{console}"));
    let kernel = console.find(line::KERNEL_BANNER).unwrap();
    assert!(kernel < waited, "{console}");
    (qemu, rom, console)
}

#[test]
fn a_video_bios_waiting_on_int_15h_ah_86h_sets_mode_13h_and_the_cube_runs() {
    let (mut qemu, _rom, console) = boot_with_a_video_bios_that_waits(VideoWait::Int15Delay);
    assert_eq!(video_waits(&mut qemu), [1, 1], "{console}");
    assert!(
        console.contains("vga: mode 13h set by the video BIOS, then tweaked"),
        "{console}"
    );
    common::cube_keys_then_escape_powers_off(&mut qemu);
}

#[test]
fn a_video_bios_waiting_for_the_bios_tick_sets_mode_13h_and_escape_powers_off() {
    let (mut qemu, _rom, console) = boot_with_a_video_bios_that_waits(VideoWait::BiosTick);
    assert_eq!(video_waits(&mut qemu), [1, 1], "{console}");
    assert!(
        console.contains("vga: mode 13h set by the video BIOS, then tweaked"),
        "{console}"
    );
    common::escape_powers_off(&mut qemu);
}

#[test]
fn a_video_bios_that_never_returns_is_abandoned_and_mode_x_set_by_registers() {
    let (mut qemu, _rom, console) = boot_with_a_video_bios_that_waits(VideoWait::Forever);
    assert_eq!(video_waits(&mut qemu), [1, 0], "{console}");
    let abandoned = format!(
        "vga: the video BIOS did not return from INT 10h AH=00h within {} ms; Mode X set by registers",
        memory::trampoline::bios_world::limit_millis()
    );
    assert!(console.contains(&abandoned), "no `{abandoned}`:\n{console}");
    assert!(
        console.contains("vga: Mode X 320x240 set, registers read back as written"),
        "{console}"
    );
    common::cube_keys_then_escape_powers_off(&mut qemu);
    // The goodbye did not call the BIOS again.
    let console = qemu.serial();
    assert!(
        !console.contains("text mode 3 set by the video BIOS"),
        "{console}"
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
        HostileBoot::VideoBiosWaits(VideoWait::Int15Delay),
        HostileBoot::VideoBiosWaits(VideoWait::BiosTick),
        HostileBoot::VideoBiosWaits(VideoWait::Forever),
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
