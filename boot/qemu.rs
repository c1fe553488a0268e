//! Starting and driving QEMU: the runner's engine and the test harness in one.
//!
//! A `Qemu` owns the emulator process. Its serial console is collected (and,
//! for the runner, echoed) by a reader thread; its QMP monitor listens on a
//! unix socket and gives us `sendkey` and `screendump`. (QMP rather than the
//! human monitor: QMP's screendump runs as a coroutine that asks the display
//! to update before it saves, and its replies are easy to tell apart from
//! events.) Dropping a `Qemu` kills the process, so a test that fails leaves
//! no emulator behind; and QEMU is started to die with the thread that
//! started it ([`dies_with_its_thread`]), so neither does a test process
//! killed outright, which drops nothing.

use crate::image::{ImageError, RgbImage};
use protocol::{BootRequest, Exit, BOOT_OPTION_FILE};
use serde_json::{json, Value};
use std::fmt;
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::UnixStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// QEMU exits with `(code << 1) | 1` for a write of `code` to isa-debug-exit.
/// QEMU's status when the kernel ends it with success (0x10): after its
/// goodbye, or when a boot request asks.
pub const EXIT_SUCCESS: i32 = Exit::Success.qemu_status();
/// QEMU's status when the kernel ends it with failure (0x11), as a boot
/// request can ask.
pub const EXIT_FAILURE: i32 = Exit::Failure.qemu_status();

/// OVMF from Debian's `ovmf` package.
pub const OVMF_CODE: &str = "/usr/share/OVMF/OVMF_CODE.fd";
/// The variables template for [`OVMF_CODE`], copied for a boot that sets
/// [`QemuOptions::uefi_resolution`].
pub const OVMF_VARS: &str = "/usr/share/OVMF/OVMF_VARS.fd";

/// The vendor GUID of OVMF's `PlatformConfig` variable
/// (`gOvmfPlatformConfigGuid`, OvmfPkg/PlatformDxe).
const OVMF_PLATFORM_CONFIG_GUID: &str = "7235c51c-0c80-4cab-87ac-3b084a6304b1";

/// 32-bit OVMF (a 32-bit UEFI, as on Bay Trail tablets and Compute Sticks)
/// from Debian's `ovmf-ia32` package: only a Secure Boot build, which needs
/// SMM and its flash writable only from SMM (Secure Boot itself stays off
/// with the empty variables of [`OVMF32_VARS`]).
pub const OVMF32_CODE: &str = "/usr/share/OVMF/OVMF32_CODE_4M.secboot.fd";
/// The variables template for [`OVMF32_CODE`], copied for each boot.
pub const OVMF32_VARS: &str = "/usr/share/OVMF/OVMF32_VARS_4M.fd";

/// The id of the display device (`bochs-display`), to which a keyboard can
/// be bound (`-device usb-kbd,display=video0`) so that
/// [`Qemu::press_key_on`] reaches it alone.
pub const DISPLAY_ID: &str = "video0";

/// How long `send_key` holds a key down, as QEMU's own default.
const DEFAULT_HOLD_MILLIS: u32 = 100;

/// What QEMU boots the disk with; each needs its own disk image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Firmware {
    /// SeaBIOS, QEMU's default, booting the BIOS image from its MBR.
    Bios,
    /// OVMF ([`OVMF_CODE`]), booting the UEFI image's EFI partition.
    Uefi,
    /// 32-bit OVMF ([`OVMF32_CODE`]) on a Q35 with SMM and a 64-bit CPU,
    /// booting `EFI/BOOT/BOOTIA32.EFI` of the one image's partition.
    Uefi32,
}

/// How the disk image is attached to the emulated PC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DiskAttachment {
    /// The first hard disk (QEMU's default: IDE on `pc`, AHCI on `q35`).
    HardDisk,
    /// A USB stick (`usb-storage`) on its own USB host controller, and no
    /// hard disk: the firmware must boot from USB, as a PC booted from a
    /// stick does.
    UsbStick(UsbHost),
    /// A virtio disk (`virtio-blk-pci`), booted from: a third disk path for
    /// the firmware beside IDE and AHCI. With [`QemuOptions::read_errors`]
    /// the firmware's virtio driver sees `EFI_DEVICE_ERROR` as from a flaky
    /// stick.
    Virtio,
}

/// A USB host controller QEMU emulates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsbHost {
    /// `qemu-xhci`: USB 3 (xHCI), what a PC of today has.
    Xhci,
    /// `usb-ehci`: USB 2 (EHCI), what a PC of the 2000s has, alone (no
    /// companion: full- and low-speed devices work only if QEMU lets it
    /// keep them).
    Ehci,
    /// `pci-ohci`: USB 1.1 (OHCI), as on AMD, SiS and VIA chipsets.
    Ohci,
    /// `piix3-usb-uhci`: USB 1.1 (UHCI), as on Intel and VIA chipsets.
    Uhci,
    /// ICH9's EHCI (`ich9-usb-ehci1`, 00:1d.7) with its three UHCI
    /// companions (`ich9-usb-uhci1..3`, 00:1d.0-2, two ports each), as
    /// QEMU's `docs/config/ich9-ehci-uhci.cfg` lays them out: devices go on
    /// the EHCI's bus, and full- and low-speed ones are handed to a
    /// companion.
    Ich9EhciWithCompanions,
}

impl UsbHost {
    /// QEMU's device name (the EHCI's, for ICH9's set).
    pub fn device(self) -> &'static str {
        match self {
            UsbHost::Xhci => "qemu-xhci",
            UsbHost::Ehci => "usb-ehci",
            UsbHost::Ohci => "pci-ohci",
            UsbHost::Uhci => "piix3-usb-uhci",
            UsbHost::Ich9EhciWithCompanions => "ich9-usb-ehci1",
        }
    }

    /// Every host, for the runner's list.
    pub const ALL: [UsbHost; 5] = [
        UsbHost::Xhci,
        UsbHost::Ehci,
        UsbHost::Ohci,
        UsbHost::Uhci,
        UsbHost::Ich9EhciWithCompanions,
    ];

    /// The runner's name for it (`--usb-stick`, `--usb-keyboard`).
    pub fn name(self) -> &'static str {
        match self {
            UsbHost::Xhci => "xhci",
            UsbHost::Ehci => "ehci",
            UsbHost::Ohci => "ohci",
            UsbHost::Uhci => "uhci",
            UsbHost::Ich9EhciWithCompanions => "ich9",
        }
    }

    /// The host of that name.
    pub fn from_name(name: &str) -> Option<UsbHost> {
        UsbHost::ALL.into_iter().find(|host| host.name() == name)
    }

    /// The `-device` values that fit the host with QEMU id `id`: devices then
    /// go on bus `{id}.0`.
    pub fn devices(self, id: &str) -> Vec<String> {
        match self {
            UsbHost::Ich9EhciWithCompanions => {
                let mut devices =
                    vec![format!("ich9-usb-ehci1,id={id},addr=1d.7,multifunction=on")];
                for (n, first_port) in [(1, 0), (2, 2), (3, 4)] {
                    devices.push(format!(
                        "ich9-usb-uhci{n},id={id}-uhci{n},addr=1d.{},multifunction=on,masterbus={id}.0,firstport={first_port}",
                        n - 1
                    ));
                }
                devices
            }
            host => vec![format!("{},id={id}", host.device())],
        }
    }
}

/// QEMU's id of the USB stick's own host controller: more USB devices go on
/// it as `bus=stickhost.0`.
pub const STICK_HOST_ID: &str = "stickhost";

/// Whether QEMU shows a window; tests look at the screen through QMP either way.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Display {
    /// No window: `-display none`.
    Headless,
    /// QEMU's default window.
    Window,
}

/// The display adapter QEMU emulates; each brings its own VGA BIOS.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Graphics {
    /// QEMU's standard VGA (Bochs VBE extensions), with the legacy VGA registers.
    StdVga,
    /// A framebuffer-only adapter with no legacy VGA at all.
    BochsDisplay,
    /// Cirrus Logic GD5446 on PCI.
    Cirrus,
    /// Cirrus Logic on the ISA bus of an `isapc` machine (no VBE linear modes).
    IsaCirrus,
    /// ATI Rage 128 Pro.
    Ati,
    /// VMware SVGA II.
    Vmware,
    /// QXL (SPICE).
    Qxl,
    /// virtio-gpu with a VGA.
    Virtio,
    /// virtio-gpu on PCI alone (`-device virtio-gpu-pci`): no legacy VGA, and
    /// under OVMF a GOP in Blt-only mode, so no framebuffer either.
    VirtioGpu,
    /// Two adapters: virtio-gpu first (a Blt-only GOP under OVMF), QEMU's
    /// standard VGA second (id `vga`, for [`Qemu::screendump_of`]).
    VirtioGpuThenStdVga,
}

impl Graphics {
    /// Every adapter, in the order `docs/hardware.md`'s table lists them.
    pub const ALL: [Graphics; 8] = [
        Graphics::StdVga,
        Graphics::Cirrus,
        Graphics::Vmware,
        Graphics::Qxl,
        Graphics::Virtio,
        Graphics::Ati,
        Graphics::IsaCirrus,
        Graphics::BochsDisplay,
    ];

    /// The two set-ups without a usable legacy VGA that the loader tests
    /// boot: `--vga` takes them too, after [`Graphics::ALL`].
    pub const WITHOUT_LEGACY_VGA: [Graphics; 2] =
        [Graphics::VirtioGpu, Graphics::VirtioGpuThenStdVga];

    /// Every adapter `--vga` takes.
    pub fn choices() -> impl Iterator<Item = Graphics> {
        Graphics::ALL
            .into_iter()
            .chain(Graphics::WITHOUT_LEGACY_VGA)
    }

    /// The runner's name for it (`--vga NAME`).
    pub fn name(self) -> &'static str {
        match self {
            Graphics::StdVga => "std",
            Graphics::BochsDisplay => "bochs-display",
            Graphics::Cirrus => "cirrus",
            Graphics::IsaCirrus => "isa-cirrus",
            Graphics::Ati => "ati",
            Graphics::Vmware => "vmware",
            Graphics::Qxl => "qxl",
            Graphics::Virtio => "virtio",
            Graphics::VirtioGpu => "virtio-gpu",
            Graphics::VirtioGpuThenStdVga => "virtio-gpu+std",
        }
    }

    /// The adapter with this runner name.
    pub fn from_name(name: &str) -> Option<Graphics> {
        Graphics::choices().find(|g| g.name() == name)
    }

    /// QEMU's arguments for it.
    fn qemu_args(self, precise_retrace: bool) -> &'static [&'static str] {
        match self {
            Graphics::StdVga if precise_retrace => &["-vga", "std,retrace=precise"],
            Graphics::StdVga => &["-vga", "std"],
            Graphics::BochsDisplay => &["-vga", "none", "-device", "bochs-display,id=video0"],
            Graphics::Cirrus => &["-vga", "none", "-device", "cirrus-vga"],
            // The board (`isapc`) and its CPU come from `Board::qemu_machine`.
            Graphics::IsaCirrus => &["-vga", "none", "-device", "isa-cirrus-vga"],
            Graphics::Ati => &["-vga", "none", "-device", "ati-vga"],
            Graphics::Vmware => &["-vga", "none", "-device", "vmware-svga"],
            Graphics::Qxl => &["-vga", "none", "-device", "qxl-vga"],
            Graphics::Virtio => &["-vga", "none", "-device", "virtio-vga"],
            Graphics::VirtioGpu => &["-vga", "none", "-device", "virtio-gpu-pci"],
            Graphics::VirtioGpuThenStdVga => &[
                "-vga",
                "none",
                "-device",
                "virtio-gpu-pci",
                "-device",
                "VGA,id=vga",
            ],
        }
    }
}

/// The emulated PC's chipset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Chipset {
    /// `-M pc`: the i440FX, QEMU's default, a late-1990s PC.
    I440fx,
    /// `-M q35`: the Q35 with ICH9, PCI Express, AHCI, as a PC of today looks.
    Q35,
}

/// The emulated PC: its chipset and which legacy devices it has. Recent Intel
/// platforms gate the 8254 PIT's clock, UEFI-only desktops have no i8042, and
/// many boards leave the HPET out of their ACPI tables; each can be taken away.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Board {
    /// The chipset.
    pub chipset: Chipset,
    /// The 8254 PIT is fitted (`pit=off` takes it away).
    pub pit: bool,
    /// The i8042 keyboard controller is fitted (`i8042=off`).
    pub i8042: bool,
    /// The HPET is fitted and in the ACPI tables (`hpet=off`).
    pub hpet: bool,
}

impl Board {
    /// QEMU's default PC: i440FX with a PIT, an i8042 and an HPET.
    pub const PC: Board = Board {
        chipset: Chipset::I440fx,
        pit: true,
        i8042: true,
        hpet: true,
    };

    /// A Q35 with every legacy device.
    pub const Q35: Board = Board {
        chipset: Chipset::Q35,
        ..Board::PC
    };

    /// QEMU's `-M` value. An ISA-only adapter needs the `isapc` board, whose
    /// default CPU (a 486) cannot run a 64-bit kernel: the CPU is named too.
    fn qemu_machine(&self, graphics: Graphics) -> Vec<String> {
        let on_off = |fitted: bool| if fitted { "on" } else { "off" };
        let name = match (graphics, self.chipset) {
            (Graphics::IsaCirrus, _) => "isapc",
            (_, Chipset::I440fx) => "pc",
            (_, Chipset::Q35) => "q35",
        };
        let mut machine = format!(
            "{name},pit={},i8042={}",
            on_off(self.pit),
            on_off(self.i8042)
        );
        if name != "isapc" {
            // isapc has no HPET property (nor an HPET).
            machine.push_str(&format!(",hpet={}", on_off(self.hpet)));
        }
        let mut args = vec!["-M".to_string(), machine];
        if name == "isapc" {
            args.extend(["-cpu".to_string(), "qemu64".to_string()]);
        }
        args
    }
}

/// An option ROM for the firmware to run (`-option-rom PATH[,bootindex=N]`):
/// SeaBIOS runs it during POST, and, if its PnP header has a Boot Entry
/// Vector and `bootindex` puts it first, boots from it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OptionRom {
    /// The ROM file: whole 512-byte blocks, its checksum right.
    pub path: PathBuf,
    /// Its place in the boot order (0 first), if it is a boot device.
    pub bootindex: Option<u32>,
}

/// A disk read that fails, injected under the disk image by QEMU's blkdebug
/// driver: every read request that covers `sector` fails with EIO, as a
/// worn disk's or stick's bad sector does, whatever the firmware's disk path
/// (IDE, AHCI, USB).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadError {
    /// The 512-byte sector (LBA) that cannot be read.
    pub sector: u64,
    /// How often reads of it fail.
    pub failures: ReadFailures,
}

/// How often an injected read error happens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ReadFailures {
    /// The first this many reads that cover the sector fail, then it reads
    /// (one blkdebug rule with `once = "on"` each).
    Times(u32),
    /// Every read of the sector fails.
    Always,
}

impl ReadError {
    /// The blkdebug rules for this error (QEMU's "Block I/O error injection
    /// using blkdebug" document):
    /// each `[inject-error]` rule is armed by the `read_aio` event that the
    /// raw format driver raises before every read, and fires on a read that
    /// covers `sector`; a `once` rule is removed once it has fired.
    fn blkdebug_rules(&self) -> String {
        let rule = |once: bool| {
            format!(
                "[inject-error]\nevent = \"read_aio\"\nerrno = \"5\"\nsector = \"{}\"\nonce = \"{}\"\n\n",
                self.sector,
                if once { "on" } else { "off" }
            )
        };
        match self.failures {
            ReadFailures::Times(n) => (0..n).map(|_| rule(true)).collect(),
            ReadFailures::Always => rule(false),
        }
    }
}

/// A file put into guest RAM at `address` before the firmware starts
/// (`-device loader,file=PATH,addr=ADDRESS,force-raw=on`): what a real PC's
/// RAM holds at power-on is whatever it held, not zeros.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RamFile {
    /// The bytes.
    pub path: PathBuf,
    /// The guest-physical address of the first byte.
    pub address: u64,
}

impl Default for Board {
    fn default() -> Self {
        Board::PC
    }
}

/// The guest's RAM unless [`QemuOptions::memory_mib`] says otherwise.
pub const DEFAULT_MEMORY_MIB: u32 = 256;

/// How to start QEMU: [`QemuOptions::new`] gives what the tests use, and the
/// fields are changed from there.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The disk image, attached raw in snapshot mode (the file is never written).
    pub image: PathBuf,
    /// How the image is attached: as the hard disk, or as a USB stick.
    pub disk: DiskAttachment,
    /// Must match the image: BIOS or UEFI.
    pub firmware: Firmware,
    /// Headless for tests, a window for a person.
    pub display: Display,
    /// The emulated display adapter.
    pub graphics: Graphics,
    /// The chipset and the legacy devices fitted.
    pub board: Board,
    /// More devices, each given to QEMU as `-device VALUE` in order (for
    /// example `qemu-xhci` then `usb-kbd,id=usbkbd`).
    pub devices: Vec<String>,
    /// Make QEMU time Input Status 1's retrace bits from the CRTC timings
    /// (about 60 Hz in Mode X) instead of toggling them on every read.
    pub precise_retrace: bool,
    /// Passed to the kernel through fw_cfg as `opt/modex/boot`.
    pub boot: BootRequest,
    /// Echo the serial console to this process's stdout as it arrives.
    pub echo_serial: bool,
    /// Fit `isa-debug-exit`, so the kernel can end QEMU. Without it the
    /// kernel powers the machine off through ACPI, as on a real PC.
    pub debug_exit: bool,
    /// On a power-off by the guest, stop the machine but keep QEMU running
    /// (`-no-shutdown`), so its last screen can still be looked at; see
    /// [`Qemu::wait_powered_off`]. Otherwise QEMU exits.
    pub keep_after_power_off: bool,
    /// Count guest time in instructions (`-icount shift=0,sleep=off`): one
    /// instruction a nanosecond, whatever the host's load, so the kernel's
    /// timing reports (boot option `bench`, `present:`) repeat exactly. The
    /// guest then runs slower than real time.
    pub instruction_clock: bool,
    /// With UEFI: boot OVMF's Secure Boot build
    /// ([`crate::secure_boot::OVMF_SECURE_BOOT_CODE`]) on a Q35 with SMM,
    /// its variables in this file (read and written: enrolled keys stay).
    /// With 32-bit UEFI (always the Secure Boot build): its variables in
    /// this file instead of a fresh copy of the empty [`OVMF32_VARS`].
    pub secure_boot_vars: Option<PathBuf>,
    /// With UEFI (without [`QemuOptions::secure_boot_vars`]): the screen
    /// size OVMF sets its console to, as its setup page would: OVMF runs
    /// from flash with a fresh copy of [`OVMF_VARS`] whose `PlatformConfig`
    /// variable holds it (written by virt-fw-vars). OVMF picks its mode of
    /// that size; on a Cirrus, 1024x768 is a 24-bit one.
    pub uefi_resolution: Option<(u32, u32)>,
    /// QEMU's `-cpu` value, when not the board's default (for example
    /// `qemu64,-nx`: a CPU without the no-execute bit).
    pub cpu: Option<String>,
    /// The guest's RAM in MiB (`-m`).
    pub memory_mib: u32,
    /// Option ROMs for SeaBIOS to run (and perhaps boot), in order.
    pub option_roms: Vec<OptionRom>,
    /// Reads of the disk image that fail (QEMU's blkdebug under the image;
    /// the image is still attached in snapshot mode).
    pub read_errors: Vec<ReadError>,
    /// Files loaded into RAM before the firmware runs, in order.
    pub ram_files: Vec<RamFile>,
}

impl QemuOptions {
    /// BIOS, headless, QEMU's default PC, standard VGA with precise retrace timing, the default
    /// boot request, no serial echo, and `isa-debug-exit` fitted.
    pub fn new(image: impl Into<PathBuf>) -> Self {
        QemuOptions {
            image: image.into(),
            disk: DiskAttachment::HardDisk,
            firmware: Firmware::Bios,
            display: Display::Headless,
            graphics: Graphics::StdVga,
            board: Board::PC,
            devices: Vec::new(),
            precise_retrace: true,
            boot: BootRequest::default(),
            echo_serial: false,
            debug_exit: true,
            keep_after_power_off: false,
            instruction_clock: false,
            secure_boot_vars: None,
            uefi_resolution: None,
            cpu: None,
            memory_mib: DEFAULT_MEMORY_MIB,
            option_roms: Vec::new(),
            read_errors: Vec::new(),
            ram_files: Vec::new(),
        }
    }
}

/// A copy of [`OVMF_VARS`] in `dir` whose `PlatformConfig` variable asks
/// OVMF for this console resolution: the struct's first two fields,
/// HorizontalResolution and VerticalResolution, little-endian UINT32s;
/// non-volatile and boot-service access, as OVMF's setup page saves it.
fn platform_config_vars(dir: &Path, (width, height): (u32, u32)) -> Result<PathBuf> {
    let data: String = [width, height]
        .iter()
        .flat_map(|value| value.to_le_bytes())
        .map(|byte| format!("{byte:02x}"))
        .collect();
    let json = format!(
        r#"{{"version": 2, "variables": [{{"name": "PlatformConfig", "guid": "{OVMF_PLATFORM_CONFIG_GUID}", "attr": 3, "data": "{data}"}}]}}"#
    );
    let json_path = dir.join("platform-config.json");
    let vars = dir.join("OVMF_VARS.fd");
    std::fs::write(&json_path, json)
        .map_err(|e| QemuError::Io(format!("cannot write {}: {e}", json_path.display())))?;
    let tool =
        crate::secure_boot::virt_fw_vars().map_err(|e| QemuError::NotInstalled(e.to_string()))?;
    let output = Command::new(&tool)
        .args(["--input", OVMF_VARS, "--output"])
        .arg(&vars)
        .arg("--set-json")
        .arg(&json_path)
        .output()
        .map_err(|e| QemuError::Io(format!("cannot run {}: {e}", tool.display())))?;
    if !output.status.success() {
        return Err(QemuError::Io(format!(
            "virt-fw-vars could not write PlatformConfig into a copy of {OVMF_VARS}: {}",
            String::from_utf8_lossy(&output.stderr)
        )));
    }
    Ok(vars)
}

/// What went wrong with QEMU; each carries a message that says what to do.
#[derive(Debug, thiserror::Error)]
pub enum QemuError {
    /// The executable or the firmware is missing: how to install it.
    #[error("{0}")]
    NotInstalled(String),
    /// The operating system refused something (a scratch directory, a wait).
    #[error("{0}")]
    Io(String),
    /// A wait ran out; the message holds the console so far.
    #[error("{0}")]
    Timeout(String),
    /// QEMU ended before what was waited for happened.
    #[error("{0}")]
    Exited(String),
    /// The QMP monitor refused a command or answered nonsense.
    #[error("{0}")]
    Monitor(String),
    /// The picture QEMU's screendump wrote could not be read.
    #[error("cannot read QEMU's screendump: {0}")]
    Screendump(ImageError),
}

type Result<T> = std::result::Result<T, QemuError>;

/// The emulator the runner and the tests start, found on PATH.
pub const QEMU_BINARY: &str = "qemu-system-x86_64";

/// Fails with an actionable message when QEMU (or OVMF, for UEFI) is missing.
pub fn check_installed(firmware: Firmware) -> Result<()> {
    let found = Command::new(QEMU_BINARY)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !found {
        return Err(QemuError::NotInstalled(format!(
            "{QEMU_BINARY} was not found. Install it with `boot/setup.sh` \
             (or `sudo apt-get install qemu-system-x86`)."
        )));
    }
    if firmware == Firmware::Uefi && !Path::new(OVMF_CODE).exists() {
        return Err(QemuError::NotInstalled(format!(
            "{OVMF_CODE} was not found. Install OVMF with `boot/setup.sh` (or `sudo apt-get install ovmf`)."
        )));
    }
    if firmware == Firmware::Uefi32 {
        for file in [OVMF32_CODE, OVMF32_VARS] {
            if !Path::new(file).exists() {
                return Err(QemuError::NotInstalled(format!(
                    "{file} was not found. Install 32-bit OVMF with `boot/setup.sh` \
                     (or `sudo apt-get install ovmf-ia32`)."
                )));
            }
        }
    }
    Ok(())
}

/// The serial console so far, and a signal for each new chunk of it.
#[derive(Default)]
struct SerialLog {
    console: Mutex<Console>,
    grew: Condvar,
}

/// The text QEMU has printed, and when each line arrived.
#[derive(Default)]
struct Console {
    text: String,
    /// For each line: where it ends in `text`, and when it arrived.
    arrivals: Vec<(usize, Instant)>,
    /// What has come after the last newline: firmware screens (shim's,
    /// MokManager's) are drawn with cursor moves and may end no line for a
    /// long time. Waits look at it; [`Qemu::serial`] leaves it out.
    partial: String,
}

/// However the guest progresses, a wait gives up after this much wall-clock
/// time: the bound for a guest that hangs without using the CPU (halted
/// with interrupts off), which no progress budget would catch.
pub const WALL_CLOCK_CEILING: Duration = Duration::from_secs(600);

/// The CPU time process `pid` has used so far, all its threads together:
/// `/proc/PID/stat`'s utime and stime, in USER_HZ ticks, which Linux fixes at
/// 100 a second for user space. For QEMU under TCG this is the emulated
/// machine's progress, whatever else the host is running; `None` once the
/// process is gone.
fn process_cpu_time(pid: u32) -> Option<Duration> {
    const USER_HZ: u64 = 100;
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name, in parentheses, may hold spaces: fields after it.
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    // utime and stime are the 14th and 15th fields; the 3rd is the first
    // after the name.
    let ticks = fields.get(11)?.parse::<u64>().ok()? + fields.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 1000 / USER_HZ))
}

/// A wait's bound by the guest's progress rather than the host's speed: the
/// wait may go on while QEMU has used less than `budget` of CPU time since
/// the serial console last grew (on a busy host QEMU gets less of the CPU,
/// and the budget stretches with it), and for at most
/// [`WALL_CLOCK_CEILING`] in all.
struct Watchdog {
    budget: Duration,
    started: Instant,
    /// QEMU's CPU time when the console last grew (or the wait began).
    cpu_at_progress: Duration,
    cpu_now: Duration,
    console_bytes: usize,
}

impl Watchdog {
    fn new(pid: u32, budget: Duration, console_bytes: usize) -> Watchdog {
        let cpu = process_cpu_time(pid).unwrap_or_default();
        Watchdog {
            budget,
            started: Instant::now(),
            cpu_at_progress: cpu,
            cpu_now: cpu,
            console_bytes,
        }
    }

    /// `None` while the wait may go on, else why it may not.
    fn expired(&mut self, pid: u32, console_bytes: usize) -> Option<String> {
        if let Some(cpu) = process_cpu_time(pid) {
            self.cpu_now = cpu;
        }
        if console_bytes != self.console_bytes {
            self.console_bytes = console_bytes;
            self.cpu_at_progress = self.cpu_now;
        }
        let quiet = self.cpu_now.saturating_sub(self.cpu_at_progress);
        let waited = self.started.elapsed();
        if quiet >= self.budget {
            Some(format!(
                "QEMU ran {quiet:.1?} of CPU time (its budget: {:?}) without a new line on \
                 serial ({waited:.1?} of wall-clock time into the wait)",
                self.budget
            ))
        } else if waited >= WALL_CLOCK_CEILING {
            Some(format!(
                "{waited:.1?} of wall-clock time passed, the ceiling of any wait \
                 (QEMU ran {quiet:.1?} of CPU time since serial last grew: a guest \
                 hung without using the CPU, or printing on and on without it)"
            ))
        } else {
            None
        }
    }
}

/// A running QEMU: its serial console (read on a thread as it arrives) and
/// its QMP monitor for keys and screendumps. Dropping it kills QEMU.
pub struct Qemu {
    child: Child,
    /// Just before QEMU was started.
    started: Instant,
    serial: Arc<SerialLog>,
    monitor: BufReader<UnixStream>,
    scratch: tempfile::TempDir,
}

impl fmt::Debug for Qemu {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Qemu")
            .field("pid", &self.child.id())
            .field("scratch", &self.scratch.path())
            .finish_non_exhaustive()
    }
}

impl Qemu {
    /// Starts QEMU and waits until its QMP monitor answers; the kernel may
    /// not have printed anything yet.
    pub fn start(options: &QemuOptions) -> Result<Qemu> {
        check_installed(options.firmware)?;
        let scratch = tempfile::Builder::new()
            .prefix("modex-cube-")
            .tempdir()
            .map_err(|e| QemuError::Io(format!("cannot make a scratch dir: {e}")))?;
        let monitor_path = scratch.path().join("monitor.sock");

        let mut command = dies_with_its_thread(QEMU_BINARY);
        let image = if options.read_errors.is_empty() {
            format!("format=raw,file={},snapshot=on", options.image.display())
        } else {
            // blkdebug between the raw format and the file: its rules in a
            // file of their own (`blkdebug:RULES:IMAGE`).
            let rules = scratch.path().join("blkdebug.conf");
            let text: String = options
                .read_errors
                .iter()
                .map(ReadError::blkdebug_rules)
                .collect();
            std::fs::write(&rules, text)
                .map_err(|e| QemuError::Io(format!("cannot write {}: {e}", rules.display())))?;
            format!(
                "format=raw,file=blkdebug:{}:{},snapshot=on",
                rules.display(),
                options.image.display()
            )
        };
        match options.disk {
            DiskAttachment::HardDisk => {
                command.arg("-drive").arg(image);
            }
            DiskAttachment::UsbStick(host) => {
                command
                    .arg("-drive")
                    .arg(format!("if=none,id=stick,{image}"));
                for device in host.devices(STICK_HOST_ID) {
                    command.arg("-device").arg(device);
                }
                command.arg("-device").arg(format!(
                    "usb-storage,bus={STICK_HOST_ID}.0,drive=stick,bootindex=0"
                ));
            }
            DiskAttachment::Virtio => {
                command
                    .arg("-drive")
                    .arg(format!("if=none,id=virtiodisk,{image}"))
                    .arg("-device")
                    .arg("virtio-blk-pci,drive=virtiodisk,bootindex=0");
            }
        }
        command
            .arg("-m")
            .arg(format!("{}M", options.memory_mib))
            .args(["-no-reboot", "-serial", "stdio"])
            .arg("-qmp")
            .arg(format!(
                "unix:{},server=on,wait=off",
                monitor_path.display()
            ));
        let mut machine = options.board.qemu_machine(options.graphics);
        if options.secure_boot_vars.is_some() || options.firmware == Firmware::Uefi32 {
            // OVMF's Secure Boot builds (32-bit OVMF has only that one) keep
            // their variables safe in SMM: Q35 with SMM on, and the flash
            // writable only from SMM.
            machine[1] = machine[1].replacen("pc,", "q35,", 1) + ",smm=on";
        }
        command.args(machine);
        command.args(options.graphics.qemu_args(options.precise_retrace));
        if let Some(cpu) = &options.cpu {
            // After the board's own `-cpu`, if any: QEMU takes the last.
            command.arg("-cpu").arg(cpu);
        }
        for device in &options.devices {
            command.arg("-device").arg(device);
        }
        for rom in &options.option_roms {
            let mut arg = rom.path.display().to_string();
            if let Some(index) = rom.bootindex {
                arg.push_str(&format!(",bootindex={index}"));
            }
            command.arg("-option-rom").arg(arg);
        }
        for file in &options.ram_files {
            command.arg("-device").arg(format!(
                "loader,file={},addr={:#x},force-raw=on",
                file.path.display(),
                file.address
            ));
        }
        match (&options.secure_boot_vars, options.firmware) {
            (Some(vars), Firmware::Uefi) => {
                command
                    .arg("-drive")
                    .arg(format!(
                        "if=pflash,format=raw,unit=0,readonly=on,file={}",
                        crate::secure_boot::OVMF_SECURE_BOOT_CODE
                    ))
                    .arg("-drive")
                    .arg(format!(
                        "if=pflash,format=raw,unit=1,file={}",
                        vars.display()
                    ))
                    .args(["-global", "driver=cfi.pflash01,property=secure,value=on"]);
            }
            (None, Firmware::Uefi) => match options.uefi_resolution {
                None => {
                    command.args(["-bios", OVMF_CODE]);
                }
                Some(resolution) => {
                    let vars = platform_config_vars(scratch.path(), resolution)?;
                    command
                        .arg("-drive")
                        .arg(format!(
                            "if=pflash,format=raw,unit=0,readonly=on,file={OVMF_CODE}"
                        ))
                        .arg("-drive")
                        .arg(format!(
                            "if=pflash,format=raw,unit=1,file={}",
                            vars.display()
                        ));
                }
            },
            (given, Firmware::Uefi32) => {
                // The given variables, else a fresh copy of the empty ones
                // each boot.
                let vars = match given {
                    Some(vars) => vars.clone(),
                    None => {
                        let vars = scratch.path().join("OVMF32_VARS_4M.fd");
                        std::fs::copy(OVMF32_VARS, &vars).map_err(|e| {
                            QemuError::Io(format!(
                                "cannot copy {OVMF32_VARS} to {}: {e}",
                                vars.display()
                            ))
                        })?;
                        vars
                    }
                };
                command
                    .arg("-drive")
                    .arg(format!(
                        "if=pflash,format=raw,unit=0,readonly=on,file={OVMF32_CODE}"
                    ))
                    .arg("-drive")
                    .arg(format!(
                        "if=pflash,format=raw,unit=1,file={}",
                        vars.display()
                    ))
                    .args(["-global", "driver=cfi.pflash01,property=secure,value=on"]);
            }
            (_, Firmware::Bios) => {}
        }
        if options.debug_exit {
            command.args(["-device", "isa-debug-exit,iobase=0xf4,iosize=0x04"]);
        }
        if options.keep_after_power_off {
            command.arg("-no-shutdown");
        }
        if options.instruction_clock {
            command.args(["-icount", "shift=0,sleep=off"]);
        }
        if options.display == Display::Headless {
            command.args(["-display", "none"]);
        }
        if !options.boot.is_empty() {
            command
                .arg("-fw_cfg")
                .arg(format!("name={BOOT_OPTION_FILE},string={}", options.boot));
        }
        command
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());

        let started = Instant::now();
        let mut child = command
            .spawn()
            .map_err(|e| QemuError::NotInstalled(format!("cannot start {QEMU_BINARY}: {e}")))?;
        let serial = Arc::new(SerialLog::default());
        spawn_reader(
            child.stdout.take().expect("stdout is piped"),
            Arc::clone(&serial),
            options.echo_serial,
        );
        spawn_reader(
            child.stderr.take().expect("stderr is piped"),
            Arc::clone(&serial),
            true,
        );

        let monitor = connect_monitor(&monitor_path, &mut child, &serial)?;
        let mut qemu = Qemu {
            child,
            started,
            serial,
            monitor: BufReader::new(monitor),
            scratch,
        };
        qemu.read_reply()?; // the greeting
        qemu.execute(json!({ "execute": "qmp_capabilities" }))?;
        Ok(qemu)
    }

    /// Everything the kernel has printed on serial so far.
    pub fn serial(&self) -> String {
        self.serial.console.lock().unwrap().text.clone()
    }

    /// The CPU time QEMU has used so far (all its threads): how far the
    /// emulated machine has got, whatever else the host runs; `None` once
    /// QEMU has exited. For a test's own bound by the guest's progress.
    pub fn cpu_time(&self) -> Option<Duration> {
        process_cpu_time(self.child.id())
    }

    /// When the line holding the first `needle` on serial arrived, counted
    /// from just before QEMU started; `None` if it has not.
    pub fn arrival(&self, needle: &str) -> Option<Duration> {
        let console = self.serial.console.lock().unwrap();
        let at = console.text.find(needle)?;
        let (_, arrived) = console.arrivals.iter().find(|(end, _)| *end > at)?;
        Some(arrived.duration_since(self.started))
    }

    /// When QEMU's first output arrived (the guest's first line on serial,
    /// unless QEMU warned on stderr first), counted from just before QEMU
    /// started; `None` before any.
    pub fn first_output(&self) -> Option<Duration> {
        let console = self.serial.console.lock().unwrap();
        let (_, arrived) = console.arrivals.first()?;
        Some(arrived.duration_since(self.started))
    }

    /// Waits until the serial console contains `needle`; returns the console.
    /// `budget` bounds the wait by the guest's progress: it fails once QEMU
    /// has used that much CPU time with nothing new on serial (see
    /// [`WALL_CLOCK_CEILING`] for the wall-clock bound).
    pub fn wait_for_serial(&mut self, needle: &str, budget: Duration) -> Result<String> {
        self.wait_for_serial_count(needle, 1, budget)
    }

    /// Waits until `needle` has appeared `count` times on the serial
    /// console; `budget` as for [`Qemu::wait_for_serial`].
    pub fn wait_for_serial_count(
        &mut self,
        needle: &str,
        count: usize,
        budget: Duration,
    ) -> Result<String> {
        let what = format!("{needle:?} (x{count})");
        self.wait_for_console(&what, budget, |text| text.matches(needle).count() >= count)
    }

    /// As [`Qemu::wait_for_serial_count`], but also looking at the text after
    /// the last newline: firmware screens (shim's, MokManager's) are drawn
    /// with cursor moves and may end no line for a long time. The kernel's
    /// lines are matched whole by the other waits, so that a line a wait saw
    /// is always in [`Qemu::serial`] too.
    pub fn wait_for_screen_text(
        &mut self,
        needle: &str,
        count: usize,
        budget: Duration,
    ) -> Result<String> {
        let what = format!("{needle:?} (x{count}) on the firmware's screen");
        self.wait_for_text(&what, budget, true, |text| {
            text.matches(needle).count() >= count
        })
    }

    /// Waits until `done` holds for the serial console's whole lines (`what`
    /// names it in an error); `budget` as for [`Qemu::wait_for_serial`].
    pub fn wait_for_console(
        &mut self,
        what: &str,
        budget: Duration,
        done: impl Fn(&str) -> bool,
    ) -> Result<String> {
        self.wait_for_text(what, budget, false, done)
    }

    fn wait_for_text(
        &mut self,
        what: &str,
        budget: Duration,
        with_partial_line: bool,
        done: impl Fn(&str) -> bool,
    ) -> Result<String> {
        let pid = self.child.id();
        let mut console = self.serial.console.lock().unwrap();
        // Firmware screens with no newline yet are progress too.
        let seen = |console: &Console| console.text.len() + console.partial.len();
        let mut watchdog = Watchdog::new(pid, budget, seen(&console));
        loop {
            if done(&console.text) {
                return Ok(console.text.clone());
            }
            if with_partial_line && !console.partial.is_empty() {
                let with_partial = format!("{}{}", console.text, console.partial);
                if done(&with_partial) {
                    return Ok(with_partial);
                }
            }
            if let Ok(Some(status)) = self.child.try_wait() {
                return Err(QemuError::Exited(format!(
                    "QEMU exited ({status}) before {what} appeared; console:\n{}",
                    console.text
                )));
            }
            if let Some(why) = watchdog.expired(pid, seen(&console)) {
                return Err(QemuError::Timeout(format!(
                    "gave up waiting for {what} on serial: {why}; console so far:\n{}",
                    console.text
                )));
            }
            console = self
                .serial
                .grew
                .wait_timeout(console, Duration::from_millis(100))
                .unwrap()
                .0;
        }
    }

    /// Sends one QMP command and returns what it returned; a QMP error
    /// reply is an error.
    fn execute(&mut self, command: Value) -> Result<Value> {
        let line = format!("{command}\n");
        self.monitor
            .get_mut()
            .write_all(line.as_bytes())
            .map_err(|e| QemuError::Monitor(format!("QMP write failed: {e}")))?;
        let mut reply = self.read_reply()?;
        if let Some(error) = reply.get("error") {
            return Err(QemuError::Monitor(format!(
                "QEMU refused {command}: {error}"
            )));
        }
        Ok(reply["return"].take())
    }

    /// Plugs a device in while the machine runs (QMP `device_add`), as
    /// `-device` would: `driver` is its type, `properties` the rest
    /// (`id`, `bus`, `port`, ...).
    pub fn device_add(&mut self, driver: &str, properties: &[(&str, &str)]) -> Result<()> {
        let mut arguments = serde_json::Map::new();
        arguments.insert("driver".into(), Value::from(driver));
        for (name, value) in properties {
            arguments.insert((*name).into(), Value::from(*value));
        }
        self.execute(json!({ "execute": "device_add", "arguments": arguments }))?;
        Ok(())
    }

    /// Pulls out the device with `id` (QMP `device_del`). QEMU completes
    /// the removal later; the guest's log says when it has seen it.
    pub fn device_del(&mut self, id: &str) -> Result<()> {
        self.execute(json!({ "execute": "device_del", "arguments": { "id": id } }))?;
        Ok(())
    }

    /// Raises an NMI on every CPU (QMP `inject-nmi`, the monitor's `nmi`),
    /// as a watchdog or a parity error would on a real PC.
    pub fn inject_nmi(&mut self) -> Result<()> {
        self.execute(json!({ "execute": "inject-nmi" }))?;
        Ok(())
    }

    /// Presses and releases a key, named as QEMU's `sendkey` names keys
    /// (`a`, `4`, `kp_4`, `f1`, `left`, `esc`, `spc`, `shift-a`, ...).
    pub fn send_key(&mut self, key: &str) -> Result<()> {
        self.send_key_held(key, DEFAULT_HOLD_MILLIS)
    }

    /// Like [`Qemu::send_key`], holding the key down for `hold_millis` (long
    /// holds make the keyboard repeat). QEMU plays keys one after another.
    pub fn send_key_held(&mut self, key: &str, hold_millis: u32) -> Result<()> {
        let key = qemu_key_name(key);
        let is_name = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
        if key.is_empty() || !key.chars().all(is_name) {
            return Err(QemuError::Monitor(format!(
                "{key:?} is not a QEMU key name"
            )));
        }
        let reply = self.execute(json!({
            "execute": "human-monitor-command",
            "arguments": { "command-line": format!("sendkey {key} {hold_millis}") },
        }))?;
        // HMP's answer comes back as the returned string: empty on success.
        match reply.as_str() {
            Some("") => Ok(()),
            _ => Err(QemuError::Monitor(format!("sendkey {key}: {reply}"))),
        }
    }

    /// Presses or releases `key` (a QEMU key name, as for [`Qemu::send_key`])
    /// on the input devices bound to the display device `display` and on no
    /// other: QMP's `input-send-event` routes by display, so a keyboard is
    /// named by binding it to one (`-device usb-kbd,display=video0`), and
    /// keys sent without a display (`sendkey`) go to the unbound keyboards,
    /// such as the PS/2 one. QEMU's usb-hid queues 16 PS/2 scancodes (an E0
    /// key's event takes two), drops an event that does not fit, and sends
    /// one queued key change a report.
    pub fn key_event_on(&mut self, display: &str, key: &str, down: bool) -> Result<()> {
        self.key_events_on(display, &[(key, down)])
    }

    /// Presses and releases `key` on the keyboards bound to `display`, back
    /// to back in one QMP command (see [`Qemu::key_event_on`]).
    pub fn press_key_on(&mut self, display: &str, key: &str) -> Result<()> {
        self.key_events_on(display, &[(key, true), (key, false)])
    }

    /// Sends key presses and releases, in order, in one QMP command to the
    /// keyboards bound to `display` (see [`Qemu::key_event_on`]).
    pub fn key_events_on(&mut self, display: &str, keys: &[(&str, bool)]) -> Result<()> {
        self.send_key_events(Some(display), keys)
    }

    /// Sends key presses and releases, in order, in one QMP command to the
    /// keyboard bound to no display: the PS/2 one. Unlike `sendkey` this
    /// bypasses QEMU's delayed-key queue (which drops events when full) and
    /// lets a key stay down across others. QEMU's PS/2 keyboard queues 16
    /// bytes and drops what does not fit, so a caller sends no more than
    /// that before the guest has read them.
    pub fn key_events(&mut self, keys: &[(&str, bool)]) -> Result<()> {
        self.send_key_events(None, keys)
    }

    fn send_key_events(&mut self, display: Option<&str>, keys: &[(&str, bool)]) -> Result<()> {
        let is_name = |c: char| c.is_ascii_alphanumeric() || c == '_';
        if let Some((key, _)) = keys
            .iter()
            .find(|(key, _)| key.is_empty() || !key.chars().all(is_name))
        {
            return Err(QemuError::Monitor(format!(
                "{key:?} is not a QEMU key name"
            )));
        }
        let events: Vec<Value> = keys
            .iter()
            .map(|(key, down)| {
                json!({
                    "type": "key",
                    "data": { "down": down, "key": { "type": "qcode", "data": qemu_key_name(key) } },
                })
            })
            .collect();
        let arguments = match display {
            Some(display) => json!({ "device": display, "events": events }),
            None => json!({ "events": events }),
        };
        self.execute(json!({
            "execute": "input-send-event",
            "arguments": arguments,
        }))?;
        Ok(())
    }

    /// QEMU's own rendering of the display, from its VGA emulation, brought up
    /// to date first.
    pub fn screendump(&mut self) -> Result<RgbImage> {
        let path = self.scratch.path().join("screen.ppm");
        let _ = std::fs::remove_file(&path);
        let reply = self.execute(json!({
            "execute": "screendump",
            "arguments": { "filename": path },
        }))?;
        let bytes = std::fs::read(&path).map_err(|e| {
            QemuError::Monitor(format!(
                "screendump wrote no file ({e}); QEMU said: {reply}"
            ))
        })?;
        RgbImage::from_ppm(&bytes).map_err(QemuError::Screendump)
    }

    /// As [`Qemu::screendump`], of the display of the device with this id
    /// (when there are several adapters; `screendump` shows the first).
    pub fn screendump_of(&mut self, device: &str) -> Result<RgbImage> {
        let path = self.scratch.path().join("screen.ppm");
        let _ = std::fs::remove_file(&path);
        let reply = self.execute(json!({
            "execute": "screendump",
            "arguments": { "filename": path, "device": device },
        }))?;
        let bytes = std::fs::read(&path).map_err(|e| {
            QemuError::Monitor(format!(
                "screendump of {device} wrote no file ({e}); QEMU said: {reply}"
            ))
        })?;
        RgbImage::from_ppm(&bytes).map_err(QemuError::Screendump)
    }

    /// `len` bytes of the guest's physical memory from `address`, as the CPU
    /// would read them (QMP `pmemsave`): RAM, or a device's memory such as
    /// the VGA's text buffer at 0xB8000.
    pub fn read_physical(&mut self, address: u64, len: u64) -> Result<Vec<u8>> {
        let path = self.scratch.path().join("memory.bin");
        let _ = std::fs::remove_file(&path);
        self.execute(json!({
            "execute": "pmemsave",
            "arguments": { "val": address, "size": len, "filename": path },
        }))?;
        let bytes = std::fs::read(&path)
            .map_err(|e| QemuError::Monitor(format!("pmemsave wrote no file: {e}")))?;
        if bytes.len() as u64 != len {
            return Err(QemuError::Monitor(format!(
                "pmemsave wrote {} bytes, not {len}",
                bytes.len()
            )));
        }
        Ok(bytes)
    }

    /// The 80x25 text screen (the VGA's text buffer at 0xB8000, the
    /// character of each cell, attributes left out), one line a row with
    /// trailing blanks cut.
    pub fn text_screen(&mut self) -> Result<String> {
        let cells = self.read_physical(0xB8000, 80 * 25 * 2)?;
        let rows: Vec<String> = cells
            .chunks(160)
            .map(|row| {
                let text: String = row
                    .iter()
                    .step_by(2)
                    .map(|&c| match c {
                        0x20..=0x7E => char::from(c),
                        _ => ' ',
                    })
                    .collect();
                text.trim_end().to_owned()
            })
            .collect();
        Ok(rows.join("\n"))
    }

    /// Waits for QEMU to exit by itself, `budget` bounding the wait as for
    /// [`Qemu::wait_for_serial`]; an error if it has not.
    pub fn wait_for_exit(&mut self, budget: Duration) -> Result<ExitStatus> {
        let pid = self.child.id();
        let mut watchdog = Watchdog::new(pid, budget, self.serial_bytes());
        loop {
            if let Some(status) = self
                .child
                .try_wait()
                .map_err(|e| QemuError::Io(e.to_string()))?
            {
                return Ok(status);
            }
            if let Some(why) = watchdog.expired(pid, self.serial_bytes()) {
                return Err(QemuError::Timeout(format!(
                    "QEMU did not exit: {why}; console:\n{}",
                    self.serial()
                )));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    fn serial_bytes(&self) -> usize {
        self.serial.console.lock().unwrap().text.len()
    }

    /// Waits up to `timeout` of wall-clock time for QEMU to exit by itself;
    /// `None` if it is still running. For a check that QEMU stays up, and a
    /// person's time limit; to wait for an exit, [`Qemu::wait_for_exit`].
    pub fn wait_exit(&mut self, timeout: Duration) -> Result<Option<ExitStatus>> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self
                .child
                .try_wait()
                .map_err(|e| QemuError::Io(e.to_string()))?
            {
                return Ok(Some(status));
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Waits until the guest has powered the machine off, with QEMU kept
    /// running by [`QemuOptions::keep_after_power_off`]: QMP's `query-status`
    /// then says `shutdown`. `budget` bounds the wait as for
    /// [`Qemu::wait_for_serial`].
    pub fn wait_powered_off(&mut self, budget: Duration) -> Result<()> {
        let pid = self.child.id();
        let mut watchdog = Watchdog::new(pid, budget, self.serial_bytes());
        loop {
            let status = self.execute(json!({ "execute": "query-status" }))?;
            if status["status"] == "shutdown" {
                return Ok(());
            }
            if let Some(why) = watchdog.expired(pid, self.serial_bytes()) {
                return Err(QemuError::Timeout(format!(
                    "the machine was not powered off (QEMU says {status}): {why}; console:\n{}",
                    self.serial()
                )));
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Whether QEMU has not exited yet.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// The next QMP message that answers a command (or greets): events, which
    /// QEMU sends whenever they happen (`{"timestamp": ..., "event": ...}`),
    /// are skipped.
    fn read_reply(&mut self) -> Result<Value> {
        loop {
            let mut line = String::new();
            match self.monitor.read_line(&mut line) {
                Ok(0) => {
                    return Err(QemuError::Exited(format!(
                        "QEMU closed its monitor; console:\n{}",
                        self.serial()
                    )))
                }
                Ok(_) => {
                    let message: Value = serde_json::from_str(&line).map_err(|e| {
                        QemuError::Monitor(format!("QMP sent something not JSON ({e}): {line}"))
                    })?;
                    if ["return", "error", "QMP"]
                        .iter()
                        .any(|key| message.get(key).is_some())
                    {
                        return Ok(message);
                    }
                }
                Err(e) => return Err(QemuError::Monitor(format!("QMP read failed: {e}"))),
            }
        }
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs `program` through util-linux's `setpriv --pdeathsig KILL`, which
/// asks the kernel (`PR_SET_PDEATHSIG`) to kill it when the thread that
/// spawned it ends, and then becomes `program` (same process, same pid). A
/// test process killed by a signal runs no `Drop`, and without this its
/// emulator would spin until its own watchdog. The process must stay with
/// the thread that spawned it, as a `Qemu` does. Without `setpriv` on PATH,
/// `program` runs alone, and only `Drop` ends it.
pub fn dies_with_its_thread(program: &str) -> Command {
    static SETPRIV: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    let has_setpriv = *SETPRIV.get_or_init(|| {
        Command::new("setpriv")
            .arg("--version")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success())
    });
    if has_setpriv {
        let mut command = Command::new("setpriv");
        command.args(["--pdeathsig", "KILL", program]);
        command
    } else {
        Command::new(program)
    }
}

fn spawn_reader(stream: impl Read + Send + 'static, log: Arc<SerialLog>, echo: bool) {
    std::thread::spawn(move || {
        let mut reader = BufReader::new(stream);
        let mut pending = Vec::new();
        loop {
            let chunk = match reader.fill_buf() {
                Ok(bytes) if !bytes.is_empty() => bytes.to_vec(),
                _ => break,
            };
            reader.consume(chunk.len());
            let arrived = Instant::now();
            pending.extend_from_slice(&chunk);
            let mut console = log.console.lock().unwrap();
            while let Some(end) = pending.iter().position(|&byte| byte == b'\n') {
                let line: Vec<u8> = pending.drain(..=end).collect();
                let text = String::from_utf8_lossy(&line).replace('\r', "");
                if echo {
                    print!("{text}");
                    let _ = std::io::stdout().flush();
                }
                console.text.push_str(&text);
                let end = console.text.len();
                console.arrivals.push((end, arrived));
            }
            console.partial = String::from_utf8_lossy(&pending).replace('\r', "");
            drop(console);
            log.grew.notify_all();
        }
    });
}

/// QEMU's CPU time to open its monitor socket: QEMU sets the machine up
/// first, in well under a second.
const MONITOR_BUDGET: Duration = Duration::from_secs(10);

fn connect_monitor(path: &Path, child: &mut Child, log: &SerialLog) -> Result<UnixStream> {
    let pid = child.id();
    let mut watchdog = Watchdog::new(pid, MONITOR_BUDGET, 0);
    loop {
        match UnixStream::connect(path) {
            Ok(stream) => {
                // A reply (a screendump's, a key's) is bounded only by the
                // ceiling: on a busy host it may take a while.
                stream.set_read_timeout(Some(WALL_CLOCK_CEILING)).ok();
                return Ok(stream);
            }
            Err(e) => {
                if let Ok(Some(status)) = child.try_wait() {
                    std::thread::sleep(Duration::from_millis(100)); // let the reader collect stderr
                    let output = log.console.lock().unwrap().text.clone();
                    return Err(QemuError::Exited(format!(
                        "QEMU exited at start ({status}): {output}"
                    )));
                }
                if let Some(why) = watchdog.expired(pid, 0) {
                    return Err(QemuError::Timeout(format!(
                        "QEMU's monitor socket never opened ({e}): {why}"
                    )));
                }
                std::thread::sleep(Duration::from_millis(20));
            }
        }
    }
}

/// QEMU's name for one of the runner's keys (`keyboard::keys`): the same
/// name except the Menu (Application) key, E0 5D on PS/2, which QEMU calls
/// `compose`; its own `menu` sends nothing to a PS/2 keyboard.
pub fn qemu_key_name(key: &str) -> &str {
    match key {
        "menu" => "compose",
        other => other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    /// A process started by [`dies_with_its_thread`] is killed when the
    /// thread that started it ends, with nothing dropped: as when the test
    /// process itself is killed. Were it not, `sleep` would end by itself
    /// after 20 s, and the status would say so.
    #[test]
    fn a_child_dies_with_the_thread_that_started_it() {
        let mut child = std::thread::spawn(|| {
            let mut child = dies_with_its_thread("sh")
                .args(["-c", "echo started; exec sleep 20"])
                .stdout(Stdio::piped())
                .spawn()
                .expect("sh starts");
            // The shell runs only once setpriv has asked for the signal, so
            // the thread must not end before this line has come.
            let mut line = String::new();
            BufReader::new(child.stdout.take().unwrap())
                .read_line(&mut line)
                .unwrap();
            assert_eq!(line, "started\n");
            child
        })
        .join()
        .unwrap();
        let status = child.wait().unwrap();
        assert_eq!(status.signal(), Some(9), "{status}");
    }
}
