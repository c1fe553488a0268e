//! The oracle nobody here wrote: QEMU's own VGA emulation. The kernel draws the
//! Mode X test pattern on the real (emulated) registers; the same drawing code
//! runs against the software VGA on the host; QEMU's screendump (640x480, each
//! Mode X pixel doubled) must equal the model's scan-out pixel for pixel.

mod common;

use common::{assert_same_picture, boot_bios, pattern_picture, BOOT_TIMEOUT};

#[test]
fn qemu_shows_what_the_software_vga_shows_for_the_test_pattern_on_both_pages() {
    let mut qemu = boot_bios(Some("test-pattern"));
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
#[test]
fn page_flips_follow_vertical_retrace_at_about_60_hz() {
    let mut qemu = boot_bios(Some("flip-rate"));
    let console = qemu.wait_for_serial("wait timeouts", BOOT_TIMEOUT).unwrap();
    let line = console
        .lines()
        .find(|l| l.starts_with("flip-rate:"))
        .expect("a flip-rate line");
    let hertz: f64 = line
        .split(" = ")
        .nth(1)
        .and_then(|rest| rest.split(" Hz").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("cannot read the rate from {line:?}"));
    println!("{line}");
    assert!(
        (50.0..=62.0).contains(&hertz),
        "flip rate {hertz} Hz is not about 60 Hz: {line}"
    );
    assert!(line.ends_with(", 0 wait timeouts"), "{line}");
}
