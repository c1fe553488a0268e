//! Scan-out: the picture the CRTC, Attribute Controller and DAC make of video
//! memory, in 256-colour graphics modes (Mode X, and mode 13h by QEMU's
//! compact chain-4 mapping) and, through `text_scanout`, in text modes.
//!
//! The model follows QEMU's renderer: memory is fetched at plane offset
//! `start + line * Offset * 2 + x / 4`, plane `x % 4`, whatever the byte,
//! word or doubleword addressing mode (QEMU applies those on CPU access), and
//! each row is repeated Maximum Scan Line + 1 times (twice more with scan
//! doubling). Line Compare resets the address to 0 as in QEMU. Not modelled:
//! horizontal panning, preset row scan, the CGA/Hercules address wrapping of
//! CRTC Mode Control bits 0-1, and the Attribute Controller's palette
//! registers, which 256-colour modes bypass on QEMU (Mode X sets them to the
//! identity anyway).

use crate::regs::{ac, crtc, gc, seq, Crtc, Graphics, Sequencer, PLANE_COUNT};

use super::memory::PLANE_BYTES;
use super::SoftVga;

/// In 256-colour modes each character clock (8 dots) shows 4 pixels, each 2 dots wide.
const PIXELS_PER_CHARACTER: usize = 4;
/// The widest picture: 256 characters of 4 pixels.
const MAX_WIDTH: usize = 256 * PIXELS_PER_CHARACTER;
/// The Offset register counts words: two plane addresses each.
const ADDRESSES_PER_OFFSET_UNIT: usize = 2;

/// The displayed picture's layout in memory: with video memory, all that
/// makes the picture's DAC indices (two equal rasters over equal memory
/// scan out the same picture).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Raster {
    pub(super) width: usize,
    pub(super) height: usize,
    /// Displayed scan lines, each row repeated.
    pub(super) scan_lines: usize,
    pub(super) scan_lines_per_row: usize,
    pub(super) addresses_per_row: usize,
    pub(super) line_compare: usize,
    pub(super) start: usize,
}

impl Raster {
    /// No raster: all zero.
    pub(super) const NONE: Raster = Raster {
        width: 0,
        height: 0,
        scan_lines: 0,
        scan_lines_per_row: 0,
        addresses_per_row: 0,
        line_compare: 0,
        start: 0,
    };
}

/// QEMU's screendump expansion of a 6-bit DAC component to 8 bits: the six
/// bits shifted up, the low bit copied into the two new ones.
pub fn dac_6_to_8(component: u8) -> u8 {
    let value = component & 0x3F;
    let low_bit = value & 1;
    (value << 2) | (low_bit << 1) | low_bit
}

impl SoftVga {
    /// The size of the displayed picture: (width, height) in dots, or (0, 0)
    /// when there is none (Bochs VBE on, or a graphics mode other than
    /// 256-colour). Text modes show their cells, 9 or 8 dots wide.
    pub fn picture_size(&self) -> (usize, usize) {
        if let Some(raster) = self.raster() {
            (raster.width, raster.height)
        } else if let Some(text) = self.text_raster() {
            text.size()
        } else {
            (0, 0)
        }
    }

    /// The displayed picture as DAC indices (pixel data before the DAC's pixel
    /// mask), row by row; returns (width, height), or (0, 0) when there is no
    /// picture (see [`SoftVga::picture_size`]). In text modes each dot is the
    /// DAC index its attribute's colour selects. Blanking does not affect the
    /// indices (see [`SoftVga::video_enabled`]).
    ///
    /// # Panics
    /// If `out` is smaller than width * height.
    pub fn scanout_indices(&self, out: &mut [u8]) -> (usize, usize) {
        let capacity = out.len();
        self.scan(
            |first, indices| out[first..first + indices.len()].copy_from_slice(indices),
            capacity,
        )
    }

    /// The displayed picture as 8-bit RGB, expanded from the DAC's 6 bits as
    /// QEMU's screendump does; black while video is blanked. Returns (width,
    /// height) as [`SoftVga::scanout_indices`] does.
    ///
    /// # Panics
    /// If `out` is smaller than width * height.
    pub fn scanout_rgb(&self, out: &mut [[u8; 3]]) -> (usize, usize) {
        let dac = &self.registers.dac;
        let enabled = self.video_enabled();
        let capacity = out.len();
        self.scan(
            |first, indices| {
                for (pixel, &index) in out[first..first + indices.len()].iter_mut().zip(indices) {
                    *pixel = if enabled {
                        dac.palette[usize::from(index & dac.pixel_mask)].map(dac_6_to_8)
                    } else {
                        [0; 3]
                    };
                }
            },
            capacity,
        )
    }

    /// Whether the screen shows video: the Attribute Controller's Palette
    /// Address Source is set and the sequencer's screen-off bit is clear.
    pub fn video_enabled(&self) -> bool {
        self.registers.attribute_index & ac::PALETTE_ADDRESS_SOURCE != 0
            && self.registers.sequencer(Sequencer::ClockingMode) & seq::CLOCKING_SCREEN_OFF == 0
    }

    pub(super) fn raster(&self) -> Option<Raster> {
        let registers = &self.registers;
        let graphics = registers.graphics(Graphics::Misc) & gc::MISC_GRAPHICS != 0;
        let shift_256 = registers.graphics(Graphics::Mode) & gc::MODE_SHIFT_256 != 0;
        if registers.vbe_enabled() || !graphics || !shift_256 {
            return None;
        }
        let maximum_scan_line = registers.crtc(Crtc::MaximumScanLine);
        let doubling = if maximum_scan_line & crtc::SCAN_DOUBLING != 0 {
            2
        } else {
            1
        };
        let scan_lines_per_row =
            (usize::from(maximum_scan_line & crtc::MAXIMUM_SCAN_LINE_MASK) + 1) * doubling;
        let scan_lines = usize::from(registers.vertical_display_end()) + 1;
        Some(Raster {
            width: (usize::from(registers.crtc(Crtc::HorizontalDisplayEnd)) + 1)
                * PIXELS_PER_CHARACTER,
            height: scan_lines / scan_lines_per_row,
            scan_lines,
            scan_lines_per_row,
            addresses_per_row: usize::from(registers.crtc(Crtc::Offset))
                * ADDRESSES_PER_OFFSET_UNIT,
            line_compare: usize::from(registers.line_compare()),
            start: usize::from(self.displayed_start),
        })
    }

    /// Calls `put(first pixel number, DAC indices)` for every displayed
    /// pixel, a row (or a text cell's line) at a time: the kernel scans out
    /// every flip, so the loop works in rows rather than pixels.
    fn scan(&self, mut put: impl FnMut(usize, &[u8]), capacity: usize) -> (usize, usize) {
        let Some(raster) = self.raster() else {
            let Some(text) = self.text_raster() else {
                return (0, 0);
            };
            let (width, height) = text.size();
            assert!(
                capacity >= width * height,
                "text scan-out needs {width} x {height} dots, the buffer holds {capacity}"
            );
            self.scan_text(&text, put);
            return (width, height);
        };
        assert!(
            capacity >= raster.width * raster.height,
            "scan-out needs {} x {} pixels, the buffer holds {capacity}",
            raster.width,
            raster.height
        );
        let planes = &self.memory.planes;
        let mut line = [0u8; MAX_WIDTH];
        raster.rows(|row, address| {
            let line = &mut line[..raster.width];
            for (quad, pixels) in line.as_chunks_mut::<PLANE_COUNT>().0.iter_mut().enumerate() {
                let offset = (address + quad) % PLANE_BYTES;
                *pixels = core::array::from_fn(|plane| planes[plane][offset]);
            }
            put(row * raster.width, line);
        });
        (raster.width, raster.height)
    }
}

impl Raster {
    /// Calls `row_at(row, plane offset)` with each displayed row and the
    /// offset its first pixel is fetched from (not yet wrapped to the
    /// plane), as the CRTC walks the scan lines: each row is fetched once,
    /// from the first of its repeated scan lines, and Line Compare restarts
    /// the address at 0. The scan-out and the tracking of which rows were
    /// written both use it, so they cannot disagree.
    pub(super) fn rows(&self, mut row_at: impl FnMut(usize, usize)) {
        for row in 0..self.height {
            row_at(row, self.row_address(row));
        }
    }

    /// The plane offset row `row`'s first scan line is fetched from. The
    /// CRTC adds the Offset after each row's last scan line and restarts at
    /// 0 after the scan line equal to Line Compare, so a row starting after
    /// that line is as many rows past 0 as rows have ended since: the walk
    /// in closed form (a present asks for every row twice, and a walk of
    /// 480 scan lines a row at a time cost more than the rows' work).
    fn row_address(&self, row: usize) -> usize {
        let first_scan_line = row * self.scan_lines_per_row;
        if first_scan_line <= self.line_compare {
            self.start + row * self.addresses_per_row
        } else {
            let rows_before_restart = (self.line_compare + 1) / self.scan_lines_per_row;
            (row - rows_before_restart) * self.addresses_per_row
        }
    }
}

#[cfg(test)]
mod raster_tests {
    use super::Raster;
    use std::vec::Vec;

    /// The CRTC's walk, scan line by scan line: the offset of each row's
    /// first scan line.
    fn walked(raster: &Raster) -> Vec<usize> {
        let mut addresses = Vec::new();
        let mut address = raster.start;
        for scan_line in 0..raster.scan_lines {
            let line_in_row = scan_line % raster.scan_lines_per_row;
            if line_in_row == 0 && scan_line / raster.scan_lines_per_row < raster.height {
                addresses.push(address);
            }
            if line_in_row == raster.scan_lines_per_row - 1 {
                address += raster.addresses_per_row;
            }
            if scan_line == raster.line_compare {
                address = 0;
            }
        }
        addresses
    }

    #[test]
    fn row_addresses_follow_the_scan_line_walk() {
        for scan_lines_per_row in 1..=5 {
            for scan_lines in [1, 2, 7, 31, 480] {
                for line_compare in (0..scan_lines + 3).chain([1023]) {
                    let raster = Raster {
                        width: 320,
                        height: scan_lines / scan_lines_per_row,
                        scan_lines,
                        scan_lines_per_row,
                        addresses_per_row: 80,
                        line_compare,
                        start: 19_200,
                    };
                    let mut rows = Vec::new();
                    raster.rows(|row, address| {
                        assert_eq!(row, rows.len());
                        rows.push(address);
                    });
                    assert_eq!(rows, walked(&raster), "{raster:?}");
                }
            }
        }
    }
}
