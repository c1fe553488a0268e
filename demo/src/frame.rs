//! One frame, at the lowest bus cost: all the work that needs no bus is done
//! first (transform, cull, scan conversion into a RAM image of the frame),
//! then the hidden page is brought up to date by writing only the pixels that
//! differ from what that page holds — which the renderer remembers, one shadow
//! image per page, since the two pages hold different frames — and the page is
//! shown in step with vertical retrace.
//!
//! The seed's own method (erase the last extent, fill every visible face) is
//! kept in `baseline` for comparison; it writes every visible pixel every frame.

use crate::scene::Scene;
use engine::{fill_convex_polygon, ClipRect, FaceCounts};
use modex::{FlipReport, ModeX, Page, PageImage, VgaBus, PAGE_PIXELS, SCREEN_HEIGHT, SCREEN_WIDTH};

pub const BACKGROUND: u8 = 0;
pub const SCREEN_CLIP: ClipRect = ClipRect {
    x0: 0,
    y0: 0,
    x1: SCREEN_WIDTH,
    y1: SCREEN_HEIGHT,
};

/// Something that draws a scene into the hidden page: this renderer and the
/// baselines it is measured against.
pub trait FrameDrawer {
    /// Draws the scene into the page not shown, returns that page, and from
    /// then on counts it as shown (the caller flips to it, or not, as it likes).
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page;

    /// Draws and shows the frame.
    fn draw_frame<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> FlipReport {
        let page = self.draw(vga, scene);
        vga.show_page(page)
    }
}

/// The scene as colour indices in RAM, background first.
pub fn render_to_image(scene: &mut Scene, image: &mut PageImage) -> FaceCounts {
    image.fill(BACKGROUND);
    scene.visible_faces(|polygon, colour| {
        fill_convex_polygon(polygon, SCREEN_CLIP, |y, x_start, x_end| {
            let row = (y * SCREEN_WIDTH) as usize;
            image[row + x_start as usize..row + x_end as usize].fill(colour);
        });
    })
}

/// Double-buffered drawing that writes each frame's changes only.
pub struct Renderer {
    shown: Page,
    /// What pages 0 and 1 hold.
    shadows: [PageImage; 2],
    /// The frame being drawn.
    next: PageImage,
}

impl Default for Renderer {
    fn default() -> Self {
        Self::new()
    }
}

impl Renderer {
    /// Expects both pages blank and page 0 shown, as `ModeX::set_mode` leaves
    /// them.
    pub const fn new() -> Self {
        Renderer {
            shown: Page(0),
            shadows: [[BACKGROUND; PAGE_PIXELS]; 2],
            next: [BACKGROUND; PAGE_PIXELS],
        }
    }

    pub fn shown_page(&self) -> Page {
        self.shown
    }

    /// Draws the scene, then lets `overlay` draw over it, into the page not
    /// shown; returns that page (counted as shown from now on) and what the
    /// scene drew and culled.
    pub fn draw_with_overlay<B: VgaBus>(
        &mut self,
        vga: &mut ModeX<B>,
        scene: &mut Scene,
        overlay: impl FnOnce(&mut PageImage, FaceCounts),
    ) -> (Page, FaceCounts) {
        let faces = render_to_image(scene, &mut self.next);
        overlay(&mut self.next, faces);
        let page = Page(1 - self.shown.0);
        vga.update_page(page, &mut self.shadows[usize::from(page.0)], &self.next);
        self.shown = page;
        (page, faces)
    }
}

impl FrameDrawer for Renderer {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        self.draw_with_overlay(vga, scene, |_, _| {}).0
    }
}
