//! The cube demo on the host: the kernel's portable parts (the demo's `App`,
//! the Mode X driver and the software VGA) in a desktop window, a VGA
//! inspector beside the picture, and animated GIF captures of the scan-out.
//!
//! Everything but the window itself lives here, as functions of the software
//! VGA's state, so that tests can check it without a display:
//!
//! * [`keys`]: host keys and the runner's key names as PS/2 scan codes (set 1);
//! * [`machine`]: the demo on the software VGA, one retrace period at a time;
//! * [`inspector`]: the numbers and the panel image of the VGA inspector;
//! * [`screen`]: the picture scaled, with the panel beside it, as the window shows it;
//! * [`record`]: the scan-outs of a run as an animated GIF.

#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod inspector;
pub mod keys;
pub mod machine;
pub mod record;
pub mod screen;
