//! What the integration tests share: booting the one image under SeaBIOS,
//! the software VGA's picture, and comparing it with QEMU's.

#![allow(dead_code)] // each test binary uses its own part of this

use boot::line;
use boot::BootOption;
use boot::{Board, Graphics, Qemu, QemuOptions, RgbImage};
use demo::app::App;
use demo::command::{Axis, Command, SceneCommand, Sense};
use modex::present::{present_rgb, FramebufferLayout, PixelOrder};
use modex::soft::SoftVga;
use modex::{ModeX, Page, SCREEN_HEIGHT, SCREEN_WIDTH};
use std::time::Duration;

pub mod flood;

#[path = "../../demo/tests/common/fuzzing.rs"]
mod fuzzing;
#[allow(unused_imports)] // each test binary uses its own part of this
pub use fuzzing::{proptest_config, soft_vga_in_mode_x};

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

/// The cube test's keys: from the starting scene, turns about Y and X, away,
/// a turn about Z, a move left.
pub const CUBE_KEYS: [(&str, Command); 10] = [
    ("r", Command::Scene(SceneCommand::Reset)),
    ("4", turn(Axis::Y, Sense::Negative)),
    ("4", turn(Axis::Y, Sense::Negative)),
    ("4", turn(Axis::Y, Sense::Negative)),
    ("8", turn(Axis::X, Sense::Negative)),
    ("8", turn(Axis::X, Sense::Negative)),
    ("a", Command::Scene(SceneCommand::Away)),
    ("a", Command::Scene(SceneCommand::Away)),
    ("f1", turn(Axis::Z, Sense::Positive)),
    ("left", Command::Scene(SceneCommand::MoveLeft)),
];

/// The budget of each wait on QEMU: how much CPU time QEMU may use without
/// a new line on serial (`boot::qemu`'s watchdog), so a busy host, which
/// gives QEMU less of the CPU, stretches it. Idle, a SeaBIOS boot reaches the
/// ready line in about 1.5 s (the kernel's first line at 1.2 s), OVMF in 4 s.
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

/// The model's text picture, as RGB.
pub fn text_picture(soft: &SoftVga) -> RgbImage {
    let mut rgb = vec![[0u8; 3]; 720 * 400];
    let (width, height) = soft.scanout_rgb(&mut rgb);
    assert!(
        matches!((width, height), (720 | 640, 400)),
        "the model is not in 80x25 text: {width}x{height}"
    );
    rgb.truncate(width * height);
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

/// A picture (320x240 Mode X, or 720x400 text) presented as the kernel
/// presents the software VGA onto a `width` x `height` screen, read back as RGB.
pub fn presented(picture: &RgbImage, width: usize, height: usize) -> RgbImage {
    let layout = FramebufferLayout {
        width,
        height,
        stride: width,
        bytes_per_pixel: 3,
        order: PixelOrder::Rgb,
    };
    let mut bytes = vec![0; layout.required_bytes()];
    present_rgb(
        &picture.pixels,
        (picture.width, picture.height),
        &layout,
        &mut bytes,
    );
    let pixels = bytes.as_chunks::<3>().0.to_vec();
    RgbImage::new(width, height, pixels)
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

/// Esc on a framebuffer boot run with `keep_after_power_off`: the kernel
/// says goodbye, then switches the machine off through ACPI, and the screen
/// QEMU kept must be the goodbye line, presented as the kernel presents it.
pub fn escape_leaves_the_goodbye_on_the_framebuffer(qemu: &mut Qemu, what: &str) {
    qemu.send_key("esc").unwrap();
    qemu.wait_powered_off(BOOT_TIMEOUT).unwrap();
    let screen = qemu.screendump().unwrap();
    let mut soft = soft_vga_in_mode_x();
    demo::screens::goodbye(&mut ModeX::new(&mut *soft));
    let expected = presented(&text_picture(&soft), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, what);
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

/// Sends key events to the USB keyboard bound to `display` and waits until
/// the demo has acted on `commands` more keys than `done`; returns the new
/// count.
pub fn send_and_wait_on(
    qemu: &mut Qemu,
    display: &str,
    events: &[(&str, bool)],
    done: u64,
    commands: u64,
) -> u64 {
    qemu.key_events_on(display, events).unwrap();
    let target = done + commands;
    qemu.wait_for_serial(&line::CommandDone(target).to_string(), BOOT_TIMEOUT)
        .unwrap();
    target
}

/// On a QEMU at the ready line with no command done yet: each of `keys`
/// pressed on the USB keyboard bound to `display`, waited for, and the
/// screen handed to `compare` with the software VGA's picture after the
/// same commands (320x240, as the model shows it). Returns the commands done.
pub fn usb_keys_match_the_software_vga(
    qemu: &mut Qemu,
    display: &str,
    keys: &[(&str, Command)],
    compare: impl Fn(&RgbImage, &RgbImage, &str),
) -> u64 {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    let mut done = 0;
    for (n, &(key, command)) in keys.iter().enumerate() {
        done = send_and_wait_on(qemu, display, &[(key, true), (key, false)], done, 1);
        app.apply(command);
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        let screen = qemu.screendump().unwrap();
        compare(
            &screen,
            &model_picture(&soft),
            &format!("usb key {} ({key})", n + 1),
        );
    }
    done
}

/// A framebuffer's screen must be the model's picture as the kernel
/// presents it.
pub fn assert_presented(screen: &RgbImage, model: &RgbImage, what: &str) {
    let expected = presented(model, screen.width, screen.height);
    assert_pictures_equal(screen, &expected, what);
}

/// The screen after a key, by how the machine booted: by BIOS the VGA's own
/// Mode X picture, by UEFI the model's picture as presented into the
/// firmware's framebuffer.
#[allow(dead_code)] // not every test file boots both ways
pub fn assert_cube_picture(
    firmware: boot::Firmware,
    screen: &RgbImage,
    model: &RgbImage,
    what: &str,
) {
    match firmware {
        boot::Firmware::Bios => assert_same_picture(screen, model, what),
        boot::Firmware::Uefi | boot::Firmware::Uefi32 => assert_presented(screen, model, what),
    }
}

/// A PC of today: no i8042, and no PIT either (recent Intel platforms gate
/// its clock), so the kernel idles without `hlt` and polls.
pub const Q35_WITHOUT_PS2: Board = Board {
    chipset: boot::Chipset::Q35,
    pit: false,
    i8042: false,
    hpet: true,
};

/// Esc pressed on the USB keyboard bound to `display`, on a machine without
/// isa-debug-exit (a real PC's way out): QEMU must exit with 0 after the
/// goodbye, and the log must show the xHCI halted and reset (its ports
/// switched off) before ACPI S5's SLP_EN, as Linux's shutdown path does.
pub fn usb_escape_powers_off_with_the_xhci_halted_first(
    qemu: &mut Qemu,
    display: &str,
    budget: Duration,
) {
    qemu.press_key_on(display, "esc").unwrap();
    let status = qemu
        .wait_exit(budget)
        .unwrap()
        .unwrap_or_else(|| panic!("still running after Esc:\n{}", qemu.serial()));
    let console = qemu.serial();
    let halted = console
        .find("usb: xHCI 1b36:000d at ")
        .and_then(|_| console.find(" halted and reset, ports switched off"))
        .unwrap_or_else(|| panic!("the xHCI was not shut down:\n{console}"));
    let switching_off = console
        .find("power: switching off (ACPI S5")
        .unwrap_or_else(|| panic!("no ACPI S5:\n{console}"));
    assert!(
        halted < switching_off,
        "the xHCI is shut down before SLP_EN:\n{console}"
    );
    assert!(console.contains(line::GOODBYE), "{console}");
    assert_eq!(status.code(), Some(0), "{console}");
}

/// The report screen as the kernel said it drew it (the lines after `from`
/// in `console`): its facts, its log window, where the window is.
pub struct ShownReport {
    pub facts: Vec<String>,
    pub log: Vec<String>,
    pub position: demo::report::LogPosition,
}

impl ShownReport {
    pub fn parse(console: &str) -> ShownReport {
        let mut facts = Vec::new();
        let mut log = Vec::new();
        let mut position = None;
        for text in console.lines() {
            if let Some(fact) = text.strip_prefix(line::REPORT_FACT) {
                facts.push(fact.to_owned());
            } else if let Some(text) = text.strip_prefix(line::REPORT_LOG) {
                log.push(text.to_owned());
            } else if let Some(shown) = line::ReportShown::parse(text) {
                position = Some(demo::report::LogPosition {
                    first: shown.first,
                    last: shown.last,
                    total: shown.total,
                });
            }
        }
        let position = position.unwrap_or_else(|| panic!("no report shown:\n{console}"));
        ShownReport {
            facts,
            log,
            position,
        }
    }

    pub fn with_report<T>(&self, use_report: impl FnOnce(&demo::report::Report) -> T) -> T {
        let facts: Vec<&str> = self.facts.iter().map(String::as_str).collect();
        let log: Vec<&str> = self.log.iter().map(String::as_str).collect();
        use_report(&demo::report::Report {
            facts: &facts,
            log: &log,
            position: self.position,
        })
    }

    /// The report drawn by `demo::report` on a software VGA in Mode X.
    pub fn picture(&self) -> RgbImage {
        let mut soft = soft_vga_in_mode_x();
        let mut image = Box::new([0u8; modex::PAGE_PIXELS]);
        self.with_report(|report| {
            demo::report::show(&mut ModeX::new(&mut *soft), &mut image, report)
        });
        model_picture(&soft)
    }

    /// The text its QR code must hold.
    pub fn qr_text(&self) -> String {
        let mut text = [0u8; demo::report::QR_TEXT_BYTES];
        let len = self.with_report(|report| demo::report::qr_text(report, &mut text));
        String::from_utf8(text[..len].to_vec()).expect("the report is ASCII")
    }
}

/// The texts of every QR code in `picture`, decoded by `rqrr` after scaling
/// the picture up (nearest neighbour) until it is at least 1200 pixels wide,
/// as a phone's camera sees a screen's pixels as large squares.
pub fn decode_qr_codes(picture: &RgbImage) -> Vec<String> {
    let scale = 1200usize.div_ceil(picture.width).max(1);
    let (width, height) = (picture.width * scale, picture.height * scale);
    let mut prepared = rqrr::PreparedImage::prepare_from_greyscale(width, height, |x, y| {
        let [r, g, b] = picture.pixel(x / scale, y / scale);
        ((u32::from(r) + u32::from(g) + u32::from(b)) / 3) as u8
    });
    prepared
        .detect_grids()
        .iter()
        .map(|grid| match grid.decode() {
            Ok((_, text)) => text,
            Err(e) => panic!("a QR code that does not decode: {e:?}"),
        })
        .collect()
}

/// The git commit the tests (and so the kernel) were built from, as the
/// kernel's build script names it.
pub fn git_commit() -> String {
    // Read by the build script when the kernel was built, so a commit made
    // while the tests run does not count.
    env!("KERNEL_COMMIT").to_owned()
}

/// The report key, on a kernel that has done `commands_done` commands with
/// a still picture on screen: the report must appear as `demo::report`
/// draws what the kernel said it shows (`on_screen` turns the model's
/// 320x240 picture into the screen's), its QR code must decode to the
/// report's text, its facts must name `firmware`, the commit and the CPU,
/// its log lines must be lines the kernel printed; Up must scroll the log
/// back a line; the key again must bring back the picture from before.
/// Three commands.
pub fn report_round_trip(
    qemu: &mut Qemu,
    commands_done: u64,
    firmware: &str,
    on_screen: impl Fn(&RgbImage, &RgbImage) -> RgbImage,
) {
    let before = qemu.screendump().unwrap();
    let printed_before = qemu.serial();
    qemu.send_key("i").unwrap();
    let done = line::CommandDone(commands_done + 1).to_string();
    let console = qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    let screen = qemu.screendump().unwrap();
    let shown = ShownReport::parse(&console[printed_before.len()..]);

    let expected = on_screen(&shown.picture(), &screen);
    assert_pictures_equal(&screen, &expected, "the report screen");

    let codes = decode_qr_codes(&screen);
    assert_eq!(codes, [shown.qr_text()], "the QR code holds the report");

    let facts = shown.facts.join("\n");
    assert!(
        shown.facts[0].ends_with(&format!("commit {}", git_commit())),
        "{facts}"
    );
    let cpu = shown
        .facts
        .iter()
        .find(|fact| fact.starts_with("cpu: "))
        .unwrap_or_else(|| panic!("no CPU: {facts}"));
    assert!(
        cpu.starts_with("cpu: AuthenticAMD, ") || cpu.starts_with("cpu: GenuineIntel, "),
        "{cpu}"
    );
    assert!(facts.contains(&format!("firmware: {firmware}")), "{facts}");
    assert!(facts.contains("adapter: PCI 1234:1111"), "{facts}");
    assert!(facts.contains("clock: "), "{facts}");
    assert!(facts.contains("counters: "), "{facts}");
    assert!(!shown.log.is_empty());
    let printed: Vec<&str> = printed_before.lines().collect();
    for text in &shown.log {
        assert!(
            printed.iter().any(|p| p.starts_with(text.as_str())),
            "{text:?} was never printed"
        );
    }
    // At the bottom of the log: its newest lines, the last one printed.
    assert_eq!(shown.position.last, shown.position.total);
    assert_eq!(
        shown.log.last().map(String::as_str),
        printed.last().copied(),
        "the window ends with the newest line"
    );

    // Up scrolls the log back a line, if it is longer than the window: the
    // window then ends one line before the newest (the command line printed
    // after the report was drawn); a shorter log stays whole.
    let printed_before = qemu.serial();
    qemu.send_key("up").unwrap();
    let done = line::CommandDone(commands_done + 2).to_string();
    let console = qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    let scrolled = ShownReport::parse(&console[printed_before.len()..]);
    let total = scrolled.position.total;
    assert_eq!(total, shown.position.total + 1);
    if total > demo::report::LOG_ROWS {
        assert_eq!(scrolled.position.last, total - 1);
        assert_eq!(scrolled.log.last(), shown.log.last());
    } else {
        assert_eq!(
            (scrolled.position.first, scrolled.position.last),
            (1, total)
        );
    }
    let screen = qemu.screendump().unwrap();
    let expected = on_screen(&scrolled.picture(), &screen);
    assert_pictures_equal(&screen, &expected, "the report scrolled back a line");

    qemu.send_key("i").unwrap();
    let done = line::CommandDone(commands_done + 3).to_string();
    qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    assert_pictures_equal(
        &qemu.screendump().unwrap(),
        &before,
        "the picture after the report",
    );
}

/// `picture` doubled in both directions, as QEMU shows 320x240 Mode X.
pub fn doubled(picture: &RgbImage) -> RgbImage {
    let (width, height) = (picture.width * 2, picture.height * 2);
    let pixels = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| picture.pixel(x / 2, y / 2))
        .collect();
    RgbImage::new(width, height, pixels)
}

/// The disk image `disk` with one bit of one byte in the middle of the
/// kernel file on its ESP flipped: a kernel the loaders must refuse.
#[allow(dead_code)] // used by some test files only
pub fn with_a_kernel_byte_changed(disk: &[u8]) -> Vec<u8> {
    with_a_file_byte_changed(disk, boot::secure_boot::KERNEL_FILE_NAME)
}

/// The disk image `disk` with one bit of one byte in the middle of file
/// `name` on its ESP flipped, as a stick that rots or a firmware that
/// hands back wrong bytes as a good read.
#[allow(dead_code)] // used by some test files only
pub fn with_a_file_byte_changed(disk: &[u8], name: &str) -> Vec<u8> {
    use boot::secure_boot as sb;
    use std::io::{Read, Seek, SeekFrom, Write};
    let mut disk = disk.to_vec();
    let esp_range = {
        let esp = sb::esp_of_disk(&disk).unwrap();
        let start = esp.as_ptr() as usize - disk.as_ptr() as usize;
        start..start + esp.len()
    };
    let mut esp = std::io::Cursor::new(disk[esp_range.clone()].to_vec());
    {
        let fs = fatfs::FileSystem::new(&mut esp, fatfs::FsOptions::new()).unwrap();
        let mut file = fs.root_dir().open_file(name).unwrap();
        let middle = file.seek(SeekFrom::End(0)).unwrap() / 2;
        file.seek(SeekFrom::Start(middle)).unwrap();
        let mut byte = [0u8];
        file.read_exact(&mut byte).unwrap();
        file.seek(SeekFrom::Start(middle)).unwrap();
        file.write_all(&[byte[0] ^ 0x01]).unwrap();
        file.flush().unwrap();
    }
    disk[esp_range].copy_from_slice(&esp.into_inner());
    disk
}

/// Esc (sent by `press_esc`) on a machine without isa-debug-exit: QEMU must
/// exit with 0 after the goodbye, and before ACPI S5's SLP_EN the log must
/// show every USB controller halted (`expected`: how many of each kind, by
/// `line::USB_HOST_KINDS` name), the EHCIs after every other (their
/// CONFIGFLAG hands the ports back to companions that are already halted),
/// as Linux's shutdown path orders it.
pub fn usb_escape_powers_off_with_every_controller_halted_first(
    qemu: &mut Qemu,
    press_esc: impl FnOnce(&mut Qemu),
    expected: &[(&str, usize)],
    budget: Duration,
) {
    press_esc(qemu);
    let status = qemu
        .wait_exit(budget)
        .unwrap()
        .unwrap_or_else(|| panic!("still running after Esc:\n{}", qemu.serial()));
    let console = qemu.serial();
    let lines: Vec<&str> = console.lines().collect();
    let halts: Vec<(usize, line::UsbHalted)> = lines
        .iter()
        .enumerate()
        .filter_map(|(at, text)| Some((at, line::UsbHalted::parse(text)?)))
        .collect();
    for (_, halt) in &halts {
        assert!(halt.halted, "{halt:?} did not halt:\n{console}");
    }
    for &(kind, count) in expected {
        let halted = halts.iter().filter(|(_, halt)| halt.kind == kind).count();
        assert_eq!(halted, count, "{kind} controllers halted:\n{console}");
    }
    assert_eq!(
        halts.len(),
        expected.iter().map(|(_, count)| count).sum::<usize>(),
        "controllers halted:\n{console}"
    );
    let last_other = halts
        .iter()
        .filter(|(_, halt)| halt.kind != "ehci")
        .map(|(at, _)| *at)
        .max();
    let first_ehci = halts
        .iter()
        .filter(|(_, halt)| halt.kind == "ehci")
        .map(|(at, _)| *at)
        .min();
    if let (Some(other), Some(ehci)) = (last_other, first_ehci) {
        assert!(
            other < ehci,
            "an EHCI halted before a companion:\n{console}"
        );
    }
    let switching_off = lines
        .iter()
        .position(|text| text.starts_with("power: switching off (ACPI S5"))
        .unwrap_or_else(|| panic!("no ACPI S5:\n{console}"));
    let last_halt = halts.iter().map(|(at, _)| *at).max().unwrap_or(0);
    assert!(
        last_halt < switching_off,
        "every controller halts before SLP_EN:\n{console}"
    );
    assert!(console.contains(line::GOODBYE), "{console}");
    assert_eq!(status.code(), Some(0), "{console}");
}

/// The kernel's `usb: keyboard on KIND FUNCTION LOCATION` lines so far, as
/// (kind, function, location).
pub fn usb_keyboards_on(console: &str) -> Vec<(String, String, String)> {
    console
        .lines()
        .filter_map(line::UsbKeyboardOn::parse)
        .map(|on| {
            (
                on.kind.to_owned(),
                on.function.to_owned(),
                on.location.to_owned(),
            )
        })
        .collect()
}

/// Each loader line on `console` (COM1) came exactly once (issue 48): under
/// OVMF the UEFI console is copied to COM1, so the loaders write COM1
/// themselves only where it is not. A loader line starts with `loader: `,
/// after any terminal escapes the console's copy puts before it.
#[allow(dead_code)] // used by some test files only
pub fn assert_each_loader_line_once(console: &str) {
    let mut counts = std::collections::BTreeMap::<&str, usize>::new();
    for text in console.lines() {
        let Some(at) = text.find("loader: ") else {
            continue;
        };
        if without_escapes(&text[..at]).is_empty() {
            *counts.entry(text[at..].trim_end()).or_default() += 1;
        }
    }
    assert!(
        counts
            .keys()
            .any(|text| text.starts_with(line::LOADER_START)),
        "no loader line:\n{console}"
    );
    let repeated: Vec<_> = counts.iter().filter(|(_, &count)| count != 1).collect();
    assert!(
        repeated.is_empty(),
        "loader lines more than once on COM1: {repeated:#?}\n{console}"
    );
}

/// `text` without its ANSI escape sequences (ESC [ parameters letter).
fn without_escapes(text: &str) -> String {
    let mut out = String::new();
    let mut chars = text.chars();
    while let Some(c) = chars.next() {
        if c == '\x1b' {
            for c in chars.by_ref() {
                if c.is_ascii_alphabetic() {
                    break;
                }
            }
        } else {
            out.push(c);
        }
    }
    out
}

/// virt-fw-vars, which `boot/setup.sh` installs under `target/tools`.
#[allow(dead_code)] // used by some test files only
pub fn virt_fw_vars() -> std::path::PathBuf {
    boot::secure_boot::virt_fw_vars().unwrap_or_else(|e| panic!("{e}"))
}

/// Runs virt-fw-vars with `args`: what it printed, or a panic with its
/// message.
#[allow(dead_code)] // used by some test files only
pub fn run_virt_fw_vars(args: &[&std::ffi::OsStr]) -> String {
    let result = std::process::Command::new(virt_fw_vars())
        .args(args)
        .output()
        .unwrap();
    assert!(
        result.status.success(),
        "virt-fw-vars {args:?}: {}",
        String::from_utf8_lossy(&result.stderr)
    );
    String::from_utf8_lossy(&result.stdout).into_owned()
}

/// The OVMF variable store `input` with `args` applied by virt-fw-vars,
/// written to `output`.
#[allow(dead_code)] // used by some test files only
pub fn vars_from(
    input: &str,
    output: &std::path::Path,
    args: &[&std::ffi::OsStr],
) -> std::path::PathBuf {
    let mut all: Vec<&std::ffi::OsStr> = vec![
        "--input".as_ref(),
        input.as_ref(),
        "--output".as_ref(),
        output.as_os_str(),
    ];
    all.extend_from_slice(args);
    run_virt_fw_vars(&all);
    output.to_owned()
}

/// After the failure's message: the guest runs on for a second of QEMU's CPU
/// time (or five seconds, if it idles halted), and must still be up with
/// nothing more on serial.
pub fn stays_up_and_quiet(qemu: &mut Qemu, console: &str) {
    let cpu = qemu.cpu_time().expect("QEMU runs");
    let started = std::time::Instant::now();
    while qemu
        .cpu_time()
        .is_some_and(|now| now < cpu + Duration::from_secs(1))
        && started.elapsed() < Duration::from_secs(5)
    {
        std::thread::sleep(Duration::from_millis(50));
    }
    assert!(
        qemu.is_running(),
        "QEMU ended (a reset, with -no-reboot) after the message:\n{}",
        qemu.serial()
    );
    assert_eq!(qemu.serial(), console, "more happened after the message");
}

/// Starts SeaBIOS with one option ROM, which `build` assembles into a
/// scratch directory (`boot::option_rom`), after `configure` has set the
/// rest of the machine; the directory holds the ROM and must outlive QEMU.
pub fn start_with_option_rom(
    build: impl FnOnce(&std::path::Path) -> Result<std::path::PathBuf, String>,
    bootindex: Option<u32>,
    configure: impl FnOnce(&mut QemuOptions),
) -> (Qemu, tempfile::TempDir) {
    let dir = tempfile::Builder::new()
        .prefix("modex-cube-rom-")
        .tempdir()
        .expect("a scratch directory");
    let path = build(dir.path()).unwrap_or_else(|e| panic!("{e}"));
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    configure(&mut options);
    options
        .option_roms
        .push(boot::OptionRom { path, bootindex });
    (Qemu::start(&options).unwrap_or_else(|e| panic!("{e}")), dir)
}

/// The cube test's keys on the PS/2 keyboard give the software VGA's
/// pictures; then [`escape_powers_off`].
pub fn cube_keys_then_escape_powers_off(qemu: &mut Qemu) {
    after_each_key_on(qemu, &CUBE_KEYS, |screen, model, _, what| {
        assert_same_picture(screen, model, what)
    });
    escape_powers_off(qemu);
}

/// Esc says goodbye and powers off with success.
pub fn escape_powers_off(qemu: &mut Qemu) {
    qemu.send_key("esc").unwrap();
    qemu.wait_for_serial(line::GOODBYE, BOOT_TIMEOUT).unwrap();
    let status = qemu.wait_for_exit(BOOT_TIMEOUT).unwrap();
    assert_eq!(
        status.code(),
        Some(boot::qemu::EXIT_SUCCESS),
        "{}",
        qemu.serial()
    );
}
