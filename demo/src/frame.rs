//! One frame, the seed's way: on the page not shown, erase what was drawn there
//! last time, fill the faces that face the viewer, then show the page in step
//! with vertical retrace. Each page remembers its own erase extent because the
//! two pages hold different frames.

use crate::scene::Scene;
use engine::{fill_convex_polygon, ClipRect, Point};
use modex::{FlipReport, ModeX, Page, VgaBus, SCREEN_HEIGHT, SCREEN_WIDTH};

const BACKGROUND: u8 = 0;
pub const SCREEN_CLIP: ClipRect = ClipRect {
    x0: 0,
    y0: 0,
    x1: SCREEN_WIDTH,
    y1: SCREEN_HEIGHT,
};

/// A half-open screen rectangle [x0, x1) x [y0, y1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Extent {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl Extent {
    /// The pixels a polygon's fill can touch: its vertices' bounding box (right
    /// and bottom edges excluded, as the filler excludes them), clipped.
    fn of_polygon(points: &[Point]) -> Option<Extent> {
        let mut extent = Extent {
            x0: i32::MAX,
            y0: i32::MAX,
            x1: i32::MIN,
            y1: i32::MIN,
        };
        for p in points {
            extent.x0 = extent.x0.min(p.x);
            extent.y0 = extent.y0.min(p.y);
            extent.x1 = extent.x1.max(p.x);
            extent.y1 = extent.y1.max(p.y);
        }
        extent.clipped()
    }

    fn clipped(self) -> Option<Extent> {
        let clipped = Extent {
            x0: self.x0.max(SCREEN_CLIP.x0),
            y0: self.y0.max(SCREEN_CLIP.y0),
            x1: self.x1.min(SCREEN_CLIP.x1),
            y1: self.y1.min(SCREEN_CLIP.y1),
        };
        (clipped.x0 < clipped.x1 && clipped.y0 < clipped.y1).then_some(clipped)
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

/// Double-buffered drawing of a scene into Mode X pages 0 and 1.
pub struct Renderer {
    shown: Page,
    /// What each page holds that the next frame drawn there must erase.
    drawn: [Option<Extent>; 2],
}

impl Default for Renderer {
    fn default() -> Self {
        Self::new()
    }
}

impl Renderer {
    /// Expects both pages blank and page 0 shown, as `ModeX::set_mode` leaves them.
    pub const fn new() -> Self {
        Renderer {
            shown: Page(0),
            drawn: [None, None],
        }
    }

    pub fn shown_page(&self) -> Page {
        self.shown
    }

    /// Draws the scene's visible faces on the hidden page and shows it.
    pub fn draw_frame<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> FlipReport {
        let page = Page(1 - self.shown.0);
        let slot = usize::from(page.0);
        if let Some(old) = self.drawn[slot].take() {
            vga.fill_rect(page, old.x0, old.y0, old.x1, old.y1, BACKGROUND);
        }
        let mut drawn = None;
        scene.visible_faces(|polygon: &[Point], colour: u8| {
            drawn = Extent::union(drawn, Extent::of_polygon(polygon));
            fill_convex_polygon(polygon, SCREEN_CLIP, |y, x_start, x_end| {
                vga.fill_span(page, y, x_start, x_end, colour)
            });
        });
        self.drawn[slot] = drawn;
        self.shown = page;
        vga.show_page(page)
    }
}
