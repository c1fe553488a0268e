//! VGA Mode X for a bare-metal kernel: 320x240, 256 colours, unchained, with
//! three pages in video memory to draw into and flip between.
//!
//! The crate has three parts:
//!
//! * [`VgaBus`], the narrow interface to a VGA: port I/O and the 64 KiB CPU
//!   window at 0xA0000. The kernel implements it with `in`/`out` and volatile
//!   stores; nothing here is `unsafe`.
//! * [`ModeX`], the driver written against the bus: mode set from any prior
//!   state, rectangle and span fills with Map Mask edges, page flips locked to
//!   vertical retrace, and a fallback 80x25 text mode.
//! * [`soft::SoftVga`], a software VGA implementing the bus, so that host tests
//!   can see every pixel, count every bus operation and run a simulated clock.
//!
//! Mode X memory layout: pixel (x, y) of a page lives in plane `x % 4` at byte
//! `page.base() + y * 80 + x / 4`.
//!
//! # Example
//!
//! Set Mode X on the software VGA, fill a rectangle on the hidden page, flip
//! to it, and read back what the VGA would put on the screen:
//!
//! ```
//! use modex::soft::SoftVga;
//! use modex::{ModeX, Page};
//!
//! let mut soft = Box::new(SoftVga::new()); // four 64 KiB planes: keep it off the stack
//! let mut vga = ModeX::new(&mut *soft);
//! vga.set_mode(); // Page::Zero is shown, all black
//! vga.fill_rect(Page::One, 10, 20, 14, 22, 12); // x 10..14, y 20..22, colour 12
//! vga.show_page(Page::One); // the start address is latched at the next retrace
//!
//! let mut screen = vec![0u8; 320 * 240];
//! assert_eq!(soft.scanout_indices(&mut screen), (320, 240));
//! assert_eq!(screen[20 * 320 + 10], 12);
//! assert_eq!(screen[21 * 320 + 13], 12);
//! assert_eq!(screen[22 * 320 + 10], 0); // the rectangle's end is exclusive
//! assert_eq!(screen[20 * 320 + 14], 0);
//! ```

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(any(test, feature = "test-support"))]
extern crate alloc;
#[cfg(test)]
extern crate std;

mod bus;
mod canvas;
pub mod card;
mod detect;
mod draw;
mod driver;
mod io;
mod mirror;
pub mod mode;
mod page;
pub mod palette;
pub mod present;
#[cfg(any(test, feature = "test-support"))]
pub mod record;
pub mod regs;
pub mod soft;
mod spans;
mod text;
mod update;

pub use bus::{poll_by_reads, VgaBus, CPU_WINDOW_BYTES};
pub use canvas::{ImageCanvas, PageCanvas, PaletteIndex};
pub use detect::legacy_vga_present;
pub use driver::ModeX;
pub use mirror::MirroredVga;
pub use page::{FlipReport, Page, PAGE_COUNT, STATUS_WAIT_MICROS};
pub use palette::Rgb6;
pub use spans::{LineSpans, PageSpans};
pub use text::{TEXT_COLUMNS, TEXT_ROWS};
pub use update::{PageImage, PageWrites, PAGE_PIXELS};

/// Visible width of a Mode X page, in pixels.
pub const SCREEN_WIDTH: i32 = 320;
/// Visible height of a Mode X page, in pixels.
pub const SCREEN_HEIGHT: i32 = 240;
/// One scan line in each plane: four pixels per byte.
pub const BYTES_PER_LINE: u16 = 80;
/// One page in each plane.
pub const PAGE_BYTES: u16 = 19200;

#[cfg(test)]
mod tests;
