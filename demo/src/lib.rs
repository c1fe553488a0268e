//! The culled-cube demo, free of hardware: the scene, the key-to-command map,
//! the frame renderer and the app that ties them together.
//! The kernel supplies a VGA bus and scancodes; the host tests supply a
//! software VGA and the same scancodes.
//!
//! A frame's data goes one way: [`scene`] hands out its faces as plain data
//! ([`faces`]), [`depth`] draws them into a RAM image, and [`frame`], which
//! alone knows both, takes the image to the VGA. No module's imports lead
//! back to itself (`demo/tests/module_graph.rs` checks).
//!
//! ```
//! use demo::app::App;
//! use modex::soft::SoftVga;
//! use modex::ModeX;
//!
//! let mut soft = Box::new(SoftVga::new());
//! ModeX::new(&mut *soft).set_mode();
//! let mut app = App::new();
//! let clock = || 0u64; // microseconds; the kernel reads the TSC
//!
//! // One frame: the spinning cube is drawn into the hidden page and shown.
//! let flip = app.step(&mut ModeX::new(&mut *soft), &clock).expect("a frame");
//! assert!(!flip.timed_out());
//! let mut screen = vec![0u8; 320 * 240];
//! soft.scanout_indices(&mut screen);
//! assert_ne!(screen[120 * 320 + 160], 0, "the cube covers the centre");
//! assert_eq!(screen[0], 0, "and not the corner");
//!
//! // Esc, pressed and released, in scancode set 1: the demo asks to quit.
//! app.feed_scancode(0x01);
//! app.feed_scancode(0x81);
//! assert!(app.quit_requested());
//! ```

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod app;
pub mod baseline;
pub mod command;
pub mod depth;
pub mod faces;
pub mod facts;
pub mod frame;
pub mod grid;
pub mod keymap;
pub mod osd;
pub mod pattern;
pub mod report;
pub mod scale;
pub mod scene;
pub mod screen;
pub mod screens;
pub mod shading;
pub mod solids;
