//! The host side: the disk images, QEMU and Bochs, and the pictures they
//! take. The runner (`boot/main.rs`) and the integration tests (`tests/`)
//! share all of it.
#![warn(missing_docs)]
#![warn(missing_debug_implementations)]

pub mod bochs;
pub mod image;
pub mod images;
pub mod qemu;
pub mod usb;

pub use image::{ImageError, RgbImage};
pub use qemu::{Display, Firmware, Graphics, Qemu, QemuError, QemuOptions};

/// The line the kernel prints on serial once its first picture is on screen
/// and it is reading keys.
pub const READY_LINE: &str = machine::protocol::line::READY;

pub use machine::protocol::{line, BootOption, BootRequest, Exit, Fault};
