//! Knowing the card: whether its video BIOS may be called, which extensions
//! it has and how to switch them off, and proof that a mode set took.

pub mod verify;
pub mod vendor;
pub mod video_bios;

pub use verify::{Mismatch, Register};
pub use vendor::{Card, ExtensionProbe, ResetStep};
pub use video_bios::{check_video_bios, Handler, NoVideoBios, VideoBios};
