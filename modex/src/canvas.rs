//! `embedded-graphics` drawing targets, so any of its text, shapes and images
//! can be drawn in Mode X: [`PageCanvas`] straight into a page in video
//! memory, [`ImageCanvas`] into a RAM image of a page (which
//! [`ModeX::update_page`] then writes out, changed pixels only).

use crate::{ModeX, Page, PageImage, PageSpans, VgaBus, SCREEN_HEIGHT, SCREEN_WIDTH};
use core::convert::Infallible;
use embedded_graphics_core::pixelcolor::raw::RawU8;
use embedded_graphics_core::pixelcolor::PixelColor;
use embedded_graphics_core::prelude::{DrawTarget, OriginDimensions, Pixel, Size};
use embedded_graphics_core::primitives::Rectangle;

/// A colour in Mode X: an index into the DAC's 256 entries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct PaletteIndex(pub u8);

impl PixelColor for PaletteIndex {
    type Raw = RawU8;
}

impl From<u8> for PaletteIndex {
    fn from(index: u8) -> Self {
        PaletteIndex(index)
    }
}

const SCREEN_SIZE: Size = Size::new(SCREEN_WIDTH as u32, SCREEN_HEIGHT as u32);

/// `area` clipped to the screen as half-open [x0, x1) x [y0, y1), or `None`
/// if nothing of it is on the screen. Worked in i64 rather than with
/// `Rectangle::intersection`, whose i32 corner arithmetic overflows (a panic
/// in debug builds) for rectangles near `i32::MAX` or over `i32::MAX` wide.
fn on_screen(area: &Rectangle) -> Option<(i32, i32, i32, i32)> {
    let clip = |start: i32, length: u32, limit: i32| {
        let end = i64::from(start) + i64::from(length);
        let (lo, hi) = (start.max(0), end.min(i64::from(limit)) as i32);
        (lo < hi).then_some((lo, hi))
    };
    let (x0, x1) = clip(area.top_left.x, area.size.width, SCREEN_WIDTH)?;
    let (y0, y1) = clip(area.top_left.y, area.size.height, SCREEN_HEIGHT)?;
    Some((x0, y0, x1, y1))
}

/// Draws straight into one page of video memory: pixels through the Map Mask
/// one at a time, solid rectangles as Map Mask rectangle fills. Anything off
/// the screen is clipped; nothing outside the page is ever written.
pub struct PageCanvas<'a, B: VgaBus> {
    vga: &'a mut ModeX<B>,
    page: Page,
}

impl<B: VgaBus> core::fmt::Debug for PageCanvas<'_, B> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PageCanvas")
            .field("vga", &self.vga)
            .field("page", &self.page)
            .finish()
    }
}

impl<'a, B: VgaBus> PageCanvas<'a, B> {
    /// A canvas over `page`.
    pub fn new(vga: &'a mut ModeX<B>, page: Page) -> Self {
        PageCanvas { vga, page }
    }
}

impl<B: VgaBus> OriginDimensions for PageCanvas<'_, B> {
    fn size(&self) -> Size {
        SCREEN_SIZE
    }
}

impl<B: VgaBus> DrawTarget for PageCanvas<'_, B> {
    type Color = PaletteIndex;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<PaletteIndex>>,
    {
        for Pixel(point, colour) in pixels {
            self.vga.put_pixel(self.page, point.x, point.y, colour.0);
        }
        Ok(())
    }

    fn fill_solid(&mut self, area: &Rectangle, colour: PaletteIndex) -> Result<(), Infallible> {
        if let Some((x0, y0, x1, y1)) = on_screen(area) {
            self.vga.fill_rect(self.page, x0, y0, x1, y1, colour.0);
        }
        Ok(())
    }

    fn clear(&mut self, colour: PaletteIndex) -> Result<(), Infallible> {
        self.vga.clear_page(self.page, colour.0);
        Ok(())
    }
}

/// Draws into a RAM image of a page, one byte per pixel, row by row, and
/// marks what it draws in the image's spans if it was given them.
pub struct ImageCanvas<'a> {
    image: &'a mut PageImage,
    drawn: Option<&'a mut PageSpans>,
}

/// Leaves out the image's 75 KiB.
impl core::fmt::Debug for ImageCanvas<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ImageCanvas").finish_non_exhaustive()
    }
}

impl<'a> ImageCanvas<'a> {
    /// A canvas over `image`.
    pub fn new(image: &'a mut PageImage) -> Self {
        ImageCanvas { image, drawn: None }
    }

    /// A canvas over `image` that marks every pixel it draws in `drawn`,
    /// for an image whose page update compares only the spans drawn.
    pub fn marking(image: &'a mut PageImage, drawn: &'a mut PageSpans) -> Self {
        ImageCanvas {
            image,
            drawn: Some(drawn),
        }
    }
}

impl OriginDimensions for ImageCanvas<'_> {
    fn size(&self) -> Size {
        SCREEN_SIZE
    }
}

impl DrawTarget for ImageCanvas<'_> {
    type Color = PaletteIndex;
    type Error = Infallible;

    fn draw_iter<I>(&mut self, pixels: I) -> Result<(), Infallible>
    where
        I: IntoIterator<Item = Pixel<PaletteIndex>>,
    {
        for Pixel(point, colour) in pixels {
            if (0..SCREEN_WIDTH).contains(&point.x) && (0..SCREEN_HEIGHT).contains(&point.y) {
                self.image[(point.y * SCREEN_WIDTH + point.x) as usize] = colour.0;
                if let Some(drawn) = self.drawn.as_deref_mut() {
                    let x = point.x as usize;
                    drawn.mark(point.y as usize, x..x + 1);
                }
            }
        }
        Ok(())
    }

    fn fill_solid(&mut self, area: &Rectangle, colour: PaletteIndex) -> Result<(), Infallible> {
        if let Some((x0, y0, x1, y1)) = on_screen(area) {
            for y in y0..y1 {
                let row = (y * SCREEN_WIDTH) as usize;
                self.image[row + x0 as usize..row + x1 as usize].fill(colour.0);
                if let Some(drawn) = self.drawn.as_deref_mut() {
                    drawn.mark(y as usize, x0 as usize..x1 as usize);
                }
            }
        }
        Ok(())
    }
}
