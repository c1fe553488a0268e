//! The culled-cube demo, free of hardware: the scene, the key-to-command map,
//! the scancode queue, the frame renderer and the app that ties them together.
//! The kernel supplies a VGA bus and scancodes; the host tests supply a
//! software VGA and the same scancodes.

#![no_std]
#![forbid(unsafe_code)]

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
