//! One frame, at the lowest bus cost: all the work that needs no bus is done
//! first (transform, cull, scan conversion into a RAM image of the frame),
//! then the hidden page is brought up to date by writing only the pixels that
//! differ from what that page holds — which the renderer remembers, one shadow
//! image per page, since the two pages hold different frames — and the page is
//! shown in step with vertical retrace.
//!
//! Which surfaces hide which is decided in [`crate::depth`]; this module
//! only turns the frame it renders into the fewest bus writes.
//!
//! Abrash's own method (erase the last extent, fill every visible face) is
//! kept in `baseline` for comparison; it writes every visible pixel every frame.

use crate::depth::render_with_depth;
use crate::scene::Scene;
use engine::{ClipRect, DepthBand, FaceCounts};
use modex::{ModeX, Page, PageImage, VgaBus, PAGE_PIXELS, SCREEN_HEIGHT, SCREEN_WIDTH};

pub use crate::depth::{render_faces_with_depth, render_painter, render_to_image};

/// The colour index behind everything drawn.
pub const BACKGROUND: u8 = 0;
/// The whole Mode X screen, for clipping.
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
}

/// Double-buffered drawing that writes each frame's changes only.
pub struct Renderer {
    shown: Page,
    /// What pages 0 and 1 hold.
    shadows: [PageImage; 2],
    /// The frame being drawn.
    next: PageImage,
    depth: DepthBand,
}

impl Default for Renderer {
    fn default() -> Self {
        Self::new()
    }
}

impl core::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // Not the three frame images: 230 KiB of colour indices.
        f.debug_struct("Renderer")
            .field("shown", &self.shown)
            .finish_non_exhaustive()
    }
}

impl Renderer {
    /// Expects both pages blank and page 0 shown, as `ModeX::set_mode` leaves
    /// them.
    pub const fn new() -> Self {
        Renderer {
            shown: Page::Zero,
            shadows: [[BACKGROUND; PAGE_PIXELS]; 2],
            next: [BACKGROUND; PAGE_PIXELS],
            depth: DepthBand::new(),
        }
    }

    /// Back to the state of [`Renderer::new`], in place (a renderer in
    /// static memory is never built again on the stack): both pages and the
    /// next frame blank, page 0 shown.
    pub fn reset(&mut self) {
        self.shown = Page::Zero;
        for image in self.shadows.iter_mut().chain([&mut self.next]) {
            image.fill(BACKGROUND);
        }
    }

    /// The page last drawn: the one on screen once the caller has flipped.
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
        let faces = render_with_depth(scene, &mut self.next, &mut self.depth);
        overlay(&mut self.next, faces);
        let page = self.shown.other();
        vga.update_page(
            page,
            &mut self.shadows[usize::from(page.index())],
            &self.next,
        );
        self.shown = page;
        (page, faces)
    }
}

impl FrameDrawer for Renderer {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        self.draw_with_overlay(vga, scene, |_, _| {}).0
    }
}

/// A borrowed renderer draws as the renderer does (the kernel lends its
/// static one to the bench).
impl FrameDrawer for &mut Renderer {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        (**self).draw(vga, scene)
    }
}
