//! A scene that grows, for finding where 60 frames a second breaks: `count`
//! solids in a grid that always fills the screen (farther away the more
//! there are), every one turning every frame, drawn with the depth test
//! everywhere as the crowd is. Every solid is transformed, projected, culled
//! and scan-converted each frame: the crowd's worst case, at any size.
//!
//! `N` is the most it can hold; the objects live inside it (about 1.1 KiB
//! each), so a large grid belongs in a static: [`Grid::new`] is `const`, and
//! an empty grid is all zero bytes (its places are empty until
//! [`Grid::reset`] fills them), so such a static costs the kernel file
//! nothing (it lands in `.bss`).
//!
//! # Example
//!
//! ```
//! use demo::grid::Grid;
//! use engine::DepthBuffer;
//! use modex::{PageSpans, PAGE_PIXELS};
//!
//! let mut grid: Box<Grid<16>> = Box::default();
//! let (mut image, mut depths) = (Box::new([0u8; PAGE_PIXELS]), Box::new(DepthBuffer::new()));
//! grid.reset(12);
//! grid.tick();
//! let counts = grid.render(&mut image, &mut PageSpans::all(), &mut depths);
//! assert!(counts.drawn > 12); // each solid shows more than one face
//! ```

use crate::depth::render_faces_with_depth;
use crate::solids::SHAPES;
use core::f64::consts::PI;
use engine::{DepthBuffer, FaceCounts, Object, Xform, PROJECTION_RATIO};
use modex::{PageImage, PageSpans, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Centre to centre, in model units: the solids are about 26 units from
/// centre to corner, so neighbours' corners pass through each other now and
/// then, and only the depth test draws that right.
const SPACING: f64 = 50.0;
/// Pixels left between the grid and the screen's edges.
const MARGIN: f64 = 12.0;
/// Each solid's turn per frame (about Y for even places, X for odd), a
/// little different for each so they do not turn in step.
const TURN: f64 = PI / 90.0;
/// Turns between re-orthonormalisations, as for the scene's solids.
const TURNS_PER_REORTHONORMALIZATION: u32 = 64;

/// Up to `N` solids in a grid; see the module.
#[derive(Debug)]
pub struct Grid<const N: usize> {
    /// The first `count` hold solids.
    objects: [Place; N],
    count: usize,
    turns: u32,
}

impl<const N: usize> Default for Grid<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Grid<N> {
    /// An empty grid (`reset` places the solids).
    pub const fn new() -> Self {
        Grid {
            objects: [const { Place::Empty }; N],
            count: 0,
            turns: 0,
        }
    }

    /// The most solids this grid holds.
    pub const fn capacity(&self) -> usize {
        N
    }

    /// How many solids are shown.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Places `count` solids (at most `N`): every shape in turn, in rows of
    /// about 4:3, centred, at the distance where the grid just fits inside
    /// the screen.
    pub fn reset(&mut self, count: usize) {
        self.count = count.min(N);
        self.turns = 0;
        let columns = columns_for(self.count);
        let rows = self.count.div_ceil(columns).max(1);
        let depth = depth_to_fit(columns, rows);
        for (index, place) in self.objects[..self.count].iter_mut().enumerate() {
            let (column, row) = ((index % columns) as f64, (index / columns) as f64);
            let x = (column - (columns as f64 - 1.0) / 2.0) * SPACING;
            let y = ((rows as f64 - 1.0) / 2.0 - row) * SPACING;
            let model = SHAPES[index % SHAPES.len()].model;
            let object_to_world = Xform::translation(x, y, depth);
            match place {
                Place::Solid(object) => {
                    object.set_model(model);
                    *object.object_to_world_mut() = object_to_world;
                }
                Place::Empty => *place = Place::Solid(Object::new(model, object_to_world)),
            }
        }
    }

    /// One frame of motion: every solid turns.
    pub fn tick(&mut self) {
        self.turns += 1;
        let reorthonormalize = self.turns.is_multiple_of(TURNS_PER_REORTHONORMALIZATION);
        for (index, object) in solids(&mut self.objects[..self.count]).enumerate() {
            let angle = TURN * (1.0 + (index % 5) as f64 / 4.0);
            let xform = object.object_to_world_mut();
            if index % 2 == 0 {
                xform.append_rotation_y(angle);
            } else {
                xform.append_rotation_x(angle);
            }
            if reorthonormalize {
                xform.reorthonormalize();
            }
        }
    }

    /// The grid drawn into `image`, the depth test on every row, in the
    /// faces' own colours; `drawn` marks where `image` may differ from the
    /// background, before and after (see `depth::render_with_depth`). Kept
    /// out of line: one copy in the kernel file, not one per bus its bench
    /// draws on.
    #[inline(never)]
    pub fn render(
        &mut self,
        image: &mut PageImage,
        drawn: &mut PageSpans,
        depths: &mut DepthBuffer,
    ) -> FaceCounts {
        let objects = &mut self.objects[..self.count];
        render_faces_with_depth(image, drawn, depths, |draw| {
            let mut counts = FaceCounts::default();
            for object in solids(objects) {
                counts += object.each_visible_face(|visible| draw(visible, visible.face.colour));
            }
            counts
        })
    }
}

/// A place in the grid. `repr(u8)`, so that an empty place is a zero tag
/// and undefined bytes, and an empty grid all zero: `Option<Object>` marks
/// `None` with a spare value (2) of one of the object's `bool`s.
#[derive(Debug)]
#[repr(u8)]
// The place is the object's storage, in the grid itself (no heap): an empty
// place's unused bytes are the point.
#[allow(clippy::large_enum_variant)]
enum Place {
    Empty,
    Solid(Object),
}

/// The solids in `places`, in order.
fn solids(places: &mut [Place]) -> impl Iterator<Item = &mut Object> {
    places.iter_mut().filter_map(|place| match place {
        Place::Solid(object) => Some(object),
        Place::Empty => None,
    })
}

/// Columns for `count` solids in a grid about as wide, for its height, as
/// the screen (4:3).
fn columns_for(count: usize) -> usize {
    let aspect = f64::from(SCREEN_WIDTH) / f64::from(SCREEN_HEIGHT);
    let mut columns = 1;
    // The smallest column count whose rows are no wider than the screen's
    // aspect asks: columns ≥ sqrt(count · aspect).
    while ((columns * columns) as f64) < count as f64 * aspect {
        columns += 1;
    }
    columns.min(count.max(1))
}

/// The view-space z that puts a `columns` by `rows` grid (plus a solid's
/// reach at each edge) just inside the screen, `MARGIN` pixels in.
fn depth_to_fit(columns: usize, rows: usize) -> f64 {
    // A point at (x, z) lands |x / z| · |PROJECTION_RATIO| · (width / 2)
    // pixels from the centre.
    let pixels_per_unit_at_one = -PROJECTION_RATIO * f64::from(SCREEN_WIDTH / 2);
    let half_width = (columns as f64 - 1.0) / 2.0 * SPACING + SPACING / 2.0;
    let half_height = (rows as f64 - 1.0) / 2.0 * SPACING + SPACING / 2.0;
    let for_width = half_width * pixels_per_unit_at_one / (f64::from(SCREEN_WIDTH / 2) - MARGIN);
    let for_height = half_height * pixels_per_unit_at_one / (f64::from(SCREEN_HEIGHT / 2) - MARGIN);
    -for_width.max(for_height)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::screen::BACKGROUND;
    use modex::PAGE_PIXELS;
    use std::boxed::Box;

    fn drawn_box(image: &PageImage) -> Option<(usize, usize, usize, usize)> {
        let width = SCREEN_WIDTH as usize;
        let mut found: Option<(usize, usize, usize, usize)> = None;
        for (index, _) in image.iter().enumerate().filter(|(_, &p)| p != BACKGROUND) {
            let (x, y) = (index % width, index / width);
            found = Some(match found {
                None => (x, y, x, y),
                Some((x0, y0, x1, y1)) => (x0.min(x), y0.min(y), x1.max(x), y1.max(y)),
            });
        }
        found
    }

    /// At every size the grid stays on the screen and fills most of it, and
    /// every solid is drawn (each shows at least one face).
    #[test]
    fn every_size_fills_the_screen_and_draws_every_solid() {
        let mut grid: Box<Grid<300>> = Box::default();
        let mut image = Box::new([0u8; PAGE_PIXELS]);
        let mut depths = Box::new(DepthBuffer::new());
        let mut drawn = Box::new(PageSpans::all());
        for count in [1, 2, 7, 16, 59, 100, 200, 300] {
            grid.reset(count);
            assert_eq!(grid.count(), count);
            for _ in 0..3 {
                grid.tick();
                let counts = grid.render(&mut image, &mut drawn, &mut depths);
                assert!(counts.drawn as usize >= count, "{count}: {counts:?}");
            }
            let (x0, y0, x1, y1) = drawn_box(&image).expect("something drawn");
            assert!(x1 < SCREEN_WIDTH as usize && y1 < SCREEN_HEIGHT as usize);
            if count >= 16 {
                // Wide or tall enough to reach near one pair of edges.
                let (wide, tall) = (x1 - x0, y1 - y0);
                assert!(wide > 250 || tall > 180, "{count}: {wide}x{tall}");
            }
        }
    }

    /// More solids than it holds are cut to its capacity.
    #[test]
    fn a_count_beyond_the_capacity_is_cut() {
        let mut grid: Box<Grid<8>> = Box::default();
        grid.reset(1000);
        assert_eq!(grid.count(), grid.capacity());
        grid.reset(0);
        let mut image = Box::new([BACKGROUND; PAGE_PIXELS]);
        let counts = grid.render(
            &mut image,
            &mut PageSpans::all(),
            &mut Box::new(DepthBuffer::new()),
        );
        assert_eq!(counts, FaceCounts::default());
        assert!(drawn_box(&image).is_none());
    }

    /// The grid's shape follows the screen's 4:3, and a larger grid stands
    /// farther away.
    #[test]
    fn columns_keep_the_screens_aspect() {
        assert_eq!(columns_for(0), 1);
        assert_eq!(columns_for(1), 1);
        assert_eq!(columns_for(12), 4); // 4 x 3
        assert_eq!(columns_for(48), 8); // 8 x 6
        let depth_small = depth_to_fit(4, 3);
        let depth_large = depth_to_fit(16, 12);
        assert!(depth_large < depth_small && depth_small < 0.0);
    }
}
