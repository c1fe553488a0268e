//! Presenting only what changed: a flip that moves a cube across a 1280x800
//! screen should not cost 4 MB of framebuffer writes, nor a scan-out and a
//! diff of the whole picture when the cube covers a fifth of it.
//!
//! How the changes are found: the presenter keeps the picture it presented
//! last (DAC indices, as scanned out) and that picture's encoded palette. A
//! pixel is written again when its index changed or its index's colour did.
//! Colours are compared entry by entry (256 of them), so DAC loads, the
//! pixel mask and blanking need nothing more. Indices are compared only in
//! the tiles of the picture (a row's run of 64 pixels) that may have
//! changed; the rest are known to be equal without being scanned out:
//!
//! * The software VGA stamps each block of video memory with the count of
//!   writes at its last write, and says what the picture is made of besides
//!   memory (its [`PictureSource`]: the raster with its start address,
//!   Offset, line compare and sizes; for text, every register). Same source,
//!   and none of a tile's memory written since: same indices in that tile.
//! * A page flip changes the source at each present. So the presenter
//!   remembers its last few presents: the source, the write count, and the
//!   tiles where that picture differed from the one before. The new picture
//!   equals the last one with the same source except in the tiles written
//!   since; that one equals the last shown except where the presents since
//!   changed something. The union of those is what gets scanned out and
//!   diffed: with Mode X's two pages, the tiles drawn into the page since it
//!   was last shown and those where the two pages differed last time.
//! * No remembered present has this source (a mode change, a new start
//!   address, any register write in text mode): all of it.
//!
//! In 256-colour modes those tiles are compared straight from the planes
//! with a copy of the shown picture kept plane by plane, eight quads of a
//! plane in one word, and only the quads that differ become pixels. The
//! palette is encoded again only after a write that can change a colour.
//!
//! The first present, and any present whose picture size or framebuffer
//! layout differs from the last, writes everything, black borders included;
//! after that only changed pixels are written (each run of changed pixels in
//! a tile's part of a row as one span, scaled), so the borders are never
//! written again and a still picture costs nothing.

use core::ops::Range;

use super::{blit, encoded_palette, FramebufferLayout, PixelOrder, Placement};
use crate::regs::PLANE_COUNT;
use crate::soft::{PictureSource, SoftVga, TileSet, TILE_PIXELS};

/// The largest picture the presenter keeps: 80x25 text in 9x16 cells. Mode X
/// is 320x240; a picture larger than this is presented black.
pub const MAX_PICTURE_PIXELS: usize = 720 * 400;

/// Quads (one byte of each plane) of the largest picture.
const PLANE_QUADS: usize = MAX_PICTURE_PIXELS / PLANE_COUNT;

/// Presents remembered: Mode X flips between two pages (three with the
/// report's), so a page was shown at most two or three presents ago.
const REMEMBERED_PRESENTS: usize = 4;

/// What one present did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PresentReport {
    /// Bytes written to the framebuffer.
    pub bytes_written: usize,
    /// Whether everything was written (first present, new size or layout).
    pub full: bool,
    /// Picture pixels scanned out and compared with those shown: the whole
    /// picture when `full`, else those of the tiles that may have changed.
    pub pixels_scanned: usize,
}

/// What the presenter remembers of one present.
#[derive(Clone)]
struct PastPresent {
    /// What the picture was made of besides memory.
    source: PictureSource,
    /// The model's count of memory writes at the time.
    memory_writes: u64,
    /// The tiles where its DAC indices differed from the present before's
    /// (every tile if it wrote everything).
    changed: TileSet,
}

impl PastPresent {
    const NONE: PastPresent = PastPresent {
        source: PictureSource::NOTHING,
        memory_writes: 0,
        changed: TileSet::new(),
    };
}

/// Presents a software VGA's picture into a framebuffer, writing only what
/// changed since its last present. ~880 KiB: keep it in a static or a `Box`.
/// It assumes nobody else writes the framebuffer between presents, and that
/// it presents one software VGA (call [`Presenter::forget`] if someone else
/// wrote, or to present another).
#[derive(Clone)]
pub struct Presenter {
    current: [u8; MAX_PICTURE_PIXELS],
    shown: [u8; MAX_PICTURE_PIXELS],
    /// `shown` plane by plane, as a 256-colour picture is in video memory:
    /// `shown_planes[p][i]` is `shown[4 * i + p]`, whatever the picture.
    shown_planes: [[u8; PLANE_QUADS]; PLANE_COUNT],
    shown_palette: [[u8; 4]; 256],
    /// The model's count of colour writes when `shown_palette` was encoded.
    shown_colour_writes: u64,
    shown_size: (usize, usize),
    /// The layout presented into last, if `presented`. (A flag rather than
    /// an Option so that a new presenter is all zero bytes: a kernel's static
    /// one then costs nothing in its image, .bss rather than .data.)
    shown_layout: FramebufferLayout,
    presented: bool,
    /// The last presents, a ring: the newest at `newest`, `remembered` of them.
    past: [PastPresent; REMEMBERED_PRESENTS],
    newest: usize,
    remembered: usize,
    /// The tiles this present scans out and compares.
    to_scan: TileSet,
}

/// Leaves out the pictures and the palette, ~870 KiB.
impl core::fmt::Debug for Presenter {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Presenter")
            .field("shown_size", &self.shown_size)
            .field("shown_layout", &self.shown_layout)
            .field("presented", &self.presented)
            .field("remembered", &self.remembered)
            .finish_non_exhaustive()
    }
}

impl Default for Presenter {
    fn default() -> Self {
        Self::new()
    }
}

impl Presenter {
    /// A presenter that has presented nothing yet. `const` so a kernel can
    /// keep one in a static.
    pub const fn new() -> Self {
        Presenter {
            current: [0; MAX_PICTURE_PIXELS],
            shown: [0; MAX_PICTURE_PIXELS],
            shown_planes: [[0; PLANE_QUADS]; PLANE_COUNT],
            shown_palette: [[0; 4]; 256],
            shown_colour_writes: 0,
            shown_size: (0, 0),
            shown_layout: FramebufferLayout {
                width: 0,
                height: 0,
                stride: 0,
                bytes_per_pixel: 0,
                order: PixelOrder::Rgb,
            },
            presented: false,
            past: [PastPresent::NONE; REMEMBERED_PRESENTS],
            newest: 0,
            remembered: 0,
            to_scan: TileSet::new(),
        }
    }

    /// The next present writes everything.
    pub fn forget(&mut self) {
        self.presented = false;
        self.remembered = 0;
    }

    /// Presents `soft`'s picture into `out` laid out as `layout`, as
    /// [`super::present`] would, writing only the pixels that differ from the
    /// last present. Nothing is written outside `out`.
    pub fn present(
        &mut self,
        soft: &SoftVga,
        layout: &FramebufferLayout,
        out: &mut [u8],
    ) -> PresentReport {
        let source = soft.picture_source();
        let memory_writes = soft.memory_writes();
        let (width, height) = soft.picture_size();
        let size = if width * height <= MAX_PICTURE_PIXELS {
            (width, height)
        } else {
            (0, 0)
        };
        let pixels = size.0 * size.1;
        // Encoding 256 colours costs as much as comparing a few tiles: not
        // again while no colour can have changed.
        let colour_writes = soft.colour_writes();
        let same_colours = self.presented
            && colour_writes == self.shown_colour_writes
            && layout.order == self.shown_layout.order;
        let palette = if same_colours {
            self.shown_palette
        } else {
            encoded_palette(soft, layout.order)
        };
        let full = !self.presented || self.shown_layout != *layout || self.shown_size != size;
        if full {
            self.to_scan.fill(size);
        } else {
            self.find_tiles_to_scan(soft, &source, size);
        }
        // The oldest remembered present, no longer needed once the tiles to
        // scan are known, becomes this one.
        let slot = (self.newest + 1) % REMEMBERED_PRESENTS;
        let (bytes_written, pixels_scanned) = if full {
            if pixels > 0 {
                soft.scanout_tiles(&self.to_scan, &mut self.current[..pixels]);
            }
            let picture = &self.current[..pixels];
            blit(picture, size, layout, out, |row, column| {
                palette[usize::from(picture[row * size.0 + column])]
            });
            self.shown[..pixels].copy_from_slice(picture);
            take_into_planes(&mut self.shown_planes, 0, picture);
            self.past[slot].changed.fill(size);
            (full_present_bytes(layout, out.len()), pixels)
        } else {
            let mut recoloured = [false; 256];
            let mut any_recoloured = false;
            if !same_colours {
                for (flag, (new, old)) in recoloured
                    .iter_mut()
                    .zip(palette.iter().zip(&self.shown_palette))
                {
                    *flag = new != old;
                    any_recoloured |= *flag;
                }
            }
            let from_planes = if any_recoloured {
                None
            } else {
                self.present_from_planes(soft, size, &palette, layout, out, slot)
            };
            from_planes.unwrap_or_else(|| {
                if pixels > 0 && self.to_scan.any(size.1) {
                    soft.scanout_tiles(&self.to_scan, &mut self.current[..pixels]);
                }
                self.present_changes(size, &palette, &recoloured, layout, out, slot)
            })
        };
        self.past[slot].source = source;
        self.past[slot].memory_writes = memory_writes;
        self.newest = slot;
        self.remembered = (self.remembered + 1).min(REMEMBERED_PRESENTS);
        self.shown_palette = palette;
        self.shown_colour_writes = colour_writes;
        self.shown_size = size;
        self.shown_layout = *layout;
        self.presented = true;
        PresentReport {
            bytes_written,
            full,
            pixels_scanned,
        }
    }

    /// The tiles whose indices may differ from those shown: going back from
    /// the newest present to the last one with the same source, the tiles
    /// each changed, and the tiles written since that one. Everything if no
    /// remembered present had this source.
    fn find_tiles_to_scan(&mut self, soft: &SoftVga, source: &PictureSource, size: (usize, usize)) {
        self.to_scan.clear();
        for back in 0..self.remembered {
            let past = &self.past[(self.newest + REMEMBERED_PRESENTS - back) % REMEMBERED_PRESENTS];
            if past.source == *source {
                soft.add_tiles_written_since(past.memory_writes, &mut self.to_scan);
                return;
            }
            self.to_scan.add(&past.changed);
        }
        self.to_scan.fill(size);
    }

    /// [`Self::present_changes`] for 256-colour pictures whose colours did
    /// not change, reading the tiles straight from the planes and comparing
    /// them with the shown picture kept plane by plane: eight quads of a
    /// plane in one word, so an unchanged tile costs eight comparisons, and
    /// a changed one becomes a mask of its changed pixels whose runs of set
    /// bits are the spans to write. Returns the bytes written and the pixels
    /// compared; None (nothing done) in other modes.
    fn present_from_planes(
        &mut self,
        soft: &SoftVga,
        (width, height): (usize, usize),
        palette: &[[u8; 4]; 256],
        layout: &FramebufferLayout,
        out: &mut [u8],
        slot: usize,
    ) -> Option<(usize, usize)> {
        let spans = Spans::new(layout, (width, height), out.len());
        let changed = &mut self.past[slot].changed;
        changed.clear();
        let (shown, shown_planes) = (&mut self.shown, &mut self.shown_planes);
        let mut written = 0;
        let mut pixels_compared = 0;
        let visited = soft.visit_tiles_in_planes(&self.to_scan, |row, tile, planes| {
            let quads = planes[0].len();
            pixels_compared += quads * PLANE_COUNT;
            let tile_start = tile * TILE_PIXELS;
            let first = row * width + tile_start;
            // 256-colour widths are whole quads, so the tile's quads start
            // at a quad of the flat picture.
            let first_quad = first / PLANE_COUNT;
            let changed_pixels = changed_pixels(&planes, shown_planes, first_quad);
            if changed_pixels == 0 {
                return;
            }
            changed.insert(row, tile);
            take_tile(
                &planes,
                changed_pixels,
                &mut shown[first..first + quads * PLANE_COUNT],
                shown_planes,
                first_quad,
            );
            for_each_run_of_bits(changed_pixels, |run| {
                let columns = tile_start + run.start..tile_start + run.end;
                let pixel =
                    |column: usize| palette[usize::from(tile_pixel(&planes, column - tile_start))];
                written += spans.write(row, columns, pixel, out);
            });
        });
        visited.then_some((written, pixels_compared))
    }

    /// Writes the pixels of the scanned tiles whose index changed, and those
    /// anywhere whose colour changed; notes the tiles that changed in
    /// `self.past[slot]` and takes the scanned ones into the shown picture.
    /// Returns the bytes written and the pixels compared.
    fn present_changes(
        &mut self,
        (width, height): (usize, usize),
        palette: &[[u8; 4]; 256],
        recoloured: &[bool; 256],
        layout: &FramebufferLayout,
        out: &mut [u8],
        slot: usize,
    ) -> (usize, usize) {
        let any_recoloured = recoloured.contains(&true);
        let spans = Spans::new(layout, (width, height), out.len());
        let across = TileSet::across(width);
        let changed = &mut self.past[slot].changed;
        changed.clear();
        let mut written = 0;
        let mut pixels_compared = 0;
        for row in 0..height {
            let scanned = self.to_scan.row(row);
            // Most rows of most frames: nothing to look at.
            if scanned == 0 && !any_recoloured {
                continue;
            }
            let line = row * width..(row + 1) * width;
            for tile in 0..across {
                let was_scanned = scanned & (1 << tile) != 0;
                if !was_scanned && !any_recoloured {
                    continue;
                }
                let columns = TileSet::columns(tile, width);
                if was_scanned {
                    pixels_compared += columns.len();
                }
                let pixels = line.start + columns.start..line.start + columns.end;
                let old = &self.shown[pixels.clone()];
                // A tile not scanned shows what it showed.
                let new = if was_scanned {
                    &self.current[pixels.clone()]
                } else {
                    old
                };
                let same = !was_scanned || same_indices(new, old);
                if !same {
                    changed.insert(row, tile);
                }
                if same && !any_recoloured {
                    continue;
                }
                let first = columns.start;
                let pixel = |column: usize| palette[usize::from(new[column - first])];
                let mut span = |span: Range<usize>| {
                    let columns = first + span.start..first + span.end;
                    written += spans.write(row, columns, pixel, out);
                };
                if any_recoloured {
                    let changed_at = |x: usize| new[x] != old[x] || recoloured[usize::from(new[x])];
                    for_each_run(new.len(), changed_at, &mut span);
                } else {
                    changed_runs(new, old, &mut span);
                }
                if !same {
                    let new = &self.current[pixels.clone()];
                    self.shown[pixels.clone()].copy_from_slice(new);
                    take_into_planes(&mut self.shown_planes, pixels.start, new);
                }
            }
        }
        (written, pixels_compared)
    }
}

/// Keeps `shown_planes` the planes of `shown` where `pixels`, from pixel
/// `first` of the picture, were taken into it.
fn take_into_planes(
    shown_planes: &mut [[u8; PLANE_QUADS]; PLANE_COUNT],
    first: usize,
    pixels: &[u8],
) {
    for (offset, &index) in pixels.iter().enumerate() {
        let pixel = first + offset;
        shown_planes[pixel % PLANE_COUNT][pixel / PLANE_COUNT] = index;
    }
}

/// The pixels of a tile (bit `4q + p` for plane `p`'s byte of quad `q`,
/// up to 16 quads) whose indices in `planes` differ from those at
/// `first_quad` of `shown_planes`.
fn changed_pixels(
    planes: &[&[u8]; PLANE_COUNT],
    shown_planes: &[[u8; PLANE_QUADS]; PLANE_COUNT],
    first_quad: usize,
) -> u64 {
    let mut pixels = 0;
    for (plane, (source, shown)) in planes.iter().zip(shown_planes).enumerate() {
        let differing = differing_bytes(source, &shown[first_quad..first_quad + source.len()]);
        // Most planes of most scanned tiles: unchanged.
        if differing != 0 {
            pixels |= every_fourth_bit(differing) << plane;
        }
    }
    pixels
}

/// Bit `k` set for each byte `k` where `new` and `old` differ (up to 16
/// bytes): a whole tile's plane as two words.
fn differing_bytes(new: &[u8], old: &[u8]) -> u16 {
    if let (Some(new), Some(old)) = (new.first_chunk::<16>(), old.first_chunk::<16>()) {
        let differing = u128::from_le_bytes(*new) ^ u128::from_le_bytes(*old);
        if differing == 0 {
            return 0;
        }
        // The low word is bytes 0 to 7, the high one 8 to 15.
        let low = nonzero_bytes(differing as u64);
        let high = nonzero_bytes((differing >> 64) as u64);
        return (low | high << 8) as u16;
    }
    // A row's last tile may hold fewer quads.
    new.iter()
        .zip(old)
        .enumerate()
        .fold(0, |bits, (k, (new, old))| {
            bits | (u16::from(new != old) << k)
        })
}

/// Bit `k` of `bits` moved to bit `4k`: a plane's differing quads as the
/// tile's pixels of plane 0.
pub(super) fn every_fourth_bit(bits: u16) -> u64 {
    let mut spread = u64::from(bits);
    spread = (spread | spread << 24) & 0x0000_00FF_0000_00FF;
    spread = (spread | spread << 12) & 0x000F_000F_000F_000F;
    spread = (spread | spread << 6) & 0x0303_0303_0303_0303;
    (spread | spread << 3) & 0x1111_1111_1111_1111
}

/// Takes a tile into the shown picture: its quads into `shown_planes` at
/// `first_quad`, and its `changed` pixels into `shown_tile`.
fn take_tile(
    planes: &[&[u8]; PLANE_COUNT],
    changed: u64,
    shown_tile: &mut [u8],
    shown_planes: &mut [[u8; PLANE_QUADS]; PLANE_COUNT],
    first_quad: usize,
) {
    for (source, shown) in planes.iter().zip(shown_planes.iter_mut()) {
        let shown = &mut shown[first_quad..first_quad + source.len()];
        // Not `copy_from_slice`: the kernel's build checks each for overlap.
        if let (Some(shown), Some(source)) = (shown.first_chunk_mut::<16>(), source.first_chunk()) {
            *shown = *source;
        } else {
            shown
                .iter_mut()
                .zip(*source)
                .for_each(|(shown, &new)| *shown = new);
        }
    }
    let mut pixels = changed;
    while pixels != 0 {
        let x = pixels.trailing_zeros() as usize;
        pixels &= pixels - 1;
        shown_tile[x] = tile_pixel(planes, x);
    }
}

/// Pixel `x` of a tile given by its quads in each plane.
fn tile_pixel(planes: &[&[u8]; PLANE_COUNT], x: usize) -> u8 {
    planes[x % PLANE_COUNT][x / PLANE_COUNT]
}

/// Calls `run` with each maximal run of set bits of `bits`, lowest first.
pub(super) fn for_each_run_of_bits(bits: u64, mut run: impl FnMut(Range<usize>)) {
    let mut left = bits;
    while left != 0 {
        let start = left.trailing_zeros();
        let length = (!(left >> start)).trailing_zeros();
        let end = start + length;
        run(start as usize..end as usize);
        left = if end < u64::BITS {
            left & u64::MAX << end
        } else {
            0
        };
    }
}

/// Bit `k` set for each nonzero byte `k` of `word` (bits 8k to 8k + 7;
/// [`word`] reads little-endian, so byte `k` is the `k`-th in memory).
pub(super) fn nonzero_bytes(word: u64) -> u32 {
    const LOW_SEVEN: u64 = 0x7F7F_7F7F_7F7F_7F7F;
    // Each byte's top bit: set where the byte is nonzero (its low seven
    // bits carry into it, or it was set); no carry crosses a byte.
    let nonzero = ((word & LOW_SEVEN).wrapping_add(LOW_SEVEN) | word) & !LOW_SEVEN;
    // The eight top bits gathered into the low byte, byte k to bit k.
    ((nonzero >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

/// Calls `span` with each maximal run of positions below `len` where
/// `changed_at` holds.
fn for_each_run(
    len: usize,
    changed_at: impl Fn(usize) -> bool,
    mut span: impl FnMut(Range<usize>),
) {
    let mut x = 0;
    while x < len {
        if !changed_at(x) {
            x += 1;
            continue;
        }
        let start = x;
        while x < len && changed_at(x) {
            x += 1;
        }
        span(start..x);
    }
}

/// Calls `span` with each maximal run of positions where `new` and `old`
/// differ, skipping equal runs of eight in one comparison.
fn changed_runs(new: &[u8], old: &[u8], mut span: impl FnMut(Range<usize>)) {
    let len = new.len().min(old.len());
    let mut run_start = None;
    let mut x = 0;
    while x < len {
        if x + 8 <= len && word(new, x) == word(old, x) {
            if let Some(start) = run_start.take() {
                span(start..x);
            }
            x += 8;
            continue;
        }
        let end = (x + 8).min(len);
        while x < end {
            if new[x] != old[x] {
                run_start.get_or_insert(x);
            } else if let Some(start) = run_start.take() {
                span(start..x);
            }
            x += 1;
        }
    }
    if let Some(start) = run_start {
        span(start..len);
    }
}

/// Eight indices from `at` as one word (no copy: the kernel's build checks
/// every `copy_from_slice` for overlap).
fn word(indices: &[u8], at: usize) -> u64 {
    indices[at..]
        .first_chunk::<8>()
        .map_or(0, |bytes| u64::from_le_bytes(*bytes))
}

/// Whether two runs of indices are equal, compared eight at a time: the
/// kernel's `memcmp` (compiler-builtins) goes byte by byte.
fn same_indices(new: &[u8], old: &[u8]) -> bool {
    let (new_words, new_rest) = new.as_chunks::<8>();
    let (old_words, old_rest) = old.as_chunks::<8>();
    new_words
        .iter()
        .zip(old_words)
        .all(|(new, old)| u64::from_ne_bytes(*new) == u64::from_ne_bytes(*old))
        && new_rest.iter().zip(old_rest).all(|(new, old)| new == old)
}

/// Bytes a full present writes: every visible pixel of every line that fits.
fn full_present_bytes(layout: &FramebufferLayout, out_len: usize) -> usize {
    if !(1..=4).contains(&layout.bytes_per_pixel) {
        return 0;
    }
    let visible_pixels = layout.visible_width();
    (0..layout.height)
        .map(|y| {
            let pixels = out_len.saturating_sub(y * layout.line_bytes()) / layout.bytes_per_pixel;
            pixels.min(visible_pixels) * layout.bytes_per_pixel
        })
        .sum()
}

/// Where a present's spans go: the framebuffer's layout and the picture's
/// placement on it.
struct Spans<'a> {
    layout: &'a FramebufferLayout,
    placement: Placement,
    /// Whether the whole picture lies on the visible screen and within the
    /// framebuffer's bytes, as it does unless the screen is smaller than the
    /// picture or the firmware's buffer is cut short: then no span needs
    /// clipping.
    unclipped: bool,
}

impl<'a> Spans<'a> {
    /// For a `width` x `height` picture on `layout` over `out_len` bytes.
    fn new(layout: &'a FramebufferLayout, (width, height): (usize, usize), out_len: usize) -> Self {
        let placement = Placement::fit((width, height), (layout.width, layout.height));
        let (scale, n) = (placement.scale, layout.bytes_per_pixel);
        let unclipped = match (
            usize::try_from(placement.left),
            usize::try_from(placement.top),
        ) {
            (Ok(left), Ok(top)) if height > 0 => {
                let right = left + width * scale;
                let bottom = top + height * scale;
                let last_line_end = (bottom - 1) * layout.line_bytes() + right * n;
                right <= layout.visible_width()
                    && bottom <= layout.height
                    && last_line_end <= out_len
            }
            _ => false,
        };
        Spans {
            layout,
            placement,
            unclipped,
        }
    }

    /// Writes picture row `row`'s `columns`, scaled, on each screen line that
    /// row covers, clipped to the visible screen and to `out`; returns the
    /// bytes written.
    fn write(
        &self,
        row: usize,
        columns: Range<usize>,
        pixel: impl Fn(usize) -> [u8; 4],
        out: &mut [u8],
    ) -> usize {
        match self.layout.bytes_per_pixel {
            1 => self.write_of::<1>(row, columns, &pixel, out),
            2 => self.write_of::<2>(row, columns, &pixel, out),
            3 => self.write_of::<3>(row, columns, &pixel, out),
            4 => self.write_of::<4>(row, columns, &pixel, out),
            _ => 0,
        }
    }

    fn write_of<const N: usize>(
        &self,
        row: usize,
        columns: Range<usize>,
        pixel: &impl Fn(usize) -> [u8; 4],
        out: &mut [u8],
    ) -> usize {
        let (layout, placement) = (self.layout, &self.placement);
        if self.unclipped {
            write_unclipped_span::<N>(layout, placement, row, columns, pixel, out)
        } else {
            write_span_of::<N>(layout, placement, row, columns, pixel, out)
        }
    }
}

/// [`Spans::write`] for a picture wholly on the screen and in `out` (so
/// nothing is clipped), in `N`-byte pixels: each column's colour encoded
/// once and stored as a `scale` x `scale` square. The frame's spans are
/// mostly a pixel or two at the edges of what moved, so this is the
/// presenter's innermost loop.
fn write_unclipped_span<const N: usize>(
    layout: &FramebufferLayout,
    placement: &Placement,
    row: usize,
    columns: Range<usize>,
    pixel: &impl Fn(usize) -> [u8; 4],
    out: &mut [u8],
) -> usize {
    let scale = placement.scale;
    let line_bytes = layout.line_bytes();
    // Not negative: the picture is on the screen.
    let top = placement.top as usize + row * scale;
    let left = placement.left as usize + columns.start * scale;
    let square_bytes = scale * N;
    let span_bytes = columns.len() * square_bytes;
    let first = top * line_bytes + left * N;
    let span = &mut out[first..first + (scale - 1) * line_bytes + span_bytes];
    let mut square_left = 0;
    for column in columns {
        let encoded = pixel(column);
        let bytes: [u8; N] = core::array::from_fn(|i| encoded[i]);
        let mut at = square_left;
        for _ in 0..scale {
            span[at..at + square_bytes]
                .as_chunks_mut::<N>()
                .0
                .fill(bytes);
            at += line_bytes;
        }
        square_left += square_bytes;
    }
    span_bytes * scale
}

/// [`Spans::write`] for `N`-byte pixels: the span's screen columns are
/// clipped to the visible width once, then each line the row covers gets
/// them pixel by pixel (the framebuffer is never read: it may be
/// write-combining). Most spans of a spinning frame are a pixel or two at
/// its edges, so the set-up is kept to a few comparisons.
fn write_span_of<const N: usize>(
    layout: &FramebufferLayout,
    placement: &Placement,
    row: usize,
    columns: Range<usize>,
    pixel: &impl Fn(usize) -> [u8; 4],
    out: &mut [u8],
) -> usize {
    let scale = placement.scale;
    // Framebuffer sizes are far below isize::MAX.
    let top = placement.top + (row * scale) as isize;
    let height = layout.height as isize;
    let lines = top.clamp(0, height) as usize..(top + scale as isize).clamp(0, height) as usize;
    let left = placement.left + (columns.start * scale) as isize;
    let right = placement.left + (columns.end * scale) as isize;
    let visible_width = layout.visible_width() as isize;
    let (from, to) = (left.clamp(0, visible_width), right.clamp(0, visible_width));
    if lines.is_empty() || from >= to {
        return 0;
    }
    // Screen pixels of the first column cropped off the left edge.
    let cropped = (from - left) as usize;
    let (from, to) = (from as usize, to as usize);
    let encode = |column: usize| -> [u8; N] {
        let encoded = pixel(column);
        core::array::from_fn(|i| encoded[i])
    };
    let line_bytes = layout.line_bytes();
    let mut written = 0;
    for y in lines {
        // As `FramebufferLayout::visible_line`: whole pixels within `out`.
        let Some(line) = out.get_mut(y * line_bytes..) else {
            break;
        };
        let pixels = line.as_chunks_mut::<N>().0;
        let end = to.min(pixels.len());
        if from >= end {
            break;
        }
        let mut column = columns.start + cropped / scale;
        let mut repeats_left = scale - cropped % scale;
        let mut bytes = encode(column);
        for screen_pixel in &mut pixels[from..end] {
            *screen_pixel = bytes;
            repeats_left -= 1;
            if repeats_left == 0 && column + 1 < columns.end {
                column += 1;
                repeats_left = scale;
                bytes = encode(column);
            }
        }
        written += (end - from) * N;
    }
    written
}
