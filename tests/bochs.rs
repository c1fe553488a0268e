//! The kernel in a second emulator: Bochs 2.7, whose VGA core and VGA BIOSes
//! are not QEMU's. Bochs's window must show, pixel for pixel, what the
//! software VGA shows for the same scene, with Bochs's standard VGA (Bochs
//! VBE and the LGPL VGA BIOS) and with its Cirrus Logic GD5446 (and the
//! Cirrus VGA BIOS); Esc must bring back an 80x25 text screen with the
//! goodbye line. And a low-speed USB keyboard on each of Bochs's own USB
//! host controllers (xHCI, EHCI, OHCI, UHCI; none of them a chip QEMU
//! models) must be heard: the kernel says it has it, and a key typed into
//! the window (which Bochs then sends to the USB keyboard alone) acts.
//!
//! Bochs draws its window from video memory on its own display timer, so
//! after the kernel reports a command done the tests wait for the window to
//! show the expected picture (and fail with the differences when it never
//! does); they never wait for a fixed time.

mod common;

use boot::bochs::{Bochs, BochsError, BochsOptions, BochsUsbHost, UsbKeyboard, VgaExtension};
use boot::line;
use boot::RgbImage;
use common::{soft_vga_in_mode_x, PIXELS};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use modex::soft::SoftVga;
use modex::ModeX;
use std::time::{Duration, Instant};

/// From Bochs's start to `screen: ready`: BIOS, bootloader, kernel set-up.
const BOOT_TIMEOUT: Duration = Duration::from_secs(60);
/// From a key to the kernel's line saying it has drawn its answer.
const KEY_TIMEOUT: Duration = Duration::from_secs(20);
/// From that line to the window showing the answer: Bochs redraws the window
/// 10 times an emulated second.
const SCREEN_TIMEOUT: Duration = Duration::from_secs(10);

/// Bochs 2.7 shows Mode X at 640x480: its renderer (iodev/display/vgacore.cc,
/// the 256-colour byte-mode path) fetches pixel x / 2 of scan line y / 2
/// (doubled because Maximum Scan Line's bit 7 or low bits are set), so every
/// Mode X pixel is a 2x2 block, as in QEMU.
const BOCHS_MODE_X_SIZE: (usize, usize) = (640, 480);
/// Bochs's 80x25 text screen: 9-dot character cells, 16 scan lines a row.
const BOCHS_TEXT_SIZE: (usize, usize) = (720, 400);

/// How Bochs widens the DAC's 6-bit components to the 8 bits of its window:
/// `component << 2` (vgacore.cc writes `pel.data[i].red << dac_shift` with
/// `dac_shift` 2 to the display library, whose X colours are exact on a
/// 24-bit visual). QEMU instead copies the low bit into the two new bits
/// (`modex::soft::dac_6_to_8`), so QEMU's 63 is 255 where Bochs's is 252.
/// The Bochs text screens seen while writing these tests agree: light cyan
/// (21, 63, 63) is (84, 252, 252).
fn bochs_dac_6_to_8(component: u8) -> u8 {
    (component & 0x3F) << 2
}

/// The model's picture as Bochs shows it: each pixel's DAC entry, widened as
/// Bochs widens it, at the model's 320x240.
fn bochs_view_of(soft: &SoftVga) -> RgbImage {
    // Bochs's byte-mode renderer hands the pixel byte straight to the display
    // library, without the DAC's pixel mask; the kernel leaves the mask at
    // 0xFF, so the mask cannot make a difference that this would hide.
    assert_eq!(soft.dac_pixel_mask(), 0xFF, "the model's DAC mask");
    assert!(soft.video_enabled(), "the model's screen is blanked");
    let mut indices = vec![0u8; PIXELS];
    let (width, height) = soft.scanout_indices(&mut indices);
    assert_eq!((width, height), (320, 240), "the model is not in Mode X");
    let pixels = indices
        .iter()
        .map(|&index| soft.dac_entry(index).map(bochs_dac_6_to_8))
        .collect();
    RgbImage::new(width, height, pixels)
}

/// Why Bochs's picture is not `expected` (320x240), or `None` if it is.
fn mode_x_mismatch(shown: &RgbImage, expected: &RgbImage) -> Option<String> {
    if (shown.width, shown.height) != BOCHS_MODE_X_SIZE {
        return Some(format!(
            "Bochs shows {}x{}, not Mode X at {}x{}",
            shown.width, shown.height, BOCHS_MODE_X_SIZE.0, BOCHS_MODE_X_SIZE.1
        ));
    }
    let halved = match shown.halve() {
        Ok(halved) => halved,
        Err(e) => {
            // Still say how far the picture is from the model: its top-left
            // pixel of each 2x2 block against the model's pixel.
            let sampled = (0..expected.height)
                .flat_map(|y| (0..expected.width).map(move |x| (x, y)))
                .filter(|&(x, y)| shown.pixel(2 * x, 2 * y) != expected.pixel(x, y))
                .count();
            return Some(format!(
                "Bochs's picture is not doubled Mode X ({e}), and the top-left pixels of \
                 {sampled} of its {} 2x2 blocks differ from the model",
                expected.pixels.len()
            ));
        }
    };
    match halved.differences(expected) {
        Ok(differences) if differences.is_empty() => None,
        Ok(differences) => Some(format!(
            "{} pixels differ, first (x, y, bochs, model): {:?}",
            differences.len(),
            &differences[..differences.len().min(5)]
        )),
        Err(e) => Some(e.to_string()),
    }
}

/// Saves what Bochs showed and what was expected beside the disk images.
fn save_pictures(name: &str, shown: &RgbImage, expected: &RgbImage) -> String {
    let dir = boot::images::images_dir();
    let _ = shown.write_png(&dir.join(format!("{name}-bochs.png")));
    let _ = expected.write_png(&dir.join(format!("{name}-model.png")));
    format!("pictures in {}", dir.display())
}

/// The error, and where the whole window it last saw is saved, if it has one.
fn with_window_saved(error: BochsError, name: &str) -> String {
    match &error {
        BochsError::NoGuestPicture {
            window: Some(window),
            ..
        } => {
            let path = boot::images::images_dir().join(format!("{name}-window.png"));
            let _ = window.write_png(&path);
            format!("{error}; the window is in {}", path.display())
        }
        _ => error.to_string(),
    }
}

fn boot(vga: VgaExtension, usb_keyboard: Option<UsbKeyboard>) -> Bochs {
    let images = boot::images::publish().expect("the build script made the images");
    // The one image (GPT with a hybrid MBR): Bochs's BIOS boots its MBR.
    let mut options = BochsOptions::new(images.hybrid, vga);
    options.usb_keyboard = usb_keyboard;
    Bochs::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

fn wait_for_serial(bochs: &mut Bochs, needle: &str, timeout: Duration) {
    let started = Instant::now();
    bochs
        .wait_for_serial(needle, timeout)
        .unwrap_or_else(|e| panic!("{e}"));
    println!("{needle:?} after {:.1?}", started.elapsed());
}

/// Boots, presses R (back to the start position, spin off), compares the
/// picture with the software VGA's, then presses Esc and checks the
/// goodbye screen.
fn picture_and_goodbye(vga: VgaExtension) {
    let name = format!("bochs-{vga:?}").to_lowercase();
    let started = Instant::now();
    let mut bochs = boot(vga, None);
    wait_for_serial(&mut bochs, boot::READY_LINE, BOOT_TIMEOUT);
    // Each of Bochs's VGA BIOSes (the LGPL VGABIOS with VBE, and its Cirrus
    // build) takes the kernel out of the bootloader's VESA mode by itself.
    let console = bochs.serial();
    for line in [
        "vga: mode 13h set by the video BIOS, then tweaked",
        "vga: Mode X 320x240 set, registers read back as written",
    ] {
        assert!(
            console.contains(line),
            "{name}: no {line:?} on serial:\n{console}"
        );
    }

    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    bochs.send_key("r").unwrap_or_else(|e| panic!("{e}"));
    wait_for_serial(&mut bochs, &line::CommandDone(1).to_string(), KEY_TIMEOUT);
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let expected = bochs_view_of(&soft);

    let shown_at = Instant::now();
    match bochs.wait_for_screen(SCREEN_TIMEOUT, |shown| {
        mode_x_mismatch(shown, &expected).is_none()
    }) {
        Ok(_) => println!("{name}: the picture after R matches after {:.1?}", shown_at.elapsed()),
        Err(BochsError::ScreenTimeout { waited, last }) => panic!(
            "{name}: after R and {waited:?}, Bochs's window still differs from the software VGA: {}; {}; serial:\n{}",
            mode_x_mismatch(&last, &expected).unwrap_or_default(),
            save_pictures(&format!("{name}-after-r"), &last, &expected),
            bochs.serial()
        ),
        Err(e) => panic!("{name}: {}", with_window_saved(e, &format!("{name}-after-r"))),
    }

    bochs.send_key("Escape").unwrap_or_else(|e| panic!("{e}"));
    wait_for_serial(&mut bochs, line::GOODBYE, KEY_TIMEOUT);
    let shown_at = Instant::now();
    match bochs.wait_for_screen(SCREEN_TIMEOUT, |shown| goodbye_mismatch(shown).is_none()) {
        Ok(_) => println!("{name}: the goodbye screen is shown after {:.1?}", shown_at.elapsed()),
        Err(BochsError::ScreenTimeout { waited, last }) => panic!(
            "{name}: {waited:?} after the goodbye line on serial, the window is not the goodbye screen: {}",
            goodbye_mismatch(&last).unwrap_or_default()
        ),
        Err(e) => panic!(
            "{name}: {}{}",
            with_window_saved(e, &format!("{name}-goodbye")),
            bochs.diagnostics()
        ),
    }
    println!("{name}: passed in {:.1?}", started.elapsed());
}

/// Why `shown` is not the goodbye screen, or `None` if it is: 80x25 text
/// with the goodbye line, white on black, centred on row 12 (see
/// kernel/src/goodbye.rs), and every other cell blank in one colour.
///
/// That colour is black on QEMU and on a real VGA, but green on Bochs 2.7:
/// Bochs does not model odd/even addressing. It writes every CPU byte to the
/// planes the Map Mask enables, at the same offset, and draws text from
/// plane 0 read as interleaved character and attribute bytes. The kernel
/// clears the screen with the Map Mask on plane 0 for the characters (0x20)
/// and then on plane 1 for the attributes (0x07), so on Bochs every
/// attribute byte is 0x20 too: black on green. The goodbye line itself is
/// written with both planes enabled, which Bochs shows correctly.
fn goodbye_mismatch(shown: &RgbImage) -> Option<String> {
    const MESSAGE_LEN: usize = "modex-cube: goodbye. The machine can be switched off.".len();
    const ROW: usize = 12;
    const CELL: (usize, usize) = (9, 16);
    const BLACK: [u8; 3] = [0; 3];
    /// Attribute 0x0F: bright white, DAC (63, 63, 63), on black.
    const WHITE: [u8; 3] = [252; 3];
    if (shown.width, shown.height) != BOCHS_TEXT_SIZE {
        return Some(format!("Bochs shows {shown:?}, not 80x25 text at 720x400"));
    }
    let first_column = (80 - MESSAGE_LEN) / 2;
    let columns = first_column * CELL.0..(first_column + MESSAGE_LEN) * CELL.0;
    let rows = ROW * CELL.1..(ROW + 1) * CELL.1;
    let blank = shown.pixel(0, 0);
    let mut lit = 0;
    for y in 0..shown.height {
        for x in 0..shown.width {
            let pixel = shown.pixel(x, y);
            let in_line = columns.contains(&x) && rows.contains(&y);
            match pixel {
                WHITE if in_line => lit += 1,
                BLACK if in_line => {}
                _ if !in_line && pixel == blank => {}
                _ => return Some(format!("pixel ({x}, {y}) is {pixel:?}")),
            }
        }
    }
    // Every glyph of the line lights some pixels; a blank line lights none.
    (lit < MESSAGE_LEN).then(|| format!("only {lit} pixels of the goodbye line are lit"))
}

#[test]
fn bochs_vbe_shows_the_software_vga_picture_and_says_goodbye() {
    picture_and_goodbye(VgaExtension::Vbe);
}

#[test]
fn bochs_cirrus_shows_the_software_vga_picture_and_says_goodbye() {
    picture_and_goodbye(VgaExtension::Cirrus);
}

/// Boots with a low-speed keyboard on `host`'s first port that takes one;
/// by the ready line the kernel must have found it at boot on a controller
/// of kind `heard_on` (an EHCI hands a low-speed device to its UHCI
/// companion) at that port, and nothing else. Then R and Esc pressed on it
/// must each act, with no byte from the PS/2 keyboard: Bochs sends the
/// window's keys to the USB keyboard alone once one is attached.
fn low_speed_keyboard_heard(host: BochsUsbHost, heard_on: &str) {
    let started = Instant::now();
    let port = host.first_low_speed_port();
    let mut bochs = boot(VgaExtension::Vbe, Some(UsbKeyboard { host, port }));
    wait_for_serial(&mut bochs, boot::READY_LINE, BOOT_TIMEOUT);
    let console = bochs.serial();
    let mut expected = line::UsbKeyboards::default();
    expected.on[line::usb_host_index(heard_on).expect("a USB host kind")] = 1;
    let found_at_boot = console
        .lines()
        .find_map(|text| line::UsbKeyboards::parse(text.strip_prefix(line::MACHINE_FACT)?));
    assert_eq!(
        found_at_boot,
        Some(expected),
        "{host:?}: the USB keyboards found at boot; serial:\n{console}"
    );
    let keyboards: Vec<_> = console
        .lines()
        .filter_map(line::UsbKeyboardOn::parse)
        .map(|on| (on.kind, on.location))
        .collect();
    assert_eq!(
        keyboards,
        [(heard_on, port.to_string().as_str())],
        "{host:?}: where the kernel has keyboards; serial:\n{console}"
    );
    // Bochs gave it the speed asked for, and the kernel addressed it so.
    let enumerated = format!("usb: {heard_on} port {port}: enumerated in ");
    assert!(
        console
            .lines()
            .any(|text| text.starts_with(&enumerated) && text.contains(" us at low speed, ")),
        "{host:?}: no low-speed enumeration on {heard_on} port {port}; serial:\n{console}"
    );
    bochs.send_key("r").unwrap_or_else(|e| panic!("{e}"));
    wait_for_serial(&mut bochs, &line::CommandDone(1).to_string(), KEY_TIMEOUT);
    bochs.send_key("Escape").unwrap_or_else(|e| panic!("{e}"));
    wait_for_serial(&mut bochs, line::GOODBYE, KEY_TIMEOUT);
    // Said before the goodbye: no key came by PS/2.
    let console = bochs.serial();
    assert!(
        console.contains("ps2: 0 keyboard bytes taken by IRQ 1, 0 by the poll"),
        "{host:?}: keys came by PS/2 too; serial:\n{console}"
    );
    println!("{host:?}: passed in {:.1?}", started.elapsed());
}

#[test]
fn bochs_xhci_hears_a_low_speed_keyboard() {
    low_speed_keyboard_heard(BochsUsbHost::Xhci, "xhci");
}

#[test]
fn bochs_ehci_hands_a_low_speed_keyboard_to_its_companion() {
    low_speed_keyboard_heard(BochsUsbHost::Ehci, "uhci");
}

#[test]
fn bochs_ohci_hears_a_low_speed_keyboard() {
    low_speed_keyboard_heard(BochsUsbHost::Ohci, "ohci");
}

#[test]
fn bochs_uhci_hears_a_low_speed_keyboard() {
    low_speed_keyboard_heard(BochsUsbHost::Uhci, "uhci");
}
