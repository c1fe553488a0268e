//! The culled-cube demo, free of hardware: the scene, the key-to-command map,
//! the scancode queue, the frame renderer and the app that ties them together.
//! The kernel supplies a VGA bus and scancodes; the host tests supply a
//! software VGA and the same scancodes.

#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

pub mod app;
pub mod baseline;
pub mod command;
pub mod frame;
pub mod keymap;
pub mod keys;
pub mod osd;
pub mod pattern;
pub mod queue;
pub mod scene;
pub mod screens;
pub mod shading;
pub mod solids;

// The 3-D pipeline projects onto the screen the Mode X driver shows. The two
// crates know nothing of each other (the pipeline is not tied to VGA), so the
// demo, which joins them, refuses to build if their screens differ.
const _: () = assert!(
    engine::SCREEN_WIDTH == modex::SCREEN_WIDTH && engine::SCREEN_HEIGHT == modex::SCREEN_HEIGHT
);
