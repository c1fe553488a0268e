//! `cargo run --release -- [OPTIONS]`: builds the kernel and its disk images
//! (cargo does that through the build script), then boots one in QEMU.

use boot::qemu::{self, Display, Firmware, Graphics, Qemu, QemuOptions};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

const USAGE: &str = "\
Boot the modex-cube kernel in QEMU.

Usage: cargo run --release -- [OPTIONS]

Options:
  --uefi                boot target/images/uefi.img with OVMF instead of the BIOS image
  --headless            no window: the serial console streams to this terminal
  --screenshot FILE     after boot (and --keys) save QEMU's picture as a PNG, then stop
  --keys \"KEYS\"         type these after boot: QEMU key names separated by spaces,
                        e.g. \"r 4 4 kp_8 a f1 left spc esc\"
  --wait SECS           with --screenshot: wait SECS after the keys before taking it
                        (default 0.5), e.g. to let the statistics measure a spin
  --vga ADAPTER         the display adapter QEMU emulates, each with its own VGA BIOS:
                        std (default), cirrus, vmware, qxl, virtio, ati, isa-cirrus,
                        bochs-display (no legacy VGA)
  --timeout SECS        stop QEMU after SECS seconds
  --boot-option OPTION  hand OPTION to the kernel via fw_cfg (see README: test-pattern,
                        flip-rate, bench, fault=...)
  --write-usb DEVICE    instead of booting, write the image (bios.img, or uefi.img with
                        --uefi) to the whole USB stick DEVICE, e.g. /dev/sdb, after checking
                        it is a removable, unmounted disk; shows what will be overwritten
                        and asks you to type its name
  -h, --help            show this help

Without a display (no $DISPLAY or $WAYLAND_DISPLAY) the kernel runs headless.
The images are also written to target/images/bios.img and target/images/uefi.img.";

struct Args {
    firmware: Firmware,
    headless: bool,
    screenshot: Option<PathBuf>,
    keys: Vec<String>,
    timeout: Option<Duration>,
    wait: Duration,
    boot_option: Option<String>,
    write_usb: Option<PathBuf>,
    graphics: Graphics,
}

fn parse_args(mut args: impl Iterator<Item = String>) -> Result<Option<Args>, String> {
    let mut parsed = Args {
        firmware: Firmware::Bios,
        headless: false,
        screenshot: None,
        keys: Vec::new(),
        timeout: None,
        wait: Duration::from_millis(500),
        boot_option: None,
        write_usb: None,
        graphics: Graphics::StdVga,
    };
    while let Some(arg) = args.next() {
        let mut value = |name: &str| {
            args.next()
                .ok_or_else(|| format!("{name} needs a value; see --help"))
        };
        match arg.as_str() {
            "-h" | "--help" => return Ok(None),
            "--uefi" => parsed.firmware = Firmware::Uefi,
            "--headless" => parsed.headless = true,
            "--screenshot" => parsed.screenshot = Some(PathBuf::from(value("--screenshot")?)),
            "--keys" => {
                parsed.keys = value("--keys")?
                    .split_whitespace()
                    .map(str::to_lowercase)
                    .collect()
            }
            "--timeout" => parsed.timeout = Some(seconds("--timeout", &value("--timeout")?)?),
            "--wait" => parsed.wait = seconds("--wait", &value("--wait")?)?,
            "--boot-option" => parsed.boot_option = Some(value("--boot-option")?),
            "--vga" => {
                let name = value("--vga")?;
                parsed.graphics = Graphics::from_name(&name).ok_or_else(|| {
                    let names: Vec<_> = Graphics::ALL.iter().map(|g| g.name()).collect();
                    format!("unknown adapter {name:?}; one of: {}", names.join(", "))
                })?;
            }
            "--write-usb" => parsed.write_usb = Some(PathBuf::from(value("--write-usb")?)),
            other => return Err(format!("unknown option {other:?}; see --help")),
        }
    }
    Ok(Some(parsed))
}

fn seconds(option: &str, text: &str) -> Result<Duration, String> {
    text.parse()
        .ok()
        .filter(|s: &f64| s.is_finite() && *s > 0.0 && *s < 1e9)
        .map(Duration::from_secs_f64)
        .ok_or_else(|| format!("{option} takes a positive number of seconds, not {text:?}"))
}

fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

fn run(args: Args) -> Result<ExitCode, String> {
    let images = boot::images::publish()?;
    let image = match args.firmware {
        Firmware::Bios => images.bios,
        Firmware::Uefi => images.uefi,
    };
    if let Some(device) = &args.write_usb {
        return write_usb(&image, device);
    }
    let headless = args.headless || args.screenshot.is_some() || !has_display();
    if !args.headless && headless && args.screenshot.is_none() {
        println!("No display found ($DISPLAY and $WAYLAND_DISPLAY are unset): running headless.");
    }
    if headless {
        println!("Serial console follows. Ctrl-C stops QEMU.");
    }
    let mut options = QemuOptions::new(&image);
    options.firmware = args.firmware;
    options.display = if headless {
        Display::Headless
    } else {
        Display::Window
    };
    options.boot_option = args.boot_option.clone();
    options.graphics = args.graphics;
    options.echo_serial = true;
    println!("Booting {} ({:?})", image.display(), args.firmware);
    let mut qemu = Qemu::start(&options).map_err(|e| e.to_string())?;

    if !args.keys.is_empty() || args.screenshot.is_some() {
        let boot_time = if args.firmware == Firmware::Uefi {
            120
        } else {
            60
        };
        qemu.wait_for_serial(boot::READY_LINE, Duration::from_secs(boot_time))
            .map_err(|e| e.to_string())?;
        for key in &args.keys {
            qemu.send_key(key).map_err(|e| format!("{e} (QEMU key names: a-z, 0-9, kp_0-kp_9, f1-f12, left, right, up, down, home, end, pgup, pgdn, spc, esc, ret)"))?;
            std::thread::sleep(Duration::from_millis(150));
        }
        if let Some(path) = &args.screenshot {
            // Let the last key's frame reach the screen.
            std::thread::sleep(args.wait);
            let picture = qemu.screendump().map_err(|e| e.to_string())?;
            picture.write_png(path)?;
            println!(
                "Saved a {}x{} screenshot to {}",
                picture.width,
                picture.height,
                path.display()
            );
            return Ok(ExitCode::SUCCESS);
        }
    }

    let status = qemu
        .wait_exit(args.timeout.unwrap_or(Duration::MAX / 4))
        .map_err(|e| e.to_string())?;
    Ok(match status {
        None => {
            println!("Stopping QEMU after the timeout.");
            ExitCode::SUCCESS
        }
        Some(status) if status.code() == Some(qemu::EXIT_SUCCESS) => ExitCode::SUCCESS,
        Some(status) if status.success() => ExitCode::SUCCESS,
        Some(status) => {
            eprintln!("QEMU ended with {status}");
            ExitCode::FAILURE
        }
    })
}

/// Writes the image to a USB stick after the checks in `boot::usb` and the
/// user's typed confirmation.
fn write_usb(image: &std::path::Path, device: &std::path::Path) -> Result<ExitCode, String> {
    let written = boot::usb::write_image_to_usb(image, device, |description| {
        println!(
            "{description}\nType the device name ({}) to overwrite it:",
            device.display()
        );
        let mut answer = String::new();
        let typed = std::io::stdin().read_line(&mut answer).is_ok();
        let answer = answer.trim();
        typed
            && (answer == device.to_string_lossy()
                || Some(answer) == device.file_name().and_then(|name| name.to_str()))
    })?;
    println!(
        "Wrote {written} bytes to {} and flushed it.",
        device.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn main() -> ExitCode {
    match parse_args(std::env::args().skip(1)) {
        Ok(None) => {
            println!("{USAGE}");
            ExitCode::SUCCESS
        }
        Ok(Some(args)) => run(args).unwrap_or_else(|message| {
            eprintln!("error: {message}");
            ExitCode::FAILURE
        }),
        Err(message) => {
            eprintln!("error: {message}");
            ExitCode::from(2)
        }
    }
}
