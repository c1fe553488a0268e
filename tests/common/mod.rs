//! What the integration tests share: booting the one image under SeaBIOS,
//! the software VGA's picture, and comparing it with QEMU's.

#![allow(dead_code)] // each test binary uses its own part of this

use boot::line;
use boot::BootOption;
use boot::{Board, Graphics, Qemu, QemuOptions, RgbImage};
use demo::app::App;
use demo::command::{Axis, Command, SceneCommand, Sense};
use modex::soft::SoftVga;
use modex::{ModeX, Page, SCREEN_HEIGHT, SCREEN_WIDTH};
use std::time::Duration;

/// A key's command that turns the object: key tables stay one line a key.
pub const fn turn(axis: Axis, sense: Sense) -> Command {
    Command::Scene(SceneCommand::Rotate(axis, sense))
}

/// From the starting scene, the cube still and turned so that three faces
/// show: the keys and the commands they stand for.
pub const TURNED: [(&str, Command); 7] = [
    ("r", Command::Scene(SceneCommand::Reset)),
    ("6", turn(Axis::Y, Sense::Positive)),
    ("6", turn(Axis::Y, Sense::Positive)),
    ("6", turn(Axis::Y, Sense::Positive)),
    ("6", turn(Axis::Y, Sense::Positive)),
    ("8", turn(Axis::X, Sense::Negative)),
    ("8", turn(Axis::X, Sense::Negative)),
];

/// Proptest's settings: `default_cases` cases, or as many as the
/// `PROPTEST_CASES` environment variable asks for, from a fixed seed so that
/// every run tries the same cases (a longer hunt with more cases still finds
/// new ones, and reproduces them).
pub fn proptest_config(default_cases: u32) -> proptest::prelude::ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_cases);
    proptest::prelude::ProptestConfig {
        cases,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5EED_CA5E),
        ..proptest::prelude::ProptestConfig::default()
    }
}

pub const BOOT_TIMEOUT: Duration = Duration::from_secs(60);
pub const PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;

/// Boots the one image (`modex-cube.img`, GPT with a hybrid MBR) under
/// SeaBIOS, headless, with an optional boot option.
pub fn boot_bios(option: Option<BootOption>) -> Qemu {
    boot_bios_on(Graphics::StdVga, option)
}

/// Boots the one image under SeaBIOS headless on a display adapter, with an
/// optional boot option.
pub fn boot_bios_on(graphics: Graphics, option: Option<BootOption>) -> Qemu {
    boot_bios_on_board(Board::PC, graphics, option)
}

/// Boots the one image under SeaBIOS headless on a board and a display
/// adapter, with an optional boot option.
pub fn boot_bios_on_board(board: Board, graphics: Graphics, option: Option<BootOption>) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.board = board;
    options.graphics = graphics;
    options.boot.option = option;
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
    assert_pictures_equal(&halved, model, what);
}

/// Two pictures of one size must be equal; if not, both are saved as PNGs
/// beside the images and the first differences are reported.
pub fn assert_pictures_equal(qemu_picture: &RgbImage, model: &RgbImage, what: &str) {
    let differences = qemu_picture
        .differences(model)
        .unwrap_or_else(|e| panic!("{what}: {e}"));
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

/// The software VGA's picture after the kernel's test-pattern sequence: both
/// pages drawn, page 0 shown, then `flips` flips.
pub fn pattern_picture(flips: u8) -> RgbImage {
    let mut soft = soft_vga_in_mode_x();
    let mut vga = ModeX::new(&mut *soft);
    demo::pattern::draw(&mut vga, Page::Zero);
    demo::pattern::draw(&mut vga, Page::One);
    vga.show_page(Page::Zero);
    for flip in 1..=flips {
        vga.show_page(Page::ALL[usize::from(flip % 2)]);
    }
    model_picture(&soft)
}

/// Boots the BIOS image, then for each key: sends it to QEMU, waits until the
/// kernel has drawn it, applies the same command to a model app on the
/// software VGA, and hands QEMU's screendump, the model's picture and the
/// model app to `compare`.
pub fn after_each_key(
    keys: &[(&str, Command)],
    compare: impl Fn(&RgbImage, &RgbImage, &App, &str),
) {
    let mut qemu = boot_bios(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    after_each_key_on(&mut qemu, keys, compare);
}

/// As [`after_each_key`], on a QEMU already booted to the ready line.
pub fn after_each_key_on(
    qemu: &mut Qemu,
    keys: &[(&str, Command)],
    compare: impl Fn(&RgbImage, &RgbImage, &App, &str),
) {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    for (n, &(key, command)) in keys.iter().enumerate() {
        qemu.send_key(key).unwrap();
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
        app.apply(command);
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        let what = format!("after key {} ({key})", n + 1);
        compare(
            &qemu.screendump().unwrap(),
            &model_picture(&soft),
            &app,
            &what,
        );
    }
}
