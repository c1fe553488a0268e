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
        let width = SCREEN_WIDTH as usize;
        let mut line_masks = [0u16; SCREEN_HEIGHT as usize];
        let mut frame_masks = 0u16;
        for (y, masks) in line_masks.iter_mut().enumerate() {
            let (old_line, new_line) =
                (&shadow[y * width..][..width], &target[y * width..][..width]);
            if old_line == new_line {
                continue;
            }
            for i in 0..usize::from(BYTES_PER_LINE) {
                let (old, new) = (quad(old_line, i), quad(new_line, i));
                if old != new {
                    for (planes, _) in address_writes(old, new) {
                        *masks |= mask_bit(planes);
                    }
                }
            }
            frame_masks |= *masks;
        }
        // The mask already set first, which saves its OUT.
        let cached = self
            .io
            .map_mask()
            .filter(|&m| frame_masks & mask_bit(m) != 0);
        let others = (1..=PlaneMask::ALL.bits())
            .map(PlaneMask::from_bits_truncate)
            .filter(|&m| Some(m) != cached && frame_masks & mask_bit(m) != 0);
        let mut written = 0;
        for mask in cached.into_iter().chain(others) {
            self.io.set_map_mask(mask);
            for (y, _) in line_masks
                .iter()
                .enumerate()
                .filter(|(_, &m)| m & mask_bit(mask) != 0)
            {
                let (old_line, new_line) =
                    (&shadow[y * width..][..width], &target[y * width..][..width]);
                let line_base = page.base() + y as u16 * BYTES_PER_LINE;
                written += self.write_line_mask(line_base, old_line, new_line, mask);
            }
        }
        for (y, _) in line_masks.iter().enumerate().filter(|(_, &m)| m != 0) {
            shadow[y * width..][..width].copy_from_slice(&target[y * width..][..width]);
        }
        written
    }

    /// The writes of one line that use `mask` (already set).
    fn write_line_mask(
        &mut self,
        line_base: u16,
        old_line: &[u8],
        new_line: &[u8],
        mask: PlaneMask,
    ) -> u32 {
        let mut written = 0;
        let mut i = 0;
        while i < usize::from(BYTES_PER_LINE) {
            // A run of addresses whose four pixels all become one colour
            // is a single fill with all planes enabled.
            if mask == PlaneMask::ALL {
                let run = solid_run(old_line, new_line, i);
                if run > 0 {
                    self.io
                        .fill_vram(line_base + i as u16, run as u16, new_line[4 * i]);
                    written += run as u32;
                    i += run;
                    continue;
                }
            }
            let (old, new) = (quad(old_line, i), quad(new_line, i));
            if old == new {
                i += 1;
                continue;
            }
            for (planes, colour) in address_writes(old, new) {
                if planes == mask {
                    self.io.write_vram8(line_base + i as u16, colour);
                    written += 1;
                }
            }
            i += 1;
        }
        written
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

/// A set of Map Masks is a 16-bit word, bit m for the mask whose value is m.
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

/// How many addresses from `start` on have all four pixels changing to one
/// and the same colour (0 if the first does not).
fn solid_run(old_line: &[u8], new_line: &[u8], start: usize) -> usize {
    let colour = new_line[4 * start];
    (start..usize::from(BYTES_PER_LINE))
        .take_while(|&i| {
            let (old, new) = (quad(old_line, i), quad(new_line, i));
            new == [colour; 4] && old.iter().all(|&o| o != colour)
        })
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
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
}
