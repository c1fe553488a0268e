//! Hidden surfaces: the one place that decides where the depth test is
//! needed and applies it.
//!
//! It draws a frame's faces, as the scene handed them out ([`Faces`], plain
//! data from [`crate::faces`]), into a RAM image of the frame, and knows
//! nothing of the scene: faces come in, pixels go out, nothing is asked
//! back. [`crate::frame`] gets the faces from the scene and gives them here.
//!
//! Every frame is drawn the same way: [`rows_needing_depth_test`] looks at
//! the objects' screen rectangles and convexity and answers with the rows
//! where two surfaces can meet; those rows are drawn with the per-pixel
//! depth test, and the rest far to near without it. The rule
//! and the loops that apply it are here.
//!
//! [`render_faces_with_depth`] draws any set of objects with the test
//! everywhere, for callers with objects of their own (`crate::grid`, the
//! benches) rather than a scene's face list.

use crate::faces::bounds::{hull, overlap_rows};
use crate::faces::{Faces, ScreenFace};
use crate::screen::{BACKGROUND, SCREEN_CLIP};
use core::ops::Range;
use engine::{
    fill_convex_polygon, ClipRect, DepthBuffer, DepthPlane, FaceCounts, Point, VisibleFace,
};
use modex::{PageImage, PageSpans, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Whether hidden surfaces need the depth test this frame. Within one convex
/// solid, backface removal leaves faces that never overlap; so the test is
/// needed only for a solid that is not convex, or where two objects' screen
/// rectangles meet. (Three solids on their orbits are usually apart.)
pub fn needs_depth_test(faces: Faces<'_>) -> bool {
    rows_needing_depth_test(faces).is_some()
}

/// The rows where the depth test can change a pixel, as one range: those
/// of a solid that is not convex, and those where two objects' screen
/// rectangles meet. Outside them no pixel is covered by two objects, nor by
/// two faces of one, so drawing without the test gives the same picture.
///
/// Small solids (the crowd's) always take the test on every row: drawn
/// without it where their rectangles kept apart, they differed from the ray
/// caster by a pixel or two away from any edge (`demo/tests/
/// hidden_surfaces.rs`), where corners rounded to pixels fold a tiny face
/// over its neighbour.
pub fn rows_needing_depth_test(faces: Faces<'_>) -> Option<Range<i32>> {
    if faces.small_solids() {
        return Some(i32::MIN..i32::MAX);
    }
    let objects = faces.objects();
    let not_convex = objects
        .iter()
        .filter(|object| !object.convex)
        .filter_map(|object| object.bounds)
        .fold(None, |rows, bounds| hull(rows, Some(bounds.rows())));
    let boxes = objects.iter().filter_map(|object| object.bounds.as_ref());
    hull(not_convex, overlap_rows(boxes))
}

/// Hidden surfaces, exactly: every face that survived backface removal is
/// scan-converted with a per-pixel depth test (−1/z from the face's plane,
/// see `engine::depth`), so the nearest surface shows whatever the objects'
/// order, shape or overlap. The depth buffer covers the whole frame, so
/// each face's rows (as the face list keeps them, see `face_rows`) are
/// drawn once.
///
/// The test is paid only where it can change a pixel. Within one convex
/// solid the faces that survive backface removal never overlap, so only the
/// rows where two objects' screen rectangles meet, or a solid that is not
/// convex, are drawn with the test ([`rows_needing_depth_test`]); the rows
/// above and below them are filled without it, far to near — for the
/// starting scene that is the whole frame, at the cost it had before the
/// depth test. Each row is drawn once, one way or the other. Tests check
/// this gives the picture of the depth test everywhere. Returns the faces'
/// counts.
///
/// `drawn` marks where `image` may differ from the background (see
/// `modex::spans`): only there is the last frame erased, and every span
/// filled is marked, so that on return it marks this frame's spans.
/// `depths` holds nothing drawn, before and after.
pub fn render_with_depth(
    faces: Faces<'_>,
    image: &mut PageImage,
    drawn: &mut PageSpans,
    depths: &mut DepthBuffer,
) -> FaceCounts {
    erase(image, drawn);
    let rows = rows_needing_depth_test(faces)
        .map(|rows| rows.start.clamp(0, SCREEN_HEIGHT)..rows.end.clamp(0, SCREEN_HEIGHT))
        .filter(|rows| !rows.is_empty());
    let Some(rows) = rows else {
        painter_rows(faces, image, drawn, 0..SCREEN_HEIGHT);
        return faces.counts();
    };
    for untested in [0..rows.start, rows.end..SCREEN_HEIGHT] {
        if !untested.is_empty() {
            painter_rows(faces, image, drawn, untested);
        }
    }
    let clip = ClipRect {
        y0: rows.start,
        y1: rows.end,
        ..SCREEN_CLIP
    };
    for face in faces.all() {
        let (true, Some(plane)) = (face.meets_rows(&rows), &face.depth_plane) else {
            continue;
        };
        face_rows(faces, face, clip, |y, xs| {
            draw_nearer(image, drawn, depths, plane, face.colour, y, xs);
        });
    }
    depths.clear(drawn);
    faces.counts()
}

/// Back to the background wherever `drawn` marks, and nothing marked.
fn erase(image: &mut PageImage, drawn: &mut PageSpans) {
    drawn.fill(image, BACKGROUND);
    drawn.clear();
}

/// The depth-tested drawing of `render_with_depth`, on every row, for any
/// set of objects: `faces` must hand every face that survived backface
/// removal, with its colour, to the function it is given, and return their
/// counts, which are returned. `drawn` and `depths` are as for
/// [`render_with_depth`].
pub fn render_faces_with_depth(
    image: &mut PageImage,
    drawn: &mut PageSpans,
    depths: &mut DepthBuffer,
    faces: impl FnOnce(&mut dyn FnMut(&VisibleFace, u8)) -> FaceCounts,
) -> FaceCounts {
    erase(image, drawn);
    let counts = faces(&mut |visible, colour| {
        if let Some(plane) = visible.depth_plane() {
            fill_nearer(
                image,
                drawn,
                depths,
                SCREEN_CLIP,
                visible.polygon,
                &plane,
                colour,
            );
        }
    });
    depths.clear(drawn);
    counts
}

/// Fills `polygon`, within `clip`, with `colour` where its plane is nearer
/// than anything drawn there yet. Always inlined:
/// it holds the inner loop, and left out of line it cost the grid's frame
/// (`cpu_cost`'s workload) 3% more instructions.
#[inline(always)]
fn fill_nearer(
    image: &mut PageImage,
    drawn: &mut PageSpans,
    depths: &mut DepthBuffer,
    clip: ClipRect,
    polygon: &[Point],
    plane: &DepthPlane,
    colour: u8,
) {
    fill_convex_polygon(polygon, clip, |y, x_start, x_end| {
        draw_nearer(image, drawn, depths, plane, colour, y, x_start..x_end);
    });
}

/// Pixels `xs` of row `y` (within the screen), marked in `drawn`, set to
/// `colour` where `plane` is nearer than anything drawn there yet.
#[inline(always)]
fn draw_nearer(
    image: &mut PageImage,
    drawn: &mut PageSpans,
    depths: &mut DepthBuffer,
    plane: &DepthPlane,
    colour: u8,
    y: i32,
    xs: Range<i32>,
) {
    let row = (y * SCREEN_WIDTH) as usize;
    drawn.mark(y as usize, xs.start as usize..xs.end as usize);
    let pixels = &mut image[row + xs.start as usize..row + xs.end as usize];
    depths.test_span(plane, y, xs.start, pixels, colour);
}

/// The painter's algorithm, kept for comparison: whole objects far to near
/// (the order the faces came in), each object's faces in model order, no
/// depth test. Exact only for convex objects that do not interpenetrate.
/// Returns the faces' counts.
pub fn render_painter(faces: Faces<'_>, image: &mut PageImage) -> FaceCounts {
    image.fill(BACKGROUND);
    painter_rows(faces, image, &mut PageSpans::none(), 0..SCREEN_HEIGHT);
    faces.counts()
}

/// The faces far to near over the rows in `rows` only, each span marked in
/// `drawn`; the rest of `image` is left as it is.
fn painter_rows(faces: Faces<'_>, image: &mut PageImage, drawn: &mut PageSpans, rows: Range<i32>) {
    let clip = ClipRect {
        y0: rows.start,
        y1: rows.end,
        ..SCREEN_CLIP
    };
    for object in faces.far_to_near() {
        for face in object {
            face_rows(faces, face, clip, |y, xs| {
                let row = (y * SCREEN_WIDTH) as usize;
                drawn.mark(y as usize, xs.start as usize..xs.end as usize);
                image[row + xs.start as usize..row + xs.end as usize].fill(face.colour);
            });
        }
    }
}

/// Each row of `face` (one of `faces`) within `clip`, whose columns must be
/// the screen's, as `row(y, xs)` from the top: the rows the face list kept,
/// or the face's polygon filled again where the list had no room for them.
#[inline(always)]
fn face_rows(
    faces: Faces<'_>,
    face: &ScreenFace,
    clip: ClipRect,
    mut row: impl FnMut(i32, Range<i32>),
) {
    match faces.spans_of(face) {
        Some(spans) => {
            for span in spans {
                let y = i32::from(span.y);
                if (clip.y0..clip.y1).contains(&y) {
                    row(y, span.x_start.into()..span.x_end.into());
                }
            }
        }
        None => fill_convex_polygon(face.polygon(), clip, |y, x_start, x_end| {
            row(y, x_start..x_end);
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::faces::FaceList;
    use crate::solids::{CUBE, LETTER_L};
    use engine::{Model, Object, Xform};
    use modex::PAGE_PIXELS;
    use std::boxed::Box;
    use std::vec::Vec;

    /// `objects` (model, x, z, convex), each turned a little, and their face
    /// list, painted in the order given.
    fn listed(objects: &[(&'static Model, f64, f64, bool)]) -> (Vec<Object>, Box<FaceList<4, 64>>) {
        let mut placed: Vec<Object> = objects
            .iter()
            .map(|&(model, x, z, _)| {
                let mut object = Object::new(model, Xform::translation(x, 0.0, z));
                object.object_to_world_mut().append_rotation_y(0.4);
                object.object_to_world_mut().append_rotation_x(0.3);
                object
            })
            .collect();
        let mut list = Box::new(FaceList::new());
        list.begin_frame(false);
        for (object, &(_, _, _, convex)) in placed.iter_mut().zip(objects) {
            list.push_object(object, convex, 0, |visible| visible.face.colour);
        }
        let order: [usize; 4] = core::array::from_fn(|index| index);
        list.set_far_to_near(&order[..objects.len()]);
        (placed, list)
    }

    #[test]
    fn the_test_is_needed_only_where_rectangles_meet_or_a_solid_is_not_convex() {
        let (_, apart) = listed(&[(&CUBE, -60.0, -150.0, true), (&CUBE, 60.0, -150.0, true)]);
        assert_eq!(rows_needing_depth_test(apart.faces()), None);
        assert!(!needs_depth_test(apart.faces()));
        let (_, meeting) = listed(&[(&CUBE, -10.0, -150.0, true), (&CUBE, 10.0, -160.0, true)]);
        let objects = meeting.faces().objects();
        let (a, b) = (objects[0].bounds.unwrap(), objects[1].bounds.unwrap());
        assert!(a.overlap_rows(&b).is_some());
        assert_eq!(rows_needing_depth_test(meeting.faces()), a.overlap_rows(&b));
        let (_, l_shape) = listed(&[(&LETTER_L, 0.0, -150.0, false)]);
        let bounds = l_shape.faces().objects()[0].bounds.unwrap();
        assert_eq!(
            rows_needing_depth_test(l_shape.faces()),
            Some(bounds.rows())
        );
        let (_, mut small) = listed(&[(&CUBE, -60.0, -150.0, true)]);
        small.begin_frame(true);
        assert_eq!(
            rows_needing_depth_test(small.faces()),
            Some(i32::MIN..i32::MAX)
        );
    }

    /// `objects` drawn into `image` with the depth test on every row, each
    /// face in its model colour; their faces' counts.
    fn depth_tested_everywhere(
        objects: &mut [Object],
        image: &mut PageImage,
        depths: &mut DepthBuffer,
    ) -> FaceCounts {
        render_faces_with_depth(image, &mut PageSpans::all(), depths, |draw| {
            let mut counts = FaceCounts::default();
            for object in objects {
                counts += object.each_visible_face(|visible| draw(visible, visible.face.colour));
            }
            counts
        })
    }

    /// Faces drawn from the rows the face list kept, and faces past its
    /// room for rows, filled from their polygons where they are drawn, make
    /// the picture the polygons make, with the test and without it.
    #[test]
    fn faces_drawn_from_kept_rows_or_polygons_make_one_picture() {
        let mut cubes: Vec<Object> = (0..24)
            .map(|i| {
                // Each a little nearer than the last, so that the last
                // pushed, which find no room for their rows, show.
                let (x, z) = (f64::from(i) * 0.2, -40.0 + f64::from(i) * 0.05);
                let mut cube = Object::new(&CUBE, Xform::translation(x, 0.0, z));
                let turn = cube.object_to_world_mut();
                turn.append_rotation_y(0.6 + 0.01 * f64::from(i));
                turn.append_rotation_x(0.4);
                cube
            })
            .collect();
        let mut list: Box<FaceList<24, 96>> = Box::default();
        let (mut from_rows, mut from_polygons) =
            (Box::new([0u8; PAGE_PIXELS]), Box::new([0u8; PAGE_PIXELS]));
        let mut depths = Box::new(DepthBuffer::new());
        for small_solids in [false, true] {
            list.begin_frame(small_solids);
            for cube in &mut cubes {
                list.push_object(cube, true, 0, |visible| visible.face.colour);
            }
            let order: Vec<usize> = (0..cubes.len()).collect();
            list.set_far_to_near(&order);
            let faces = list.faces();
            let without_rows = faces
                .all()
                .iter()
                .filter(|face| faces.spans_of(face).is_none());
            assert!(without_rows.count() > 0, "some faces past the rows kept");
            render_with_depth(faces, &mut from_rows, &mut PageSpans::all(), &mut depths);
            depth_tested_everywhere(&mut cubes, &mut from_polygons, &mut depths);
            assert!(
                from_rows
                    .iter()
                    .filter(|&&pixel| pixel != BACKGROUND)
                    .count()
                    > PAGE_PIXELS / 2
            );
            assert!(from_rows == from_polygons, "small solids: {small_solids}");
            // And far to near, with no depth test.
            render_painter(faces, &mut from_rows);
            from_polygons.fill(BACKGROUND);
            for face in faces.far_to_near().flatten() {
                fill_convex_polygon(face.polygon(), SCREEN_CLIP, |y, x_start, x_end| {
                    let row = (y * SCREEN_WIDTH) as usize;
                    from_polygons[row + x_start as usize..row + x_end as usize].fill(face.colour);
                });
            }
            assert!(
                from_rows == from_polygons,
                "painted, small solids: {small_solids}"
            );
        }
    }

    /// Drawn with the test only where it is needed, and far to near
    /// elsewhere, the picture is the one drawn with the test everywhere.
    #[test]
    fn the_rows_drawn_without_the_test_match_the_test_everywhere() {
        let mut everywhere = Box::new([0u8; PAGE_PIXELS]);
        let mut mixed = Box::new([0u8; PAGE_PIXELS]);
        let mut depths = Box::new(DepthBuffer::new());
        for (mut objects, list) in [
            listed(&[(&CUBE, -12.0, -150.0, true), (&CUBE, 12.0, -150.0, true)]),
            listed(&[(&LETTER_L, 0.0, -150.0, false)]),
        ] {
            let faces = list.faces();
            let rows = rows_needing_depth_test(faces).expect("the test somewhere");
            assert!(rows.start > 0 && rows.end < SCREEN_HEIGHT, "{rows:?}");
            let counts = depth_tested_everywhere(&mut objects, &mut everywhere, &mut depths);
            assert_eq!(counts, faces.counts());
            assert_eq!(
                render_with_depth(faces, &mut mixed, &mut PageSpans::all(), &mut depths),
                counts
            );
            assert!(mixed.iter().any(|&pixel| pixel != BACKGROUND));
            assert!(everywhere == mixed);
        }
    }
}
