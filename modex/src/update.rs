//! Bringing a page up to date with the fewest video-memory writes.
//!
//! The caller renders the next frame into RAM first (colour indices, one byte
//! a pixel) and keeps a shadow of what each page holds. Each group of four
//! pixels x = 4i..4i+3 on a line is one byte address i, with pixel 4i+p in
//! plane p, so a page can be updated address by address: pixels that already
//! hold their new colour are left alone, and the changed ones get one write per
//! distinct new colour, with the Map Mask selecting exactly their planes. That
//! is the lower bound on writes for the change; only the Map Mask writes come
//! on top, and the driver's cache drops the ones that would not change it.

use crate::bus::VgaBus;
use crate::driver::ModeX;
use crate::page::Page;
use crate::{BYTES_PER_LINE, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Pixels in a page: one byte each in a RAM image of it.
pub const PAGE_PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;
const ALL_PLANES: u8 = 0x0F;

/// A page's picture in RAM: row-major colour indices.
pub type PageImage = [u8; PAGE_PIXELS];

impl<B: VgaBus> ModeX<B> {
    /// Makes `page` show `target`, given that it shows `shadow` now; only
    /// changed pixels are written, and `shadow` becomes `target`. Returns the
    /// number of video-memory bytes written.
    pub fn update_page(&mut self, page: Page, shadow: &mut PageImage, target: &PageImage) -> u32 {
        let mut written = 0;
        const WIDTH: usize = SCREEN_WIDTH as usize;
        let lines = shadow
            .as_chunks_mut::<WIDTH>()
            .0
            .iter_mut()
            .zip(target.as_chunks::<WIDTH>().0);
        for (y, (old_line, new_line)) in lines.enumerate() {
            if old_line == new_line {
                continue;
            }
            let line_base = page.base() + y as u16 * BYTES_PER_LINE;
            let mut i = 0;
            while i < usize::from(BYTES_PER_LINE) {
                let (old, new) = (quad(old_line, i), quad(new_line, i));
                if old == new {
                    i += 1;
                    continue;
                }
                // A run of addresses whose four pixels all become one colour
                // is a single fill with all planes enabled.
                let run = solid_run(old_line, new_line, i);
                if run > 0 {
                    self.set_map_mask(ALL_PLANES);
                    self.bus.fill_vram(line_base + i as u16, run as u16, new[0]);
                    written += run as u32;
                    i += run;
                } else {
                    written += self.update_address(line_base + i as u16, old, new);
                    i += 1;
                }
            }
            old_line.copy_from_slice(new_line);
        }
        written
    }

    /// One write per distinct new colour among the changed pixels of the
    /// address.
    fn update_address(&mut self, address: u16, old: [u8; 4], new: [u8; 4]) -> u32 {
        let mut pending = (0..4)
            .filter(|&p| old[p] != new[p])
            .fold(0u8, |mask, p| mask | 1 << p);
        let mut writes = 0;
        while pending != 0 {
            let colour = new[pending.trailing_zeros() as usize];
            let planes = (0..4)
                .filter(|&p| pending & 1 << p != 0 && new[p] == colour)
                .fold(0u8, |m, p| m | 1 << p);
            self.set_map_mask(planes);
            self.bus.write_vram8(address, colour);
            pending &= !planes;
            writes += 1;
        }
        writes
    }
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
            let written = vga.update_page(Page(0), &mut shadow, &target);
            let after = vga.bus().counts();
            assert_eq!(after.vram_writes - before.vram_writes, u64::from(written));
            assert_eq!(&*shadow, &*target);
            assert_eq!(indices(vga.bus()), target.to_vec(), "round {round}");
        }
        // Nothing changed: nothing is written.
        let before = vga.bus().counts();
        assert_eq!(vga.update_page(Page(0), &mut shadow, &target), 0);
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
        assert_eq!(vga.update_page(Page(0), &mut shadow, &target), 2);
        target[..4].copy_from_slice(&[5, 7, 7, 7]);
        assert_eq!(vga.update_page(Page(0), &mut shadow, &target), 1);
        assert_eq!(&indices(vga.bus())[..4], &[5, 7, 7, 7]);
    }
}
