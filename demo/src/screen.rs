//! The screen every picture of the demo is drawn for: the colour behind
//! everything and the rectangle everything is clipped to. Depends on nothing
//! else in the crate, so every module that draws can share it.

use engine::ClipRect;
use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};

/// The colour index behind everything drawn.
pub const BACKGROUND: u8 = 0;
/// The whole Mode X screen, for clipping.
pub const SCREEN_CLIP: ClipRect = ClipRect {
    x0: 0,
    y0: 0,
    x1: SCREEN_WIDTH,
    y1: SCREEN_HEIGHT,
};
