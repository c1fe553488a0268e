//! Bringing a page up to date with the fewest video-memory writes.
//!
//! The caller renders the next frame into RAM first (colour indices, one byte
//! a pixel) and keeps a shadow of what each page holds. Each group of four
//! pixels x = 4i..4i+3 on a line is one byte address i, with pixel 4i+p in
//! plane p, so a page can be updated address by address: pixels that already
//! hold their new colour are left alone, and the changed ones get one write per
//! distinct new colour, with the Map Mask selecting exactly their planes. That
//! is the lower bound on writes for the change. The writes are then ordered by
//! Map Mask, so each distinct mask the frame needs costs one port write.

use crate::bus::VgaBus;
use crate::driver::ModeX;
use crate::page::Page;
use crate::regs::PlaneMask;
use crate::spans::PageSpans;
use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};
use core::ops::Range;

/// Pixels in a page: one byte each in a RAM image of it.
pub const PAGE_PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;

/// A page's picture in RAM: row-major colour indices.
pub type PageImage = [u8; PAGE_PIXELS];

impl<B: VgaBus> ModeX<B> {
    /// Makes `page` show `target`, given that it shows `shadow` now and
    /// that the two can differ only at the addresses `spans` marks; only
    /// changed pixels are written, and `shadow` becomes `target`. Returns
    /// the number of video-memory bytes written.
    ///
    /// Only the marked addresses are read: the renderer marks what it drew
    /// this frame and what the page held (`crate::spans`), and everywhere
    /// else both are the background. [`PageSpans::all`] compares every
    /// pixel. Either way the writes are the same, in the same order: an
    /// unmarked address is unchanged, and no write reaches past one.
    ///
    /// Writes to different addresses are independent, so they are grouped by
    /// Map Mask: one pass per distinct mask the frame needs, each setting the
    /// Map Mask once and then writing every address that needs it. The port
    /// writes are then the number of distinct masks, not one per change of
    /// mask between neighbouring addresses.
    pub fn update_page(
        &mut self,
        page: Page,
        shadow: &mut PageImage,
        target: &PageImage,
        spans: &PageSpans,
    ) -> u32 {
        self.update_page_with(page, shadow, target, spans, &mut PageWrites::new())
    }

    /// [`ModeX::update_page`] with the room for the frame's writes kept by
    /// the caller: a renderer that keeps one saves clearing 128 KiB every
    /// frame (what `update_page` costs the cube's frame most after the
    /// comparison itself).
    pub fn update_page_with(
        &mut self,
        page: Page,
        shadow: &mut PageImage,
        target: &PageImage,
        spans: &PageSpans,
        writes: &mut PageWrites,
    ) -> u32 {
        self.issued_by("ModeX::update_page", |vga| {
            let written = if writes.collect(spans, shadow, target) {
                vga.write_by_mask(page, writes)
            } else {
                // More writes than the list holds (a whole new picture): the
                // same writes in the same order, found again for each mask.
                vga.write_by_passes(page, spans, shadow, target)
            };
            spans.copy(target, shadow);
            written
        })
    }

    /// Writes the whole of `image` into `page`, whatever it held: one pass
    /// per plane, every address written. For a picture with no shadow to
    /// compare with (the report screen on the spare page); 76,800 writes.
    pub fn write_page(&mut self, page: Page, image: &PageImage) {
        self.issued_by("ModeX::write_page", |vga| {
            let width = SCREEN_WIDTH as usize;
            for plane in 0..4u8 {
                vga.io.set_map_mask(PlaneMask::plane(plane));
                for y in 0..SCREEN_HEIGHT as usize {
                    let line = &image[y * width..][..width];
                    let line_base = page.base() + y as u16 * BYTES_PER_LINE;
                    for i in 0..usize::from(BYTES_PER_LINE) {
                        vga.io
                            .write_vram8(line_base + i as u16, line[4 * i + usize::from(plane)]);
                    }
                }
            }
        })
    }

    /// The Map Masks in the order they are set: the one already set first,
    /// which saves its OUT, then the rest in increasing order.
    fn mask_order(&self, frame_masks: u16) -> impl Iterator<Item = PlaneMask> {
        let cached = self
            .io
            .map_mask()
            .filter(|&m| frame_masks & mask_bit(m) != 0);
        let others = (1..=PlaneMask::ALL.bits())
            .map(PlaneMask::from_bits_truncate)
            .filter(move |&m| Some(m) != cached && frame_masks & mask_bit(m) != 0);
        cached.into_iter().chain(others)
    }

    /// Makes the collected writes mask by mask, each mask's in the order
    /// they were found, following the list's links.
    fn write_by_mask(&mut self, page: Page, writes: &PageWrites) -> u32 {
        let mut written = 0;
        for mask in self.mask_order(writes.masks) {
            self.io.set_map_mask(mask);
            for write in writes.with_mask(mask) {
                let address = page.base() + write.address;
                if write.count == 1 {
                    self.io.write_vram8(address, write.colour);
                } else {
                    self.io.fill_vram(address, write.count, write.colour);
                }
                written += u32::from(write.count);
            }
        }
        written
    }

    /// Finds and makes the writes mask by mask, visiting for each mask only
    /// the lines that need it.
    fn write_by_passes(
        &mut self,
        page: Page,
        spans: &PageSpans,
        shadow: &PageImage,
        target: &PageImage,
    ) -> u32 {
        let mut line = LineWrites::new();
        let mut line_masks = [0u16; SCREEN_HEIGHT as usize];
        let mut frame_masks = 0u16;
        for (y, masks) in line_masks.iter_mut().enumerate() {
            for write in line.find(spans, shadow, target, y) {
                *masks |= mask_bit(write.mask);
            }
            frame_masks |= *masks;
        }
        let mut written = 0;
        for mask in self.mask_order(frame_masks) {
            self.io.set_map_mask(mask);
            for (y, masks) in line_masks.iter().enumerate() {
                if masks & mask_bit(mask) == 0 {
                    continue;
                }
                let line_base = page.base() + y as u16 * BYTES_PER_LINE;
                for write in line.find(spans, shadow, target, y) {
                    if write.mask != mask {
                        continue;
                    }
                    if write.count == 1 {
                        self.io.write_vram8(line_base + write.address, write.colour);
                    } else {
                        self.io
                            .fill_vram(line_base + write.address, write.count, write.colour);
                    }
                    written += u32::from(write.count);
                }
            }
        }
        written
    }
}

/// One write of the page update: `count` addresses from `address` (relative
/// to the page), each given `colour` through Map Mask `mask`. A count above
/// one is a run of addresses whose four pixels all become one colour, one
/// fill with all planes enabled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Write {
    address: u16,
    count: u16,
    colour: u8,
    mask: PlaneMask,
}

/// Writes a frame's update can collect before it falls back to finding them
/// again mask by mask: far more than a spinning scene needs (the crowd of 59
/// solids averages 3,600; a screen-filling grid of 256 turning solids about
/// 5,000), 128 KiB with the links, in a [`PageWrites`].
const WRITE_LIST_CAPACITY: usize = 16_384;
/// The end of a mask's chain of writes.
const NO_WRITE: u16 = u16::MAX;
const _: () = assert!(WRITE_LIST_CAPACITY < NO_WRITE as usize);

/// Room for a frame's writes in the order they are found (line by line,
/// address by address), each mask's chained in that order, and the set of
/// masks among them: making them mask by mask is then one step per write,
/// not one pass over the whole list per mask. All zero when new, so a
/// renderer in static memory keeps one in `.bss`; each update starts it
/// afresh by resetting the chains' ends, not the 128 KiB.
pub struct PageWrites {
    list: [Write; WRITE_LIST_CAPACITY],
    /// For each write but its mask's last, the next with the same mask.
    next_with_mask: [u16; WRITE_LIST_CAPACITY],
    /// Each mask's first and last write, or `NO_WRITE`.
    first_with_mask: [u16; 16],
    last_with_mask: [u16; 16],
    len: usize,
    masks: u16,
}

/// Not the 16,384 writes.
impl core::fmt::Debug for PageWrites {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PageWrites")
            .field("len", &self.len)
            .finish_non_exhaustive()
    }
}

impl Default for PageWrites {
    fn default() -> Self {
        Self::new()
    }
}

impl PageWrites {
    /// Empty room, all zero.
    pub const fn new() -> Self {
        PageWrites {
            list: [Write {
                address: 0,
                count: 0,
                colour: 0,
                mask: PlaneMask::NONE,
            }; WRITE_LIST_CAPACITY],
            next_with_mask: [0; WRITE_LIST_CAPACITY],
            first_with_mask: [0; 16],
            last_with_mask: [0; 16],
            len: 0,
            masks: 0,
        }
    }

    /// Collects every write the marked addresses need; false if there are
    /// more than the list holds (what was collected is then of no use).
    fn collect(&mut self, spans: &PageSpans, shadow: &PageImage, target: &PageImage) -> bool {
        self.first_with_mask = [NO_WRITE; 16];
        self.last_with_mask = [NO_WRITE; 16];
        (self.len, self.masks) = (0, 0);
        let mut line = LineWrites::new();
        for y in 0..SCREEN_HEIGHT as usize {
            let line_base = y as u16 * BYTES_PER_LINE;
            for &write in line.find(spans, shadow, target, y) {
                if !self.push(Write {
                    address: line_base + write.address,
                    ..write
                }) {
                    return false;
                }
            }
        }
        true
    }

    /// Appends `write` to the list and to its mask's chain; false if full.
    fn push(&mut self, write: Write) -> bool {
        let index = self.len;
        let Some(slot) = self.list.get_mut(index) else {
            return false;
        };
        *slot = write;
        let mask = usize::from(write.mask.bits());
        match self.last_with_mask[mask] {
            NO_WRITE => self.first_with_mask[mask] = index as u16,
            last => self.next_with_mask[usize::from(last)] = index as u16,
        }
        self.last_with_mask[mask] = index as u16;
        self.len += 1;
        self.masks |= mask_bit(write.mask);
        true
    }

    /// The writes with `mask`, in the order they were found.
    fn with_mask(&self, mask: PlaneMask) -> impl Iterator<Item = &Write> {
        let mask = usize::from(mask.bits());
        let (mut next, last) = (self.first_with_mask[mask], self.last_with_mask[mask]);
        core::iter::from_fn(move || {
            let write = self.list.get(usize::from(next))?;
            next = if next == last {
                NO_WRITE
            } else {
                self.next_with_mask[usize::from(next)]
            };
            Some(write)
        })
    }
}

/// The most writes one line can need: one per pixel.
const LINE_WRITE_CAPACITY: usize = SCREEN_WIDTH as usize;

/// The writes one line needs, found into a buffer that is reused line after
/// line: no call per write, and the search is compiled once for every bus
/// and caller.
struct LineWrites {
    list: [Write; LINE_WRITE_CAPACITY],
    len: usize,
}

impl LineWrites {
    fn new() -> Self {
        LineWrites {
            list: [Write::default(); LINE_WRITE_CAPACITY],
            len: 0,
        }
    }

    /// The writes line `y` needs over the addresses `spans` marks on it, in
    /// address order (addresses relative to the line).
    fn find(
        &mut self,
        spans: &PageSpans,
        shadow: &PageImage,
        target: &PageImage,
        y: usize,
    ) -> &[Write] {
        let width = SCREEN_WIDTH as usize;
        let (old_line, new_line) = (&shadow[y * width..][..width], &target[y * width..][..width]);
        self.len = 0;
        for run in spans.runs(y) {
            self.add_run(old_line, new_line, run);
        }
        &self.list[..self.len]
    }

    fn push(&mut self, write: Write) {
        // At most one write a pixel, so the list never fills; were it ever
        // to, the extra write would be dropped, never written out of bounds.
        if let Some(slot) = self.list.get_mut(self.len) {
            *slot = write;
            self.len += 1;
        }
    }

    /// Adds the writes that bring `old_line` to `new_line` at the addresses
    /// in `quads`, in address order: a run of addresses whose four pixels
    /// all become one colour is one write with all planes (a fill); any
    /// other changed address gets one write per distinct new colour among
    /// its changed pixels.
    ///
    /// Most marked addresses keep their pixels: [`first_change`] passes
    /// over them two at a time.
    fn add_run(&mut self, old_line: &[u8], new_line: &[u8], quads: Range<usize>) {
        let mut i = quads.start;
        loop {
            i = first_change(old_line, new_line, i..quads.end);
            if i >= quads.end {
                break;
            }
            // Address i changes. (An unchanged address never starts a run.)
            let (old, new) = (quad(old_line, i), quad(new_line, i));
            let run = solid_run(old_line, new_line, i, quads.end);
            if run > 0 {
                self.push(Write {
                    address: i as u16,
                    count: run as u16,
                    colour: new as u8,
                    mask: PlaneMask::ALL,
                });
                i += run;
                continue;
            }
            let mut pending = differing_bytes(old, new);
            while pending != 0 {
                // The first changed pixel's colour, and every changed pixel
                // of that colour: one write.
                let colour = (new >> (8 * pending.trailing_zeros())) as u8;
                let planes = pending & !differing_bytes(new, splat(colour));
                pending &= !planes;
                self.push(Write {
                    address: i as u16,
                    count: 1,
                    colour,
                    mask: PlaneMask::from_bits_truncate(planes),
                });
            }
            i += 1;
        }
    }
}

/// A mask's bit in a set of masks (one bit per mask value, 0 to 15).
fn mask_bit(planes: PlaneMask) -> u16 {
    1 << planes.bits()
}

/// The four pixels at `address`, pixel 4·address in the low byte (plane 0).
fn quad(line: &[u8], address: usize) -> u32 {
    line.get(4 * address..4 * address + 4)
        .and_then(|quad| quad.try_into().ok())
        .map_or(0, u32::from_le_bytes)
}

/// The first address of `quads` whose pixels differ between the lines, or
/// `quads.end` if none does. Four addresses (sixteen pixels) are compared
/// at a time, one 128-bit compare (which the compiler may make of two
/// 64-bit ones), and the lowest differing byte of a differing four names
/// its address; the range's last one to three addresses, which a 16-byte
/// load would reach past, are compared a quad at a time.
fn first_change(old_line: &[u8], new_line: &[u8], quads: Range<usize>) -> usize {
    let pixels = 4 * quads.start..4 * quads.end;
    let (Some(old), Some(new)) = (old_line.get(pixels.clone()), new_line.get(pixels)) else {
        return quads.end;
    };
    let fours = old.as_chunks::<16>().0.iter().zip(new.as_chunks::<16>().0);
    for (k, (&old, &new)) in fours.enumerate() {
        let changed = u128::from_le_bytes(old) ^ u128::from_le_bytes(new);
        if changed != 0 {
            // Little-endian: the lowest byte is the first address's plane 0.
            return quads.start + 4 * k + changed.trailing_zeros() as usize / 32;
        }
    }
    let left_over = quads.start + old.len() / 16 * 4;
    (left_over..quads.end)
        .find(|&i| quad(old_line, i) != quad(new_line, i))
        .unwrap_or(quads.end)
}

/// `colour` in all four bytes of a quad.
fn splat(colour: u8) -> u32 {
    u32::from(colour) * 0x0101_0101
}

/// Which of the four bytes (planes) differ between `a` and `b`, as a plane
/// mask (bit n for byte n), without a branch a byte: a byte's top bit is set
/// if its low seven bits, plus 0x7F, carry into it, or if it was set; the
/// four top bits are then gathered into bits 24 to 27 by one multiply (the
/// other products fall on bits no two share, so nothing carries).
fn differing_bytes(a: u32, b: u32) -> u8 {
    let x = a ^ b;
    let tops = (((x & 0x7F7F_7F7F) + 0x7F7F_7F7F) | x) & 0x8080_8080;
    ((tops >> 7).wrapping_mul(0x0102_0408) >> 24) as u8
}

/// How many addresses from `start` on (before `end`) have all four pixels
/// changing to one and the same colour, the new colour at `start` (0 if the
/// first does not).
fn solid_run(old_line: &[u8], new_line: &[u8], start: usize, end: usize) -> usize {
    let colour = splat(new_line[4 * start]);
    (start..end)
        .take_while(|&i| {
            quad(new_line, i) == colour && differing_bytes(quad(old_line, i), colour) == 0x0F
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::Recorder;
    use crate::soft::SoftVga;
    use std::boxed::Box;
    use std::vec;
    use std::vec::Vec;

    fn indices(soft: &SoftVga) -> std::vec::Vec<u8> {
        let mut out = vec![0u8; PAGE_PIXELS];
        soft.scanout_indices(&mut out);
        out
    }

    #[test]
    fn the_page_ends_up_showing_the_target_and_only_changes_are_written() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        let mut seed = 7u32;
        for round in 0..20 {
            // A random mix of solid runs and scattered pixels.
            for (i, pixel) in target.iter_mut().enumerate() {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                if (seed >> 24).is_multiple_of(8) || (i / 320 + round).is_multiple_of(37) {
                    *pixel = ((seed >> 16) % 4) as u8 + if i % 320 > 150 { 9 } else { 0 };
                }
            }
            let before = vga.bus().counts();
            let written = vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all());
            let after = vga.bus().counts();
            assert_eq!(after.vram_writes - before.vram_writes, u64::from(written));
            // At most one Map Mask write per distinct mask (15 at most).
            assert!(
                after.port_writes - before.port_writes <= 15,
                "round {round}"
            );
            assert_eq!(&*shadow, &*target);
            assert_eq!(indices(vga.bus()), target.to_vec(), "round {round}");
        }
        // Nothing changed: nothing is written.
        let before = vga.bus().counts();
        assert_eq!(
            vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all()),
            0
        );
        assert_eq!(vga.bus().counts(), before);
    }

    #[test]
    fn an_address_with_two_new_colours_takes_two_writes() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        target[..4].copy_from_slice(&[5, 5, 0, 6]);
        assert_eq!(
            vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all()),
            2
        );
        target[..4].copy_from_slice(&[5, 7, 7, 7]);
        assert_eq!(
            vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all()),
            1
        );
        assert_eq!(&indices(vga.bus())[..4], &[5, 7, 7, 7]);
    }

    #[test]
    fn each_distinct_map_mask_is_set_once_per_frame() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        // Masks alternating from address to address, on many lines: the
        // old order would set the Map Mask before nearly every write.
        for y in 0..100 {
            for i in 0..80 {
                let pixel = y * 320 + 4 * i;
                if i % 2 == 0 {
                    target[pixel] = 9; // plane 0
                } else {
                    target[pixel + 1..pixel + 3].fill(10); // planes 1 and 2
                }
            }
        }
        let before = vga.bus().counts();
        assert_eq!(
            vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all()),
            8000
        );
        let after = vga.bus().counts();
        assert!(after.port_writes - before.port_writes <= 2);
        assert_eq!(indices(vga.bus()), target.to_vec());
    }

    /// The list of writes, bounded by the changed bytes, makes exactly the
    /// bus operations of the mask-by-mask passes over every changed line, in
    /// the same order: only the work to find them differs.
    #[test]
    fn the_collected_writes_are_the_passes_writes_in_the_same_order() {
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        let mut seed = 11u32;
        for round in 0..40 {
            // Small changes in a few places, as a spinning frame has, with
            // solid runs, scattered pixels and runs cut by the line's end.
            for _ in 0..200 {
                seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                let at = (seed >> 8) as usize % (PAGE_PIXELS - 16);
                let len = 1 + (seed >> 3) as usize % 14;
                target[at..at + len].fill(9 + (seed % 7) as u8);
            }
            let changed = PageSpans::all();
            let mut writes = Box::new(PageWrites::new());
            assert!(
                writes.collect(&changed, &shadow, &target),
                "a small change fits"
            );
            let mut by_list = ModeX::new(Recorder::default());
            by_list.write_by_mask(Page::One, &writes);
            let mut by_passes = ModeX::new(Recorder::default());
            by_passes.write_by_passes(Page::One, &changed, &shadow, &target);
            assert!(!by_list.bus().0.is_empty());
            assert_eq!(by_list.bus().0, by_passes.bus().0, "round {round}");
            // And the whole update leaves the shadow equal to the target.
            let mut vga = ModeX::new(Recorder::default());
            vga.update_page(Page::One, &mut shadow, &target, &changed);
            assert!(shadow[..] == target[..], "round {round}");
        }
    }

    #[test]
    fn a_whole_new_picture_is_more_than_the_list_holds_and_still_drawn() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        // Every address changes two ways: 2 writes each, 38,400 in all.
        let target: Box<PageImage> =
            Box::new(core::array::from_fn(|i| if i % 4 < 2 { 9 } else { 10 }));
        let changed = PageSpans::all();
        assert!(!PageWrites::new().collect(&changed, &shadow, &target));
        assert_eq!(
            vga.update_page(Page::Zero, &mut shadow, &target, &PageSpans::all()),
            38_400
        );
        assert_eq!(indices(vga.bus()), target.to_vec());
        assert!(shadow[..] == target[..]);
    }

    /// The page update over the spans the renderer keeps (the union of what
    /// the frame drew and what the page held when last drawn) makes the bus
    /// operations of comparing every pixel: the same ones, in the same
    /// order, frame after frame on two pages. The frames are random spans,
    /// runs and single pixels drawn over the background the way the
    /// renderer draws them (cleared at the last frame's marks, every span
    /// marked), now and then a blank frame, and now and then one with more
    /// writes than the list holds.
    #[test]
    fn the_marked_spans_make_the_bus_operations_of_comparing_every_pixel() {
        const BACKGROUND: u8 = 0;
        let width = SCREEN_WIDTH as usize;
        let mut frame = Box::new([BACKGROUND; PAGE_PIXELS]);
        let mut drawn = Box::new(PageSpans::none());
        let mut held = [Box::new(PageSpans::none()), Box::new(PageSpans::none())];
        let mut shadows = [Box::new(*frame), Box::new(*frame)];
        let mut full_shadows = shadows.clone();
        let mut by_spans = ModeX::new(Recorder::default());
        let mut by_pixels = ModeX::new(Recorder::default());
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut random = move |below: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 16) as usize % below
        };
        let (mut compared, mut overflowed) = (0, 0);
        let mut writes = Box::new(PageWrites::new());
        for round in 0..400 {
            drawn.fill(&mut frame[..], BACKGROUND);
            drawn.clear();
            let mut span = |y: usize, x0: usize, x1: usize, colour: u8| {
                frame[y * width + x0..y * width + x1].fill(colour);
                drawn.mark(y, x0..x1);
            };
            match round % 50 {
                // A blank frame: the last two are erased.
                7 => {}
                // Noise on most lines: more writes than the list holds.
                31 => {
                    for y in 20..220 {
                        for x in 0..width {
                            span(y, x, x + 1, 1 + random(5) as u8);
                        }
                    }
                }
                _ => {
                    // Solids' spans: a few shapes of spans, and stray pixels.
                    for _ in 0..1 + random(12) {
                        let (top, rows) = (random(240), 1 + random(60));
                        let (mut x0, mut x1) = (random(320), 0);
                        x1 = (x0 + random(90)).min(width).max(x1);
                        let colour = 1 + random(14) as u8;
                        for y in top..(top + rows).min(240) {
                            x0 = (x0 + random(5)).saturating_sub(2).min(width - 1);
                            x1 = (x1 + random(5)).saturating_sub(2).clamp(x0 + 1, width);
                            span(y, x0, x1, colour);
                        }
                    }
                    for _ in 0..random(30) {
                        let x = random(width);
                        span(random(240), x, x + 1, random(16) as u8);
                    }
                }
            }
            let page = round % 2;
            let mut compare = held[page].clone();
            compare.add(&drawn);
            let which = if page == 0 { Page::Zero } else { Page::One };
            by_spans.bus_mut().0.clear();
            by_pixels.bus_mut().0.clear();
            // One room for the writes, kept from frame to frame as the
            // renderer keeps it, through frames too large for it.
            let written =
                by_spans.update_page_with(which, &mut shadows[page], &frame, &compare, &mut writes);
            let expected =
                by_pixels.update_page(which, &mut full_shadows[page], &frame, &PageSpans::all());
            assert_eq!(by_spans.bus().0, by_pixels.bus().0, "round {round}");
            assert_eq!(written, expected, "round {round}");
            assert!(shadows[page][..] == frame[..], "round {round}");
            assert!(full_shadows[page][..] == frame[..], "round {round}");
            compared += usize::from(written > 0);
            overflowed += usize::from(written > WRITE_LIST_CAPACITY as u32);
            held[page].clone_from(&drawn);
        }
        assert!(compared > 350 && overflowed > 0, "{compared}, {overflowed}");
    }

    /// The writes for one address range found the plain way, a pixel at a
    /// time: what the word-at-a-time search must find, in the same order.
    fn writes_pixel_by_pixel(old: &[u8], new: &[u8], quads: Range<usize>) -> Vec<Write> {
        let quad = |line: &[u8], i: usize| {
            [
                line[4 * i],
                line[4 * i + 1],
                line[4 * i + 2],
                line[4 * i + 3],
            ]
        };
        let mut writes = Vec::new();
        let mut i = quads.start;
        while i < quads.end {
            let (o, n) = (quad(old, i), quad(new, i));
            if o == n {
                i += 1;
                continue;
            }
            let colour = n[0];
            let run = (i..quads.end)
                .take_while(|&j| {
                    quad(new, j) == [colour; 4] && quad(old, j).iter().all(|&p| p != colour)
                })
                .count();
            if run > 0 {
                writes.push(Write {
                    address: i as u16,
                    count: run as u16,
                    colour,
                    mask: PlaneMask::ALL,
                });
                i += run;
                continue;
            }
            let mut done = [false; 4];
            for p in 0..4 {
                if o[p] == n[p] || done[p] {
                    continue;
                }
                let mut planes = 0u8;
                for q in p..4 {
                    if o[q] != n[q] && n[q] == n[p] {
                        planes |= 1 << q;
                        done[q] = true;
                    }
                }
                writes.push(Write {
                    address: i as u16,
                    count: 1,
                    colour: n[p],
                    mask: PlaneMask::from_bits_truncate(planes),
                });
            }
            i += 1;
        }
        writes
    }

    /// The word-at-a-time search finds the writes of the pixel-by-pixel
    /// one, in the same order, over random lines and every shape of run:
    /// odd and even lengths, odd and even starts, the line's last address.
    #[test]
    fn the_word_search_finds_the_writes_of_the_pixel_by_pixel_search() {
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        let mut seed = 0x1234_5678u32;
        let mut random = move |below: u32| {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) % below
        };
        let mut line = LineWrites::new();
        let mut found = 0;
        for y in 0..SCREEN_HEIGHT as usize {
            // Few colours, so runs, repeats and unchanged pixels are common.
            for x in 0..320 {
                shadow[y * 320 + x] = random(3) as u8;
                target[y * 320 + x] = if random(4) == 0 {
                    random(3) as u8
                } else {
                    shadow[y * 320 + x]
                };
            }
            if y % 3 == 0 {
                // Solid stretches over changed pixels: fills.
                let (x0, len) = (random(300) as usize, random(20) as usize);
                target[y * 320 + x0..][..len].fill(7);
            }
            let start = random(80) as usize;
            let end = (start + random(12) as usize).min(80);
            let mut spans = PageSpans::none();
            spans.mark(y, 4 * start..4 * end);
            let (old, new) = (&shadow[y * 320..][..320], &target[y * 320..][..320]);
            let expected = writes_pixel_by_pixel(old, new, start..end);
            assert_eq!(
                line.find(&spans, &shadow, &target, y),
                &expected[..],
                "line {y}, {start}..{end}"
            );
            found += expected.len();
        }
        assert!(found > 500, "{found}");
    }

    /// A change in the last address of a run, which a 64-bit compare from
    /// the address before it (odd lengths) would have to reach past the run
    /// for, reaches the page: it is compared on its own.
    #[test]
    fn a_change_in_the_last_address_of_a_run_is_written() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        for (y, length) in (1..=9usize).enumerate() {
            for start in [0usize, 1, 80 - length] {
                let line = y * 10 + start % 2 + 2 * usize::from(start > 1);
                let spans = {
                    let mut spans = PageSpans::none();
                    spans.mark(line, 4 * start..4 * (start + length));
                    spans
                };
                // One pixel of the run's last address, plane 3.
                let pixel = line * 320 + 4 * (start + length - 1) + 3;
                target[pixel] = 9;
                assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target, &spans), 1);
                assert_eq!(
                    indices(vga.bus())[pixel],
                    9,
                    "{length} addresses from {start}"
                );
            }
        }
    }

    #[test]
    fn runs_are_the_marked_addresses_and_touching_spans_are_one_run() {
        let mut spans = PageSpans::none();
        assert_eq!(spans.runs(3).count(), 0);
        spans.mark(3, 5..9); // addresses 1 and 2
        spans.mark(3, 12..13); // 3: touches, one run
        spans.mark(3, 40..41);
        spans.mark(3, 316..400); // cut at the line's end
        spans.mark(3, 20..20); // empty
        spans.mark(240, 0..320); // no such line
        let runs: std::vec::Vec<_> = spans.runs(3).collect();
        assert_eq!(runs, [1..4, 10..11, 79..80]);
        let mut image = [7u8; PAGE_PIXELS];
        spans.fill(&mut image[..], 0);
        let cleared: std::vec::Vec<_> = (0..PAGE_PIXELS).filter(|&i| image[i] == 0).collect();
        let expected: std::vec::Vec<_> = [4..16, 40..44, 316..320]
            .into_iter()
            .flatten()
            .map(|x| 3 * 320 + x)
            .collect();
        assert_eq!(cleared, expected);
        let mut whole_line = PageSpans::all().runs(239);
        assert_eq!(whole_line.next(), Some(0..80));
        assert_eq!(whole_line.next(), None);
    }
}
