//! The culled-cube demo, free of hardware: the scene, the key-to-command map,
//! the scancode queue and the frame loop. The kernel supplies a bus and keys.

#![no_std]

pub mod pattern;
pub mod queue;
