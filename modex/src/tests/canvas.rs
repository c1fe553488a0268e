//! The embedded-graphics targets: drawing through them gives what drawing
//! the same primitives pixel by pixel gives, inside the page drawn on only.

use super::{assert_picture, mode_x, page_pixels, page_range, power_on, Picture, WIDTH};
use crate::{ImageCanvas, Page, PageCanvas, PageImage, PaletteIndex, PAGE_PIXELS};
use core::convert::Infallible;
use embedded_graphics::mono_font::{ascii::FONT_6X10, MonoTextStyleBuilder};
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{Circle, PrimitiveStyle, Rectangle};
use embedded_graphics::text::{Baseline, Text};

/// The reference: every pixel set one at a time into a plain array, with
/// embedded-graphics' own default `fill_solid` (pixel by pixel).
struct Reference(Picture);

impl OriginDimensions for Reference {
    fn size(&self) -> Size {
        Size::new(320, 240)
    }
}

impl DrawTarget for Reference {
    type Color = PaletteIndex;
    type Error = Infallible;
    fn draw_iter<I: IntoIterator<Item = Pixel<PaletteIndex>>>(
        &mut self,
        pixels: I,
    ) -> Result<(), Infallible> {
        for Pixel(p, colour) in pixels {
            if (0..320).contains(&p.x) && (0..240).contains(&p.y) {
                self.0 .0[p.y as usize * WIDTH + p.x as usize] = colour.0;
            }
        }
        Ok(())
    }
}

/// Text, a filled rectangle partly off the left and top, a circle outline
/// partly off the right, and rectangles wholly off screen or empty.
fn scene<D: DrawTarget<Color = PaletteIndex, Error = Infallible>>(target: &mut D) {
    let style = MonoTextStyleBuilder::new()
        .font(&FONT_6X10)
        .text_color(PaletteIndex(15))
        .background_color(PaletteIndex(1))
        .build();
    let _ =
        Text::with_baseline("Mode X 0123 fps", Point::new(3, 1), style, Baseline::Top).draw(target);
    let fill = PrimitiveStyle::with_fill(PaletteIndex(12));
    let _ = Rectangle::new(Point::new(-7, -5), Size::new(50, 30))
        .into_styled(fill)
        .draw(target);
    let _ = Rectangle::new(Point::new(101, 77), Size::new(13, 9))
        .into_styled(fill)
        .draw(target);
    let _ = Rectangle::new(Point::new(400, 10), Size::new(13, 9))
        .into_styled(fill)
        .draw(target);
    let _ = Rectangle::new(Point::new(-100, -100), Size::new(50, 50))
        .into_styled(fill)
        .draw(target);
    let _ = Rectangle::new(Point::new(10, 10), Size::new(0, 9))
        .into_styled(fill)
        .draw(target);
    let _ = Rectangle::new(Point::new(300, 230), Size::new(90, 90))
        .into_styled(fill)
        .draw(target);
    let _ = Circle::new(Point::new(290, 100), 60)
        .into_styled(PrimitiveStyle::with_stroke(PaletteIndex(14), 3))
        .draw(target);
}

fn reference() -> Picture {
    let mut reference = Reference(Picture::filled(0));
    scene(&mut reference);
    reference.0
}

#[test]
fn a_page_canvas_draws_what_the_reference_draws_and_nothing_else() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.bus_mut().set_write_guard(Some(page_range(Page::One)));
    scene(&mut PageCanvas::new(&mut vga, Page::One));
    assert_eq!(vga.bus().guard_violations(), 0);
    let soft = vga.into_bus();
    assert_picture(&reference(), &page_pixels(soft, Page::One), "page 1");
    assert_picture(
        &Picture::filled(0),
        &page_pixels(soft, Page::Zero),
        "page 0",
    );
}

#[test]
fn an_image_canvas_draws_what_the_reference_draws() {
    let mut image: PageImage = [0; PAGE_PIXELS];
    scene(&mut ImageCanvas::new(&mut image));
    assert_picture(&reference(), &Picture(image.to_vec()), "image");
}

#[test]
fn clearing_a_page_canvas_fills_that_page_only() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.bus_mut().set_write_guard(Some(page_range(Page::Two)));
    let _ = PageCanvas::new(&mut vga, Page::Two).clear(PaletteIndex(9));
    assert_eq!(vga.bus().guard_violations(), 0);
    let soft = vga.into_bus();
    assert_picture(&Picture::filled(9), &page_pixels(soft, Page::Two), "page 2");
}

/// `fill_solid` straight on a page: clipped like the reference, through the
/// Map Mask rectangle fill (the same bus writes as `fill_rect`), page only.
#[test]
fn fill_solid_clips_to_the_screen_and_uses_the_rectangle_fill() {
    let cases = [
        ((-7, -5), (50, 30)),                                 // negative origin
        ((300, 230), (90, 90)),                               // partly off right and bottom
        ((400, 10), (13, 9)),                                 // off to the right
        ((-100, -100), (50, 50)),                             // off above and to the left
        ((0, 240), (320, 1)),                                 // just below
        ((10, 10), (0, 9)),                                   // zero width, on screen
        ((10, 10), (9, 0)),                                   // zero height, on screen
        ((-2_000_000_000, 3), (u32::MAX, 2)),                 // wider than i32, covers the row
        ((i32::MAX - 1, i32::MAX - 1), (u32::MAX, u32::MAX)), // far off, would overflow i32
    ];
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let mut expected = Picture::filled(0);
    for (index, ((x, y), (w, h))) in cases.into_iter().enumerate() {
        let colour = 20 + index as u8;
        let (x1, y1) = (i64::from(x) + i64::from(w), i64::from(y) + i64::from(h));
        let (x1, y1) = (x1.min(1000) as i32, y1.min(1000) as i32);
        expected.fill_rect(x, y, x1, y1, colour);
        // The bus writes fill_rect itself makes for the same rectangle.
        let mut other = power_on();
        let mut direct = mode_x(&mut other);
        direct.bus_mut().reset_counts();
        direct.fill_rect(Page::One, x, y, x1, y1, colour);
        let rect_writes = direct.bus().counts().vram_writes;

        vga.bus_mut().set_write_guard(Some(page_range(Page::One)));
        vga.bus_mut().reset_counts();
        let area = Rectangle::new(Point::new(x, y), Size::new(w, h));
        let _ = PageCanvas::new(&mut vga, Page::One).fill_solid(&area, PaletteIndex(colour));
        assert_eq!(vga.bus().guard_violations(), 0, "case {index}");
        assert_eq!(vga.bus().counts().vram_writes, rect_writes, "case {index}");
    }
    let soft = vga.into_bus();
    assert_picture(&expected, &page_pixels(soft, Page::One), "page 1");
    assert_picture(
        &Picture::filled(0),
        &page_pixels(soft, Page::Zero),
        "page 0",
    );
}
