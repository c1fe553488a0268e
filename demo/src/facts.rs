//! What the kernel found out about the machine, as one typed record. Each
//! subsystem fills in its part once, at boot; the record is then written to
//! the log ([`MachineFacts::rows`], one line a fact), drawn on the report
//! screen and carried by the fault panel and its QR code. Nothing searches
//! the log for a fact.
//!
//! Each row is written for a person reading the report screen: short, and
//! whole words, so that wrapping ([`crate::report::wrap`]) never has to cut
//! one.
//!
//! # Example
//!
//! ```
//! use demo::facts::{Display, MachineFacts};
//! use firmware::boot_firmware::Firmware;
//!
//! let mut facts = MachineFacts::new("0.1.0", "abc1234");
//! facts.firmware = Some(Firmware::Bios);
//! facts.display = Display::ModeX { by_video_bios: true, verified: Some(true) };
//! let mut rows = Vec::new();
//! facts.rows(|row| rows.push(row.to_string()));
//! assert_eq!(rows[0], "modex-cube 0.1.0 commit abc1234");
//! assert!(rows.contains(&"firmware: Bios".to_string()));
//! assert!(rows.contains(&"display: VGA Mode X by video BIOS, read back".to_string()));
//! ```

use clock::tsc_rate::{Source, TscRate};
use core::fmt;
use firmware::boot_firmware::Firmware;
use firmware::secure_boot::SecureBoot;
use kernel_log::text_of_field;
use protocol::line::UsbKeyboards;

/// The machine's facts, filled in at boot.
#[derive(Clone, Copy, Debug)]
pub struct MachineFacts {
    /// The kernel's version.
    pub version: &'static str,
    /// The commit it was built from.
    pub commit: &'static str,
    /// CPUID's vendor and brand.
    pub cpu: Cpu,
    /// Whether no-execute is on (EFER.NXE); `None` before it was looked at.
    pub nx: Option<bool>,
    /// Which firmware booted the machine; `None` before it was told.
    pub firmware: Option<Firmware>,
    /// The display controller's PCI vendor and device; `None` if there is
    /// none on PCI.
    pub adapter: Option<(u16, u16)>,
    /// How the picture reaches the screen.
    pub display: Display,
    /// The PS/2 keyboard controller.
    pub ps2: Ps2,
    /// USB host controllers driven (xHCI, EHCI, OHCI, UHCI).
    pub usb_controllers: u8,
    /// USB keyboards set up, by the kind of controller each is on.
    pub usb_keyboards: UsbKeyboards,
    /// The clock's rate and source; `None` before it was found.
    pub clock: Option<TscRate>,
    /// Whether Secure Boot was on and who checked the loader; `None` before
    /// it was told (said as "unknown", never as on or off).
    pub secure_boot: Option<SecureBoot>,
}

/// CPUID's identification, as the CPU gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Cpu {
    /// Leaf 0's vendor (12 bytes).
    pub vendor: [u8; 12],
    /// Leaves 0x8000_0002..4's brand string (48 bytes, maybe unterminated,
    /// often padded with spaces).
    pub brand: [u8; 48],
}

/// How the picture reaches the screen.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Display {
    /// Not decided yet.
    Unknown,
    /// True Mode X on the VGA's registers.
    ModeX {
        /// Mode 13h came from the video BIOS (then tweaked); else the
        /// registers alone set the mode.
        by_video_bios: bool,
        /// The registers read back as written; `None` before the check.
        verified: Option<bool>,
    },
    /// Mode X on the software VGA, presented into the firmware's
    /// framebuffer.
    Framebuffer {
        /// Pixels across.
        width: u32,
        /// Pixels down.
        height: u32,
        /// Bytes a pixel.
        bytes_per_pixel: u8,
        /// Screen pixels per Mode X pixel.
        scale: u32,
        /// The framebuffer was mapped write-combining and that read back;
        /// `None` before it was tried.
        write_combining: Option<bool>,
    },
    /// No picture: the reason, for the log.
    Nothing(&'static str),
}

/// The PS/2 keyboard controller, as the kernel found it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ps2 {
    /// Not looked at yet.
    Unknown,
    /// Set up and answering.
    Ready,
    /// Nothing answered at the 8042's ports.
    Absent,
    /// Set up failed: why.
    Failed(&'static str),
}

impl MachineFacts {
    /// A record knowing only the build.
    pub const fn new(version: &'static str, commit: &'static str) -> Self {
        MachineFacts {
            version,
            commit,
            cpu: Cpu {
                vendor: [0; 12],
                brand: [0; 48],
            },
            nx: None,
            firmware: None,
            adapter: None,
            display: Display::Unknown,
            ps2: Ps2::Unknown,
            usb_controllers: 0,
            usb_keyboards: UsbKeyboards { on: [0; 4] },
            clock: None,
            secure_boot: None,
        }
    }

    /// Hands each fact's row, in the report's order, to `row`: the build, the
    /// CPU, NX, the firmware, the adapter, the display, the keyboards, the
    /// USB keyboards' controllers, the clock, Secure Boot. Facts not yet known say so.
    pub fn rows(&self, mut row: impl FnMut(&dyn fmt::Display)) {
        row(&format_args!(
            "modex-cube {} commit {}",
            self.version, self.commit
        ));
        row(&CpuRow(&self.cpu));
        row(&NxRow(self.nx));
        row(&FirmwareRow(self.firmware));
        row(&AdapterRow(self.adapter));
        row(&self.display);
        row(&KeyboardRow(self.ps2, self.usb_controllers));
        row(&self.usb_keyboards);
        row(&ClockRow(self.clock));
        row(&SecureBootRow(self.secure_boot));
    }
}

/// The rows [`MachineFacts::rows`] gives.
pub const FACT_COUNT: usize = 10;

struct CpuRow<'a>(&'a Cpu);

impl fmt::Display for CpuRow<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let vendor = text_of_field(&self.0.vendor).trim();
        match (vendor, text_of_field(&self.0.brand).trim()) {
            ("", "") => f.write_str("cpu: not identified"),
            (vendor, "") => write!(f, "cpu: {vendor} (no brand string)"),
            (vendor, brand) => write!(f, "cpu: {vendor}, {brand}"),
        }
    }
}

struct NxRow(Option<bool>);

impl fmt::Display for NxRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self.0 {
            Some(true) => "nx: on (no-execute pages enforced)",
            Some(false) => "nx: off (the CPU offers none, or it is disabled)",
            None => "nx: not looked at",
        })
    }
}

struct FirmwareRow(Option<Firmware>);

impl fmt::Display for FirmwareRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(firmware) => write!(f, "firmware: {firmware:?}"),
            None => f.write_str("firmware: not told yet"),
        }
    }
}

struct AdapterRow(Option<(u16, u16)>);

impl fmt::Display for AdapterRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some((vendor, device)) => write!(
                f,
                "adapter: PCI {vendor:04x}:{device:04x} {}",
                crate::report::pci_name(vendor, device)
            ),
            None => f.write_str("adapter: no PCI display controller"),
        }
    }
}

impl fmt::Display for Display {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Display::Unknown => f.write_str("display: not set up yet"),
            Display::ModeX {
                by_video_bios,
                verified,
            } => {
                let by = if by_video_bios {
                    "video BIOS"
                } else {
                    "registers"
                };
                let check = match verified {
                    Some(true) => "read back",
                    Some(false) => "NOT as written",
                    None => "unchecked",
                };
                write!(f, "display: VGA Mode X by {by}, {check}")
            }
            Display::Framebuffer {
                width,
                height,
                bytes_per_pixel,
                scale,
                write_combining,
            } => {
                write!(
                    f,
                    "display: framebuffer {width}x{height}x{bytes_per_pixel} scale {scale}"
                )?;
                match write_combining {
                    Some(true) => f.write_str(", WC"),
                    Some(false) => f.write_str(", UC"),
                    None => Ok(()),
                }
            }
            Display::Nothing(why) => write!(f, "display: none: {why}"),
        }
    }
}

struct KeyboardRow(Ps2, u8);

impl fmt::Display for KeyboardRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Ps2::Unknown => f.write_str("keyboard: PS/2 not looked at")?,
            Ps2::Ready => f.write_str("keyboard: PS/2 ready")?,
            Ps2::Absent => f.write_str("keyboard: no PS/2 controller")?,
            Ps2::Failed(why) => write!(f, "keyboard: PS/2 failed ({why})")?,
        }
        match self.1 {
            0 => f.write_str("; no USB host"),
            1 => f.write_str("; USB on 1 host"),
            n => write!(f, "; USB on {n} hosts"),
        }
    }
}

struct SecureBootRow(Option<SecureBoot>);

impl fmt::Display for SecureBootRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(state) => write!(f, "Secure Boot: {state}"),
            None => f.write_str("Secure Boot: unknown"),
        }
    }
}

struct ClockRow(Option<TscRate>);

impl fmt::Display for ClockRow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some(rate) = self.0 else {
            return f.write_str("clock: not calibrated yet");
        };
        let khz = rate.hz / 1000;
        write!(f, "clock: TSC {}.{:03} MHz", khz / 1000, khz % 1000)?;
        let source = match rate.source {
            Source::CpuidCrystal | Source::CpuidBaseFrequency => "from CPUID",
            Source::PmTimer => "from the PM timer",
            Source::Hpet => "from the HPET",
            Source::Pit => "from the PIT",
            Source::Assumed => "assumed",
        };
        write!(f, " {source}")?;
        match rate.error_ppm {
            Some(ppm) => write!(f, ", {ppm} ppm"),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::FACT_COLUMNS;
    use firmware::secure_boot::{CheckedBy, Unknown};
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn rows(facts: &MachineFacts) -> Vec<String> {
        let mut rows = Vec::new();
        facts.rows(|row| rows.push(row.to_string()));
        rows
    }

    fn known() -> MachineFacts {
        let mut facts = MachineFacts::new("0.1.0", "0123456789ab");
        facts.cpu.vendor.copy_from_slice(b"GenuineIntel");
        let brand = b"       Intel(R) Core(TM) i7-8565U CPU @ 1.80GHz";
        facts.cpu.brand[..brand.len()].copy_from_slice(brand);
        facts.nx = Some(true);
        facts.firmware = Some(Firmware::Uefi);
        facts.adapter = Some((0x8086, 0x3ea0));
        facts.display = Display::Framebuffer {
            width: 1920,
            height: 1080,
            bytes_per_pixel: 4,
            scale: 4,
            write_combining: Some(true),
        };
        facts.ps2 = Ps2::Ready;
        facts.usb_controllers = 3;
        facts.usb_keyboards.on = [0, 1, 0, 2];
        facts.clock = Some(TscRate {
            hz: 1_992_000_000,
            source: Source::PmTimer,
            error_ppm: Some(20),
        });
        facts.secure_boot = Some(SecureBoot::On(CheckedBy::YourKeyInDb));
        facts
    }

    #[test]
    fn a_known_machine_reads_as_designed_and_every_row_fits_the_screen() {
        let rows = rows(&known());
        assert_eq!(rows.len(), FACT_COUNT);
        assert_eq!(
            rows,
            [
                "modex-cube 0.1.0 commit 0123456789ab",
                "cpu: GenuineIntel, Intel(R) Core(TM) i7-8565U CPU @ 1.80GHz",
                "nx: on (no-execute pages enforced)",
                "firmware: Uefi",
                "adapter: PCI 8086:3ea0 Intel",
                "display: framebuffer 1920x1080x4 scale 4, WC",
                "keyboard: PS/2 ready; USB on 3 hosts",
                "USB keyboards: 1 ehci, 2 uhci",
                "clock: TSC 1992.000 MHz from the PM timer, 20 ppm",
                "Secure Boot: on (your key in db)",
            ]
        );
        // The CPU's brand is the one row whose length the kernel does not
        // choose; every other row fits a report row whole.
        for row in rows.iter().filter(|row| !row.starts_with("cpu: ")) {
            assert!(row.len() <= FACT_COLUMNS, "{row:?}");
        }
    }

    #[test]
    fn unknown_facts_say_so() {
        let rows = rows(&MachineFacts::new("0.1.0", "x"));
        assert_eq!(rows[1], "cpu: not identified");
        assert_eq!(rows[2], "nx: not looked at");
        assert_eq!(rows[3], "firmware: not told yet");
        assert_eq!(rows[5], "display: not set up yet");
        assert_eq!(rows[7], "USB keyboards: none");
        assert_eq!(rows[8], "clock: not calibrated yet");
        assert_eq!(rows[9], "Secure Boot: unknown");
    }

    #[test]
    fn every_display_and_keyboard_state_fits_a_row() {
        let displays = [
            Display::ModeX {
                by_video_bios: false,
                verified: Some(false),
            },
            Display::ModeX {
                by_video_bios: true,
                verified: None,
            },
            Display::Framebuffer {
                width: 65535,
                height: 65535,
                bytes_per_pixel: 4,
                scale: 204,
                write_combining: Some(false),
            },
            Display::Nothing("no usable GOP"),
        ];
        for display in displays {
            let text = display.to_string();
            assert!(text.len() <= FACT_COLUMNS, "{text:?}");
        }
        let states = [
            SecureBoot::NotUefi,
            SecureBoot::Unknown(Unknown::NoRecord),
            SecureBoot::Off,
            SecureBoot::SetupMode,
            SecureBoot::On(CheckedBy::ShimYourKey),
            SecureBoot::On(CheckedBy::YourKeyInDb),
            SecureBoot::On(CheckedBy::ShimNotChecking),
            SecureBoot::On(CheckedBy::Shim),
            SecureBoot::On(CheckedBy::Firmware),
        ];
        for state in states {
            let text = SecureBootRow(Some(state)).to_string();
            assert!(text.len() <= FACT_COLUMNS, "{text:?}");
        }
        for ps2 in [Ps2::Unknown, Ps2::Ready, Ps2::Absent, Ps2::Failed("no ACK")] {
            for usb in [0, 1, 8] {
                let text = KeyboardRow(ps2, usb).to_string();
                assert!(text.len() <= FACT_COLUMNS, "{text:?}");
            }
        }
        let text = UsbKeyboards { on: [99; 4] }.to_string();
        assert!(text.len() <= FACT_COLUMNS, "{text:?}");
    }
}
