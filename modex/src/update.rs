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
use crate::spans::{PageSpans, GROUP_PIXELS};
use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Pixels in a page: one byte each in a RAM image of it.
pub const PAGE_PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;

/// A page's picture in RAM: row-major colour indices.
pub type PageImage = [u8; PAGE_PIXELS];

const WIDTH: usize = SCREEN_WIDTH as usize;
const LINES: usize = SCREEN_HEIGHT as usize;
/// The groups of four addresses (sixteen pixels) of a line.
const GROUPS: usize = WIDTH / GROUP_PIXELS;

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
    /// the caller: a renderer that keeps one saves clearing 160 KiB every
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
            // The lines collected are already shadowed; the rest of a frame
            // of more writes than the list holds (a whole new picture) is
            // found again for each mask, then copied.
            let collected = writes.collect(spans, shadow, target);
            let written = vga.write_by_mask(page, writes, collected, spans, shadow, target);
            spans.copy(collected..LINES, target, shadow);
            written
        })
    }

    /// Writes the whole of `image` into `page`, whatever it held: one pass
    /// per plane, every address written. For a picture with no shadow to
    /// compare with (the report screen on the spare page); 76,800 writes.
    pub fn write_page(&mut self, page: Page, image: &PageImage) {
        self.issued_by("ModeX::write_page", |vga| {
            for plane in 0..4u8 {
                vga.io.set_map_mask(PlaneMask::plane(plane));
                for y in 0..LINES {
                    let line = &image[y * WIDTH..][..WIDTH];
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

    /// Makes the frame's writes mask by mask. For each mask: first the
    /// listed writes with it, in the order they were found, following the
    /// list's links; then, if the list holds only the lines before
    /// `listed_lines`, those of the lines from there on, found again line by
    /// line (visiting only the lines that need the mask) from the `shadow`
    /// they have not yet been copied into.
    fn write_by_mask(
        &mut self,
        page: Page,
        listed: &PageWrites,
        listed_lines: usize,
        spans: &PageSpans,
        shadow: &mut PageImage,
        target: &PageImage,
    ) -> u32 {
        let mut rest = (listed_lines < LINES).then(|| LineWrites::masks_from(listed_lines));
        let mut frame_masks = listed.masks();
        if let Some(rest) = &mut rest {
            frame_masks |= rest.find_masks(spans, shadow, target);
        }
        let mut written = 0;
        for mask in self.mask_order(frame_masks) {
            self.io.set_map_mask(mask);
            for write in listed.with_mask(mask) {
                written += self.make(page.base(), &write);
            }
            let Some(rest) = &mut rest else { continue };
            for y in listed_lines..LINES {
                if rest.line_masks[y] & mask_bit(mask) == 0 {
                    continue;
                }
                for write in rest.find(spans, shadow, target, y) {
                    if write.mask == mask {
                        written += self.make(page.base(), write);
                    }
                }
            }
        }
        written
    }

    /// One write, its address from `base`, with its mask already set;
    /// returns the bytes written.
    fn make(&mut self, base: u16, write: &Write) -> u32 {
        if write.count == 1 {
            self.io.write_vram8(base + write.address, write.colour);
        } else {
            self.io
                .fill_vram(base + write.address, write.count, write.colour);
        }
        u32::from(write.count)
    }
}

/// One write of the page update: `count` addresses from `address` (from the
/// page's first), each given `colour` through Map Mask `mask`. A count above
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
/// again mask by mask: more than a spinning scene needs (the crowd of 59
/// solids averages 3,600; a screen-filling grid of 256 turning solids about
/// 5,000). Each mask's list has room for all of them, 512 KiB in a
/// [`PageWrites`].
const WRITE_LIST_CAPACITY: usize = 8_192;
/// The most writes one line can need: one per pixel (an address's four
/// pixels take at most four writes).
const LINE_WRITE_CAPACITY: usize = WIDTH;

/// Where the search puts the writes it finds: the frame's list
/// ([`PageWrites`]) or one line's ([`LineWrites`]).
trait WriteSink {
    /// Whether the search brings the shadow line it compares up to the new
    /// one as it goes, at each changed address: the frame's list, which
    /// finds each write once, does; a line's, found again for each mask,
    /// must not.
    const SHADOWS: bool;
    fn push(&mut self, write: Write);
}

/// One write of a mask's list in [`PageWrites`]: a [`Write`] less the mask
/// its list is for, four bytes. (A count is at most a line's 80 addresses.)
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct Listed {
    address: u16,
    count: u8,
    colour: u8,
}

/// Room for a frame's writes, each mask's in a list of its own in the order
/// they are found (line by line, address by address): making them mask by
/// mask is then a walk along each list, and listing one is a store and a
/// count. All zero when new, so a renderer in static memory keeps one in
/// `.bss`; each update starts it afresh by zeroing the counts, not the
/// 512 KiB.
pub struct PageWrites {
    /// Mask m's writes in list m (list 0, no planes, stays empty).
    lists: [[Listed; WRITE_LIST_CAPACITY]; 16],
    /// How many writes each mask's list holds.
    counts: [u16; 16],
    /// How many writes all the lists hold.
    len: usize,
}

/// Not the writes.
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
            lists: [[Listed {
                address: 0,
                count: 0,
                colour: 0,
            }; WRITE_LIST_CAPACITY]; 16],
            counts: [0; 16],
            len: 0,
        }
    }

    /// Collects the writes the marked addresses need, line by line from the
    /// first, straight into the list, and brings `shadow` up to `target` at
    /// every line collected. Returns the first line not collected: all
    /// (`SCREEN_HEIGHT`) unless one more line's writes might not have fitted.
    fn collect(&mut self, spans: &PageSpans, shadow: &mut PageImage, target: &PageImage) -> usize {
        self.counts = [0; 16];
        self.len = 0;
        for y in 0..LINES {
            let marked = spans.marked(y);
            if marked == 0 {
                continue;
            }
            if self.len + LINE_WRITE_CAPACITY > WRITE_LIST_CAPACITY {
                return y;
            }
            find_line_writes(self, y, marked, shadow, target);
        }
        LINES
    }

    /// The masks of the writes listed, one bit each.
    fn masks(&self) -> u16 {
        (0..16)
            .filter(|&mask| self.counts[mask] > 0)
            .fold(0, |masks, mask| masks | 1 << mask)
    }

    /// The writes with `mask`, in the order they were found.
    fn with_mask(&self, mask: PlaneMask) -> impl Iterator<Item = Write> + '_ {
        let mask_index = usize::from(mask.bits()) & 15;
        let count = usize::from(self.counts[mask_index]);
        let listed = self.lists[mask_index].get(..count).unwrap_or_default();
        listed.iter().map(move |listed| Write {
            address: listed.address,
            count: u16::from(listed.count),
            colour: listed.colour,
            mask,
        })
    }
}

impl WriteSink for PageWrites {
    const SHADOWS: bool = true;

    /// Appends `write` to its mask's list. `collect` starts a line only
    /// with room for all its writes, so none is ever dropped here (and none
    /// could be written out of bounds).
    fn push(&mut self, write: Write) {
        let mask = usize::from(write.mask.bits()) & 15;
        let count = self.counts[mask];
        if let Some(slot) = self.lists[mask].get_mut(usize::from(count)) {
            *slot = Listed {
                address: write.address,
                count: write.count as u8,
                colour: write.colour,
            };
            self.counts[mask] = count + 1;
            self.len += 1;
        }
    }
}

/// The writes of the lines a frame's list had no room for, found again
/// line by line into a buffer reused line after line, and which masks each
/// of those lines needs.
struct LineWrites {
    list: [Write; LINE_WRITE_CAPACITY],
    len: usize,
    first_line: usize,
    line_masks: [u16; LINES],
}

impl LineWrites {
    fn masks_from(first_line: usize) -> Self {
        LineWrites {
            list: [Write::default(); LINE_WRITE_CAPACITY],
            len: 0,
            first_line,
            line_masks: [0; LINES],
        }
    }

    /// Finds which masks each line from the first needs; returns them all.
    fn find_masks(&mut self, spans: &PageSpans, shadow: &mut PageImage, target: &PageImage) -> u16 {
        let mut all = 0;
        for y in self.first_line..LINES {
            let masks = self
                .find(spans, shadow, target, y)
                .iter()
                .fold(0, |masks, write| masks | mask_bit(write.mask));
            self.line_masks[y] = masks;
            all |= masks;
        }
        all
    }

    /// The writes line `y` needs, in address order, addresses from the
    /// page's first; `shadow` is read, not changed.
    fn find(
        &mut self,
        spans: &PageSpans,
        shadow: &mut PageImage,
        target: &PageImage,
        y: usize,
    ) -> &[Write] {
        self.len = 0;
        find_line_writes(self, y, spans.marked(y), shadow, target);
        &self.list[..self.len]
    }
}

impl WriteSink for LineWrites {
    const SHADOWS: bool = false;

    fn push(&mut self, write: Write) {
        // At most one write a pixel, so the list never fills; were it ever
        // to, the extra write would be dropped, never written out of bounds.
        if let Some(slot) = self.list.get_mut(self.len) {
            *slot = write;
            self.len += 1;
        }
    }
}

/// Finds the writes that bring line `y` of the page image `old` to `new`
/// within the groups `marked` sets (bit i for the line's pixels 16i to
/// 16i + 15, its addresses 4i to 4i + 3), in address order, and gives them
/// to `sink`, their addresses from the page's first: a run of addresses
/// whose four pixels all become one colour is one write with all planes (a
/// fill); any other changed address gets one write per distinct new colour
/// among its changed pixels. With [`WriteSink::SHADOWS`], `old` takes each
/// group's new pixels once its writes are found.
///
/// A marked group whose pixels all agree costs one 16-byte compare and a
/// step to the next. Of a group that differs, the changed pixels of all
/// four addresses are found at once, and only its addresses with some are
/// visited. A fill goes on through the run of marked groups it starts in,
/// never past it, so never past the line's end.
fn find_line_writes<S: WriteSink>(
    sink: &mut S,
    y: usize,
    marked: u32,
    old: &mut PageImage,
    new: &PageImage,
) {
    // The line's first group in the page: a line is twenty groups, so a
    // group's pixels start at 16 times its number in the page image, and
    // its addresses at 4 times it in the page.
    let line_group = y * GROUPS;
    let mut runs = marked;
    // The group a fill ended inside, and its addresses the fill did not
    // write: the only ones of it still to search. (A search that shadows
    // finds the others unchanged by then.)
    let (mut after_fill_group, mut after_fill) = (usize::MAX, 0xF);
    while runs != 0 {
        // The lowest run of marked groups: adding its lowest bit carries
        // through it and stops on the bit past it (at most 20 bits are
        // set, so the sum fits).
        let mut group = line_group + runs.trailing_zeros() as usize;
        let past = runs + runs.isolate_lowest_one();
        runs &= past;
        let end = line_group + (past.trailing_zeros() as usize).min(GROUPS);
        'run: while group < end {
            let this = group;
            group += 1;
            let mut changed = differing_pixels(old, new, this);
            if changed == 0 {
                continue;
            }
            if !S::SHADOWS && this == after_fill_group {
                // Four bits an address: its pixels (planes) that change.
                changed &= ALL_PLANES_OF[after_fill];
            }
            while changed != 0 {
                let slot = changed.trailing_zeros() / 4;
                let mut planes_left = (changed >> (4 * slot)) as u8 & 0x0F;
                changed &= !(0x0F << (4 * slot));
                let address = 4 * this + slot as usize;
                let new_quad = quad(new, address);
                if planes_left == 0x0F && new_quad == splat(new_quad as u8) {
                    let fill_end = solid_run_end(old, new, 4 * end, address);
                    sink.push(Write {
                        address: address as u16,
                        count: (fill_end - address) as u16,
                        colour: new_quad as u8,
                        mask: PlaneMask::ALL,
                    });
                    if S::SHADOWS {
                        // The group's addresses before the fill, and the fill.
                        let pixels = GROUP_PIXELS * this..4 * fill_end;
                        if let (Some(old), Some(new)) =
                            (old.get_mut(pixels.clone()), new.get(pixels))
                        {
                            old.copy_from_slice(new);
                        }
                    }
                    // Go on after the fill: in the group it ends in, from
                    // its end.
                    group = fill_end / 4;
                    if !S::SHADOWS {
                        (after_fill_group, after_fill) = (group, 0xF << (fill_end % 4) & 0xF);
                    }
                    continue 'run;
                }
                while planes_left != 0 {
                    // The first changed pixel's colour, and every changed
                    // pixel of that colour: one write.
                    let colour = (new_quad >> (8 * planes_left.trailing_zeros())) as u8;
                    let planes = match planes_left.is_power_of_two() {
                        true => planes_left,
                        false => planes_left & !differing_bytes(new_quad, splat(colour)),
                    };
                    planes_left &= !planes;
                    sink.push(Write {
                        address: address as u16,
                        count: 1,
                        colour,
                        mask: PlaneMask::from_bits_truncate(planes),
                    });
                }
            }
            if S::SHADOWS {
                // Every changed address of the group is written: the shadow
                // takes the whole group at once.
                if let (Some(old), Some(new)) = (
                    old.as_chunks_mut::<GROUP_PIXELS>().0.get_mut(this),
                    new.as_chunks::<GROUP_PIXELS>().0.get(this),
                ) {
                    *old = *new;
                }
            }
        }
    }
}

/// Which of the sixteen pixels of group `group` (addresses `4 * group` to
/// `4 * group + 3`) differ between the lines: bit 4j + p for address
/// `4 * group + j`, plane p (one 16-byte compare where the target has one).
fn differing_pixels(old: &[u8], new: &[u8], group: usize) -> u32 {
    let (Some(old), Some(new)) = (
        old.as_chunks::<GROUP_PIXELS>().0.get(group),
        new.as_chunks::<GROUP_PIXELS>().0.get(group),
    ) else {
        return 0;
    };
    let differ: [bool; 16] = core::array::from_fn(|i| old[i] != new[i]);
    differ
        .iter()
        .enumerate()
        .fold(0, |bits, (i, &differs)| bits | u32::from(differs) << i)
}

/// For each set of the four addresses of a group (bit j for address j), all
/// four planes of each (bits 4j to 4j + 3).
const ALL_PLANES_OF: [u32; 16] = {
    let mut table = [0; 16];
    let mut addresses = 0;
    while addresses < 16 {
        let mut j = 0;
        while j < 4 {
            if addresses & 1 << j != 0 {
                table[addresses] |= 0xF << (4 * j);
            }
            j += 1;
        }
        addresses += 1;
    }
    table
};

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

/// The end of the run of addresses from `start` (which starts one) whose
/// four pixels all change to one and the same colour, the new colour at
/// `start`: it goes on up to, not including, address `run_end` at most.
fn solid_run_end(old: &[u8], new: &[u8], run_end: usize, start: usize) -> usize {
    let colour = quad(new, start);
    let mut end = start + 1;
    while end < run_end
        && quad(new, end) == colour
        && differing_bytes(quad(old, end), colour) == 0x0F
    {
        end += 1;
    }
    end
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{Operation, Recorder};
    use crate::soft::SoftVga;
    use crate::tests::xorshift;
    use core::ops::Range;
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
            let (mut listed_shadow, mut passes_shadow) = (shadow.clone(), shadow.clone());
            assert_eq!(
                writes.collect(&changed, &mut listed_shadow, &target),
                LINES,
                "a small change fits"
            );
            let mut by_list = ModeX::new(Recorder::default());
            by_list.write_by_mask(
                Page::One,
                &writes,
                LINES,
                &changed,
                &mut listed_shadow,
                &target,
            );
            let mut by_passes = ModeX::new(Recorder::default());
            let no_writes = Box::new(PageWrites::new());
            by_passes.write_by_mask(
                Page::One,
                &no_writes,
                0,
                &changed,
                &mut passes_shadow,
                &target,
            );
            assert!(listed_shadow[..] == target[..], "round {round}");
            assert!(passes_shadow[..] == shadow[..], "round {round}");
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
        assert!(PageWrites::new().collect(&changed, &mut shadow.clone(), &target) < LINES);
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
        let mut random = xorshift(0x2545_f491_4f6c_dd1du64);
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
    /// The runs of addresses line `y` has marked: its marked groups'.
    fn marked_addresses(spans: &PageSpans, y: usize) -> impl Iterator<Item = Range<usize>> + '_ {
        spans.runs(y).map(|pixels| pixels.start / 4..pixels.end / 4)
    }

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

    /// The search by groups of sixteen pixels finds the writes of the
    /// pixel-by-pixel one, in the same order, over random lines and every
    /// shape of marked span: odd and even lengths, odd and even starts, the
    /// line's last address.
    #[test]
    fn the_group_search_finds_the_writes_of_the_pixel_by_pixel_search() {
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        let mut seed = 0x1234_5678u32;
        let mut random = move |below: u32| {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) % below
        };
        let mut line = Box::new(LineWrites::masks_from(0));
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
            // Addresses from the page's first, as the search gives them.
            let line_base = y as u16 * BYTES_PER_LINE;
            let expected: Vec<Write> = marked_addresses(&spans, y)
                .flat_map(|run| writes_pixel_by_pixel(old, new, run))
                .map(|write| Write {
                    address: line_base + write.address,
                    ..write
                })
                .collect();
            assert_eq!(
                line.find(&spans, &mut shadow, &target, y),
                &expected[..],
                "line {y}, {start}..{end}"
            );
            found += expected.len();
        }
        assert!(found > 500, "{found}");
    }

    /// The page update makes the writes the pixel-by-pixel search finds
    /// over each marked run, grouped by mask, each mask's in address order:
    /// over random lines with several runs of marks, fills that start in a
    /// four two runs share and reach into the second, and frames of more
    /// writes than the list holds, whose lines past the list's are found
    /// again mask by mask. Marked pixels end up shadowed, no others.
    #[test]
    fn the_page_update_makes_the_pixel_by_pixel_writes_grouped_by_mask() {
        let mut random = xorshift(0x9E37_79B9_7F4A_7C15u64);
        let mut writes = Box::new(PageWrites::new());
        let (mut listed, mut overflowed, mut fills) = (0, 0, 0);
        for round in 0..48 {
            let mut shadow = Box::new([0u8; PAGE_PIXELS]);
            let mut target = Box::new([0u8; PAGE_PIXELS]);
            let mut spans = Box::new(PageSpans::none());
            let noise = round % 4 == 3;
            for y in 0..LINES {
                let line = y * WIDTH;
                for x in 0..WIDTH {
                    shadow[line + x] = random(3) as u8;
                    target[line + x] = match noise || random(4) == 0 {
                        true => random(5) as u8,
                        false => shadow[line + x],
                    };
                }
                for _ in 0..random(4) {
                    // Solid stretches over changed pixels: fills.
                    let (x0, length) = (random(WIDTH), 4 + random(40));
                    target[line + x0..line + (x0 + length).min(WIDTH)].fill(7);
                }
                for _ in 0..random(6) + 8 * usize::from(noise) {
                    // Runs of marks with gaps, some of one or two addresses.
                    let x0 = random(WIDTH);
                    spans.mark(y, x0..x0 + 1 + random(48));
                }
            }
            let mut found = Vec::new();
            for y in 0..LINES {
                let (old, new) = (&shadow[y * WIDTH..][..WIDTH], &target[y * WIDTH..][..WIDTH]);
                for run in marked_addresses(&spans, y) {
                    for write in writes_pixel_by_pixel(old, new, run) {
                        let address = y as u16 * BYTES_PER_LINE + write.address;
                        found.push(Write { address, ..write });
                    }
                }
            }
            let mut expected = ModeX::new(Recorder::default());
            for mask in (1..16).map(PlaneMask::from_bits_truncate) {
                if found.iter().any(|write| write.mask == mask) {
                    expected.io.set_map_mask(mask);
                    for write in found.iter().filter(|write| write.mask == mask) {
                        expected.make(Page::One.base(), write);
                    }
                }
            }
            let before = shadow.clone();
            let mut vga = ModeX::new(Recorder::default());
            vga.update_page_with(Page::One, &mut shadow, &target, &spans, &mut writes);
            assert_eq!(vga.bus().0, expected.bus().0, "round {round}");
            for y in 0..LINES {
                let marked = spans.marked(y);
                for x in 0..WIDTH {
                    let pixel = y * WIDTH + x;
                    let wanted = match marked >> (x / GROUP_PIXELS) & 1 != 0 {
                        true => target[pixel],
                        false => before[pixel],
                    };
                    assert_eq!(shadow[pixel], wanted, "round {round}, line {y}, x {x}");
                }
            }
            listed += usize::from(found.len() <= WRITE_LIST_CAPACITY - LINE_WRITE_CAPACITY);
            overflowed += usize::from(found.len() > WRITE_LIST_CAPACITY);
            fills += found.iter().filter(|write| write.count > 1).count();
        }
        assert!(listed > 30 && overflowed >= 12, "{listed}, {overflowed}");
        assert!(fills > 2_000, "{fills}");
    }

    /// A fill across the groups of a run of marks is one write, the
    /// changes on both sides of it are found, in order, and nothing past
    /// the run's ends is: a solid stretch that goes on past the run is cut
    /// at its end. Runs of one group and runs to the line's end are tried
    /// too.
    #[test]
    fn a_fill_crosses_the_groups_of_its_run_and_stops_at_its_end() {
        let mut line = LineWrites::masks_from(0);
        for (run, fill) in [
            (56..72, 60..70),
            (60..64, 61..64),
            (64..68, 64..66),
            (40..80, 62..80),
            (56..64, 60..70),
        ] {
            let mut shadow = Box::new([0u8; PAGE_PIXELS]);
            let mut target = Box::new([0u8; PAGE_PIXELS]);
            // Every address changes, outside the fill one plane of each.
            for address in 0..80 {
                target[4 * address + address % 4] = 3;
            }
            target[4 * fill.start..4 * fill.end].fill(5);
            let mut spans = PageSpans::none();
            spans.mark(0, 4 * run.start..4 * run.end);
            let expected = writes_pixel_by_pixel(&shadow[..320], &target[..320], run.clone());
            let filled = fill.start.max(run.start)..fill.end.min(run.end);
            assert!(expected
                .iter()
                .any(|write| write.count as usize == filled.len()));
            assert_eq!(
                line.find(&spans, &mut shadow, &target, 0),
                &expected[..],
                "{run:?}"
            );
        }
    }

    /// The page's groups run on from line to line, as video memory does,
    /// but a fill does not: a solid stretch from the end of one marked line
    /// into the start of the next is two fills, one a line, as the
    /// pixel-by-pixel search finds them, and both reach the page.
    #[test]
    fn a_fill_stops_at_the_end_of_its_line() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadow = Box::new([0u8; PAGE_PIXELS]);
        let mut target = Box::new([0u8; PAGE_PIXELS]);
        let mut spans = PageSpans::none();
        spans.mark(4, 0..320);
        spans.mark(5, 0..320);
        // Addresses 76 to 79 of line 4 and 0 to 3 of line 5.
        target[5 * 320 - 16..5 * 320 + 16].fill(6);
        let mut recorded = ModeX::new(Recorder::default());
        let mut recorded_shadow = shadow.clone();
        recorded.update_page(Page::Zero, &mut recorded_shadow, &target, &spans);
        let fills: Vec<_> = recorded
            .bus()
            .0
            .iter()
            .filter_map(|operation| match operation {
                Operation::Fill {
                    offset,
                    count,
                    value: 6,
                } => Some((*offset, *count)),
                _ => None,
            })
            .collect();
        let line_4_end = Page::Zero.base() + 4 * BYTES_PER_LINE + 76;
        assert_eq!(fills, [(line_4_end, 4), (line_4_end + 4, 4)]);
        assert_eq!(vga.update_page(Page::Zero, &mut shadow, &target, &spans), 8);
        assert_eq!(&indices(vga.bus())[..], &target[..]);
        assert_eq!(shadow, target);
    }

    /// A change in the last address of a marked span reaches the page,
    /// whatever the span's length (one to nine addresses) and start (the
    /// line's first address, the second, or so that it ends the line).
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
    fn runs_are_the_marked_groups_and_touching_spans_are_one_run() {
        let mut spans = PageSpans::none();
        assert_eq!(spans.runs(3).count(), 0);
        spans.mark(3, 5..9); // group 0
        spans.mark(3, 16..17); // group 1: touches, one run
        spans.mark(3, 70..71); // group 4
        spans.mark(3, 316..400); // group 19, cut at the line's end
        spans.mark(3, 48..48); // empty, between groups 2 and 3
        spans.mark(240, 0..320); // no such line
        let runs: std::vec::Vec<_> = spans.runs(3).collect();
        assert_eq!(runs, [0..32, 64..80, 304..320]);
        let mut image = [7u8; PAGE_PIXELS];
        spans.fill(&mut image[..], 0);
        let cleared: std::vec::Vec<_> = (0..PAGE_PIXELS).filter(|&i| image[i] == 0).collect();
        let expected: std::vec::Vec<_> = [0..32, 64..80, 304..320]
            .into_iter()
            .flatten()
            .map(|x| 3 * 320 + x)
            .collect();
        assert_eq!(cleared, expected);
        let mut whole_line = PageSpans::all().runs(239);
        assert_eq!(whole_line.next(), Some(0..320));
        assert_eq!(whole_line.next(), None);
    }

    #[test]
    fn a_span_marks_exactly_the_groups_its_pixels_lie_in() {
        // Spans of one pixel or more: the renderer marks no empty ones.
        for start in 0..320 {
            for end in start + 1..=330 {
                let mut spans = PageSpans::none();
                spans.mark(7, start..end);
                let groups = (0..GROUPS)
                    .filter(|group| (start..end.min(320)).any(|x| x / GROUP_PIXELS == *group));
                let expected = groups.fold(0u32, |bits, group| bits | 1 << group);
                assert_eq!(spans.marked(7), expected, "pixels {start}..{end}");
            }
        }
    }
}
