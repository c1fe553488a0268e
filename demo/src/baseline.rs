//! The two ways of drawing Mode X that the renderer is measured against.
//!
//! * [`OriginalMethod`]: Abrash's — erase the rectangle drawn into this page
//!   last time with the Map Mask rectangle fill, then fill every visible face
//!   with Map Mask spans.
//! * [`PerPixel`]: the common one (the `vga` crate draws Mode X this way) — the
//!   same erase and fill, but pixel by pixel, each with its own Map Mask OUT.

use crate::frame::FrameDrawer;
use crate::scene::Scene;
use crate::screen::{BACKGROUND, SCREEN_CLIP};
use engine::{fill_convex_polygon, Point};
use modex::{ModeX, Page, VgaBus};

/// A half-open screen rectangle [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Extent {
    /// Leftmost column.
    pub x0: i32,
    /// Top row.
    pub y0: i32,
    /// One past the rightmost column.
    pub x1: i32,
    /// One past the bottom row.
    pub y1: i32,
}

impl Extent {
    /// The pixels a polygon's fill can touch: its vertices' bounding box (right
    /// and bottom edges excluded, as the filler excludes them), clipped.
    fn of_polygon(points: &[Point]) -> Option<Extent> {
        let x0 = points.iter().map(|p| p.x).min()?.max(SCREEN_CLIP.x0);
        let y0 = points.iter().map(|p| p.y).min()?.max(SCREEN_CLIP.y0);
        let x1 = points.iter().map(|p| p.x).max()?.min(SCREEN_CLIP.x1);
        let y1 = points.iter().map(|p| p.y).max()?.min(SCREEN_CLIP.y1);
        (x0 < x1 && y0 < y1).then_some(Extent { x0, y0, x1, y1 })
    }

    fn union(a: Option<Extent>, b: Option<Extent>) -> Option<Extent> {
        match (a, b) {
            (Some(a), Some(b)) => Some(Extent {
                x0: a.x0.min(b.x0),
                y0: a.y0.min(b.y0),
                x1: a.x1.max(b.x1),
                y1: a.y1.max(b.y1),
            }),
            (a, None) => a,
            (None, b) => b,
        }
    }
}

/// How a baseline puts pixels on the page.
trait PixelPath {
    fn rect<B: VgaBus>(vga: &mut ModeX<B>, page: Page, extent: Extent, colour: u8);
    fn span<B: VgaBus>(vga: &mut ModeX<B>, page: Page, y: i32, x0: i32, x1: i32, colour: u8);
}

/// Erase-then-fill with per-page erase extents, generic over the pixel path.
#[derive(Debug)]
pub struct ExtentRenderer<P> {
    shown: Page,
    drawn: [Option<Extent>; 2],
    path: core::marker::PhantomData<P>,
}

impl<P> Default for ExtentRenderer<P> {
    fn default() -> Self {
        ExtentRenderer {
            shown: Page::Zero,
            drawn: [None, None],
            path: core::marker::PhantomData,
        }
    }
}

#[allow(private_bounds)]
impl<P: PixelPath> FrameDrawer for ExtentRenderer<P> {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        let page = self.shown.other();
        let slot = usize::from(page.index());
        if let Some(old) = self.drawn[slot].take() {
            P::rect(vga, page, old, BACKGROUND);
        }
        let mut drawn = None;
        scene.visible_faces(|polygon, colour| {
            drawn = Extent::union(drawn, Extent::of_polygon(polygon));
            fill_convex_polygon(polygon, SCREEN_CLIP, |y, x0, x1| {
                P::span(vga, page, y, x0, x1, colour)
            });
        });
        self.drawn[slot] = drawn;
        self.shown = page;
        page
    }
}

/// Fills spans through the Map Mask, four pixels a write, as Abrash does.
#[derive(Debug)]
pub struct MapMaskSpans;

impl PixelPath for MapMaskSpans {
    fn rect<B: VgaBus>(vga: &mut ModeX<B>, page: Page, e: Extent, colour: u8) {
        vga.fill_rect(page, e.x0, e.y0, e.x1, e.y1, colour);
    }
    fn span<B: VgaBus>(vga: &mut ModeX<B>, page: Page, y: i32, x0: i32, x1: i32, colour: u8) {
        vga.fill_span(page, y, x0, x1, colour);
    }
}

/// Sets the Map Mask for every pixel: the slowest honest way.
#[derive(Debug)]
pub struct MapMaskPerPixel;

impl MapMaskPerPixel {
    fn pixel<B: VgaBus>(vga: &mut ModeX<B>, page: Page, x: i32, y: i32, colour: u8) {
        // Map Mask index and value in one OUT, every pixel, then the byte.
        vga.put_pixel_uncached(page, x, y, colour);
    }
}

impl PixelPath for MapMaskPerPixel {
    fn rect<B: VgaBus>(vga: &mut ModeX<B>, page: Page, e: Extent, colour: u8) {
        for y in e.y0..e.y1 {
            Self::span(vga, page, y, e.x0, e.x1, colour);
        }
    }
    fn span<B: VgaBus>(vga: &mut ModeX<B>, page: Page, y: i32, x0: i32, x1: i32, colour: u8) {
        for x in x0..x1 {
            Self::pixel(vga, page, x, y, colour);
        }
    }
}

/// The method of Abrash's original program.
pub type OriginalMethod = ExtentRenderer<MapMaskSpans>;
/// Pixel by pixel, a Map Mask OUT each.
pub type PerPixel = ExtentRenderer<MapMaskPerPixel>;
