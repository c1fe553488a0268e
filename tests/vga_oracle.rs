//! The oracle nobody here wrote: QEMU's own VGA emulation. The kernel draws the
//! Mode X test pattern on the real (emulated) registers; the same drawing code
//! runs against the software VGA on the host; QEMU's screendump (640x480, each
//! Mode X pixel doubled) must equal the model's scan-out pixel for pixel.

use boot::{Qemu, QemuOptions, RgbImage};
use modex::soft::SoftVga;
use modex::{ModeX, Page};
use std::time::Duration;

const BOOT_TIMEOUT: Duration = Duration::from_secs(60);

fn boot(option: &str) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.bios);
    options.boot_option = Some(option.to_owned());
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

/// The software VGA's picture after the kernel's test-pattern sequence.
fn model_picture(flips: u8) -> RgbImage {
    let mut soft = Box::new(SoftVga::new());
    let mut vga = ModeX::new(&mut *soft);
    vga.set_mode();
    demo::pattern::draw(&mut vga, Page(0));
    demo::pattern::draw(&mut vga, Page(1));
    vga.show_page(Page(0));
    for flip in 1..=flips {
        vga.show_page(Page(flip % 2));
    }
    let mut rgb = vec![[0u8; 3]; 320 * 240];
    let (width, height) = soft.scanout_rgb(&mut rgb);
    assert_eq!((width, height), (320, 240), "the model is not in 320x240");
    RgbImage::new(width, height, rgb)
}

fn assert_same_picture(qemu_picture: &RgbImage, model: &RgbImage, what: &str) {
    assert_eq!(
        (qemu_picture.width, qemu_picture.height),
        (640, 480),
        "{what}: QEMU is not showing 640x480"
    );
    let halved = qemu_picture
        .halve()
        .unwrap_or_else(|e| panic!("{what}: {e}"));
    let differences = halved.differences(model).unwrap();
    if !differences.is_empty() {
        let dir = boot::images::images_dir();
        let _ = qemu_picture.write_png(&dir.join("oracle-qemu.png"));
        let _ = model.write_png(&dir.join("oracle-model.png"));
        panic!(
            "{what}: {} pixels differ, first (x, y, qemu, model): {:?}; pictures in {}",
            differences.len(),
            &differences[..differences.len().min(5)],
            dir.display()
        );
    }
}

#[test]
fn qemu_shows_what_the_software_vga_shows_for_the_test_pattern_on_both_pages() {
    let mut qemu = boot("test-pattern");
    qemu.wait_for_serial("pattern: page 0 shown", BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(&qemu.screendump().unwrap(), &model_picture(0), "page 0");

    qemu.send_key("spc").unwrap();
    qemu.wait_for_serial("pattern: page 1 shown", BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &model_picture(1),
        "page 1 after a flip",
    );

    qemu.send_key("spc").unwrap();
    qemu.wait_for_serial_count("pattern: page 0 shown", 2, BOOT_TIMEOUT)
        .unwrap();
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &model_picture(2),
        "page 0 after flipping back",
    );
}

/// With `-vga std,retrace=precise` QEMU times Input Status 1 from the CRTC
/// values, so page flips locked to vertical retrace run at the refresh rate.
#[test]
fn page_flips_follow_vertical_retrace_at_about_60_hz() {
    let mut qemu = boot("flip-rate");
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
