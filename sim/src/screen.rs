//! The window's picture: the software VGA's scan-out scaled by a whole
//! factor (each pixel a square block, as a monitor shows Mode X's doubled
//! pixels), with the inspector's panel to its right when it is open.

use crate::inspector::Panel;
use crate::machine::PICTURE_PIXELS;
use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};

const WIDTH: usize = SCREEN_WIDTH as usize;
const HEIGHT: usize = SCREEN_HEIGHT as usize;

/// The window's size for a scale and an optional panel width.
pub fn window_size(scale: usize, panel_width: Option<usize>) -> (usize, usize) {
    (WIDTH * scale + panel_width.unwrap_or(0), HEIGHT * scale)
}

/// `0RGB` for the window.
pub fn to_0rgb([r, g, b]: [u8; 3]) -> u32 {
    u32::from(r) << 16 | u32::from(g) << 8 | u32::from(b)
}

/// The window's pixels: the picture (320x240 RGB) scaled by `scale`, then
/// the panel's rows beside it (cut to the picture's height).
pub fn compose(picture: &[[u8; 3]], scale: usize, panel: Option<&Panel>) -> Vec<u32> {
    assert_eq!(picture.len(), PICTURE_PIXELS, "a Mode X picture is 320x240");
    let (width, height) = window_size(scale, panel.map(|panel| panel.width));
    let mut pixels = Vec::with_capacity(width * height);
    for y in 0..height {
        let row = &picture[y / scale * WIDTH..][..WIDTH];
        for &colour in row {
            pixels.extend(std::iter::repeat_n(to_0rgb(colour), scale));
        }
        if let Some(panel) = panel {
            pixels.extend_from_slice(&panel.pixels[y * panel.width..][..panel.width]);
        }
    }
    pixels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_pixel_becomes_a_square_block() {
        let mut picture = vec![[0u8; 3]; PICTURE_PIXELS];
        picture[WIDTH + 2] = [1, 2, 3]; // (2, 1)
        let pixels = compose(&picture, 3, None);
        assert_eq!(pixels.len(), 960 * 720);
        for y in 0..720 {
            for x in 0..960 {
                let inside = (6..9).contains(&x) && (3..6).contains(&y);
                assert_eq!(
                    pixels[y * 960 + x],
                    if inside { 0x010203 } else { 0 },
                    "({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn the_panel_goes_to_the_right() {
        let picture = vec![[9u8; 3]; PICTURE_PIXELS];
        let panel = Panel {
            width: 5,
            height: 600,
            encoding: crate::inspector::Encoding::Xrgb,
            pixels: (0..3000).collect(),
            drawn: Default::default(),
        };
        let pixels = compose(&picture, 2, Some(&panel));
        assert_eq!(window_size(2, Some(5)), (645, 480));
        assert_eq!(pixels.len(), 645 * 480);
        assert_eq!(pixels[639], 0x090909);
        assert_eq!(&pixels[640..645], &[0, 1, 2, 3, 4]);
        assert_eq!(&pixels[645 + 640..645 * 2], &[5, 6, 7, 8, 9]);
    }
}
