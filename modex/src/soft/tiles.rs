//! What a present needs to scan out only what may have changed: which tiles
//! of the picture (a row's run of 64 pixels) read video memory written since
//! a given moment, what else the picture is made of, and a scan-out of
//! chosen tiles.
//!
//! The memory knows which blocks of plane offsets were written and when (a
//! count of writes, see `memory`). In 256-colour modes a tile's pixels are
//! fetched from a known range of plane offsets, so a tile whose blocks were
//! not written since a present shows what it showed then, provided the
//! raster (start address, Offset, line compare, sizes: all the registers the
//! scan-out reads) is the same. Text modes read the glyphs of plane 2 from
//! anywhere, so there any write counts for every tile, and the picture
//! source includes every register write.

use super::memory::{BLOCKS, BLOCK_OFFSETS, PLANE_BYTES};
use super::scanout::Raster;
use super::SoftVga;
use crate::regs::PLANE_COUNT;

/// Pixels in a tile, the unit of change: 16 plane offsets in 256-colour modes.
pub(crate) const TILE_PIXELS: usize = 64;
/// Tiles across a row at most; in a wider picture (text) the last tile
/// stretches to the row's end.
pub(crate) const MAX_TILES_ACROSS: usize = u16::BITS as usize;
/// Rows of a picture at most: Vertical Display End has 10 bits.
pub(crate) const MAX_ROWS: usize = 1024;

/// A set of tiles of a picture: per row, a bit per tile.
#[derive(Clone, PartialEq, Eq)]
pub(crate) struct TileSet {
    rows: [u16; MAX_ROWS],
}

impl core::fmt::Debug for TileSet {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let tiles: u32 = self.rows.iter().map(|row| row.count_ones()).sum();
        write!(f, "TileSet({tiles} tiles)")
    }
}

impl TileSet {
    /// No tiles.
    pub(crate) const fn new() -> Self {
        TileSet {
            rows: [0; MAX_ROWS],
        }
    }

    /// Tiles across a picture `width` pixels wide.
    pub(crate) fn across(width: usize) -> usize {
        width.div_ceil(TILE_PIXELS).min(MAX_TILES_ACROSS)
    }

    /// The pixel columns of tile `tile` of a row `width` pixels wide.
    pub(crate) fn columns(tile: usize, width: usize) -> core::ops::Range<usize> {
        let start = tile * TILE_PIXELS;
        if tile + 1 >= Self::across(width) {
            start..width
        } else {
            start..start + TILE_PIXELS
        }
    }

    /// A row's bits for its first `across` tiles.
    pub(crate) fn row_of_all(across: usize) -> u16 {
        u16::MAX
            .checked_shr((MAX_TILES_ACROSS - across) as u32)
            .unwrap_or(0)
    }

    /// Empties the set.
    pub(crate) fn clear(&mut self) {
        self.rows = [0; MAX_ROWS];
    }

    /// Every tile of a `width` x `height` picture (and no other).
    pub(crate) fn fill(&mut self, (width, height): (usize, usize)) {
        let all = Self::row_of_all(Self::across(width));
        let height = height.min(MAX_ROWS);
        self.rows[..height].fill(all);
        self.rows[height..].fill(0);
    }

    /// Adds `other`'s tiles.
    pub(crate) fn add(&mut self, other: &TileSet) {
        for (row, other) in self.rows.iter_mut().zip(&other.rows) {
            *row |= other;
        }
    }

    /// Adds tile `tile` of row `row`.
    pub(crate) fn insert(&mut self, row: usize, tile: usize) {
        self.rows[row] |= 1 << tile;
    }

    /// Whether any of the first `height` rows has a tile.
    pub(crate) fn any(&self, height: usize) -> bool {
        self.rows[..height.min(MAX_ROWS)]
            .iter()
            .any(|&row| row != 0)
    }

    /// Adds the tiles of `tiles` (bit `t` for tile `t`) to row `row`.
    pub(crate) fn add_to_row(&mut self, row: usize, tiles: u16) {
        self.rows[row] |= tiles;
    }

    /// The set's tiles in row `row` among its first `across`, lowest first.
    pub(crate) fn tiles_in_row(&self, row: usize, across: usize) -> impl Iterator<Item = usize> {
        let mut left = self.row(row) & Self::row_of_all(across);
        core::iter::from_fn(move || {
            let tile = (left != 0).then(|| left.trailing_zeros() as usize)?;
            left &= left - 1;
            Some(tile)
        })
    }

    /// Row `row`'s tiles, bit `t` for tile `t` (0 past the last row).
    pub(crate) fn row(&self, row: usize) -> u16 {
        self.rows.get(row).copied().unwrap_or(0)
    }
}

/// What the displayed picture is made of besides video memory: the same
/// source over unchanged memory gives the same DAC indices. (The DAC, the
/// pixel mask and blanking only colour the indices; the presenter compares
/// colours itself.)
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct PictureSource {
    kind: SourceKind,
    /// The raster, for 256-colour pictures (else all zero).
    raster: Raster,
    /// For text: the start address latched and the register writes so far,
    /// as any register may change the text picture (else zero).
    text: (u16, u64),
}

/// Fieldless, so `Nothing` is 0 and [`PictureSource::NOTHING`] is all zero
/// bytes (a kernel's static presenter stays in .bss).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
enum SourceKind {
    /// No picture (Bochs VBE, or a graphics mode the model does not show).
    Nothing,
    Graphics,
    Text,
}

impl PictureSource {
    /// No picture.
    pub(crate) const NOTHING: Self = PictureSource {
        kind: SourceKind::Nothing,
        raster: Raster::NONE,
        text: (0, 0),
    };
}

impl SoftVga {
    /// What the displayed picture is made of now, besides video memory.
    pub(crate) fn picture_source(&self) -> PictureSource {
        if let Some(raster) = self.raster() {
            PictureSource {
                kind: SourceKind::Graphics,
                raster,
                text: (0, 0),
            }
        } else if self.text_raster().is_some() {
            PictureSource {
                kind: SourceKind::Text,
                raster: Raster::NONE,
                text: (self.displayed_start, self.register_writes),
            }
        } else {
            PictureSource::NOTHING
        }
    }

    /// CPU writes to video memory so far: note it at a present, and
    /// [`SoftVga::add_tiles_written_since`] tells what was written after.
    pub(crate) fn memory_writes(&self) -> u64 {
        self.memory.writes
    }

    /// Adds to `tiles` every tile of the displayed picture that reads video
    /// memory written after the moment `memory_writes()` said `writes`:
    /// those of the blocks written since in 256-colour modes, every tile in
    /// text modes if anything was written.
    pub(crate) fn add_tiles_written_since(&self, writes: u64, tiles: &mut TileSet) {
        if self.memory.writes == writes {
            return;
        }
        let Some(raster) = self.raster() else {
            if self.text_raster().is_some() {
                tiles.fill(self.picture_size());
            }
            return;
        };
        let written = &self.memory.block_written;
        let quads_per_row = raster.width / PLANE_COUNT;
        raster.rows(|row, address| {
            // The blocks the row reads, in order: quad `q` of the row is at
            // `first + q`, in block `(skew + q) / BLOCK_OFFSETS` from the first.
            let first = address % PLANE_BYTES;
            let skew = first % BLOCK_OFFSETS;
            let first_block = first / BLOCK_OFFSETS;
            let blocks = (skew + quads_per_row).div_ceil(BLOCK_OFFSETS);
            let written_since = |block: usize| written[(first_block + block) % BLOCKS] > writes;
            let mut row_tiles = 0;
            if skew == 0 {
                // A row that starts a block, as Mode X's pages' rows do:
                // block `b` is tile `b` (a block's 16 offsets are a tile's
                // quads).
                for block in 0..blocks {
                    row_tiles |= u16::from(written_since(block)) << block;
                }
            } else {
                for block in (0..blocks).filter(|&block| written_since(block)) {
                    let quads = (block * BLOCK_OFFSETS).saturating_sub(skew)
                        ..((block + 1) * BLOCK_OFFSETS - skew).min(quads_per_row);
                    row_tiles |= tiles_of_quads(quads);
                }
            }
            tiles.add_to_row(row, row_tiles);
        });
    }

    /// Scans out the tiles of `tiles` into `out` (the picture row by row, as
    /// [`SoftVga::scanout_indices`] lays it out), leaving the rest of `out`
    /// alone; text modes scan out everything. Returns the picture's size.
    ///
    /// # Panics
    /// If `out` is smaller than the picture.
    pub(crate) fn scanout_tiles(&self, tiles: &TileSet, out: &mut [u8]) -> (usize, usize) {
        let Some(raster) = self.raster() else {
            return self.scanout_indices(out);
        };
        let width = raster.width;
        assert!(
            out.len() >= width * raster.height,
            "scan-out needs {width} x {} pixels, the buffer holds {}",
            raster.height,
            out.len()
        );
        let planes = &self.memory.planes;
        let across = TileSet::across(width);
        raster.rows(|row, address| {
            let line = &mut out[row * width..(row + 1) * width];
            for tile in tiles.tiles_in_row(row, across) {
                let quads = quads_of(tile, width);
                let pixels = &mut line[quads.start * PLANE_COUNT..quads.end * PLANE_COUNT];
                let pixels = pixels.as_chunks_mut::<PLANE_COUNT>().0;
                let first = (address + quads.start) % PLANE_BYTES;
                let count = pixels.len();
                if first + count <= PLANE_BYTES {
                    // The usual case: one run of each plane, no wrap to check.
                    for (plane, source) in planes.iter().enumerate() {
                        for (pixels, &index) in pixels.iter_mut().zip(&source[first..first + count])
                        {
                            pixels[plane] = index;
                        }
                    }
                } else {
                    for (quad, pixels) in quads.zip(pixels) {
                        let offset = (address + quad) % PLANE_BYTES;
                        *pixels = core::array::from_fn(|plane| planes[plane][offset]);
                    }
                }
            }
        });
        (width, raster.height)
    }
}

impl SoftVga {
    /// In 256-colour modes, calls `visit(row, tile, planes)` for each tile of
    /// `tiles` with its quads' bytes in each plane (pixel `4 * q + p` of the
    /// tile is `planes[p][q]`), so the picture can be compared with what was
    /// shown without scanning it out first; returns false, visiting nothing,
    /// in other modes.
    pub(crate) fn visit_tiles_in_planes(
        &self,
        tiles: &TileSet,
        mut visit: impl FnMut(usize, usize, [&[u8]; PLANE_COUNT]),
    ) -> bool {
        let Some(raster) = self.raster() else {
            return false;
        };
        let planes = &self.memory.planes;
        let across = TileSet::across(raster.width);
        // A tile whose plane offsets wrap past the end is copied here.
        let mut wrapped = [[0u8; TILE_QUADS]; PLANE_COUNT];
        raster.rows(|row, address| {
            for tile in tiles.tiles_in_row(row, across) {
                let quads = quads_of(tile, raster.width);
                let count = quads.len();
                let first = (address + quads.start) % PLANE_BYTES;
                if first + count <= PLANE_BYTES {
                    visit(
                        row,
                        tile,
                        planes.each_ref().map(|plane| &plane[first..first + count]),
                    );
                } else {
                    for (copy, plane) in wrapped.iter_mut().zip(planes) {
                        for (quad, byte) in copy[..count].iter_mut().enumerate() {
                            *byte = plane[(first + quad) % PLANE_BYTES];
                        }
                    }
                    visit(row, tile, wrapped.each_ref().map(|copy| &copy[..count]));
                }
            }
        });
        true
    }
}

/// The tiles of a 256-colour row that quads `quads` (not empty, within the
/// row) fall in, as a row's bits.
fn tiles_of_quads(quads: core::ops::Range<usize>) -> u16 {
    let quads_per_tile = TILE_PIXELS / PLANE_COUNT;
    let last_tile = MAX_TILES_ACROSS - 1;
    let first = (quads.start / quads_per_tile).min(last_tile);
    let last = ((quads.end - 1) / quads_per_tile).min(last_tile);
    let through_last = (u32::MAX >> (u32::BITS as usize - 1 - last)) as u16;
    through_last & !((1u16 << first) - 1)
}

/// Quads in a tile of a 256-colour row (one plane offset each).
pub(crate) const TILE_QUADS: usize = TILE_PIXELS / PLANE_COUNT;
// A block of written offsets is one tile's quads, which the rows that start
// a block rely on.
const _: () = assert!(BLOCK_OFFSETS == TILE_QUADS);

/// The quads (4 pixels, one plane offset) of tile `tile` of a 256-colour row
/// `width` pixels wide: as [`TileSet::columns`], as such a row is at most
/// 1,024 pixels, 16 tiles, so its last tile never stretches.
fn quads_of(tile: usize, width: usize) -> core::ops::Range<usize> {
    let start = tile * TILE_QUADS;
    start..(start + TILE_QUADS).min(width / PLANE_COUNT)
}
