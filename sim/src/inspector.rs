//! The VGA inspector: what the software VGA holds and what each frame cost,
//! as numbers and as a panel image shown beside the picture.
//!
//! Everything here is a pure function of the software VGA's state and bus
//! counts, so tests check the figures without a window.

use std::collections::VecDeque;
use std::convert::Infallible;
use std::ops::Range;
use std::sync::OnceLock;

use embedded_graphics::mono_font::{ascii::FONT_6X10, MonoTextStyle};
use embedded_graphics::pixelcolor::{BinaryColor, Rgb888};
use embedded_graphics::prelude::*;
use embedded_graphics::text::{Baseline, Text};
use modex::regs::{gc, Graphics, Sequencer};
use modex::soft::{dac_6_to_8, BusCounts, SoftVga};
use modex::{Page, BYTES_PER_LINE, PAGE_COUNT, SCREEN_HEIGHT};

/// What one frame cost on the bus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameCost {
    /// Bytes written to video memory.
    pub vram_writes: u64,
    /// OUTs (a 16-bit OUT counts once).
    pub port_writes: u64,
    /// The fewest video-memory writes that could have drawn the frame: for
    /// each address of the page, the number of distinct new colours among
    /// its four pixels that changed (as `benches/bus_cost.rs` counts it).
    pub lower_bound: u64,
}

/// The cost of a frame from the bus counts before and after it and the
/// drawn page's bytes in each plane before and after (all empty when
/// nothing was drawn), as [`lower_bound_in_planes`] takes them.
pub fn frame_cost(
    before: BusCounts,
    after: BusCounts,
    old_planes: [&[u8]; 4],
    new_planes: [&[u8]; 4],
) -> FrameCost {
    FrameCost {
        vram_writes: after.vram_writes - before.vram_writes,
        port_writes: after.port_writes - before.port_writes,
        lower_bound: lower_bound_in_planes(old_planes, new_planes),
    }
}

/// Σ over the addresses of a page (four pixels each, one per plane) of the
/// distinct new colours among the pixels that changed: one write through
/// the Map Mask sets every plane that takes the same colour.
pub fn lower_bound(old_page: &[u8], new_page: &[u8]) -> u64 {
    old_page
        .as_chunks::<4>()
        .0
        .iter()
        .zip(new_page.as_chunks::<4>().0)
        .map(|(&old, &new)| address_bound(old, new))
        .sum()
}

/// [`lower_bound`] read straight from the planes, with no page image made:
/// `old[plane]` and `new[plane]` are that plane's bytes of the page, before
/// and after. Sixteen addresses at a time: a stretch unchanged in all four
/// planes (most of a frame's) costs a comparison of each plane's sixteen
/// bytes, and a changed one is counted without a branch, each address's
/// lane as `address_bound` counts it, so that the compiler makes it
/// sixteen lanes a step where there are vectors (SSE2, WebAssembly's SIMD).
pub fn lower_bound_in_planes(old: [&[u8]; 4], new: [&[u8]; 4]) -> u64 {
    let addresses = old.iter().chain(&new).map(|plane| plane.len()).min();
    let addresses = addresses.unwrap_or(0);
    let old = old.map(|plane| &plane[..addresses]);
    let new = new.map(|plane| &plane[..addresses]);
    let pixels = |planes: [&[u8]; 4], address: usize| planes.map(|plane| plane[address]);
    let old_lanes = old.map(|plane| plane.as_chunks::<LANES>().0);
    let new_lanes = new.map(|plane| plane.as_chunks::<LANES>().0);
    let mut bound = 0;
    for stretch in 0..addresses / LANES {
        let old = old_lanes.map(|plane| &plane[stretch]);
        let new = new_lanes.map(|plane| &plane[stretch]);
        if old == new {
            continue;
        }
        bound += stretch_bound(old, new);
    }
    bound
        + (addresses / LANES * LANES..addresses)
            .map(|address| address_bound(pixels(old, address), pixels(new, address)))
            .sum::<u64>()
}

/// Addresses [`lower_bound_in_planes`] takes at a time.
const LANES: usize = 16;

/// [`address_bound`] of each of [`LANES`] addresses, added up: a plane
/// counts where its byte changed and its new colour is none of the new
/// colours of the changed planes before it.
fn stretch_bound(old: [&[u8; LANES]; 4], new: [&[u8; LANES]; 4]) -> u64 {
    let mut counts = [0u8; LANES];
    for (lane, count) in counts.iter_mut().enumerate() {
        let changed = [0, 1, 2, 3].map(|plane| old[plane][lane] != new[plane][lane]);
        let repeats =
            |plane: usize, before: usize| changed[before] & (new[plane][lane] == new[before][lane]);
        let counted = [
            changed[0],
            changed[1] & !repeats(1, 0),
            changed[2] & !(repeats(2, 0) | repeats(2, 1)),
            changed[3] & !(repeats(3, 0) | repeats(3, 1) | repeats(3, 2)),
        ];
        *count = counted.iter().map(|&c| u8::from(c)).sum();
    }
    counts.iter().map(|&count| u64::from(count)).sum()
}

/// One address's share of the lower bound: the distinct new colours among
/// its four pixels (one per plane) that changed.
fn address_bound(old: [u8; 4], new: [u8; 4]) -> u64 {
    // Most addresses of a frame are unchanged: one comparison each.
    if old == new {
        return 0;
    }
    // No allocation: this runs for every changed address of every frame
    // (in the web page too, where an allocation costs more).
    let mut colours = [0u8; 4];
    let mut distinct = 0;
    for plane in (0..4).filter(|&p| old[p] != new[p]) {
        if !colours[..distinct].contains(&new[plane]) {
            colours[distinct] = new[plane];
            distinct += 1;
        }
    }
    distinct as u64
}

/// The registers the inspector shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VgaState {
    /// The CRTC start address the VGA latched at the last vertical retrace.
    pub start_address: u16,
    /// The Mode X page that address is the start of, if it is one.
    pub shown_page: Option<u8>,
    /// Sequencer Map Mask: the planes CPU writes reach.
    pub map_mask: u8,
    /// Graphics Controller Bit Mask: the bits of each byte writes change.
    pub bit_mask: u8,
    /// Graphics Controller write mode (0-3).
    pub write_mode: u8,
}

/// The registers the inspector shows, read from the software VGA.
pub fn vga_state(vga: &SoftVga) -> VgaState {
    let start_address = vga.displayed_start();
    let shown_page = Page::ALL
        .into_iter()
        .find(|page| page.base() == start_address)
        .map(Page::index);
    VgaState {
        start_address,
        shown_page,
        map_mask: vga.sequencer(Sequencer::MapMask),
        bit_mask: vga.graphics(Graphics::BitMask),
        write_mode: vga.graphics(Graphics::Mode) & gc::MODE_WRITE_MASK,
    }
}

/// Frames the running plot shows.
pub const PLOT_FRAMES: usize = 384;

/// The costs of the last [`PLOT_FRAMES`] frames, oldest first.
#[derive(Clone, Debug, Default)]
pub struct History {
    costs: VecDeque<FrameCost>,
    frames: u64,
}

impl History {
    /// Adds the cost of the frame just run.
    pub fn push(&mut self, cost: FrameCost) {
        if self.costs.len() == PLOT_FRAMES {
            self.costs.pop_front();
        }
        self.costs.push_back(cost);
        self.frames += 1;
    }

    /// The last frame's cost (zero before the first).
    pub fn last(&self) -> FrameCost {
        self.costs.back().copied().unwrap_or_default()
    }

    /// Frames pushed so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// The costs in the plot, oldest first.
    pub fn costs(&self) -> impl Iterator<Item = &FrameCost> {
        self.costs.iter()
    }
}

/// The inspector's text, line by line.
pub fn text_lines(state: &VgaState, history: &History) -> Vec<String> {
    let mut lines = Vec::new();
    write_text_lines(state, history, &mut lines);
    lines
}

/// [`text_lines`] written into `lines`, reusing its strings (the panel
/// writes them every frame, with no allocation once they have grown).
fn write_text_lines(state: &VgaState, history: &History, lines: &mut Vec<String>) {
    use std::fmt::Write;
    lines.resize_with(TEXT_LINES as usize, String::new);
    lines.iter_mut().for_each(String::clear);
    let last = history.last();
    // Writing into a String cannot fail.
    let _ = write!(
        lines[0],
        "CRTC start address 0x{:04X}: ",
        state.start_address
    );
    let _ = match state.shown_page {
        Some(page) => write!(lines[0], "page {page} of 0-{} shown", PAGE_COUNT - 1),
        None => write!(lines[0], "not the start of a page"),
    };
    let _ = write!(
        lines[1],
        "Map Mask 0x{:02X}  Bit Mask 0x{:02X}  write mode {}",
        state.map_mask, state.bit_mask, state.write_mode
    );
    let _ = write!(
        lines[2],
        "frame {}, last frame's bus work:",
        history.frames()
    );
    let _ = write!(
        lines[3],
        "video-memory writes {:>6}  lower bound {:>6}",
        last.vram_writes, last.lower_bound
    );
    let _ = write!(lines[4], "port writes {:>6}", last.port_writes);
}

/// How a [`Panel`] packs a colour into each `u32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    /// `0RGB` in the number, as the desktop window takes it.
    Xrgb,
    /// The bytes R, G, B, 255 in memory order, as a canvas's `ImageData`
    /// takes them (the web page hands the pixels over without a copy).
    Rgba,
}

impl Encoding {
    fn pack(self, [r, g, b]: [u8; 3]) -> u32 {
        match self {
            Encoding::Xrgb => crate::screen::to_0rgb([r, g, b]),
            Encoding::Rgba => u32::from_ne_bytes([r, g, b, 255]),
        }
    }
}

/// An RGB image, one colour in each `u32` as its [`Encoding`] packs it.
#[derive(Clone, Debug)]
pub struct Panel {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// How each pixel is packed.
    pub encoding: Encoding,
    /// Row by row.
    pub pixels: Vec<u32>,
    /// What [`redraw_panel`] drew last, and the rows changed since they
    /// were last taken.
    pub(crate) drawn: Drawn,
}

/// The rows of an image changed since they were last taken: what a canvas
/// showing the image must take again (the panel's, the web page's picture).
#[derive(Clone, Debug, Default)]
pub struct ChangedRows {
    flags: Vec<bool>,
}

impl ChangedRows {
    /// All `rows` rows changed (nothing has been shown yet).
    pub fn all(rows: usize) -> Self {
        ChangedRows {
            flags: vec![true; rows],
        }
    }

    /// Rows `rows` changed (what lies past the last row is ignored).
    pub fn mark(&mut self, rows: Range<usize>) {
        let end = rows.end.min(self.flags.len());
        if let Some(flags) = self.flags.get_mut(rows.start.min(end)..end) {
            flags.fill(true);
        }
    }

    /// The runs of rows changed since the last call, top down, into `runs`
    /// (emptied first); none are changed after it.
    pub fn take(&mut self, runs: &mut Vec<Range<usize>>) {
        runs.clear();
        let flags = &mut self.flags;
        let mut row = 0;
        while row < flags.len() {
            if flags[row] {
                let start = row;
                while row < flags.len() && flags[row] {
                    flags[row] = false;
                    row += 1;
                }
                runs.push(start..row);
            }
            row += 1;
        }
    }
}

/// What a panel shows, kept so that [`redraw_panel`] draws again only
/// what changed, and the rows it changed, so that a canvas takes only those.
#[derive(Clone, Debug, Default)]
pub(crate) struct Drawn {
    /// Each plane's image, 80 bytes a row, as drawn (empty: none yet).
    planes: Vec<u8>,
    /// The colours the plane images were drawn in.
    palette: Vec<u32>,
    /// The text lines as drawn.
    lines: Vec<String>,
    /// The lines of this redraw, written in place of a fresh `Vec` each time.
    next_lines: Vec<String>,
    /// The panel's rows changed since last taken.
    changed_rows: ChangedRows,
    /// The history's frames and last cost when the plots were drawn.
    plotted: Option<(u64, FrameCost)>,
}

/// The panel's width; its height is the picture's beside it.
pub const PANEL_WIDTH: usize = 400;
/// The least height that holds everything.
pub const PANEL_MIN_HEIGHT: usize = 470;

const BACKGROUND: Rgb888 = Rgb888::new(24, 24, 32);
const TEXT: Rgb888 = Rgb888::new(230, 230, 230);
const VRAM_COLOUR: Rgb888 = Rgb888::new(90, 160, 255);
const BOUND_COLOUR: Rgb888 = Rgb888::new(255, 190, 60);
const PORT_COLOUR: Rgb888 = Rgb888::new(120, 220, 120);
const AXIS_COLOUR: Rgb888 = Rgb888::new(80, 80, 80);
const MARGIN: i32 = 8;
const LINE_HEIGHT: i32 = 11;
const PLANE_GAP: i32 = 16;
const PLANES_TOP: i32 = 26;
const PLOT_HEIGHT: i32 = 56;
/// The panel's rows, top down: what is drawn once and what every frame.
const TEXT_TOP: i32 = PLANES_TOP + SCREEN_HEIGHT + 6;
const TEXT_LINES: i32 = 5;
const LEGEND_TOP: i32 = TEXT_TOP + TEXT_LINES * LINE_HEIGHT + 4;
const BUS_PLOT_TOP: i32 = LEGEND_TOP + LINE_HEIGHT;
const PORT_LEGEND_TOP: i32 = BUS_PLOT_TOP + PLOT_HEIGHT + 4;
const PORT_PLOT_TOP: i32 = PORT_LEGEND_TOP + LINE_HEIGHT;

impl Panel {
    /// The inspector's panel with only what never changes drawn (the
    /// background, the title, the labels): [`redraw_panel`] draws the rest,
    /// as often as the VGA changes, into the same pixels. At least
    /// [`PANEL_MIN_HEIGHT`] high; `height` may ask for more.
    pub fn inspector(height: usize, encoding: Encoding) -> Self {
        let (width, height) = (PANEL_WIDTH, height.max(PANEL_MIN_HEIGHT));
        let mut panel = Panel {
            width,
            height,
            encoding,
            pixels: vec![encoding.pack(rgb(BACKGROUND)); width * height],
            drawn: Drawn {
                changed_rows: ChangedRows::all(height),
                ..Drawn::default()
            },
        };
        panel.text("VGA inspector (V hides it)", MARGIN, 2, TEXT);
        for plane in 0..4 {
            let left = plane_left(plane);
            panel.text(&format!("plane {plane}"), left, PLANES_TOP - 12, TEXT);
        }
        panel.text("video-memory writes", MARGIN, LEGEND_TOP, VRAM_COLOUR);
        panel.text("lower bound", MARGIN + 22 * 6, LEGEND_TOP, BOUND_COLOUR);
        panel.text("port writes", MARGIN, PORT_LEGEND_TOP, PORT_COLOUR);
        panel
    }

    /// `text` in `FONT_6X10` with its top left at (x, y), clipped to the
    /// panel. Printable ASCII, all the inspector writes, is drawn from the
    /// font's glyphs as bit rows ([`glyph_rows`]), for less than half of
    /// what embedded-graphics' text renderer costs (`Panel::text` in the
    /// web page's profile of a crowd frame: 59 µs before, 23 after);
    /// anything else goes through that renderer. The same pixels either way (a test
    /// draws every glyph both ways).
    fn text(&mut self, text: &str, x: i32, y: i32, colour: Rgb888) {
        if !text.bytes().all(|byte| GLYPH_CHARACTERS.contains(&byte)) {
            self.text_by_renderer(text, x, y, colour);
            return;
        }
        let colour = self.encoding.pack(rgb(colour));
        let glyphs = glyph_rows();
        for (index, byte) in text.bytes().enumerate() {
            let left = x + index as i32 * GLYPH_WIDTH;
            let rows = &glyphs[usize::from(byte - GLYPH_CHARACTERS.start)];
            for (row, &bits) in (y..).zip(rows) {
                for column in 0..GLYPH_WIDTH {
                    if bits & (1 << column) != 0 {
                        self.put(left + column, row, colour);
                    }
                }
            }
        }
    }

    /// `text` as embedded-graphics' text renderer draws it.
    fn text_by_renderer(&mut self, text: &str, x: i32, y: i32, colour: Rgb888) {
        let style = MonoTextStyle::new(&FONT_6X10, colour);
        // Drawing into a Vec cannot fail.
        let _ = Text::with_baseline(text, Point::new(x, y), style, Baseline::Top).draw(self);
    }

    fn put(&mut self, x: i32, y: i32, colour: u32) {
        if (0..self.width as i32).contains(&x) && (0..self.height as i32).contains(&y) {
            self.pixels[y as usize * self.width + x as usize] = colour;
        }
    }

    /// Paints `rows` rows from `top` with the background, for what is
    /// drawn there anew.
    fn clear_rows(&mut self, top: i32, rows: i32) {
        let background = self.encoding.pack(rgb(BACKGROUND));
        let width = self.width;
        self.pixels[top as usize * width..][..rows as usize * width].fill(background);
        self.mark_changed(top as usize..(top + rows) as usize);
    }

    fn mark_changed(&mut self, rows: Range<usize>) {
        self.drawn.changed_rows.mark(rows);
    }

    /// The runs of rows changed since the last call (all of them the first
    /// time), top down, into `runs` (emptied first): a canvas showing the
    /// panel needs only those again.
    pub fn take_changed_rows(&mut self, runs: &mut Vec<Range<usize>>) {
        self.drawn.changed_rows.take(runs);
    }
}

fn rgb(colour: Rgb888) -> [u8; 3] {
    [colour.r(), colour.g(), colour.b()]
}

/// The characters [`glyph_rows`] holds: printable ASCII.
const GLYPH_CHARACTERS: Range<u8> = 0x20..0x7F;
/// `FONT_6X10`'s glyph size, and the step from one character to the next.
const GLYPH_WIDTH: i32 = 6;
const GLYPH_HEIGHT: usize = 10;

/// Each printable ASCII character's glyph in `FONT_6X10`, a row of bits a
/// line (bit n: the pixel n from the left), as embedded-graphics' text
/// renderer draws it: made once, by that renderer, the first time text is
/// drawn.
fn glyph_rows() -> &'static [[u8; GLYPH_HEIGHT]; GLYPH_CHARACTERS.end as usize - 0x20] {
    static GLYPHS: OnceLock<[[u8; GLYPH_HEIGHT]; GLYPH_CHARACTERS.end as usize - 0x20]> =
        OnceLock::new();
    GLYPHS.get_or_init(|| {
        /// One glyph's pixels, as bits.
        struct GlyphCell([u8; GLYPH_HEIGHT]);
        impl OriginDimensions for GlyphCell {
            fn size(&self) -> Size {
                Size::new(GLYPH_WIDTH as u32, GLYPH_HEIGHT as u32)
            }
        }
        impl DrawTarget for GlyphCell {
            type Color = BinaryColor;
            type Error = Infallible;
            fn draw_iter<I: IntoIterator<Item = Pixel<BinaryColor>>>(
                &mut self,
                pixels: I,
            ) -> Result<(), Infallible> {
                for Pixel(point, colour) in pixels {
                    let inside = (0..GLYPH_WIDTH).contains(&point.x)
                        && (0..GLYPH_HEIGHT as i32).contains(&point.y);
                    if inside && colour.is_on() {
                        self.0[point.y as usize] |= 1 << point.x;
                    }
                }
                Ok(())
            }
        }
        let mut glyphs = [[0; GLYPH_HEIGHT]; GLYPH_CHARACTERS.end as usize - 0x20];
        for (glyph, character) in glyphs.iter_mut().zip(GLYPH_CHARACTERS) {
            let mut cell = GlyphCell([0; GLYPH_HEIGHT]);
            let mut utf8 = [0; 4];
            let text = char::from(character).encode_utf8(&mut utf8);
            let style = MonoTextStyle::new(&FONT_6X10, BinaryColor::On);
            let _ = Text::with_baseline(text, Point::zero(), style, Baseline::Top).draw(&mut cell);
            *glyph = cell.0;
        }
        glyphs
    })
}

/// The left edge of plane `plane`'s image.
fn plane_left(plane: usize) -> i32 {
    MARGIN + plane as i32 * (i32::from(BYTES_PER_LINE) + PLANE_GAP)
}

impl OriginDimensions for Panel {
    fn size(&self) -> Size {
        Size::new(self.width as u32, self.height as u32)
    }
}

impl DrawTarget for Panel {
    type Color = Rgb888;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<Rgb888>>>(
        &mut self,
        pixels: I,
    ) -> Result<(), Infallible> {
        for Pixel(point, colour) in pixels {
            let colour = self.encoding.pack(rgb(colour));
            self.put(point.x, point.y, colour);
        }
        Ok(())
    }
}

/// The panel: the displayed page's bytes in each plane as an image (80
/// bytes by 240 lines, each byte in its DAC colour), the registers, the last
/// frame's figures and a running plot of them, in `0RGB`. At least
/// [`PANEL_MIN_HEIGHT`] high; `height` may ask for more.
pub fn draw_panel(vga: &SoftVga, history: &History, height: usize) -> Panel {
    let mut panel = Panel::inspector(height, Encoding::Xrgb);
    redraw_panel(&mut panel, vga, history);
    panel
}

/// Draws into `panel` (made by [`Panel::inspector`]) everything that changes
/// with the VGA and the history, over what it showed before: the result is
/// [`draw_panel`]'s, pixel for pixel, without painting the panel afresh.
/// Only what changed is drawn again: a plane image's row whose bytes or
/// colours changed, a text line whose text did, the plots when the history
/// has a new frame (the panel is redrawn with one history, which only
/// grows); [`Panel::take_changed_rows`] says which rows that touched.
pub fn redraw_panel(panel: &mut Panel, vga: &SoftVga, history: &History) {
    let state = vga_state(vga);
    draw_planes(panel, vga, state.start_address);
    // Only the lines whose text changed (the frame's number, the figures).
    let mut lines = std::mem::take(&mut panel.drawn.next_lines);
    write_text_lines(&state, history, &mut lines);
    for (index, line) in lines.iter().enumerate() {
        if panel.drawn.lines.get(index) != Some(line) {
            let y = TEXT_TOP + index as i32 * LINE_HEIGHT;
            panel.clear_rows(y, LINE_HEIGHT);
            panel.text(line, MARGIN, y, TEXT);
        }
    }
    panel.drawn.next_lines = std::mem::replace(&mut panel.drawn.lines, lines);
    // The plots change only with a frame pushed to the history.
    let plotted = Some((history.frames(), history.last()));
    if panel.drawn.plotted == plotted {
        return;
    }
    panel.drawn.plotted = plotted;
    let vram = |cost: &FrameCost| cost.vram_writes;
    let bound = |cost: &FrameCost| cost.lower_bound;
    draw_plot(
        panel,
        history,
        BUS_PLOT_TOP,
        [(vram, VRAM_COLOUR), (bound, BOUND_COLOUR)],
    );
    draw_plot(
        panel,
        history,
        PORT_PLOT_TOP,
        [(|cost: &FrameCost| cost.port_writes, PORT_COLOUR)],
    );
}

/// Each plane's bytes of the page from `start`, a row of 80 at a time, every
/// pixel of the images written (nothing else to clear); a row whose bytes
/// and colours are those drawn last is left as it is.
fn draw_planes(panel: &mut Panel, vga: &SoftVga, start: u16) {
    let encoding = panel.encoding;
    let drawn = &mut panel.drawn;
    let palette_before = drawn.palette.len();
    drawn.palette.resize(256, 0);
    let mut same_colours = palette_before == 256;
    for (index, colour) in drawn.palette.iter_mut().enumerate() {
        let new = encoding.pack(vga.dac_entry(index as u8).map(dac_6_to_8));
        same_colours &= *colour == new;
        *colour = new;
    }
    let row_bytes = usize::from(BYTES_PER_LINE);
    let rows = SCREEN_HEIGHT as usize;
    let image_bytes = rows * row_bytes;
    if drawn.planes.len() != 4 * image_bytes {
        drawn.planes = vec![0; 4 * image_bytes];
        same_colours = false;
    }
    let mut wrapped = [0u8; BYTES_PER_LINE as usize];
    for plane in 0..4 {
        let left = plane_left(plane) as usize;
        let bytes = vga.plane(plane);
        for row in 0..rows {
            let first = start.wrapping_add((row * row_bytes) as u16);
            let first = usize::from(first);
            // A row is a slice of the plane unless it wraps past its end.
            let now: &[u8] = match bytes.get(first..first + row_bytes) {
                Some(slice) => slice,
                None => {
                    for (x, byte) in wrapped.iter_mut().enumerate() {
                        *byte = bytes[(first + x) % bytes.len()];
                    }
                    &wrapped
                }
            };
            let shown = &mut panel.drawn.planes[(plane * rows + row) * row_bytes..][..row_bytes];
            if same_colours && same_bytes(shown, now) {
                continue;
            }
            shown.copy_from_slice(now);
            let y = PLANES_TOP as usize + row;
            let line = y * panel.width + left;
            let palette = &panel.drawn.palette;
            for (pixel, &byte) in panel.pixels[line..][..row_bytes].iter_mut().zip(now) {
                *pixel = palette[usize::from(byte)];
            }
            panel.mark_changed(y..y + 1);
        }
    }
}

/// Whether two runs of bytes are equal, eight bytes to a comparison (a
/// slice comparison is `memcmp`, a byte-by-byte loop in WebAssembly): the
/// panel's plane rows, the web page's picture rows.
pub fn same_bytes(a: &[u8], b: &[u8]) -> bool {
    let (a_words, a_rest) = a.as_chunks::<8>();
    let (b_words, b_rest) = b.as_chunks::<8>();
    a.len() == b.len()
        && a_rest == b_rest
        && a_words
            .iter()
            .zip(b_words)
            .all(|(a, b)| u64::from_ne_bytes(*a) == u64::from_ne_bytes(*b))
}

/// A figure of each frame's cost, and its colour in the plot.
type Series = (fn(&FrameCost) -> u64, Rgb888);

/// One column per frame, the newest on the right, every series on one scale
/// whose top is the largest value shown (written at the top right): the
/// first series as bars, the others as points over them.
fn draw_plot<const SERIES: usize>(
    panel: &mut Panel,
    history: &History,
    top: i32,
    series: [Series; SERIES],
) {
    let largest = history
        .costs()
        .flat_map(|cost| series.iter().map(move |(value, _)| value(cost)))
        .max()
        .unwrap_or(0)
        .max(1);
    // Each series' height in each column, counted from 1 at the bottom row
    // (0: no frame there yet).
    let mut heights = [[0u8; PLOT_FRAMES]; SERIES];
    let start = PLOT_FRAMES - history.costs.len();
    for (heights, (value, _)) in heights.iter_mut().zip(&series) {
        for (height, cost) in heights[start..].iter_mut().zip(history.costs()) {
            // At most PLOT_HEIGHT, which fits.
            *height = (1 + value(cost) * (PLOT_HEIGHT as u64 - 1) / largest) as u8;
        }
    }
    panel.clear_rows(top, PLOT_HEIGHT);
    let pack = |colour| panel.encoding.pack(rgb(colour));
    let (background, axis) = (pack(BACKGROUND), pack(AXIS_COLOUR));
    let colours = series.map(|(_, colour)| pack(colour));
    // Row by row, each pixel chosen without a branch, so that a row is a
    // few vector operations.
    let width = panel.width;
    for level in 1..=PLOT_HEIGHT as u8 {
        let y = (top + PLOT_HEIGHT) as usize - usize::from(level);
        let row = &mut panel.pixels[y * width + MARGIN as usize..][..PLOT_FRAMES];
        let empty = if level == 1 { axis } else { background };
        for (column, pixel) in row.iter_mut().enumerate() {
            let mut colour = if level <= heights[0][column] {
                colours[0]
            } else {
                empty
            };
            for (heights, &point) in heights.iter().zip(&colours).skip(1) {
                if level == heights[column] {
                    colour = point;
                }
            }
            *pixel = colour;
        }
    }
    let mut digits = itoa::Buffer::new();
    panel.text(
        digits.format(largest),
        MARGIN + PLOT_FRAMES as i32 - 6 * 8,
        top,
        TEXT,
    );
}

#[cfg(test)]
mod tests;
