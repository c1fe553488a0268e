//! The host side: the disk images, QEMU and Bochs, and the pictures they
//! take. The runner (`boot/main.rs`) and the integration tests (`tests/`)
//! share all of it.
//!
//! The pictures are compared as [`RgbImage`]s. QEMU's screendump of the
//! 320x240 Mode X screen is 640x480, every pixel doubled; halving it gives
//! back the picture the kernel drew:
//!
//! ```
//! use boot::{Graphics, RgbImage};
//!
//! // A 4x2 screendump (binary PPM) of a 2x1 picture: red, then blue.
//! let mut ppm = b"P6\n4 2\n255\n".to_vec();
//! for _row in 0..2 {
//!     ppm.extend_from_slice(&[255, 0, 0, 255, 0, 0, 0, 0, 255, 0, 0, 255]);
//! }
//! let screendump = RgbImage::from_ppm(&ppm)?;
//! let picture = screendump.halve()?;
//! assert_eq!(picture, RgbImage::new(2, 1, vec![[255, 0, 0], [0, 0, 255]]));
//! assert!(screendump.differences(&picture).is_err(), "sizes differ");
//!
//! // The runner's `--vga` names for the adapters QEMU emulates.
//! assert_eq!(Graphics::from_name("isa-cirrus"), Some(Graphics::IsaCirrus));
//! # Ok::<(), boot::ImageError>(())
//! ```
#![warn(missing_docs)]
#![warn(missing_debug_implementations)]

pub mod bochs;
pub mod disk_layout;
pub mod image;
pub mod images;
pub mod option_rom;
pub mod qemu;
pub mod secure_boot;
pub mod usb;

pub use image::{ImageError, RgbImage};
pub use qemu::{
    Board, Chipset, DiskAttachment, Display, Firmware, Graphics, OptionRom, Qemu, QemuError,
    QemuOptions, RamFile, ReadError, ReadFailures, UsbHost,
};

/// The line the kernel prints on serial once its first picture is on screen
/// and it is reading keys.
pub const READY_LINE: &str = protocol::line::READY;

pub use protocol::{line, BootOption, BootRequest, ClockReference, Exit, Fault};
