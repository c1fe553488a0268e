//! UEFI boots and machines without a legacy VGA. A UEFI boot draws through
//! the firmware framebuffer whatever the VGA registers say: Mode X runs on
//! the kernel's software VGA and each flip is presented into the framebuffer
//! the bootloader got from UEFI GOP. QEMU's screendump of that framebuffer
//! must equal the model's picture scaled the same way by the same `present`,
//! with OVMF and QEMU's standard VGA as with `-vga none -device
//! bochs-display`, where nothing answers on the VGA ports at all. A BIOS
//! boot, and UEFI with the `modex=true-mode-x` boot option, drive the real
//! registers. Every boot here is of the one image (`modex-cube.img`), OVMF's
//! on a Q35. The text screens (fault panels, goodbye) are in `text_screens`.

mod common;
#[path = "uefi_parts/text_screens.rs"]
mod text_screens;

use boot::{Board, BootOption, BootRequest, Firmware, Graphics, Qemu, QemuOptions};
use common::{
    assert_pictures_equal, assert_same_picture, model_picture, pattern_picture, presented,
    soft_vga_in_mode_x, BOOT_TIMEOUT,
};
use demo::app::App;
use demo::command::{Axis, Command, SceneCommand, Sense};
use modex::present::Placement;
use modex::ModeX;
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
const LEGACY_FOUND: &str = "display: legacy VGA found";
const NO_LEGACY: &str = "display: no legacy VGA";
const UEFI_FRAMEBUFFER: &str = "display: UEFI boot: drawing through the firmware framebuffer";

fn boot(firmware: Firmware, graphics: Graphics, option: Option<BootOption>) -> Qemu {
    let request = BootRequest {
        option,
        ..BootRequest::default()
    };
    boot_with(firmware, graphics, request, true)
}

/// As `boot`; without `debug_exit` the kernel powers the machine off through
/// ACPI where it would end QEMU, and QEMU keeps the last screen.
fn boot_with(
    firmware: Firmware,
    graphics: Graphics,
    request: BootRequest,
    debug_exit: bool,
) -> Qemu {
    Qemu::start(&options_for(firmware, graphics, request, debug_exit))
        .unwrap_or_else(|e| panic!("{e}"))
}

fn options_for(
    firmware: Firmware,
    graphics: Graphics,
    request: BootRequest,
    debug_exit: bool,
) -> QemuOptions {
    // The one image, under either firmware; OVMF on a Q35, as UEFI PCs are.
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    if firmware == Firmware::Uefi {
        options.board = Board::Q35;
    }
    options.firmware = firmware;
    options.graphics = graphics;
    options.boot = request;
    options.debug_exit = debug_exit;
    options.keep_after_power_off = !debug_exit;
    options
}

/// The framebuffer as the kernel reported it on serial:
/// `display: framebuffer 1280x800 stride 1280 bgr 4 bytes/pixel, scale 3`.
struct ReportedFramebuffer {
    width: usize,
    height: usize,
    order: String,
    bytes_per_pixel: usize,
    scale: usize,
}

fn reported_framebuffer(console: &str) -> ReportedFramebuffer {
    let line = console
        .lines()
        .find_map(|line| line.strip_prefix("display: framebuffer "))
        .unwrap_or_else(|| panic!("no framebuffer line on serial:\n{console}"));
    let unreadable = || -> ! { panic!("cannot read the framebuffer line {line:?}") };
    let number = |word: Option<&str>| -> usize {
        word.and_then(|w| w.trim_end_matches(',').parse().ok())
            .unwrap_or_else(|| unreadable())
    };
    // "1280x800 stride 1280 bgr 4 bytes/pixel, scale 3"
    let words: Vec<&str> = line.split_whitespace().collect();
    let (width, height) = words[0].split_once('x').unwrap_or_else(|| unreadable());
    assert_eq!(
        (words.get(1), words.get(5), words.get(6)),
        (Some(&"stride"), Some(&"bytes/pixel,"), Some(&"scale")),
        "{line:?}"
    );
    ReportedFramebuffer {
        width: number(Some(width)),
        height: number(Some(height)),
        order: words[3].to_owned(),
        bytes_per_pixel: number(words.get(4).copied()),
        scale: number(words.get(7).copied()),
    }
}

/// Boots UEFI with the test pattern on `graphics`, checks the framebuffer
/// path was taken and the screen equals the pattern presented, and returns
/// what the kernel reported of the framebuffer.
fn framebuffer_shows_the_pattern(graphics: Graphics, what: &str) -> ReportedFramebuffer {
    let mut qemu = boot(Firmware::Uefi, graphics, Some(BootOption::TestPattern));
    let console = qemu
        .wait_for_serial("pattern: page 0 shown", UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(UEFI_FRAMEBUFFER), "{console}");
    assert!(!console.contains(LEGACY_FOUND), "{console}");
    let reported = reported_framebuffer(&console);
    let screen = qemu.screendump().unwrap();
    assert_eq!(
        (screen.width, screen.height),
        (reported.width, reported.height),
        "QEMU's display and the bootloader's framebuffer differ in size"
    );
    // The test pattern: both pages drawn, page 0 shown.
    let expected = presented(&pattern_picture(0), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, what);
    reported
}

#[test]
fn without_legacy_vga_the_framebuffer_shows_the_software_vga_scaled() {
    let reported = framebuffer_shows_the_pattern(Graphics::BochsDisplay, "uefi framebuffer");
    println!(
        "framebuffer {}x{} {} {} bytes/pixel, scale {}",
        reported.width, reported.height, reported.order, reported.bytes_per_pixel, reported.scale
    );
    let expected_scale = Placement::fit((320, 240), (reported.width, reported.height)).scale;
    assert_eq!(reported.scale, expected_scale);
    assert!(
        expected_scale >= 2,
        "a {}x{} screen",
        reported.width,
        reported.height
    );
}

#[test]
fn without_legacy_vga_the_lit_solids_reach_the_framebuffer_too() {
    let keys = [
        ("r", Command::Scene(SceneCommand::Reset)),
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("8", common::turn(Axis::X, Sense::Negative)),
        ("n", Command::Scene(SceneCommand::NextSolid)),
        ("m", Command::Scene(SceneCommand::ToggleSeveral)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
    ];
    let mut qemu = boot(Firmware::Uefi, Graphics::BochsDisplay, None);
    qemu.wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    for (n, &(key, command)) in keys.iter().enumerate() {
        qemu.send_key(key).unwrap();
        let done = boot::line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
        app.apply(command);
    }
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let screen = qemu.screendump().unwrap();
    let expected = presented(&model_picture(&soft), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, "lit solids on the framebuffer");
    // The report screen and back, presented the same way.
    common::report_round_trip(&mut qemu, keys.len() as u64, "Uefi", |model, screen| {
        presented(model, screen.width, screen.height)
    });
}

#[test]
fn a_bios_boot_of_the_same_image_finds_the_legacy_vga() {
    let mut qemu = boot(
        Firmware::Bios,
        Graphics::StdVga,
        Some(BootOption::TestPattern),
    );
    let console = qemu
        .wait_for_serial("pattern: page 0 shown", BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(LEGACY_FOUND), "{console}");
    assert!(!console.contains(NO_LEGACY), "{console}");
}

/// The default UEFI boot takes the framebuffer path even though QEMU's
/// standard VGA answers on the legacy registers (a real Intel iGPU answers
/// too, with its VGA plane disabled), and the registers are never touched:
/// QEMU shows GOP's mode with the presented picture.
#[test]
fn uefi_with_the_standard_vga_draws_through_the_framebuffer() {
    framebuffer_shows_the_pattern(Graphics::StdVga, "uefi std vga framebuffer");
}

/// `modex=true-mode-x` puts OVMF + standard VGA back on the real registers:
/// QEMU shows the VGA's own 640x480 Mode X picture, as on a BIOS boot.
#[test]
fn uefi_with_the_standard_vga_and_the_option_runs_true_mode_x() {
    let request = BootRequest {
        true_mode_x: true,
        option: Some(BootOption::TestPattern),
        ..BootRequest::default()
    };
    let mut qemu = boot_with(Firmware::Uefi, Graphics::StdVga, request, true);
    let console = qemu
        .wait_for_serial("pattern: page 0 shown", UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(LEGACY_FOUND), "{console}");
    assert!(!console.contains(UEFI_FRAMEBUFFER), "{console}");
    assert!(!console.contains(NO_LEGACY), "{console}");
    // A UEFI boot never calls a video BIOS, even when the registers are used.
    assert!(
        console.contains("the video BIOS will not be called: not a BIOS boot (Uefi)"),
        "{console}"
    );
    let screen = qemu.screendump().unwrap();
    assert_same_picture(&screen, &pattern_picture(0), "true mode x under uefi");
}

/// OVMF on a Cirrus at 1024x768 (its `PlatformConfig` variable, as OVMF's
/// setup page sets it): GOP's mode is 24-bit, 3 bytes a pixel, and the
/// Cirrus has no 4-byte mode of that size. The loader keeps the mode and
/// hands on 3 bytes (it said 4, and the kernel refused the buffer as too
/// small: a black screen); the cube is drawn, QEMU's picture equal to the
/// software VGA's presented after each key.
#[test]
fn uefi_on_a_cirrus_at_1024x768_draws_the_cube_in_3_byte_pixels() {
    const KEYS: [(&str, Command); 3] = [
        ("r", Command::Scene(SceneCommand::Reset)),
        ("6", common::turn(Axis::Y, Sense::Positive)),
        ("l", Command::Scene(SceneCommand::ToggleLighting)),
    ];
    let mut options = options_for(
        Firmware::Uefi,
        Graphics::Cirrus,
        BootRequest::default(),
        true,
    );
    options.uefi_resolution = Some((1024, 768));
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("1024x768 Bitmask (console): usable, 3 bytes/pixel"),
        "{console}"
    );
    assert!(
        console.contains(
            "loader: keeping the current mode, 1024x768 at 3 bytes/pixel: \
             no mode of its size has 4 bytes a pixel"
        ),
        "{console}"
    );
    let reported = reported_framebuffer(&console);
    assert_eq!(
        (reported.width, reported.height, reported.bytes_per_pixel),
        (1024, 768, 3),
        "{console}"
    );
    common::after_each_key_on(&mut qemu, &KEYS, |screen, model, _, what| {
        assert_eq!((screen.width, screen.height), (1024, 768), "{what}");
        let expected = presented(model, screen.width, screen.height);
        assert_pictures_equal(screen, &expected, &format!("cirrus 1024x768, {what}"));
    });
}
