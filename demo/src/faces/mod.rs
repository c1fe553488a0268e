//! A frame's faces as plain data: what the scene hands out and the depth
//! policy draws.
//!
//! Data goes one way. [`crate::scene::Scene::faces`] projects its objects,
//! removes the faces turned away, colours the rest and writes them into a
//! [`FaceList`], with each object's screen rectangle, whether it is convex,
//! and the objects' order far to near; [`crate::depth`] reads the list as
//! [`Faces`] and draws it into the frame; [`crate::frame`] calls the one,
//! then the other. Neither calls back into the other, and this module
//! depends on neither (only on `engine` and the screen's rectangle), so
//! neither depends on the other.
//!
//! A face is culled, coloured, given its depth plane and scan-converted
//! into its rows on the screen ([`Span`]) here, once a frame, or once for as
//! long as its object stays put (the list keeps the last frame's faces, see
//! [`FaceList`]), and the depth policy draws its rows once a frame. The list
//! is fixed-size, as there is no heap: its owner sizes it for the most
//! objects and faces it can show.

pub mod bounds;

use crate::screen::SCREEN_CLIP;
use bounds::ScreenBox;
use core::ops::Range;
use engine::{
    fill_convex_polygon, DepthPlane, FaceCounts, Object, Point, VisibleFace, MAX_FACE_VERTICES,
};

/// The rows a [`FaceList`] keeps for one frame's faces, 48 KiB: the crowd
/// of 59 small solids fills about 3,300, a cube filling the screen at most
/// 720.
/// Faces past them keep none, and are scan-converted where they are drawn.
pub const SPANS_PER_FRAME: usize = 8192;

/// One row of a face on the screen: pixels `x_start..x_end` of row `y`,
/// within the screen, as the polygon filler finds them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Span {
    /// The row.
    pub y: u16,
    /// The first pixel drawn.
    pub x_start: u16,
    /// The pixel just right of the last one drawn.
    pub x_end: u16,
}

impl Span {
    const EMPTY: Span = Span {
        y: 0,
        x_start: 0,
        x_end: 0,
    };
}

/// One face to draw: it faces the viewer, its corners are on the screen,
/// and its colour is decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ScreenFace {
    corners: [Point; MAX_FACE_VERTICES],
    corner_count: u8,
    /// The palette colour to fill it with.
    pub colour: u8,
    /// −1/z across the face, for the depth test: `None` for a plane through
    /// the eye (seen edge-on), which the depth test leaves out.
    pub depth_plane: Option<DepthPlane>,
    top: i32,
    bottom: i32,
    /// Where its rows are in the frame's spans, when the list had room.
    spans: Option<(u32, u32)>,
}

impl ScreenFace {
    const EMPTY: ScreenFace = ScreenFace {
        corners: [Point::new(0, 0); MAX_FACE_VERTICES],
        corner_count: 0,
        colour: 0,
        depth_plane: None,
        top: 0,
        bottom: 0,
        spans: None,
    };

    /// The face `visible` (which survived backface removal) in `colour`.
    pub fn new(visible: &VisibleFace, colour: u8) -> Self {
        let polygon = visible.polygon;
        let mut corners = [Point::default(); MAX_FACE_VERTICES];
        corners[..polygon.len()].copy_from_slice(polygon);
        ScreenFace {
            corners,
            // At most MAX_FACE_VERTICES (8): `Object` refuses bigger faces.
            corner_count: polygon.len() as u8,
            colour,
            depth_plane: visible.depth_plane(),
            top: polygon.iter().map(|p| p.y).min().unwrap_or(0),
            bottom: polygon.iter().map(|p| p.y).max().unwrap_or(0),
            spans: None,
        }
    }

    /// The face's corners on the screen, in the face's order.
    pub fn polygon(&self) -> &[Point] {
        &self.corners[..usize::from(self.corner_count)]
    }

    /// Whether the face's fill can reach `rows`: the filler draws the rows
    /// from its top corner down to, not including, its bottom one.
    pub fn meets_rows(&self, rows: &Range<i32>) -> bool {
        self.top < rows.end && self.bottom > rows.start
    }
}

/// One object's part of the list: its faces, where it lies on the screen,
/// and whether it is convex.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ObjectFaces {
    first_face: usize,
    end_face: usize,
    /// Where its faces' rows are in the frame's spans.
    first_span: usize,
    end_span: usize,
    /// The rectangle around all its vertices on the screen (drawn or not):
    /// its drawing never leaves it. `None` for a model with no vertices.
    pub bounds: Option<ScreenBox>,
    /// Convex, so that its faces that survive backface removal never
    /// overlap one another.
    pub convex: bool,
    /// Its faces drawn and culled.
    counts: FaceCounts,
    /// What its faces were found from: the object's projection number
    /// ([`Object::projection`]) and the colouring's.
    found_from: (u64, u64),
}

impl ObjectFaces {
    /// An unused place: all zero, so that a list in a static starts in
    /// `.bss` rather than in the kernel file (`tests/size.rs`). No object
    /// was found from projection 0.
    const EMPTY: ObjectFaces = ObjectFaces {
        first_face: 0,
        end_face: 0,
        first_span: 0,
        end_span: 0,
        bounds: None,
        convex: false,
        counts: FaceCounts {
            drawn: 0,
            culled: 0,
        },
        found_from: (0, 0),
    };
}

/// One frame's part of a [`FaceList`].
#[derive(Clone, Debug)]
struct FrameFaces<const OBJECTS: usize, const FACES: usize> {
    objects: [ObjectFaces; OBJECTS],
    object_count: usize,
    faces: [ScreenFace; FACES],
    face_count: usize,
    spans: [Span; SPANS_PER_FRAME],
    span_count: usize,
    far_to_near: [usize; OBJECTS],
    counts: FaceCounts,
    small_solids: bool,
}

impl<const OBJECTS: usize, const FACES: usize> FrameFaces<OBJECTS, FACES> {
    const EMPTY: Self = FrameFaces {
        objects: [ObjectFaces::EMPTY; OBJECTS],
        object_count: 0,
        faces: [ScreenFace::EMPTY; FACES],
        face_count: 0,
        spans: [Span::EMPTY; SPANS_PER_FRAME],
        span_count: 0,
        far_to_near: [0; OBJECTS],
        counts: FaceCounts {
            drawn: 0,
            culled: 0,
        },
        small_solids: false,
    };

    /// Adds `faces` to the object being pushed. Panics if the list has no
    /// room left.
    fn add_faces(&mut self, faces: &[ScreenFace]) {
        let room = self.face_count..self.face_count + faces.len();
        let Some(room) = self.faces.get_mut(room) else {
            panic!("the face list holds at most {FACES} faces");
        };
        room.copy_from_slice(faces);
        self.face_count += faces.len();
    }

    /// Adds the face `visible` in `colour` to the object being pushed, with
    /// its rows on the screen when they fit. Panics if the list has no room
    /// for the face.
    fn add_face(&mut self, visible: &VisibleFace, colour: u8) {
        let mut face = ScreenFace::new(visible, colour);
        let first = self.span_count;
        let (spans, mut count) = (&mut self.spans, first);
        let mut fits = true;
        fill_convex_polygon(face.polygon(), SCREEN_CLIP, |y, x_start, x_end| {
            // Within the screen, so each fits a u16.
            let span = Span {
                y: y as u16,
                x_start: x_start as u16,
                x_end: x_end as u16,
            };
            match spans.get_mut(count) {
                Some(slot) => *slot = span,
                None => fits = false,
            }
            count += 1;
        });
        if fits {
            face.spans = Some((first as u32, count as u32));
            self.span_count = count;
        }
        self.add_faces(&[face]);
    }

    /// Adds `faces`, one object's faces last frame, with their rows:
    /// `spans`, that object's rows in last frame's spans from index
    /// `first_span` on, copied where they fit (where they do not, the faces
    /// keep no rows).
    fn add_kept_faces(&mut self, faces: &[ScreenFace], spans: &[Span], first_span: usize) {
        let first_face = self.face_count;
        self.add_faces(faces);
        let start = self.span_count;
        let copied = match self.spans.get_mut(start..start + spans.len()) {
            Some(room) => {
                room.copy_from_slice(spans);
                self.span_count += spans.len();
                true
            }
            None => false,
        };
        let rebased = |index: u32| (index as usize - first_span + start) as u32;
        for face in &mut self.faces[first_face..self.face_count] {
            face.spans = face
                .spans
                .filter(|_| copied)
                .map(|(first, end)| (rebased(first), rebased(end)));
        }
    }

    /// Ends the object whose faces were added from `first_face` on, and
    /// their rows from `first_span` on. Panics if the list has no room for
    /// another object.
    fn end_object(&mut self, first_face: usize, first_span: usize, object: ObjectFaces) {
        let Some(slot) = self.objects.get_mut(self.object_count) else {
            panic!("the face list holds at most {OBJECTS} objects");
        };
        *slot = ObjectFaces {
            first_face,
            end_face: self.face_count,
            first_span,
            end_span: self.span_count,
            ..object
        };
        self.object_count += 1;
        self.counts += object.counts;
    }
}

/// Room for one frame's faces: up to `OBJECTS` objects with `FACES` faces
/// between them. The scene fills it ([`FaceList::begin_frame`], then
/// [`FaceList::push_object`] per object, then [`FaceList::set_far_to_near`]);
/// the depth policy reads it through [`FaceList::faces`].
///
/// It keeps the last frame's faces beside the frame's, so that an object
/// that has not moved since (its [`Object::projection`] the same) and is
/// coloured the same way gets last frame's faces copied rather than culled,
/// coloured and given depth planes again. Half the crowd waits its turn to
/// move each frame.
#[derive(Clone, Debug)]
pub struct FaceList<const OBJECTS: usize, const FACES: usize> {
    /// This frame's and the last frame's, in turn.
    frames: [FrameFaces<OBJECTS, FACES>; 2],
    /// Which of `frames` is this frame's.
    current: usize,
}

impl<const OBJECTS: usize, const FACES: usize> Default for FaceList<OBJECTS, FACES> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const OBJECTS: usize, const FACES: usize> FaceList<OBJECTS, FACES> {
    /// An empty list; `const`, so that it can live in a static beside the
    /// renderer's images.
    pub const fn new() -> Self {
        FaceList {
            frames: [FrameFaces::EMPTY; 2],
            current: 0,
        }
    }

    /// Empties the list for a new frame, keeping the last one's faces.
    /// `small_solids`: some objects are so small on the screen that rounding
    /// their corners to pixels can fold a face over its neighbour (see
    /// [`Faces::small_solids`]).
    pub fn begin_frame(&mut self, small_solids: bool) {
        self.current = 1 - self.current;
        let frame = &mut self.frames[self.current];
        frame.object_count = 0;
        frame.face_count = 0;
        frame.span_count = 0;
        frame.counts = FaceCounts::default();
        frame.small_solids = small_solids;
    }

    /// Adds `object` (projected first if it moved) with its screen
    /// rectangle and each face that survives backface removal, in model
    /// order, coloured by `colour`; counts the faces drawn and culled.
    /// `colouring` names the way `colour` colours: the caller gives another
    /// number whenever what the colours depend on, beyond the face and
    /// where it is, changes. An object pushed in the same place in the
    /// order last frame, unmoved and coloured the same way, gets last
    /// frame's faces.
    ///
    /// Panics if the list has no room left: its owner sizes it for the most
    /// objects and faces it shows, so that would be a mistake in that sizing.
    pub fn push_object(
        &mut self,
        object: &mut Object,
        convex: bool,
        colouring: u64,
        colour: impl Fn(&VisibleFace) -> u8,
    ) {
        let found_from = (object.projection(), colouring);
        let [even, odd] = &mut self.frames;
        let (frame, last) = match self.current {
            0 => (even, &*odd),
            _ => (odd, &*even),
        };
        let (first_face, first_span) = (frame.face_count, frame.span_count);
        let slot = frame.object_count;
        let kept = last
            .objects
            .get(slot)
            .filter(|kept| slot < last.object_count && kept.found_from == found_from)
            .filter(|kept| kept.convex == convex)
            .and_then(|kept| {
                let faces = last.faces.get(kept.first_face..kept.end_face)?;
                Some((
                    *kept,
                    faces,
                    last.spans.get(kept.first_span..kept.end_span)?,
                ))
            });
        let object = match kept {
            Some((kept, faces, spans)) => {
                frame.add_kept_faces(faces, spans, kept.first_span);
                kept
            }
            None => {
                let bounds = ScreenBox::around(object.screen_vertices());
                let counts =
                    object.each_visible_face(|visible| frame.add_face(visible, colour(visible)));
                ObjectFaces {
                    bounds,
                    convex,
                    counts,
                    found_from,
                    ..ObjectFaces::EMPTY
                }
            }
        };
        frame.end_object(first_face, first_span, object);
    }

    /// The order the objects pushed this frame are painted in without the
    /// depth test, farthest first: indices in the order they were pushed.
    /// Panics unless `order` names each of them once.
    pub fn set_far_to_near(&mut self, order: &[usize]) {
        let frame = &mut self.frames[self.current];
        assert_eq!(order.len(), frame.object_count, "an order for every object");
        let mut named = [false; OBJECTS];
        for &index in order {
            assert!(
                index < frame.object_count && !named[index],
                "object {index} named twice or missing"
            );
            named[index] = true;
        }
        frame.far_to_near[..order.len()].copy_from_slice(order);
    }

    /// The frame's faces, to draw.
    pub fn faces(&self) -> Faces<'_> {
        let frame = &self.frames[self.current];
        Faces {
            objects: &frame.objects[..frame.object_count],
            faces: &frame.faces[..frame.face_count],
            spans: &frame.spans[..frame.span_count],
            far_to_near: &frame.far_to_near[..frame.object_count],
            counts: frame.counts,
            small_solids: frame.small_solids,
        }
    }
}

/// A frame's faces, as filled into a [`FaceList`]: read-only, to draw.
#[derive(Clone, Copy, Debug)]
pub struct Faces<'list> {
    objects: &'list [ObjectFaces],
    faces: &'list [ScreenFace],
    spans: &'list [Span],
    far_to_near: &'list [usize],
    counts: FaceCounts,
    small_solids: bool,
}

impl<'list> Faces<'list> {
    /// The objects, in the order they were pushed.
    pub fn objects(&self) -> &'list [ObjectFaces] {
        self.objects
    }

    /// Every face, object by object in the order they were pushed, each
    /// object's in model order: the order the depth test draws them in
    /// (where two faces tie in depth, the first drawn shows).
    pub fn all(&self) -> &'list [ScreenFace] {
        self.faces
    }

    /// The rows `face` (one of [`Faces::all`]) covers on the screen, top
    /// to bottom, as `fill_convex_polygon` finds them within the screen:
    /// `None` where the list had no room for them, and the face's polygon
    /// must be filled where it is drawn.
    pub fn spans_of(&self, face: &ScreenFace) -> Option<&'list [Span]> {
        let (first, end) = face.spans?;
        self.spans.get(first as usize..end as usize)
    }

    /// The faces of `object` (one of [`Faces::objects`]).
    pub fn of(&self, object: &ObjectFaces) -> &'list [ScreenFace] {
        &self.faces[object.first_face..object.end_face]
    }

    /// Each object's faces, the objects farthest first: the painter's order.
    pub fn far_to_near(&self) -> impl Iterator<Item = &'list [ScreenFace]> {
        let (objects, faces) = (self.objects, self.faces);
        self.far_to_near.iter().map(move |&index| {
            let object = &objects[index];
            &faces[object.first_face..object.end_face]
        })
    }

    /// How many faces were drawn and culled.
    pub fn counts(&self) -> FaceCounts {
        self.counts
    }

    /// Some objects are so small on the screen that rounding their corners
    /// to pixels can fold a face over its neighbour, away from any edge
    /// between objects: only the depth test everywhere draws them right.
    pub fn small_solids(&self) -> bool {
        self.small_solids
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solids::{CUBE, TETRAHEDRON};
    use engine::Xform;
    use std::boxed::Box;
    use std::vec::Vec;

    fn cube_at(x: f64, z: f64) -> Object {
        Object::new(&CUBE, Xform::translation(x, 0.0, z))
    }

    #[test]
    fn each_object_keeps_its_own_faces_bounds_and_convexity() {
        let mut list: FaceList<3, 20> = FaceList::new();
        let (mut near, mut far) = (cube_at(-40.0, -100.0), cube_at(40.0, -300.0));
        let mut turned = Object::new(&TETRAHEDRON, Xform::translation(0.0, 0.0, -200.0));
        turned.object_to_world_mut().append_rotation_y(0.5);
        list.begin_frame(true);
        list.push_object(&mut near, true, 7, |_| 7);
        list.push_object(&mut far, false, 0, |visible| visible.face.colour);
        list.push_object(&mut turned, true, 9, |_| 9);
        list.set_far_to_near(&[1, 2, 0]);
        let faces = list.faces();
        assert!(faces.small_solids());
        let objects = faces.objects();
        assert_eq!(objects.len(), 3);
        let mut counts = FaceCounts::default();
        for (object, (mut engine_object, convex)) in
            objects
                .iter()
                .zip([(near, true), (far, false), (turned, true)])
        {
            let mut expected = Vec::new();
            counts += engine_object.each_visible_face(|v| expected.push(v.polygon.to_vec()));
            let listed: Vec<_> = faces
                .of(object)
                .iter()
                .map(|f| f.polygon().to_vec())
                .collect();
            assert_eq!(listed, expected);
            assert_eq!(object.convex, convex);
            assert_eq!(
                object.bounds,
                ScreenBox::around(engine_object.screen_vertices())
            );
        }
        assert_eq!(faces.counts(), counts);
        assert!(faces.of(&objects[0]).iter().all(|face| face.colour == 7));
        assert!(faces.of(&objects[2]).iter().all(|face| face.colour == 9));
        let all: usize = objects.iter().map(|object| faces.of(object).len()).sum();
        assert_eq!(faces.all().len(), all);
        let order: Vec<_> = faces.far_to_near().collect();
        assert_eq!(
            order,
            [
                faces.of(&objects[1]),
                faces.of(&objects[2]),
                faces.of(&objects[0])
            ]
        );
        // A new frame starts empty.
        list.begin_frame(false);
        let faces = list.faces();
        assert!(faces.all().is_empty() && faces.objects().is_empty());
        assert_eq!(faces.counts(), FaceCounts::default());
        assert!(!faces.small_solids());
    }

    /// Frame by frame, the list hands out what a fresh one does, while it
    /// colours an object's faces again only when the object moved, the
    /// colouring changed, or another object took its place in the order.
    #[test]
    fn only_an_unmoved_object_coloured_the_same_keeps_last_frames_faces() {
        let mut list: FaceList<3, 20> = FaceList::new();
        let mut objects = [cube_at(-40.0, -100.0), cube_at(40.0, -300.0)];
        objects[1].object_to_world_mut().append_rotation_y(0.5);
        // The frames in which each object's faces were coloured.
        let coloured = core::cell::RefCell::new([Vec::new(), Vec::new()]);
        for frame in 0..12 {
            if frame % 3 == 1 {
                objects[0].object_to_world_mut().append_rotation_x(0.3);
            }
            // A new way of colouring every four frames; the order reversed
            // from frame 9.
            let colouring = frame / 4;
            let order: [usize; 2] = if frame < 9 { [0, 1] } else { [1, 0] };
            let mut fresh: FaceList<3, 20> = FaceList::new();
            list.begin_frame(false);
            fresh.begin_frame(false);
            for index in order {
                let object = &mut objects[index];
                let colour = |_: &VisibleFace| {
                    let frames = &mut coloured.borrow_mut()[index];
                    if frames.last() != Some(&frame) {
                        frames.push(frame);
                    }
                    5 + colouring as u8
                };
                list.push_object(object, true, colouring, colour);
                fresh.push_object(object, true, colouring, |_| 5 + colouring as u8);
            }
            list.set_far_to_near(&[1, 0]);
            fresh.set_far_to_near(&[1, 0]);
            let (kept, fresh) = (list.faces(), fresh.faces());
            assert_eq!(kept.objects(), fresh.objects(), "frame {frame}");
            assert_eq!(kept.all(), fresh.all(), "frame {frame}");
            assert_eq!(kept.counts(), fresh.counts(), "frame {frame}");
            for face in kept.all() {
                let rows = kept.spans_of(face);
                assert_eq!(rows, fresh.spans_of(face), "frame {frame}");
                assert_eq!(rows, Some(&filled_rows(face)[..]), "frame {frame}");
            }
        }
        let [moved, unmoved] = coloured.into_inner();
        // New colourings at 0, 4 and 8, the order changed at 9, and moves
        // at 1, 4, 7 and 10.
        assert_eq!(unmoved, [0, 4, 8, 9]);
        assert_eq!(moved, [0, 1, 4, 7, 8, 9, 10]);
    }

    /// The rows the polygon filler finds for `face` within the screen.
    fn filled_rows(face: &ScreenFace) -> Vec<Span> {
        let mut rows = Vec::new();
        fill_convex_polygon(face.polygon(), SCREEN_CLIP, |y, x_start, x_end| {
            rows.push(Span {
                y: y as u16,
                x_start: x_start as u16,
                x_end: x_end as u16,
            })
        });
        rows
    }

    /// Cubes so near that each fills the screen need more rows than the
    /// list keeps: the faces that fit keep the filler's rows, the rest keep
    /// none (and are filled where they are drawn), in the frame that found
    /// them and in the next, which keeps them.
    #[test]
    fn faces_past_the_rows_kept_keep_none() {
        let mut list: Box<FaceList<24, 96>> = Box::default();
        let mut cubes: Vec<Object> = (0..24)
            .map(|i| cube_at(f64::from(i) * 0.1, -40.0))
            .collect();
        for cube in &mut cubes {
            cube.object_to_world_mut().append_rotation_y(0.6);
            cube.object_to_world_mut().append_rotation_x(0.4);
        }
        for frame in 0..2 {
            list.begin_frame(false);
            for cube in &mut cubes {
                list.push_object(cube, true, 0, |_| 1);
            }
            let faces = list.faces();
            let (mut kept, mut none, mut rows) = (0, 0, 0);
            for face in faces.all() {
                match faces.spans_of(face) {
                    Some(spans) => {
                        assert_eq!(spans, &filled_rows(face)[..], "frame {frame}");
                        kept += 1;
                        rows += spans.len();
                    }
                    None => {
                        assert!(
                            rows + filled_rows(face).len() > SPANS_PER_FRAME,
                            "frame {frame}"
                        );
                        none += 1;
                    }
                }
            }
            assert!(
                kept > 0 && none > 0,
                "frame {frame}: {kept} kept, {none} not"
            );
            assert!(rows <= SPANS_PER_FRAME);
        }
    }

    #[test]
    fn a_face_meets_the_rows_its_fill_can_reach() {
        let mut object = cube_at(0.0, -100.0);
        let mut face = None;
        object.each_visible_face(|visible| face = Some(ScreenFace::new(visible, 3)));
        let face = face.expect("the front face");
        let top = face.polygon().iter().map(|p| p.y).min().unwrap();
        let bottom = face.polygon().iter().map(|p| p.y).max().unwrap();
        assert!(face.meets_rows(&(top..top + 1)));
        assert!(face.meets_rows(&(bottom - 1..bottom)));
        assert!(!face.meets_rows(&(bottom..bottom + 40)));
        assert!(!face.meets_rows(&(top - 40..top)));
        assert!(face.depth_plane.is_some());
    }

    #[test]
    #[should_panic(expected = "the face list holds at most 5 faces")]
    fn a_list_too_small_says_so() {
        let mut list: FaceList<2, 5> = FaceList::new();
        list.begin_frame(false);
        // Three faces of a cube seen from a corner, twice.
        for _ in 0..2 {
            let mut cube = cube_at(30.0, -100.0);
            cube.object_to_world_mut().append_rotation_y(0.6);
            cube.object_to_world_mut().append_rotation_x(0.6);
            list.push_object(&mut cube, true, 0, |_| 1);
        }
    }

    #[test]
    #[should_panic(expected = "named twice or missing")]
    fn an_order_must_name_each_object_once() {
        let mut list: FaceList<2, 12> = FaceList::new();
        list.begin_frame(false);
        list.push_object(&mut cube_at(0.0, -100.0), true, 0, |_| 1);
        list.push_object(&mut cube_at(0.0, -200.0), true, 0, |_| 1);
        list.set_far_to_near(&[1, 1]);
    }
}
