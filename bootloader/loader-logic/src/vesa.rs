//! What BIOS stage 2 makes of a VBE mode's pixels (issue 61). VBE gives bits
//! a pixel (15 for 5-5-5, 24, 32) and bytes a scan line; the kernel is told
//! bytes a pixel and a stride in pixels. Upstream divided the bits by 8,
//! which made a 15-bit pixel 1 byte, and divided the line by that, which
//! loses bytes when a 24-bit mode's line is not a whole number of pixels.
//! A mode that cannot be described so is skipped; of two modes of one size,
//! one of 4 bytes a pixel is preferred to one of 3.

/// A VBE mode's pixels as the kernel is told them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VesaPixels {
    /// Bytes a pixel, 1 to 4.
    pub bytes_per_pixel: u8,
    /// Pixels from the start of one line to the start of the next.
    pub stride: u16,
}

/// The pixels of a mode of `bits_per_pixel` and `bytes_per_scanline`, or
/// None when they cannot be described: no bits, more than 4 bytes, or a
/// line that is not a whole number of pixels.
pub fn pixels(bits_per_pixel: u8, bytes_per_scanline: u16) -> Option<VesaPixels> {
    let bytes_per_pixel = bits_per_pixel.div_ceil(8);
    if !(1..=4).contains(&bytes_per_pixel)
        || !bytes_per_scanline.is_multiple_of(u16::from(bytes_per_pixel))
    {
        return None;
    }
    Some(VesaPixels {
        bytes_per_pixel,
        stride: bytes_per_scanline / u16::from(bytes_per_pixel),
    })
}

/// A candidate mode, as far as the choice goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VesaCandidate {
    /// Width in pixels.
    pub width: u16,
    /// Height in pixels.
    pub height: u16,
    /// Bytes a pixel.
    pub bytes_per_pixel: u8,
    /// Whether its components' positions name RGB or BGR (else the kernel
    /// is told only the positions).
    pub known_format: bool,
}

/// Whether `next` replaces `best`: upstream's rule (anything replaces a
/// best of unknown format; else a wider mode, or as wide and taller), and
/// at the same size a mode of 4 bytes a pixel replaces one of fewer.
pub fn replaces(best: &VesaCandidate, next: &VesaCandidate) -> bool {
    let same_size = (best.width, best.height) == (next.width, next.height);
    !best.known_format
        || best.width < next.width
        || (best.width == next.width && best.height < next.height)
        || (same_size && best.bytes_per_pixel < 4 && next.bytes_per_pixel == 4)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_sizes_round_up_to_whole_bytes() {
        let size = |bits| pixels(bits, 1920).map(|p| p.bytes_per_pixel);
        assert_eq!(size(8), Some(1));
        // 5-5-5 in a 16-bit word: upstream's 15 / 8 made it 1 byte.
        assert_eq!(size(15), Some(2));
        assert_eq!(size(16), Some(2));
        assert_eq!(size(24), Some(3));
        assert_eq!(size(32), Some(4));
    }

    #[test]
    fn a_24_bit_line_is_its_bytes_over_three() {
        assert_eq!(
            pixels(24, 1024 * 3),
            Some(VesaPixels {
                bytes_per_pixel: 3,
                stride: 1024
            })
        );
        // Padded lines are fine while they hold whole pixels.
        assert_eq!(pixels(24, 2400 + 3 * 16).map(|p| p.stride), Some(816));
    }

    #[test]
    fn lines_of_part_pixels_and_impossible_sizes_are_refused() {
        // 640 3-byte pixels padded to 2048 bytes: 682 2/3 pixels a line.
        assert_eq!(pixels(24, 2048), None);
        assert_eq!(pixels(15, 1281), None);
        assert_eq!(pixels(0, 1024), None);
        assert_eq!(
            pixels(4, 320),
            Some(VesaPixels {
                bytes_per_pixel: 1,
                stride: 320
            })
        );
        assert_eq!(pixels(40, 4000), None);
    }

    fn mode(width: u16, height: u16, bytes_per_pixel: u8) -> VesaCandidate {
        VesaCandidate {
            width,
            height,
            bytes_per_pixel,
            known_format: true,
        }
    }

    #[test]
    fn at_one_size_4_bytes_replace_3_and_not_the_other_way() {
        assert!(replaces(&mode(1024, 768, 3), &mode(1024, 768, 4)));
        assert!(!replaces(&mode(1024, 768, 4), &mode(1024, 768, 3)));
        assert!(!replaces(&mode(1024, 768, 4), &mode(1024, 768, 4)));
        assert!(!replaces(&mode(1024, 768, 3), &mode(1024, 768, 3)));
    }

    #[test]
    fn size_still_comes_first() {
        assert!(replaces(&mode(800, 600, 4), &mode(1024, 768, 3)));
        assert!(!replaces(&mode(1024, 768, 3), &mode(800, 600, 4)));
        assert!(replaces(&mode(1024, 600, 4), &mode(1024, 768, 2)));
        let unknown = VesaCandidate {
            known_format: false,
            ..mode(1280, 720, 4)
        };
        assert!(replaces(&unknown, &mode(640, 480, 3)));
    }
}
