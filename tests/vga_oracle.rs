//! The oracle nobody here wrote: QEMU's own VGA emulation. The kernel draws the
//! Mode X test pattern on the real (emulated) registers; the same drawing code
//! runs against the software VGA on the host; QEMU's screendump (640x480, each
//! Mode X pixel doubled) must equal the model's scan-out pixel for pixel.

mod common;

use boot::BootOption;
use common::{assert_same_picture, boot_bios, pattern_picture, BOOT_TIMEOUT};

#[test]
fn qemu_shows_what_the_software_vga_shows_for_the_test_pattern_on_both_pages() {
    let mut qemu = boot_bios(Some(BootOption::TestPattern));
    qemu.wait_for_serial("pattern: page 0 shown", BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(&qemu.screendump().unwrap(), &pattern_picture(0), "page 0");

    qemu.send_key("spc").unwrap();
    qemu.wait_for_serial("pattern: page 1 shown", BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &pattern_picture(1),
        "page 1 after a flip",
    );

    qemu.send_key("spc").unwrap();
    qemu.wait_for_serial_count("pattern: page 0 shown", 2, BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &pattern_picture(2),
        "page 0 after flipping back",
    );
}

/// With `-vga std,retrace=precise` QEMU times Input Status 1 from the CRTC
/// values, so page flips locked to vertical retrace run at the refresh rate.
/// On a VGA that is Mode X's 59.71 Hz (800 dots by 527 lines at 25.175 MHz);
/// QEMU times a character clock as a whole number of nanoseconds (317 ns
/// for 317.77), so its refresh is 59.86 Hz. Flips can never outrun that; on
/// a busy host the emulator can truly miss a retrace, which the kernel counts,
/// so flips plus missed retraces must make it by the kernel's clock.
#[test]
fn page_flips_follow_vertical_retrace_at_60_hz() {
    const CHARACTER_NANOS: f64 = 317.0; // 1e9 / (25.175 MHz / 8), truncated
    const REFRESH_HZ: f64 = 1e9 / (100.0 * 527.0 * CHARACTER_NANOS);
    let mut qemu = boot_bios(Some(BootOption::FlipRate));
    let console = qemu.wait_for_serial("wait timeouts", BOOT_TIMEOUT).unwrap();
    let line = console
        .lines()
        .find(|l| l.starts_with("flip-rate:"))
        .expect("a flip-rate line");
    println!("{line}");
    // "flip-rate: F flips in E us = H Hz, M missed retraces, T wait timeouts"
    let numbers: Vec<f64> = line
        .split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter_map(|word| word.parse().ok())
        .collect();
    let [flips, micros, hertz, missed, timeouts] = numbers[..] else {
        panic!("cannot read {line:?}");
    };
    assert_eq!(timeouts, 0.0, "{line}");
    assert!(
        hertz <= REFRESH_HZ * 1.002,
        "flips outran the refresh: {line}"
    );
    let retraces_hz = (flips + missed) * 1e6 / micros;
    assert!(
        (retraces_hz / REFRESH_HZ - 1.0).abs() < 0.01,
        "flips + missed retraces = {retraces_hz:.3} Hz, not {REFRESH_HZ:.3} Hz: {line}"
    );
}
