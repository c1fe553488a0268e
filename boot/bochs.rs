//! Bochs 2.7 as a second emulator, with its own VGA core and VGA BIOSes, for
//! the same picture tests as QEMU, and with its own USB host controllers
//! (chips QEMU has no model of) for a USB keyboard.
//!
//! Bochs has no monitor to take screenshots or type keys, so a `Bochs` runs
//! it under its own Xvfb with the X display library (the `xvfb` crate, which
//! the simulator's window tests use too): keys are typed into the window
//! with `xdotool`, and the window is read back with `xwd`. The serial
//! console goes to a file that is read as it grows. Dropping a `Bochs` kills
//! Bochs and its X server.

use crate::image::RgbImage;
use std::io;
use std::path::{Path, PathBuf};
use std::process::{Child, ExitStatus, Stdio};
use std::time::{Duration, Instant};
use xvfb::{X11Error, Xvfb};

/// The Debian packages a Bochs run needs besides the X tools' (`bochs-x` is
/// Bochs's X display plugin, `bochsbios` and `vgabios` its ROMs).
pub const APT_PACKAGES: &str = "bochs bochsbios vgabios bochs-x xvfb xdotool x11-apps";

const SYSTEM_BIOS: &str = "/usr/share/bochs/BIOS-bochs-latest";
/// The LGPL VGA BIOS with Bochs VBE (Bochs's `VGABIOS-lgpl-latest`).
const VBE_VGA_BIOS: &str = "/usr/share/vgabios/vgabios.bin";
const CIRRUS_VGA_BIOS: &str = "/usr/share/vgabios/vgabios-cirrus.bin";

/// Instructions per emulated second. With `clock: sync=slowdown` Bochs runs as
/// fast as it can (but never ahead of the host's clock) and emulated time is
/// instructions / ips, so this sets how
/// much host work an emulated second costs, and the boot waits in emulated
/// time (the BIOS's, the kernel's TSC calibration over 0.2 s). Measured to
/// `screen: ready` on a 2-core machine shared with other builds: 2.3-7 s at
/// 10-25 M, 8 s at 50 M, 2.6-24 s at 150 M, 55 s at 400 M. 25 M still leaves
/// the kernel about 400 000 instructions per 60 Hz frame; a frame it cannot
/// finish in time only misses a retrace, which these tests do not look at.
pub const DEFAULT_IPS: u64 = 25_000_000;

/// Bochs's X window is the guest picture with a toolbar above it and a
/// status bar below, both as wide as the picture (measured on Bochs 2.7's X
/// display library: a 720x400 text screen makes a 720x450 window).
const TOOLBAR_HEIGHT: usize = 32;
const STATUS_BAR_HEIGHT: usize = 18;

/// Bochs's X window title begins with this.
const WINDOW_NAME: &str = "^Bochs";

/// How long to wait for Xvfb and for Bochs's window; both take well under a
/// second on an idle machine.
const START_TIMEOUT: Duration = Duration::from_secs(30);
/// Xvfb's screen: room for Bochs's largest window here (720x450).
const SCREEN: (u32, u32) = (1024, 768);
/// How often the serial file and the window are looked at while waiting.
const POLL_INTERVAL: Duration = Duration::from_millis(20);

/// The VGA Bochs emulates, each with the VGA BIOS made for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VgaExtension {
    /// Bochs's standard VGA with the Bochs VBE extension (DISPI), on the ISA bus.
    Vbe,
    /// A Cirrus Logic GD5446 on the PCI bus.
    Cirrus,
}

/// How to start Bochs: [`BochsOptions::new`] and changes from there.
#[derive(Clone, Debug)]
pub struct BochsOptions {
    /// The BIOS disk image; Bochs has no UEFI, and the image is padded to
    /// whole cylinders in a scratch copy.
    pub image: PathBuf,
    /// Which VGA, and so which VGA BIOS.
    pub vga: VgaExtension,
    /// Emulated instructions per second ([`DEFAULT_IPS`]).
    pub ips: u64,
    /// A low-speed USB keyboard on one of Bochs's USB host controllers, or
    /// none. With one attached, Bochs sends every key of its window to it
    /// instead of the PS/2 keyboard.
    pub usb_keyboard: Option<UsbKeyboard>,
}

/// Bochs's own USB host controllers, none of them a chip QEMU models.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BochsUsbHost {
    /// The UHCI of the i440FX chipset's PIIX3 (PCI 00:01.2), 2 ports.
    Uhci,
    /// An OHCI on a PCI slot, 2 ports.
    Ohci,
    /// An EHCI with UHCI companions, 6 ports; a low-speed device is handed
    /// to a companion.
    Ehci,
    /// An xHCI: ports 1 and 2 are USB 3 (SuperSpeed only), 3 and 4 USB 2.
    Xhci,
}

impl BochsUsbHost {
    /// The bochsrc option that enables it.
    fn option(self) -> &'static str {
        match self {
            BochsUsbHost::Uhci => "usb_uhci",
            BochsUsbHost::Ohci => "usb_ohci",
            BochsUsbHost::Ehci => "usb_ehci",
            BochsUsbHost::Xhci => "usb_xhci",
        }
    }

    /// The first root port a low-speed keyboard may use: on the xHCI the
    /// first USB 2 port, after the USB 3 ones.
    pub fn first_low_speed_port(self) -> u8 {
        match self {
            BochsUsbHost::Xhci => 3,
            BochsUsbHost::Uhci | BochsUsbHost::Ohci | BochsUsbHost::Ehci => 1,
        }
    }
}

/// A low-speed USB keyboard (`speed:low`, as most cheap keyboards are) on a
/// root port (numbered from 1) of one of Bochs's USB host controllers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsbKeyboard {
    /// The controller.
    pub host: BochsUsbHost,
    /// Its root port, from 1.
    pub port: u8,
}

impl BochsOptions {
    /// The given image and VGA at [`DEFAULT_IPS`].
    pub fn new(image: impl Into<PathBuf>, vga: VgaExtension) -> Self {
        BochsOptions {
            image: image.into(),
            vga,
            ips: DEFAULT_IPS,
            usb_keyboard: None,
        }
    }
}

/// What went wrong with Bochs; the messages say what to do or what was seen.
#[derive(Debug, thiserror::Error)]
pub enum BochsError {
    /// Debian packages are missing: how to install them.
    #[error(
        "the Bochs tests need the Debian packages {}. Install them with `boot/setup.sh` \
         (or `sudo apt-get install {APT_PACKAGES}`).",
        .missing.join(", ")
    )]
    NotInstalled {
        /// The packages to install, in `apt-get install` order.
        missing: Vec<&'static str>,
    },
    /// The `bochs` executable could not be started.
    #[error("cannot start bochs: {0}")]
    Spawn(io::Error),
    /// A file of the run (the padded disk, the bochsrc) could not be made.
    #[error("{what}: {error}")]
    Io {
        /// What was being done, as the message's first words.
        what: String,
        /// Why it failed.
        error: io::Error,
    },
    /// The X server, `xdotool` or `xwd` failed.
    #[error(transparent)]
    X11(#[from] X11Error),
    /// Bochs ended before what was waited for happened.
    #[error("bochs exited ({status}) {when}; console:\n{console}{diagnostics}")]
    Exited {
        /// How Bochs ended.
        status: ExitStatus,
        /// "before ... appeared on serial", "before opening its window", ...
        when: String,
        /// The serial console up to the exit.
        console: String,
        /// Bochs's own output and log tail ([`Bochs::diagnostics`]).
        diagnostics: String,
    },
    /// The serial console never showed `needle`.
    #[error(
        "timed out after {waited:?} waiting for {needle:?} on serial; console so far:\n\
         {console}{diagnostics}"
    )]
    SerialTimeout {
        /// The text waited for.
        needle: String,
        /// How long it was waited for.
        waited: Duration,
        /// The serial console when the wait ran out.
        console: String,
        /// Bochs's own output and log tail ([`Bochs::diagnostics`]).
        diagnostics: String,
    },
    /// Bochs opened no window.
    #[error("Bochs opened no window named {WINDOW_NAME:?} within {waited:?}{diagnostics}")]
    NoWindow {
        /// How long the window was waited for.
        waited: Duration,
        /// Bochs's own output and log tail ([`Bochs::diagnostics`]).
        diagnostics: String,
    },
    /// The window is not laid out as Bochs 2.7 lays it out.
    #[error("{0}")]
    Layout(LayoutError),
    /// The window never held a guest picture while it was waited on.
    #[error("after {waited:?} the window still has no guest picture: {why}")]
    NoGuestPicture {
        /// How long the window was looked at.
        waited: Duration,
        /// What was wrong with its last look.
        why: LayoutError,
        /// The whole window as last captured (none if it was being resized).
        window: Option<RgbImage>,
    },
    /// The window never showed what was waited for; `last` is what it showed.
    #[error("the window did not show the expected picture within {waited:?}; it shows {last:?}")]
    ScreenTimeout {
        /// How long the window was looked at.
        waited: Duration,
        /// The guest picture it showed last.
        last: RgbImage,
    },
}

/// Why a window picture has no guest picture where Bochs 2.7 puts it.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    /// Not taller than the toolbar and the status bar.
    #[error("a {width}x{height} window has no room for a guest picture")]
    TooShort {
        /// The window's width in pixels.
        width: usize,
        /// The window's height in pixels.
        height: usize,
    },
    /// The window changed size while it was being captured.
    #[error("the window changed size while it was captured")]
    Resizing,
    /// The status bar's white top line is not where the layout puts it.
    #[error("row {row} of the {width}x{height} window is not the status bar's white top line")]
    NoStatusBar {
        /// Where the status bar's top line should be.
        row: usize,
        /// The window's width in pixels.
        width: usize,
        /// The window's height in pixels.
        height: usize,
    },
}

type Result<T> = std::result::Result<T, BochsError>;

/// Fails with an actionable message when a tool or ROM is missing.
pub fn check_installed() -> Result<()> {
    let mut missing = xvfb::missing_packages();
    if !xvfb::on_path("bochs") {
        missing.insert(0, "bochs");
    }
    if !x_display_plugin_installed() {
        missing.push("bochs-x");
    }
    if !Path::new(SYSTEM_BIOS).exists() {
        missing.push("bochsbios");
    }
    if !Path::new(VBE_VGA_BIOS).exists() || !Path::new(CIRRUS_VGA_BIOS).exists() {
        missing.push("vgabios");
    }
    if missing.is_empty() {
        return Ok(());
    }
    Err(BochsError::NotInstalled { missing })
}

/// Bochs's X display library is a plugin in `/usr/lib/<multiarch>/bochs/plugins`.
fn x_display_plugin_installed() -> bool {
    std::fs::read_dir("/usr/lib").is_ok_and(|dirs| {
        dirs.flatten()
            .any(|dir| dir.path().join("bochs/plugins/libbx_x_gui.so").exists())
    })
}

/// A running Bochs in its own Xvfb: serial console, keys and window
/// pictures. Dropping it kills Bochs, then its X server.
pub struct Bochs {
    bochs: Child,
    /// Dropped after Bochs is killed (see `Drop`).
    xvfb: Xvfb,
    /// Bochs's window, as xdotool and xwd name it.
    window: String,
    scratch: tempfile::TempDir,
}

impl std::fmt::Debug for Bochs {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Bochs")
            .field("pid", &self.bochs.id())
            .field("window", &self.window)
            .field("scratch", &self.scratch.path())
            .finish_non_exhaustive()
    }
}

impl Bochs {
    /// Starts Xvfb and Bochs, and waits for Bochs's window to open; the
    /// kernel may not have printed anything yet.
    pub fn start(options: &BochsOptions) -> Result<Bochs> {
        check_installed()?;
        let scratch = tempfile::Builder::new()
            .prefix("modex-cube-bochs-")
            .tempdir()
            .map_err(|e| io_error("cannot make a scratch dir", e))?;
        let (disk, cylinders) = padded_disk(&options.image, scratch.path())?;
        let bochsrc = scratch.path().join("bochsrc");
        std::fs::write(
            &bochsrc,
            bochsrc_text(options, &disk, cylinders, scratch.path()),
        )
        .map_err(|e| io_error("cannot write the bochsrc", e))?;
        // The Debian build of Bochs starts in its debugger; these are the
        // debugger commands: continue.
        let debugger_commands = scratch.path().join("continue.rc");
        std::fs::write(&debugger_commands, "c\n")
            .map_err(|e| io_error("cannot write the debugger commands", e))?;

        // Both killed with the test's thread, as QEMU is (`bochs` below).
        let xvfb = Xvfb::start_with(
            crate::qemu::dies_with_its_thread("Xvfb"),
            SCREEN,
            START_TIMEOUT,
        )?;
        // On an error `xvfb` is dropped, which stops it.
        let bochs = spawn_bochs(&bochsrc, &debugger_commands, xvfb.display(), scratch.path())?;
        let mut bochs = Bochs {
            bochs,
            xvfb,
            window: String::new(),
            scratch,
        };
        bochs.window = bochs.find_window()?;
        Ok(bochs)
    }

    /// Everything the kernel has printed on serial so far.
    pub fn serial(&self) -> String {
        let bytes = std::fs::read(self.scratch.path().join("serial.txt")).unwrap_or_default();
        String::from_utf8_lossy(&bytes).replace('\r', "")
    }

    /// Waits until the serial console contains `needle`; returns the console.
    pub fn wait_for_serial(&mut self, needle: &str, timeout: Duration) -> Result<String> {
        let deadline = Instant::now() + timeout;
        loop {
            let text = self.serial();
            if text.contains(needle) {
                return Ok(text);
            }
            self.fail_if_exited(&format!("before {needle:?} appeared on serial"))?;
            if Instant::now() >= deadline {
                return Err(BochsError::SerialTimeout {
                    needle: needle.to_owned(),
                    waited: timeout,
                    console: text,
                    diagnostics: self.diagnostics(),
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// Presses and releases a key, named as X names keysyms (`r`, `4`,
    /// `Escape`, `Left`, `F1`, ...).
    pub fn send_key(&mut self, keysym: &str) -> Result<()> {
        self.xvfb
            .run("xdotool", &["key", "--window", &self.window, keysym])?;
        Ok(())
    }

    /// Bochs's whole window as the X server shows it: toolbar, guest
    /// picture, status bar (without the X border, which `xwd` would include).
    pub fn window_picture(&mut self) -> Result<RgbImage> {
        Ok(self.xvfb.capture(&self.window)?.into())
    }

    /// The guest's picture: the window without its toolbar and status bar.
    pub fn screen(&mut self) -> Result<RgbImage> {
        guest_area(&self.window_picture()?).map_err(BochsError::Layout)
    }

    /// Looks at the guest's picture until `accept` takes it (and returns it)
    /// or `timeout` passes. Bochs redraws its window from video memory on its
    /// own display timer, so a picture the kernel has finished reaches the
    /// window a little later; this waits for it to be shown, not for a time.
    /// A window whose bars are not where they belong (just after Bochs has
    /// resized it for a new mode, before it repaints them), or that changes
    /// size while `xwd` reads it, counts as not yet showing the picture.
    pub fn wait_for_screen(
        &mut self,
        timeout: Duration,
        mut accept: impl FnMut(&RgbImage) -> bool,
    ) -> Result<RgbImage> {
        let deadline = Instant::now() + timeout;
        loop {
            let window = match self.window_picture() {
                Ok(window) => Some(window),
                Err(BochsError::X11(e)) if e.window_resized_during_capture() => None,
                Err(e) => return Err(e),
            };
            let last = window
                .as_ref()
                .map_or(Err(LayoutError::Resizing), guest_area);
            if let Ok(picture) = &last {
                if accept(picture) {
                    return last.map_err(BochsError::Layout);
                }
            }
            self.fail_if_exited("while waiting for a picture")?;
            if Instant::now() >= deadline {
                return Err(match last {
                    Ok(last) => BochsError::ScreenTimeout {
                        waited: timeout,
                        last,
                    },
                    Err(why) => BochsError::NoGuestPicture {
                        waited: timeout,
                        why,
                        window,
                    },
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }

    /// Whether Bochs has not exited yet.
    pub fn is_running(&mut self) -> bool {
        matches!(self.bochs.try_wait(), Ok(None))
    }

    /// Bochs's own output and the tail of its log, for error messages.
    pub fn diagnostics(&self) -> String {
        let read = |name: &str| {
            std::fs::read_to_string(self.scratch.path().join(name)).unwrap_or_default()
        };
        let log = read("bochs.log");
        let tail: Vec<&str> = log.lines().rev().take(20).collect();
        format!(
            "\n--- bochs output ---\n{}\n--- end of bochs log ---\n{}",
            read("bochs.out").trim_end(),
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        )
    }

    fn fail_if_exited(&mut self, when: &str) -> Result<()> {
        match self.bochs.try_wait() {
            Ok(Some(status)) => Err(BochsError::Exited {
                status,
                when: when.to_owned(),
                console: self.serial(),
                diagnostics: self.diagnostics(),
            }),
            _ => Ok(()),
        }
    }

    /// Bochs opens its window while it initialises, before the guest runs.
    fn find_window(&mut self) -> Result<String> {
        let deadline = Instant::now() + START_TIMEOUT;
        loop {
            if let Ok(found) = self.xvfb.run("xdotool", &["search", "--name", WINDOW_NAME]) {
                let found = String::from_utf8_lossy(&found);
                if let Some(window) = found.split_whitespace().next() {
                    return Ok(window.to_owned());
                }
            }
            self.fail_if_exited("before opening its window")?;
            if Instant::now() >= deadline {
                return Err(BochsError::NoWindow {
                    waited: START_TIMEOUT,
                    diagnostics: self.diagnostics(),
                });
            }
            std::thread::sleep(POLL_INTERVAL);
        }
    }
}

impl Drop for Bochs {
    /// Bochs goes first, so that its X server never sees it lose the
    /// display; the `xvfb` field's own drop then stops the server.
    fn drop(&mut self) {
        let _ = self.bochs.kill();
        let _ = self.bochs.wait();
    }
}

/// Starts Bochs on `display` with its output (its own messages and the
/// debugger's) in `bochs.out` in `dir`.
fn spawn_bochs(
    bochsrc: &Path,
    debugger_commands: &Path,
    display: &str,
    dir: &Path,
) -> Result<Child> {
    let output = std::fs::File::create(dir.join("bochs.out"))
        .map_err(|e| io_error("cannot create bochs.out", e))?;
    // Killed with the test's thread, as QEMU is: a test process killed by
    // a signal runs no `Drop`, and Bochs would otherwise stop at its
    // breakpoint until someone kills it.
    crate::qemu::dies_with_its_thread("bochs")
        .arg("-q")
        .arg("-f")
        .arg(bochsrc)
        .arg("-rc")
        .arg(debugger_commands)
        .env("DISPLAY", display)
        .current_dir(dir)
        // At the end of its commands the debugger reads stdin: EOF would quit,
        // so it gets a pipe that stays open (in the `Child`) and says
        // nothing: a stop at the magic breakpoint lasts until Bochs is killed.
        .stdin(Stdio::piped())
        .stdout(output.try_clone().map_err(|e| io_error("bochs.out", e))?)
        .stderr(output)
        .spawn()
        .map_err(BochsError::Spawn)
}

fn io_error(what: &str, error: io::Error) -> BochsError {
    BochsError::Io {
        what: what.to_owned(),
        error,
    }
}

/// Bochs's hard disks are whole cylinders of 16 heads x 63 sectors: a copy
/// of the image padded with zeros to the next cylinder, and its cylinders.
fn padded_disk(image: &Path, dir: &Path) -> Result<(PathBuf, u64)> {
    const CYLINDER_BYTES: u64 = 16 * 63 * 512;
    let mut bytes = std::fs::read(image)
        .map_err(|e| io_error(&format!("cannot read {}", image.display()), e))?;
    let cylinders = (bytes.len() as u64).div_ceil(CYLINDER_BYTES);
    bytes.resize((cylinders * CYLINDER_BYTES) as usize, 0);
    let disk = dir.join("disk.img");
    std::fs::write(&disk, bytes).map_err(|e| io_error("cannot write the padded disk", e))?;
    Ok((disk, cylinders))
}

fn bochsrc_text(options: &BochsOptions, disk: &Path, cylinders: u64, dir: &Path) -> String {
    // The window is redrawn from video memory 10 times a second of
    // *emulated* time (realtime=0), so the kernel's own waits (the goodbye
    // line's 2 s before the magic breakpoint) always span 20 redraws and 20
    // rounds of X event handling, however busy the host. With realtime=1
    // the redraws followed a host-time timer that, on a loaded machine,
    // stalled for over 10 s at a time (3 of 12 runs failed: the window kept
    // the loader's 800x600 after Mode X, or Bochs reached the breakpoint
    // before it had handled the resize to text mode, leaving its bars
    // unpainted); with realtime=0, 26 of 26 passed, 10 beside four busy loops.
    let vga = match options.vga {
        VgaExtension::Vbe => format!(
            "vga: extension=vbe, update_freq=10, realtime=0\n\
             vgaromimage: file={VBE_VGA_BIOS}\n"
        ),
        VgaExtension::Cirrus => format!(
            "pci: enabled=1, chipset=i440fx, slot1=cirrus\n\
             vga: extension=cirrus, update_freq=10, realtime=0\n\
             vgaromimage: file={CIRRUS_VGA_BIOS}\n"
        ),
    };
    // The USB controllers are PCI devices, on the PCI bus Bochs has by
    // default (an i440FX); it places them in free slots itself, and the
    // UHCI is the chipset's own.
    let usb = options
        .usb_keyboard
        .map(|UsbKeyboard { host, port }| {
            format!(
                "{option}: enabled=1, port{port}=keyboard, options{port}=\"speed:low\"\n",
                option = host.option()
            )
        })
        .unwrap_or_default();
    format!(
        "# Written by boot/bochs.rs for one test run.\n\
         # A 64-bit CPU for the kernel's long mode.\n\
         cpu: model=corei7_sandy_bridge_2600k, ips={ips}\n\
         memory: guest=256, host=256\n\
         romimage: file={SYSTEM_BIOS}\n\
         {vga}\
         {usb}\
         ata0-master: type=disk, path={disk}, mode=flat, cylinders={cylinders}, heads=16, spt=63\n\
         boot: disk\n\
         com1: enabled=1, mode=file, dev={serial}\n\
         # Emulated time follows the instruction count, but never runs ahead\n\
         # of the host's clock (it may fall behind on a busy host).\n\
         clock: sync=slowdown, time0=local\n\
         display_library: x\n\
         mouse: enabled=0\n\
         # No sound device to open (and complain about) on a test machine.\n\
         speaker: enabled=0\n\
         # The kernel marks the moment before it switches the machine off\n\
         # with Bochs's magic breakpoint (xchg bx, bx, a no-op elsewhere):\n\
         # Bochs stops in its debugger there, with the goodbye screen in its\n\
         # window for the test to read, instead of closing it. The kernel\n\
         # shows the line for 2 s first, which `sync=slowdown` below makes at\n\
         # least 2 s of host time: 20 window redraws.\n\
         magic_break: enabled=1\n\
         # A log for error messages; panics and errors are logged, never\n\
         # asked about in a dialog and never fatal, so a run always ends with\n\
         # the test's verdict.\n\
         log: {log}\n\
         panic: action=report\n\
         error: action=report\n\
         info: action=ignore\n\
         debug: action=ignore\n",
        ips = options.ips,
        disk = disk.display(),
        serial = dir.join("serial.txt").display(),
        log = dir.join("bochs.log").display(),
    )
}

/// The guest picture inside Bochs's window: the full width, between the
/// toolbar and the status bar. The status bar's top row is a white line
/// across the window; finding it where the layout puts it confirms that the
/// bars are the heights Bochs 2.7 draws them (and that the picture is not
/// cut short or shifted).
pub fn guest_area(window: &RgbImage) -> std::result::Result<RgbImage, LayoutError> {
    const WHITE: [u8; 3] = [255; 3];
    let bars = TOOLBAR_HEIGHT + STATUS_BAR_HEIGHT;
    if window.height <= bars {
        return Err(LayoutError::TooShort {
            width: window.width,
            height: window.height,
        });
    }
    let height = window.height - bars;
    let status_bar_top = TOOLBAR_HEIGHT + height;
    if (0..window.width).any(|x| window.pixel(x, status_bar_top) != WHITE) {
        return Err(LayoutError::NoStatusBar {
            row: status_bar_top,
            width: window.width,
            height: window.height,
        });
    }
    let start = TOOLBAR_HEIGHT * window.width;
    let pixels = window.pixels[start..start + height * window.width].to_vec();
    Ok(RgbImage::new(window.width, height, pixels))
}
