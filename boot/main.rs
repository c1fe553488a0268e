//! `cargo run --release -- [OPTIONS]`: builds the kernel and its disk images
//! (cargo does that through the build script), then boots one in QEMU.

use boot::qemu::{self, Display, Firmware, Graphics, Qemu, QemuOptions};
use boot::secure_boot::KeySet;
use boot::usb::UsbError;
use boot::BootRequest;
use boot::{Chipset, DiskAttachment, UsbHost};
use clap::Parser;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

/// Boot the modex-cube kernel in QEMU.
///
/// Without a display (no $DISPLAY or $WAYLAND_DISPLAY) the kernel runs
/// headless. The image that boots both ways is also written to
/// target/images/modex-cube.img (with the single-firmware bios.img and
/// uefi.img beside it).
#[derive(Debug, Parser)]
#[command(name = "cargo run --release --", version)]
struct Args {
    /// Boot the image with OVMF (UEFI) instead of SeaBIOS.
    #[arg(long)]
    uefi: bool,
    /// Boot the one image with 32-bit OVMF (a 32-bit UEFI, as on Bay Trail
    /// tablets) on a Q35 with SMM: its loader is EFI/BOOT/BOOTIA32.EFI.
    #[arg(long, conflicts_with_all = ["uefi", "secure_boot"])]
    uefi32: bool,
    /// No window: the serial console streams to this terminal.
    #[arg(long)]
    headless: bool,
    /// After boot (and --keys) save QEMU's picture as a PNG, then stop.
    #[arg(long, value_name = "FILE")]
    screenshot: Option<PathBuf>,
    /// Type these after boot, separated by spaces, e.g. "r 4 4 kp_8 a f1 left spc esc".
    /// The names are listed in docs/runner.md and in an unknown name's error.
    #[arg(long, value_name = "KEYS", value_parser = parse_keys, default_value = "")]
    keys: KeyNames,
    /// With --screenshot: wait SECS after the keys before taking it, e.g. to let
    /// the statistics measure a spin.
    #[arg(long, value_name = "SECS", value_parser = seconds, default_value = "0.5")]
    wait: Duration,
    /// The display adapter QEMU emulates, each with its own VGA BIOS.
    #[arg(long = "vga", value_name = "ADAPTER", value_parser = adapter, default_value = "std")]
    graphics: Graphics,
    /// Count guest time in instructions (QEMU's -icount shift=0,sleep=off):
    /// one instruction a nanosecond whatever the host's load, so the timings
    /// the kernel reports (bench, present:) repeat exactly. The guest runs
    /// slower than real time.
    #[arg(long)]
    icount: bool,
    /// Stop QEMU after SECS seconds.
    #[arg(long, value_name = "SECS", value_parser = seconds)]
    timeout: Option<Duration>,
    /// Hand OPTION to the kernel via fw_cfg: test-pattern, flip-rate,
    /// clock-check, bench, fault=KIND, exit=success|failure, and/or
    /// modex=true-mode-x (see docs/runner.md).
    #[arg(long, value_name = "OPTION", value_parser = boot_request, default_value = "")]
    boot_option: BootRequest,
    /// Instead of booting, write the image (modex-cube.img, which boots under
    /// BIOS and UEFI, unless --image says otherwise) to the whole USB disk
    /// DEVICE, e.g. /dev/sdb, after checking it is an unmounted disk that is
    /// removable or on USB; shows what will be overwritten and asks you to
    /// type its name.
    #[arg(long, value_name = "DEVICE")]
    write_usb: Option<PathBuf>,
    /// Which image to boot or write: `one` (modex-cube.img, for BIOS and
    /// UEFI), or the single-firmware `bios` (bios.img) or `uefi` (uefi.img).
    #[arg(long, value_enum, default_value_t = ImageChoice::One)]
    image: ImageChoice,
    /// Boot (or write) the signed stick, modex-cube-secure-boot.img, with
    /// OVMF's Secure Boot build and the key set KEYS (plain --secure-boot:
    /// 2011), its variables kept in target/secure-boot/ (so an enrolled key
    /// stays).
    #[arg(
        long,
        value_name = "KEYS",
        value_enum,
        num_args = 0..=1,
        default_missing_value = "2011"
    )]
    secure_boot: Option<KeySet>,
    /// Sign with this private key (PEM) instead of the one kept in
    /// ~/.config/modex-cube/secure-boot (made there on first use).
    #[arg(long, value_name = "FILE", requires = "sign_cert")]
    sign_key: Option<PathBuf>,
    /// The certificate (PEM) of --sign-key.
    #[arg(long, value_name = "FILE", requires = "sign_key")]
    sign_cert: Option<PathBuf>,
    /// Boot (or write) this disk image file instead of the one just built,
    /// e.g. an older build's, to compare.
    #[arg(long, value_name = "FILE", conflicts_with = "image")]
    disk: Option<PathBuf>,
    /// Attach the image as a USB stick on this USB host controller (xhci,
    /// ehci, ohci, uhci, or ich9: ICH9's EHCI with three UHCI companions)
    /// instead of as the hard disk: the firmware boots from USB.
    #[arg(long, value_name = "HOST", value_parser = usb_host)]
    usb_stick: Option<UsbHost>,
    /// Fit a USB host controller of this kind (as for --usb-stick) with a
    /// usb-kbd on it; may be given again for more (on ich9 the keyboard is
    /// a full-speed one, which the EHCI hands to a UHCI companion).
    #[arg(long, value_name = "HOST", value_parser = usb_host)]
    usb_keyboard: Vec<UsbHost>,
    /// Boot headless, wait for the kernel's ready line, print how long after
    /// QEMU's start the first serial output, the kernel's banner and the
    /// ready line arrived, then stop.
    #[arg(long)]
    boot_time: bool,
    /// The chipset: pc (i440FX, QEMU's default) or q35.
    #[arg(long, value_name = "CHIPSET", value_parser = chipset, default_value = "pc")]
    machine: Chipset,
}

/// The runner's `--image` names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum ImageChoice {
    /// modex-cube.img: GPT with a hybrid MBR, for BIOS (and CSM) and UEFI.
    One,
    /// bios.img: MBR only.
    Bios,
    /// uefi.img: GPT only.
    Uefi,
}

/// Key names checked against `keyboard::keys`, the one table of them.
#[derive(Clone, Debug, Default)]
struct KeyNames(Vec<String>);

fn parse_keys(text: &str) -> Result<KeyNames, String> {
    text.split_whitespace()
        .map(|name| match keyboard::keys::scancode_for_name(name) {
            Some(_) => Ok(name.to_lowercase()),
            None => Err(format!(
                "unknown key {name:?}; key names: {}",
                keyboard::keys::names().collect::<Vec<_>>().join(" ")
            )),
        })
        .collect::<Result<_, _>>()
        .map(KeyNames)
}

fn boot_request(text: &str) -> Result<BootRequest, String> {
    BootRequest::parse(text).map_err(|unknown| unknown.to_string())
}

fn seconds(text: &str) -> Result<Duration, String> {
    text.parse()
        .ok()
        .filter(|s: &f64| s.is_finite() && *s > 0.0 && *s < 1e9)
        .map(Duration::from_secs_f64)
        .ok_or_else(|| format!("a positive number of seconds, not {text:?}"))
}

fn adapter(name: &str) -> Result<Graphics, String> {
    Graphics::from_name(name).ok_or_else(|| {
        let names: Vec<_> = Graphics::choices().map(Graphics::name).collect();
        format!("unknown adapter {name:?}; one of: {}", names.join(", "))
    })
}

fn usb_host(name: &str) -> Result<UsbHost, String> {
    UsbHost::from_name(name).ok_or_else(|| {
        let names: Vec<_> = UsbHost::ALL.into_iter().map(UsbHost::name).collect();
        format!("unknown USB host {name:?}; one of: {}", names.join(", "))
    })
}

fn chipset(name: &str) -> Result<Chipset, String> {
    match name {
        "pc" => Ok(Chipset::I440fx),
        "q35" => Ok(Chipset::Q35),
        _ => Err(format!("unknown chipset {name:?}; one of: pc, q35")),
    }
}

fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

fn run(args: Args) -> anyhow::Result<ExitCode> {
    let firmware = if args.uefi {
        Firmware::Uefi
    } else if args.uefi32 {
        Firmware::Uefi32
    } else {
        Firmware::Bios
    };
    let images = boot::images::publish()?;
    // The one image boots under both firmwares.
    let image = match (&args.disk, args.image) {
        _ if args.secure_boot.is_some() || args.sign_key.is_some() => {
            signed_stick(args.sign_key.as_deref(), args.sign_cert.as_deref())?
        }
        (Some(file), _) => file.clone(),
        (None, ImageChoice::One) => images.hybrid,
        (None, ImageChoice::Bios) => images.bios,
        (None, ImageChoice::Uefi) => images.uefi,
    };
    let firmware = if args.secure_boot.is_some() {
        Firmware::Uefi
    } else {
        firmware
    };
    let mismatch = match (args.image, firmware) {
        (ImageChoice::Bios, Firmware::Uefi) => Some("bios.img has no UEFI loader"),
        (ImageChoice::Uefi, Firmware::Bios) => Some("uefi.img has no BIOS boot code"),
        (ImageChoice::Bios, Firmware::Uefi32) => Some("bios.img has no UEFI loader"),
        (ImageChoice::Uefi, Firmware::Uefi32) => {
            Some("uefi.img has no 32-bit UEFI loader (only the one image has)")
        }
        _ => None,
    };
    if let (Some(why), None) = (mismatch, &args.write_usb) {
        anyhow::bail!("{why}; boot it with the other firmware, or use --image one");
    }
    if let Some(device) = &args.write_usb {
        return write_usb(&image, device);
    }
    let headless = args.headless || args.screenshot.is_some() || args.boot_time || !has_display();
    if !args.headless && headless && args.screenshot.is_none() {
        println!("No display found ($DISPLAY and $WAYLAND_DISPLAY are unset): running headless.");
    }
    if headless && !args.boot_time {
        println!("Serial console follows. Ctrl-C stops QEMU.");
    }
    let mut options = QemuOptions::new(&image);
    options.firmware = firmware;
    options.display = if headless {
        Display::Headless
    } else {
        Display::Window
    };
    options.boot = args.boot_option;
    options.graphics = args.graphics;
    options.echo_serial = !args.boot_time;
    options.instruction_clock = args.icount;
    options.board.chipset = args.machine;
    if let Some(host) = args.usb_stick {
        options.disk = DiskAttachment::UsbStick(host);
    }
    for (n, host) in args.usb_keyboard.iter().enumerate() {
        let id = format!("usbkbdhost{n}");
        options.devices.extend(host.devices(&id));
        let full_speed = if *host == UsbHost::Ich9EhciWithCompanions {
            ",usb_version=1"
        } else {
            ""
        };
        options
            .devices
            .push(format!("usb-kbd,bus={id}.0{full_speed}"));
    }
    if let Some(keys) = args.secure_boot {
        options.secure_boot_vars = Some(secure_boot_vars(&image, keys)?);
    }
    println!("Booting {} ({:?})", image.display(), firmware);
    let mut qemu = Qemu::start(&options)?;
    if args.boot_time {
        return boot_time(&mut qemu);
    }

    if !args.keys.0.is_empty() || args.screenshot.is_some() {
        let boot_time = if firmware == Firmware::Bios { 60 } else { 120 };
        qemu.wait_for_serial(boot::READY_LINE, Duration::from_secs(boot_time))?;
        for key in &args.keys.0 {
            qemu.send_key(key)?;
            std::thread::sleep(Duration::from_millis(150));
        }
        if let Some(path) = &args.screenshot {
            // Let the last key's frame reach the screen.
            std::thread::sleep(args.wait);
            let picture = qemu.screendump()?;
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

    let status = qemu.wait_exit(args.timeout.unwrap_or(Duration::MAX / 4))?;
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

/// Makes `target/images/modex-cube-secure-boot.img`, signed with the given
/// key or the user's own (made on first use), and says where the key is.
fn signed_stick(key: Option<&Path>, cert: Option<&Path>) -> anyhow::Result<PathBuf> {
    use boot::secure_boot::{self as sb, KeyOrigin};
    let key = match (key, cert) {
        (Some(key), Some(cert)) => sb::given_key(key, cert)?,
        _ => {
            let dir = sb::default_key_dir();
            let (key, origin) = sb::make_or_reuse_key(&dir)?;
            if origin == KeyOrigin::Made {
                println!(
                    "Made your Secure Boot signing key in {} (keep it: a PC that enrolled \
                     its certificate boots only sticks signed with it).",
                    dir.display()
                );
            }
            key
        }
    };
    let shim = sb::Shim::read(&sb::default_shim_dir())?;
    let pieces = sb::BuiltPieces::of_this_build()?;
    let disk = sb::signed_disk(&pieces, &key, Some(&shim), sb::Route::Shim)?;
    let path = boot::images::images_dir().join(sb::SIGNED_IMAGE_NAME);
    sb::write_whole(&path, &disk)?;
    println!(
        "Signed the loader with {}; wrote {}",
        key.cert.display(),
        path.display()
    );
    Ok(path)
}

/// The Secure Boot variables of `keys` kept under target/secure-boot/,
/// and what to do if the stick's key is not enrolled in them.
fn secure_boot_vars(image: &Path, keys: KeySet) -> anyhow::Result<PathBuf> {
    use boot::secure_boot as sb;
    let dir = boot::images::images_dir()
        .parent()
        .map(|target| target.join("secure-boot"))
        .unwrap_or_else(|| PathBuf::from("secure-boot"));
    let (vars, enrolled) = sb::runner_vars(&dir, keys, image)?;
    if keys == KeySet::User {
        println!(
            "Your certificate is in db of {}, Microsoft's third-party CA is not: the firmware \
             starts shim, and shim the loader, by your signature alone.",
            vars.display()
        );
    } else if !enrolled {
        println!(
            "Your key is not enrolled in {} yet. Shim will say \"Verification failed\": press \
             Enter, then any key for MokManager; choose \"Enroll key from disk\", the disk, \
             {}, \"Continue\", \"Yes\" and \"Reboot\". From then on it boots.",
            vars.display(),
            sb::ENROLL_FILE_NAME
        );
    }
    Ok(vars)
}

/// Waits for the ready line and prints when the first output, the banner
/// and the ready line arrived, counted from QEMU's start.
fn boot_time(qemu: &mut Qemu) -> anyhow::Result<ExitCode> {
    qemu.wait_for_serial(boot::READY_LINE, Duration::from_secs(120))?;
    let seconds = |arrival: Option<Duration>| {
        arrival.map_or_else(|| "-".to_owned(), |d| format!("{:.2}", d.as_secs_f64()))
    };
    println!(
        "boot time (s from QEMU's start): first output {}, banner {}, ready {}",
        seconds(qemu.first_output()),
        seconds(qemu.arrival(boot::line::KERNEL_BANNER)),
        seconds(qemu.arrival(boot::READY_LINE)),
    );
    Ok(ExitCode::SUCCESS)
}

/// Writes the image to a USB stick after the checks in `boot::usb` and the
/// user's typed confirmation.
fn write_usb(image: &Path, device: &Path) -> anyhow::Result<ExitCode> {
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
    })
    .map_err(|error| {
        // "Nothing was written" only where it is true, and not twice where
        // the error itself says so.
        if error.device_untouched() && !matches!(error, UsbError::NotConfirmed { .. }) {
            anyhow::Error::new(error)
                .context(format!("nothing was written to {}", device.display()))
        } else {
            anyhow::Error::new(error)
        }
    })?;
    println!(
        "Wrote {} bytes to {} and flushed it.",
        written.bytes,
        device.display()
    );
    if let Some(lba) = written.backup_gpt_lba {
        println!(
            "Moved the backup GPT to the stick's last sector (LBA {lba}), as `sgdisk -e` does."
        );
    }
    Ok(ExitCode::SUCCESS)
}

fn main() -> ExitCode {
    let args = Args::parse();
    run(args).unwrap_or_else(|error| {
        eprintln!("error: {error:#}");
        ExitCode::FAILURE
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_arguments_are_consistent() {
        Args::command().debug_assert();
    }

    #[test]
    fn key_names_come_from_the_one_table() {
        let args = Args::try_parse_from(["runner", "--keys", "R 4 kp_8 left esc"]).unwrap();
        assert_eq!(args.keys.0, ["r", "4", "kp_8", "left", "esc"]);
        let error = Args::try_parse_from(["runner", "--keys", "r nope"]).unwrap_err();
        assert!(error.to_string().contains("\"nope\""), "{error}");
        assert!(error.to_string().contains("pgdn"), "{error}");
    }

    #[test]
    fn every_adapter_the_runner_takes_is_named_when_one_is_wrong() {
        for graphics in Graphics::choices() {
            let args = Args::try_parse_from(["runner", "--vga", graphics.name()]).unwrap();
            assert_eq!(args.graphics, graphics);
        }
        let error = Args::try_parse_from(["runner", "--vga", "hercules"]).unwrap_err();
        for graphics in Graphics::choices() {
            assert!(error.to_string().contains(graphics.name()), "{error}");
        }
    }

    #[test]
    fn the_one_image_is_the_default() {
        let args = Args::try_parse_from(["runner", "--write-usb", "/dev/sdb"]).unwrap();
        assert_eq!(args.image, ImageChoice::One);
        let args = Args::try_parse_from(["runner", "--image", "bios"]).unwrap();
        assert_eq!(args.image, ImageChoice::Bios);
        assert!(Args::try_parse_from(["runner", "--image", "floppy"]).is_err());
    }

    #[test]
    fn boot_options_are_checked_before_qemu_sees_them() {
        let args = Args::try_parse_from(["runner", "--boot-option", "fault=page"]).unwrap();
        assert_eq!(
            args.boot_option.option,
            Some(boot::BootOption::Fault(boot::Fault::Page))
        );
        let args = Args::try_parse_from(["runner", "--boot-option", "modex=true-mode-x bench"]);
        assert!(args.unwrap().boot_option.true_mode_x);
        let error = Args::try_parse_from(["runner", "--boot-option", "fault=pgae"]).unwrap_err();
        assert!(error.to_string().contains("fault=page"), "{error}");
    }

    #[test]
    fn adapters_and_durations_are_checked() {
        let args = Args::try_parse_from(["runner", "--vga", "cirrus", "--wait", "2"]).unwrap();
        assert_eq!(args.graphics, Graphics::Cirrus);
        assert_eq!(args.wait, Duration::from_secs(2));
        assert!(Args::try_parse_from(["runner", "--vga", "s3"]).is_err());
        assert!(Args::try_parse_from(["runner", "--timeout", "-1"]).is_err());
    }

    #[test]
    fn plain_secure_boot_is_the_2011_key_set_and_the_others_are_named() {
        let keys = |args: &[&str]| Args::try_parse_from(args).map(|args| args.secure_boot);
        assert_eq!(keys(&["runner"]).unwrap(), None);
        let plain = keys(&["runner", "--secure-boot"]).unwrap();
        assert_eq!(plain, Some(KeySet::Microsoft2011));
        // Plain, then another option: that option is not taken as the value.
        let args =
            Args::try_parse_from(["runner", "--secure-boot", "--write-usb", "/dev/sdb"]).unwrap();
        assert_eq!(args.secure_boot, Some(KeySet::Microsoft2011));
        assert_eq!(args.write_usb, Some(PathBuf::from("/dev/sdb")));
        for (name, set) in [
            ("2011", KeySet::Microsoft2011),
            ("2023", KeySet::Microsoft2023),
            ("user", KeySet::User),
        ] {
            assert_eq!(keys(&["runner", "--secure-boot", name]).unwrap(), Some(set));
        }
        let error = keys(&["runner", "--secure-boot", "2016"]).unwrap_err();
        assert!(error.to_string().contains("2011, 2023, user"), "{error}");
    }

    #[test]
    fn the_instruction_clock_is_asked_for_by_name() {
        assert!(!Args::try_parse_from(["runner"]).unwrap().icount);
        let args = Args::try_parse_from(["runner", "--uefi", "--icount"]).unwrap();
        assert!(args.icount && args.uefi);
    }

    #[test]
    fn usb_hosts_are_named_and_keyboards_may_be_fitted_on_several() {
        let args = Args::try_parse_from([
            "runner",
            "--usb-stick",
            "ich9",
            "--usb-keyboard",
            "uhci",
            "--usb-keyboard",
            "ohci",
        ])
        .unwrap();
        assert_eq!(args.usb_stick, Some(UsbHost::Ich9EhciWithCompanions));
        assert_eq!(args.usb_keyboard, [UsbHost::Uhci, UsbHost::Ohci]);
        let error = Args::try_parse_from(["runner", "--usb-keyboard", "vhci"]).unwrap_err();
        assert!(
            error.to_string().contains("xhci, ehci, ohci, uhci, ich9"),
            "{error}"
        );
        for host in UsbHost::ALL {
            assert_eq!(UsbHost::from_name(host.name()), Some(host));
        }
    }
}
