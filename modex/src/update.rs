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
use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};
use core::ops::Range;

/// Pixels in a page: one byte each in a RAM image of it.
pub const PAGE_PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;

/// A page's picture in RAM: row-major colour indices.
pub type PageImage = [u8; PAGE_PIXELS];

impl<B: VgaBus> ModeX<B> {
    /// Makes `page` show `target`, given that it shows `shadow` now; only
    /// changed pixels are written, and `shadow` becomes `target`. Returns the
    /// number of video-memory bytes written.
    ///
    /// Writes to different addresses are independent, so they are grouped by
    /// Map Mask: one pass per distinct mask the frame needs, each setting the
    /// Map Mask once and then writing every address that needs it. The port
    /// writes are then the number of distinct masks, not one per change of
    /// mask between neighbouring addresses. To find the addresses of a mask
    /// without a list of them, each line keeps the set of masks it needs, and
    /// a pass visits only the lines that need its mask.
    pub fn update_page(&mut self, page: Page, shadow: &mut PageImage, target: &PageImage) -> u32 {
        self.issued_by("ModeX::update_page", |vga| {
            let width = SCREEN_WIDTH as usize;
            // Each line's changed bytes, found eight at a time: the rest of the
            // work is bounded by what changed, not by the screen.
            let mut changed: [Option<Range<usize>>; SCREEN_HEIGHT as usize] =
                [const { None }; SCREEN_HEIGHT as usize];
            for (y, range) in changed.iter_mut().enumerate() {
                *range =
                    changed_bytes(&shadow[y * width..][..width], &target[y * width..][..width]);
            }
            let mut writes = Writes::new();
            let written = if writes.collect(&changed, shadow, target) {
                vga.write_by_mask(page, &writes)
            } else {
                // More writes than the list holds (a whole new picture): the
                // same writes in the same order, found again for each mask.
                vga.write_by_passes(page, &changed, shadow, target)
            };
            for (y, range) in changed.iter().enumerate() {
                if let Some(range) = range {
                    let line = y * width;
                    shadow[line + range.start..line + range.end]
                        .copy_from_slice(&target[line + range.start..line + range.end]);
                }
            }
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
        changed: &[Option<Range<usize>>],
        shadow: &PageImage,
        target: &PageImage,
    ) -> u32 {
        let width = SCREEN_WIDTH as usize;
        let mut line_masks = [0u16; SCREEN_HEIGHT as usize];
        let mut frame_masks = 0u16;
        for (y, range) in changed.iter().enumerate() {
            let Some(range) = range else { continue };
            let (old_line, new_line) =
                (&shadow[y * width..][..width], &target[y * width..][..width]);
            each_write(old_line, new_line, quads(range), |write| {
                line_masks[y] |= mask_bit(write.mask);
            });
            frame_masks |= line_masks[y];
        }
        let mut written = 0;
        for mask in self.mask_order(frame_masks) {
            self.io.set_map_mask(mask);
            for (y, range) in changed.iter().enumerate() {
                let Some(range) = range
                    .as_ref()
                    .filter(|_| line_masks[y] & mask_bit(mask) != 0)
                else {
                    continue;
                };
                let (old_line, new_line) =
                    (&shadow[y * width..][..width], &target[y * width..][..width]);
                let line_base = page.base() + y as u16 * BYTES_PER_LINE;
                each_write(old_line, new_line, quads(range), |write| {
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

    /// Collects every write the changed lines need; false if there are more
    /// than the list holds (what was collected is then of no use).
    fn collect(
        &mut self,
        changed: &[Option<Range<usize>>],
        shadow: &PageImage,
        target: &PageImage,
    ) -> bool {
        let width = SCREEN_WIDTH as usize;
        let mut overflow = false;
        for (y, range) in changed.iter().enumerate() {
            let Some(range) = range else { continue };
            let (old_line, new_line) =
                (&shadow[y * width..][..width], &target[y * width..][..width]);
            let line_base = y as u16 * BYTES_PER_LINE;
            each_write(old_line, new_line, quads(range), |write| {
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

/// The byte addresses (quads of four pixels) that hold the changed bytes.
fn quads(bytes: &Range<usize>) -> Range<usize> {
    bytes.start / 4..bytes.end.div_ceil(4)
}

/// The bytes from the first that differs to the last that differs, compared
/// eight at a time; `None` if the lines are equal.
fn changed_bytes(old: &[u8], new: &[u8]) -> Option<Range<usize>> {
    const WORD: usize = 8;
    let differs = |i: usize| {
        let a = u64::from_ne_bytes(old[i * WORD..][..WORD].try_into().unwrap_or_default());
        let b = u64::from_ne_bytes(new[i * WORD..][..WORD].try_into().unwrap_or_default());
        a != b
    };
    let words = old.len().min(new.len()) / WORD;
    let first = (0..words).find(|&i| differs(i))?;
    let last = (first..words).rev().find(|&i| differs(i)).unwrap_or(first);
    let (start, end) = (first * WORD, (last + 1) * WORD);
    // Narrow to the exact bytes within the first and last words.
    let start = (start..end).find(|&i| old[i] != new[i]).unwrap_or(start);
    let end = (start..end)
        .rev()
        .find(|&i| old[i] != new[i])
        .map_or(end, |i| i + 1);
    Some(start..end)
}

/// Calls `write` for each write that brings `old_line` to `new_line` at the
/// addresses in `quads`, in address order, addresses relative to the line:
/// a run of addresses whose four pixels all become one colour is one write
/// with all planes (a fill); any other changed address gets one write per
/// distinct new colour among its changed pixels.
fn each_write(old_line: &[u8], new_line: &[u8], quads: Range<usize>, mut write: impl FnMut(Write)) {
    let mut i = quads.start;
    while i < quads.end {
        // Most addresses inside a changed range keep their pixels: one
        // compare, and on. (An unchanged address never starts a run.)
        if quad(old_line, i) == quad(new_line, i) {
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
            let written = vga.update_page(Page::Zero, &mut shadow, &target);
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
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target), 0);
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
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target), 2);
        target[..4].copy_from_slice(&[5, 7, 7, 7]);
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target), 1);
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
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target), 8000);
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
            let width = SCREEN_WIDTH as usize;
            let changed: std::vec::Vec<_> = (0..SCREEN_HEIGHT as usize)
                .map(|y| {
                    changed_bytes(&shadow[y * width..][..width], &target[y * width..][..width])
                })
                .collect();
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
            vga.update_page(Page::One, &mut shadow, &target);
            assert!(shadow[..] == target[..], "round {round}");
        }
    }

    #[test]
    fn changed_bytes_are_found_exactly() {
        let old = [0u8; 320];
        assert_eq!(changed_bytes(&old, &old), None);
        for (first, last) in [(0, 0), (7, 8), (9, 9), (3, 318), (319, 319), (100, 163)] {
            let mut new = old;
            new[first] = 1;
            new[last] = 2;
            assert_eq!(
                changed_bytes(&old, &new),
                Some(first..last + 1),
                "{first}..={last}"
            );
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
        let width = SCREEN_WIDTH as usize;
        let changed: std::vec::Vec<_> = (0..SCREEN_HEIGHT as usize)
            .map(|y| changed_bytes(&shadow[y * width..][..width], &target[y * width..][..width]))
            .collect();
        assert!(!Writes::new().collect(&changed, &shadow, &target));
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target), 38_400);
        assert_eq!(indices(vga.bus()), target.to_vec());
        assert!(shadow[..] == target[..]);
    }
}
