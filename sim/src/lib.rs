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
//! * [`oplog`]: a frame's bus operations, named by the `modex` function
//!   that issued each, and their replay (the web page's slow motion);
//! * [`screen`]: the picture scaled, with the panel beside it, as the window shows it;
//! * [`record`]: the scan-outs of a run as an animated GIF.
//!
//! The demo headless, as the window tests and the GIF recorder run it:
//!
//! ```
//! use sim::inspector::vga_state;
//! use sim::keys::scancode_for_name;
//! use sim::machine::{Machine, PICTURE_PIXELS};
//!
//! // Mode X set and the first frame drawn, as the kernel does at boot.
//! let mut machine = Machine::new();
//! let shown = vga_state(machine.vga()).shown_page;
//! assert!(shown.is_some(), "Mode X shows one of its pages");
//!
//! // Every frame is one retrace period on the model's clock.
//! let retraces = machine.vga().frame_count();
//! machine.frame();
//! assert_eq!(machine.vga().frame_count(), retraces + 1);
//!
//! // The cube is on screen: more than one colour.
//! let picture = machine.scanout_rgb();
//! assert_eq!(picture.len(), PICTURE_PIXELS);
//! assert!(picture.iter().any(|&pixel| pixel != picture[0]));
//!
//! // Keys go in as the PS/2 scan codes the kernel's decoder reads.
//! machine.tap(scancode_for_name("left").unwrap());
//! assert_eq!(machine.app().commands(), 1);
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod inspector;
pub mod keys;
pub mod machine;
pub mod oplog;
pub mod record;
pub mod screen;
