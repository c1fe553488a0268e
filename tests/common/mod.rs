//! What the integration tests share: booting the BIOS image, the software
//! VGA's picture, and comparing it with QEMU's.

#![allow(dead_code)] // each test binary uses its own part of this

use boot::{Qemu, QemuOptions, RgbImage};
use modex::soft::SoftVga;
use modex::{ModeX, SCREEN_HEIGHT, SCREEN_WIDTH};
use std::time::Duration;

pub const BOOT_TIMEOUT: Duration = Duration::from_secs(60);
pub const PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;

/// Boots the BIOS image headless, with an optional boot option.
pub fn boot_bios(option: Option<&str>) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.bios);
    options.boot_option = option.map(str::to_owned);
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

/// A software VGA already in Mode X, boxed (it holds 256 KiB of planes).
pub fn soft_vga_in_mode_x() -> Box<SoftVga> {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    soft
}

/// The model's displayed picture, as RGB.
pub fn model_picture(soft: &SoftVga) -> RgbImage {
    let mut rgb = vec![[0u8; 3]; PIXELS];
    let (width, height) = soft.scanout_rgb(&mut rgb);
    assert_eq!(
        (width, height),
        (320, 240),
        "the model is not showing 320x240"
    );
    RgbImage::new(width, height, rgb)
}

/// QEMU's 640x480 picture of Mode X must be the model's 320x240, doubled.
pub fn assert_same_picture(qemu_picture: &RgbImage, model: &RgbImage, what: &str) {
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
        let name = what.replace(|c: char| !c.is_ascii_alphanumeric(), "-");
        let _ = qemu_picture.write_png(&dir.join(format!("{name}-qemu.png")));
        let _ = model.write_png(&dir.join(format!("{name}-model.png")));
        panic!(
            "{what}: {} pixels differ, first (x, y, qemu, model): {:?}; pictures in {}",
            differences.len(),
            &differences[..differences.len().min(5)],
            dir.display()
        );
    }
}
