//! Hidden surfaces: the one place that decides where the depth test is
//! needed and applies it.
//!
//! Every frame is drawn the same way: [`rows_needing_depth_test`] asks the
//! scene about its objects (how many, which are convex, where they are on
//! screen) and answers with the rows where two surfaces can meet; those rows
//! are drawn with the per-pixel depth test, band by band, and the rest far to
//! near without it. [`crate::scene::Scene`] answers questions about objects
//! only; the rule and the loops that apply it are here.

mod bounds;

use crate::frame::{BACKGROUND, SCREEN_CLIP};
use crate::scene::{Scene, MAX_OBJECTS};
use bounds::{hull, overlap_rows, ScreenBox};
use core::ops::Range;
use engine::{
    fill_convex_polygon, ClipRect, DepthBand, FaceCounts, Object, VisibleFace, BANDS, BAND_ROWS,
};
use modex::{PageImage, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Whether hidden surfaces need the depth test this frame. Within one convex
/// solid, backface removal leaves faces that never overlap; every object but a
/// non-convex solid in the cube's place is convex; so the test is needed
/// only for a non-convex solid, or where two objects' screen rectangles
/// meet. (Three solids on their orbits are usually apart.)
pub fn needs_depth_test(scene: &mut Scene) -> bool {
    rows_needing_depth_test(scene).is_some()
}

/// The rows where the depth test can change a pixel, as one range: those
/// of a non-convex solid, and those where two objects' screen rectangles
/// meet. Outside them no pixel is covered by two objects, nor by two
/// faces of one, so drawing without the test gives the same picture.
///
/// The crowd always takes the test on every row: its small solids, drawn
/// without it where their rectangles kept apart, differed from the ray
/// caster by a pixel or two away from any edge (`demo/tests/
/// hidden_surfaces.rs`), where corners rounded to pixels fold a tiny face
/// over its neighbour.
pub fn rows_needing_depth_test(scene: &mut Scene) -> Option<Range<i32>> {
    if scene.crowd() {
        return Some(i32::MIN..i32::MAX);
    }
    let primary_convex = scene.solid().convex;
    let mut boxes = [ScreenBox::default(); MAX_OBJECTS];
    let mut boxed = 0;
    for object in scene.objects_mut() {
        if let Some(bounds) = ScreenBox::around(object.screen_vertices()) {
            boxes[boxed] = bounds;
            boxed += 1;
        }
    }
    let boxes = &boxes[..boxed];
    let primary = match boxes.first() {
        Some(bounds) if !primary_convex => Some(bounds.rows()),
        _ => None,
    };
    hull(primary, overlap_rows(boxes))
}

/// The scene as colour indices in RAM, background first, each pixel showing
/// the nearest face there (the depth test; see `render_with_depth`).
pub fn render_to_image(scene: &mut Scene, image: &mut PageImage) -> FaceCounts {
    render_with_depth(scene, image, &mut DepthBand::new())
}

/// Hidden surfaces, exactly: backface removal first rejects the faces turned
/// away, then every remaining face is scan-converted with a per-pixel depth
/// test (−1/z from the face's plane, see `engine::depth`), so the nearest
/// surface shows whatever the objects' order, shape or overlap. The depth
/// buffer covers one band of rows at a time (`band`), so the faces are
/// walked once per band.
///
/// The test is paid only where it can change a pixel. Within one convex
/// solid the faces that survive backface removal never overlap, so only the
/// bands holding rows where two objects' screen rectangles meet, or a
/// non-convex solid, are drawn with the test ([`rows_needing_depth_test`]);
/// the rows above and below them are filled without it, far to near — for the
/// starting scene that is the whole frame, at the cost it had before the depth
/// test. Each row is drawn once, one way or the other. Tests check this gives
/// the picture of the depth test everywhere.
pub fn render_with_depth(
    scene: &mut Scene,
    image: &mut PageImage,
    band: &mut DepthBand,
) -> FaceCounts {
    let Some(rows) = rows_needing_depth_test(scene) else {
        return render_painter(scene, image);
    };
    let first = rows.start.clamp(0, SCREEN_HEIGHT) / BAND_ROWS;
    let last = (rows.end.clamp(0, SCREEN_HEIGHT) + BAND_ROWS - 1) / BAND_ROWS;
    if first == last {
        return render_painter(scene, image);
    }
    for untested in [0..first * BAND_ROWS, last * BAND_ROWS..SCREEN_HEIGHT] {
        if !untested.is_empty() {
            painter_rows(scene, image, untested);
        }
    }
    depth_test_bands(image, band, first..last, |clip, draw| {
        scene.each_visible_face_in_rows(clip.y0..clip.y1, |visible, colour| draw(visible, colour))
    })
}

/// Every face of `objects` that survives backface removal, object by object,
/// leaving out (while still counting) the faces whose corners all lie above
/// or all below `rows`: a band's faces, without paying for the depth plane of
/// a face that misses the band.
pub fn each_visible_face_in_rows<'a>(
    objects: impl IntoIterator<Item = &'a mut Object>,
    rows: Range<i32>,
    mut draw: impl FnMut(&VisibleFace),
) -> FaceCounts {
    let mut counts = FaceCounts::default();
    for object in objects {
        counts += object.each_visible_face(|visible| {
            let top = visible.polygon.iter().map(|p| p.y).min().unwrap_or(0);
            let bottom = visible.polygon.iter().map(|p| p.y).max().unwrap_or(0);
            // The filler draws rows top..bottom.
            if top < rows.end && bottom > rows.start {
                draw(visible);
            }
        });
    }
    counts
}

/// The depth-tested drawing of `render_with_depth` for any set of objects:
/// `faces` is called once per band, with the band's rows, and must hand every
/// face that survived backface removal — it may leave out those that miss
/// the band's rows — with its colour, to the function it is given. The
/// counts of the first band are returned.
pub fn render_faces_with_depth(
    image: &mut PageImage,
    band: &mut DepthBand,
    faces: impl FnMut(ClipRect, &mut dyn FnMut(&VisibleFace, u8)) -> FaceCounts,
) -> FaceCounts {
    depth_test_bands(image, band, 0..BANDS, faces)
}

/// `render_faces_with_depth` for the bands in `bands` only: their rows are
/// cleared to the background and drawn with the depth test; the rest of
/// `image` is left as it is.
fn depth_test_bands(
    image: &mut PageImage,
    band: &mut DepthBand,
    bands: Range<i32>,
    mut faces: impl FnMut(ClipRect, &mut dyn FnMut(&VisibleFace, u8)) -> FaceCounts,
) -> FaceCounts {
    let mut counts = None;
    for index in bands {
        band.start(index);
        let clip = band.clip();
        let rows = (clip.y0 * SCREEN_WIDTH) as usize..(clip.y1 * SCREEN_WIDTH) as usize;
        image[rows].fill(BACKGROUND);
        let band_counts = faces(clip, &mut |visible, colour| {
            let Some(plane) = visible.depth_plane() else {
                return;
            };
            fill_convex_polygon(visible.polygon, clip, |y, x_start, x_end| {
                let row = (y * SCREEN_WIDTH) as usize;
                let pixels = &mut image[row + x_start as usize..row + x_end as usize];
                band.test_span(&plane, y, x_start, pixels, colour);
            });
        });
        counts.get_or_insert(band_counts);
    }
    counts.unwrap_or_default()
}

/// The painter's algorithm, kept for comparison: whole objects far to near by
/// the distance of their centres, faces in model order, no depth test. Exact
/// only for convex objects that do not interpenetrate.
pub fn render_painter(scene: &mut Scene, image: &mut PageImage) -> FaceCounts {
    painter_rows(scene, image, 0..SCREEN_HEIGHT)
}

/// `render_painter` for the rows in `rows` only; the rest of `image` is left
/// as it is.
fn painter_rows(scene: &mut Scene, image: &mut PageImage, rows: Range<i32>) -> FaceCounts {
    image[(rows.start * SCREEN_WIDTH) as usize..(rows.end * SCREEN_WIDTH) as usize]
        .fill(BACKGROUND);
    let clip = ClipRect {
        y0: rows.start,
        y1: rows.end,
        ..SCREEN_CLIP
    };
    scene.visible_faces(|polygon, colour| {
        fill_convex_polygon(polygon, clip, |y, x_start, x_end| {
            let row = (y * SCREEN_WIDTH) as usize;
            image[row + x_start as usize..row + x_end as usize].fill(colour);
        });
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::SceneCommand;
    use modex::PAGE_PIXELS;
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
        let mut band = Box::new(DepthBand::new());
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
                let a = render_faces_with_depth(&mut depth, &mut band, |clip, draw| {
                    scene.each_visible_face_in_rows(clip.y0..clip.y1, |v, c| draw(v, c))
                });
                let b = render_painter(&mut scene, &mut painter);
                assert_eq!(render_with_depth(&mut scene, &mut mixed, &mut band), a);
                assert!(depth == mixed, "the bands drawn without the test differ");
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
