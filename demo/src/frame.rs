//! One frame, at the lowest bus cost: all the work that needs no bus is done
//! first (transform, cull, scan conversion into a RAM image of the frame),
//! then the hidden page is brought up to date by writing only the pixels that
//! differ from what that page holds — which the renderer remembers, one shadow
//! image per page, since the two pages hold different frames — and the page is
//! shown in step with vertical retrace. Only the spans the frame drew and the
//! spans the page held are compared (`modex::spans`): everywhere else both
//! are the background.
//!
//! This module orchestrates the frame, and a frame's data goes one way
//! through it: the scene hands out its faces ([`Scene::faces`], plain data
//! of `crate::faces`), the depth policy draws them into the RAM image
//! ([`crate::depth`], which decides which surfaces hide which), and the
//! image goes to the VGA here. The scene and the depth policy never call
//! each other; only this module knows both.
//!
//! Abrash's own method (erase the last extent, fill every visible face) is
//! kept in `baseline` for comparison; it writes every visible pixel every frame.

use crate::depth;
use crate::scene::{Scene, SceneFaces};
use engine::{DepthBuffer, FaceCounts};
use modex::{ModeX, Page, PageImage, PageSpans, PageWrites, VgaBus, PAGE_PIXELS};

pub use crate::depth::render_faces_with_depth;
pub use crate::screen::{BACKGROUND, SCREEN_CLIP};

/// The scene as colour indices in RAM, background first, each pixel showing
/// the nearest face there: the frame `Renderer` draws (see
/// [`depth::render_with_depth`]). Returns the faces drawn and culled. For
/// tests and host tools: the face list and the depth buffer, 567 KiB
/// between them, are on the stack.
pub fn render_to_image(scene: &mut Scene, image: &mut PageImage) -> FaceCounts {
    let mut list = SceneFaces::new();
    depth::render_with_depth(
        scene.faces(&mut list),
        image,
        &mut PageSpans::all(),
        &mut DepthBuffer::new(),
    )
}

/// The scene painted by the painter's algorithm, kept for comparison (see
/// [`depth::render_painter`]): whole objects far to near, no depth test.
/// The face list, 267 KiB, is on the stack.
pub fn render_painter(scene: &mut Scene, image: &mut PageImage) -> FaceCounts {
    let mut list = SceneFaces::new();
    depth::render_painter(scene.faces(&mut list), image)
}

/// Whether the scene's frame needs the depth test anywhere (see
/// [`depth::needs_depth_test`]). The face list, 267 KiB, is on the stack.
pub fn needs_depth_test(scene: &mut Scene) -> bool {
    let mut list = SceneFaces::new();
    depth::needs_depth_test(scene.faces(&mut list))
}

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
    /// Where pages 0 and 1 can hold anything but the background: the spans
    /// drawn into the frame each was last given.
    held: [PageSpans; 2],
    /// The frame being drawn.
    next: PageImage,
    /// Where `next` can differ from the background: the spans drawn into it.
    drawn: PageSpans,
    depth: DepthBuffer,
    /// The scene's faces this frame.
    faces: SceneFaces,
    /// Room for a page update's writes, kept so it is not cleared each frame.
    writes: PageWrites,
    /// Compare every pixel, not the spans (a check on the spans for tests).
    compare_every_pixel: bool,
}

impl Default for Renderer {
    fn default() -> Self {
        Self::new()
    }
}

impl core::fmt::Debug for Renderer {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        // Not the three frame images (230 KiB of colour indices) nor the
        // faces.
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
            held: [PageSpans::none(), PageSpans::none()],
            next: [BACKGROUND; PAGE_PIXELS],
            drawn: PageSpans::none(),
            depth: DepthBuffer::new(),
            faces: SceneFaces::new(),
            writes: PageWrites::new(),
            compare_every_pixel: false,
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
        for spans in self.held.iter_mut().chain([&mut self.drawn]) {
            spans.clear();
        }
    }

    /// With `true`, each page update compares every pixel of the frame
    /// with the page's shadow instead of the spans drawn and held: the same
    /// bus operations if the spans are right, which tests check.
    pub fn compare_every_pixel(&mut self, every_pixel: bool) {
        self.compare_every_pixel = every_pixel;
    }

    /// The frame last drawn, as it went to the page.
    pub fn frame(&self) -> &PageImage {
        &self.next
    }

    /// What the renderer believes `page` holds.
    pub fn shadow(&self, page: Page) -> &PageImage {
        &self.shadows[usize::from(page.index())]
    }

    /// The page last drawn: the one on screen once the caller has flipped.
    pub fn shown_page(&self) -> Page {
        self.shown
    }

    /// Draws the scene, then lets `overlay` draw over it, into the page not
    /// shown; returns that page (counted as shown from now on) and what the
    /// scene drew and culled. The scene's faces go to the depth policy,
    /// which draws them into the next frame; the frame goes to the page.
    /// `overlay` must mark in the spans it is given every pixel it draws.
    pub fn draw_with_overlay<B: VgaBus>(
        &mut self,
        vga: &mut ModeX<B>,
        scene: &mut Scene,
        overlay: impl FnOnce(&mut PageImage, &mut PageSpans, FaceCounts),
    ) -> (Page, FaceCounts) {
        let faces = scene.faces(&mut self.faces);
        let faces =
            depth::render_with_depth(faces, &mut self.next, &mut self.drawn, &mut self.depth);
        overlay(&mut self.next, &mut self.drawn, faces);
        let page = self.shown.other();
        let index = usize::from(page.index());
        // The page can differ from the frame only where one of them is not
        // the background; from now on it holds the frame's spans.
        let held = &mut self.held[index];
        if self.compare_every_pixel {
            held.mark_all();
        } else {
            held.add(&self.drawn);
        }
        vga.update_page_with(
            page,
            &mut self.shadows[index],
            &self.next,
            held,
            &mut self.writes,
        );
        held.clone_from(&self.drawn);
        self.shown = page;
        (page, faces)
    }
}

impl FrameDrawer for Renderer {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        self.draw_with_overlay(vga, scene, |_, _, _| {}).0
    }
}

/// A borrowed renderer draws as the renderer does (the kernel lends its
/// static one to the bench).
impl FrameDrawer for &mut Renderer {
    fn draw<B: VgaBus>(&mut self, vga: &mut ModeX<B>, scene: &mut Scene) -> Page {
        (**self).draw(vga, scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneCommand;
    use std::boxed::Box;

    /// The starting scene (one convex cube, flat colours) looks exactly as
    /// before the depth test, and so do the three solids while their orbits
    /// keep them apart: there the painter's order was already exact. (One
    /// convex solid alone is drawn without the depth test, as before it; for
    /// solids with faces of five corners, rounding a nearly edge-on face's
    /// corners to pixels can fold it over its neighbour by a pixel, and there
    /// the two ways may pick different faces, within the edge band that
    /// `demo/tests/hidden_surfaces.rs` allows.)
    #[test]
    fn the_depth_test_changes_nothing_where_the_painters_order_was_exact() {
        let mut depth = Box::new([0u8; PAGE_PIXELS]);
        let mut painter = Box::new([0u8; PAGE_PIXELS]);
        let mut mixed = Box::new([0u8; PAGE_PIXELS]);
        let mut depths = Box::new(DepthBuffer::new());
        let mut list = Box::new(SceneFaces::new());
        for (shape, several, frames) in [(0, false, 360), (0, true, 360)] {
            let mut scene = Scene::new();
            for _ in 0..shape {
                scene.apply(SceneCommand::NextSolid);
            }
            assert!(scene.solid().convex);
            if several {
                scene.apply(SceneCommand::ToggleSeveral);
            }
            if !several {
                assert!(!needs_depth_test(&mut scene));
            }
            let mut skipped = 0;
            for frame in 0..frames {
                scene.tick();
                skipped += usize::from(!needs_depth_test(&mut scene));
                // The depth test itself, even where it would be skipped.
                let a = render_faces_with_depth(
                    &mut depth,
                    &mut PageSpans::all(),
                    &mut depths,
                    |draw| scene.each_visible_face(|v, c| draw(v, c)),
                );
                let b = render_painter(&mut scene, &mut painter);
                let faces = scene.faces(&mut list);
                assert_eq!(
                    depth::render_with_depth(faces, &mut mixed, &mut PageSpans::all(), &mut depths),
                    a
                );
                assert!(depth == mixed, "the rows drawn without the test differ");
                assert_eq!(a, b);
                assert!(
                    depth == painter,
                    "shape {shape}, frame {frame}, several: {several}"
                );
            }
            // The orbits keep the three apart for some frames, not all.
            if several {
                assert!(
                    skipped > 0 && skipped < frames,
                    "{skipped} of {frames} skipped"
                );
            }
        }
    }
}
