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
        self.issued_by("ModeX::update_page", |vga| {
            let mut writes = Writes::new();
            let written = if writes.collect(spans, shadow, target) {
                vga.write_by_mask(page, &writes)
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
    fn write_by_mask(&mut self, page: Page, writes: &Writes) -> u32 {
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
        let mut line_masks = [0u16; SCREEN_HEIGHT as usize];
        let mut frame_masks = 0u16;
        for (y, masks) in line_masks.iter_mut().enumerate() {
            each_write_on_line(spans, shadow, target, y, &mut |write| {
                *masks |= mask_bit(write.mask);
            });
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
                each_write_on_line(spans, shadow, target, y, &mut |write| {
                    if write.mask != mask {
                        return;
                    }
                    if write.count == 1 {
                        self.io.write_vram8(line_base + write.address, write.colour);
                    } else {
                        self.io
                            .fill_vram(line_base + write.address, write.count, write.colour);
                    }
                    written += u32::from(write.count);
                });
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
/// 5,000), 128 KiB of stack with the links.
const WRITE_LIST_CAPACITY: usize = 16_384;
/// The end of a mask's chain of writes.
const NO_WRITE: u16 = u16::MAX;
const _: () = assert!(WRITE_LIST_CAPACITY < NO_WRITE as usize);

/// A frame's writes in the order they are found (line by line, address by
/// address), each mask's chained in that order, and the set of masks among
/// them: making them mask by mask is then one step per write, not one pass
/// over the whole list per mask.
struct Writes {
    list: [Write; WRITE_LIST_CAPACITY],
    /// For each write, the next with the same mask, or `NO_WRITE`.
    next_with_mask: [u16; WRITE_LIST_CAPACITY],
    /// Each mask's first and last write, or `NO_WRITE`.
    first_with_mask: [u16; 16],
    last_with_mask: [u16; 16],
    len: usize,
    masks: u16,
}

impl Writes {
    fn new() -> Self {
        Writes {
            list: [Write::default(); WRITE_LIST_CAPACITY],
            next_with_mask: [NO_WRITE; WRITE_LIST_CAPACITY],
            first_with_mask: [NO_WRITE; 16],
            last_with_mask: [NO_WRITE; 16],
            len: 0,
            masks: 0,
        }
    }

    /// Collects every write the marked addresses need; false if there are
    /// more than the list holds (what was collected is then of no use).
    fn collect(&mut self, spans: &PageSpans, shadow: &PageImage, target: &PageImage) -> bool {
        let mut overflow = false;
        for y in 0..SCREEN_HEIGHT as usize {
            let line_base = y as u16 * BYTES_PER_LINE;
            each_write_on_line(spans, shadow, target, y, &mut |write| {
                if overflow
                    || !self.push(Write {
                        address: line_base + write.address,
                        ..write
                    })
                {
                    overflow = true;
                }
            });
            if overflow {
                return false;
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
        let mut next = self.first_with_mask[usize::from(mask.bits())];
        core::iter::from_fn(move || {
            let write = self.list.get(usize::from(next))?;
            next = self.next_with_mask[usize::from(next)];
            Some(write)
        })
    }
}

/// Calls `write` for each write line `y` needs, over the addresses
/// `spans` marks on it, in address order (addresses relative to the line).
/// One indirect call a write keeps the search compiled once, not once for
/// each bus and caller.
fn each_write_on_line(
    spans: &PageSpans,
    shadow: &PageImage,
    target: &PageImage,
    y: usize,
    write: &mut dyn FnMut(Write),
) {
    let width = SCREEN_WIDTH as usize;
    let (old_line, new_line) = (&shadow[y * width..][..width], &target[y * width..][..width]);
    for run in spans.runs(y) {
        each_write(old_line, new_line, run, write);
    }
}

/// Calls `write` for each write that brings `old_line` to `new_line` at the
/// addresses in `quads`, in address order, addresses relative to the line:
/// a run of addresses whose four pixels all become one colour is one write
/// with all planes (a fill); any other changed address gets one write per
/// distinct new colour among its changed pixels.
fn each_write(old_line: &[u8], new_line: &[u8], quads: Range<usize>, write: &mut dyn FnMut(Write)) {
    let mut i = quads.start;
    while i < quads.end {
        // Most addresses inside a changed range keep their pixels: one
        // compare, and on. (An unchanged address never starts a run.)
        if quad_bits(old_line, i) == quad_bits(new_line, i) {
            i += 1;
            continue;
        }
        let run = solid_run(old_line, new_line, i, quads.end);
        if run > 0 {
            write(Write {
                address: i as u16,
                count: run as u16,
                colour: new_line[4 * i],
                mask: PlaneMask::ALL,
            });
            i += run;
            continue;
        }
        let (old, new) = (quad(old_line, i), quad(new_line, i));
        if old != new {
            for (planes, colour) in address_writes(old, new) {
                write(Write {
                    address: i as u16,
                    count: 1,
                    colour,
                    mask: planes,
                });
            }
        }
        i += 1;
    }
}

/// The writes that bring one address from `old` to `new`: one per distinct
/// new colour among the changed pixels, as (planes, colour).
fn address_writes(old: [u8; 4], new: [u8; 4]) -> impl Iterator<Item = (PlaneMask, u8)> {
    let mut pending = (0..4)
        .filter(|&p| old[p] != new[p])
        .fold(0u8, |mask, p| mask | 1 << p);
    core::iter::from_fn(move || {
        if pending == 0 {
            return None;
        }
        let colour = new[pending.trailing_zeros() as usize];
        let planes = (0..4)
            .filter(|&p| pending & 1 << p != 0 && new[p] == colour)
            .fold(0u8, |m, p| m | 1 << p);
        pending &= !planes;
        Some((PlaneMask::from_bits_truncate(planes), colour))
    })
}

/// A mask's bit in a set of masks (one bit per mask value, 0 to 15).
fn mask_bit(planes: PlaneMask) -> u16 {
    1 << planes.bits()
}

/// The four pixels at `address` as one word: one load and one compare.
fn quad_bits(line: &[u8], address: usize) -> u32 {
    line.get(4 * address..4 * address + 4)
        .and_then(|quad| quad.try_into().ok())
        .map_or(0, u32::from_ne_bytes)
}

fn quad(line: &[u8], address: usize) -> [u8; 4] {
    [
        line[4 * address],
        line[4 * address + 1],
        line[4 * address + 2],
        line[4 * address + 3],
    ]
}

/// How many addresses from `start` on (before `end`) have all four pixels
/// changing to one and the same colour (0 if the first does not).
fn solid_run(old_line: &[u8], new_line: &[u8], start: usize, end: usize) -> usize {
    let colour = new_line[4 * start];
    (start..end)
        .take_while(|&i| {
            let (old, new) = (quad(old_line, i), quad(new_line, i));
            new == [colour; 4] && old.iter().all(|&o| o != colour)
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::regs::Port;
    use crate::soft::SoftVga;
    use std::boxed::Box;
    use std::vec;

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

    /// Every bus operation, in order.
    #[derive(Default)]
    struct Recorder(std::vec::Vec<(char, u16, u16)>);

    impl VgaBus for Recorder {
        fn write_port8(&mut self, port: Port, value: u8) {
            self.0.push(('o', port.number(), u16::from(value)));
        }
        fn write_port16(&mut self, port: Port, value: u16) {
            self.0.push(('w', port.number(), value));
        }
        fn read_port8(&mut self, _port: Port) -> u8 {
            0
        }
        fn write_vram8(&mut self, offset: u16, value: u8) {
            self.0.push(('m', offset, u16::from(value)));
        }
        fn read_vram8(&mut self, _offset: u16) -> u8 {
            0
        }
        fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
            self.0.push(('f', offset, count << 8 | u16::from(value)));
        }
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
            let mut writes = Box::new(Writes::new());
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
        assert!(!Writes::new().collect(&changed, &shadow, &target));
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
            let written = by_spans.update_page(which, &mut shadows[page], &frame, &compare);
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
