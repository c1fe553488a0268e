//! Knowing the card: whether its video BIOS may be called, which extensions
//! it has and how to switch them off, and proof that a mode set took.

pub mod mode_set;
pub mod vendor;
pub mod verify;
pub mod video_bios;

pub use mode_set::{BiosCallFailure, Fallback, ModeSetReport, Route, BIOS_MODE_13H};
pub use vendor::{Card, ExtensionProbe, ResetStep};
pub use verify::{Mismatch, Register};
pub use video_bios::{check_video_bios, Handler, NoVideoBios, VideoBios};
