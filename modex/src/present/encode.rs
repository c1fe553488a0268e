//! How a colour becomes the bytes of one framebuffer pixel: byte-per-component
//! orders, grey, and packed bit fields such as the 16-bit 5-6-5 and 5-5-5
//! formats some firmware hands over.

/// How the bytes of one framebuffer pixel encode a colour.
///
/// `repr(u8)` fixes `Rgb`'s tag at 0, so a [`super::Presenter`] that has
/// presented nothing is all zero bytes (see there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum PixelOrder {
    /// Red, green, blue: one byte each, a fourth byte zero. (With fewer than
    /// 3 bytes a pixel, the components that fit.)
    Rgb,
    /// Blue, green, red: one byte each, any further bytes zero (UEFI's usual
    /// 0x00RRGGBB in little-endian words).
    Bgr,
    /// Luminance in every byte of the pixel. For 8-bit grey that is the pixel;
    /// for a packed format nobody described it is at least a grey picture in
    /// every 8-bit-per-component layout.
    Grey,
    /// Bit fields of a little-endian pixel word (16-bit 5-6-5 or 5-5-5, say).
    Packed(PackedFormat),
}

/// One colour component's bit field in a packed pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Channel {
    /// Bit offset of the field's lowest bit.
    pub shift: u8,
    /// Width of the field, 1 to 8 bits.
    pub bits: u8,
}

/// A packed pixel format: where red, green and blue sit in the pixel word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PackedFormat {
    /// Red's bit field.
    pub red: Channel,
    /// Green's bit field.
    pub green: Channel,
    /// Blue's bit field.
    pub blue: Channel,
}

impl PackedFormat {
    /// 16-bit 5-6-5, red in the top bits: the usual 16-bit framebuffer.
    pub const RGB565: PackedFormat = PackedFormat {
        red: Channel { shift: 11, bits: 5 },
        green: Channel { shift: 5, bits: 6 },
        blue: Channel { shift: 0, bits: 5 },
    };
    /// 15-bit 5-5-5 in a 16-bit word, red in bits 10-14, bit 15 unused.
    pub const RGB555: PackedFormat = PackedFormat {
        red: Channel { shift: 10, bits: 5 },
        green: Channel { shift: 5, bits: 5 },
        blue: Channel { shift: 0, bits: 5 },
    };

    /// The format of a pixel of `pixel_bits` bits whose components start at
    /// these bit offsets, which is all a bootloader reports of an unusual
    /// format. Each field reaches up to the next one, at most 8 bits; the
    /// topmost gets the width of the lowest, because no format has a wider
    /// top field (5-6-5 and 5-5-5 both have 5 at each end; 8-8-8 has 8), and
    /// without that rule 5-5-5 would read as 6-5-5. None if two components
    /// share an offset or a field would not fit in the pixel.
    pub fn from_positions(red: u8, green: u8, blue: u8, pixel_bits: u8) -> Option<Self> {
        let mut starts = [red, green, blue];
        starts.sort_unstable();
        let [low, middle, high] = starts;
        if low == middle || middle == high {
            return None;
        }
        let low_bits = (middle - low).min(8);
        let width = |start: u8| match start {
            s if s == low => low_bits,
            s if s == middle => (high - middle).min(8),
            _ => low_bits,
        };
        let channel = |shift: u8| {
            let bits = width(shift);
            (u16::from(shift) + u16::from(bits) <= u16::from(pixel_bits))
                .then_some(Channel { shift, bits })
        };
        Some(PackedFormat {
            red: channel(red)?,
            green: channel(green)?,
            blue: channel(blue)?,
        })
    }

    /// The pixel word of an 8-bit-per-component colour: each component's top
    /// bits (a 6-bit DAC colour expanded to 8 bits comes back exactly in a
    /// 6-bit field).
    pub fn word(&self, [red, green, blue]: [u8; 3]) -> u32 {
        let field = |value: u8, channel: Channel| {
            let bits = channel.bits.clamp(1, 8);
            (u32::from(value) >> (8 - bits)) << channel.shift
        };
        field(red, self.red) | field(green, self.green) | field(blue, self.blue)
    }
}

/// A framebuffer's pixel format as firmware and bootloaders name it (the
/// shape of `bootloader_api`'s `PixelFormat`, without depending on it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FirmwareFormat {
    /// Red, green, blue in byte order.
    Rgb,
    /// Blue, green, red in byte order.
    Bgr,
    /// One grey level.
    Grey,
    /// Components at these bit offsets of the pixel word (UEFI's bit masks).
    BitOffsets {
        /// Red's lowest bit.
        red: u8,
        /// Green's lowest bit.
        green: u8,
        /// Blue's lowest bit.
        blue: u8,
    },
    /// Anything else.
    Other,
}

impl PixelOrder {
    /// How to encode colours for a framebuffer of `format` with
    /// `bytes_per_pixel`; None when the format cannot be understood (a
    /// caller may fall back to [`PixelOrder::Grey`]). Byte orders with two
    /// bytes a pixel are 5-6-5 with red at the end the name puts it (BGR:
    /// blue in the low bits, as in 32-bit BGR).
    pub fn for_framebuffer(format: FirmwareFormat, bytes_per_pixel: usize) -> Option<Self> {
        let rgb565_reversed = PackedFormat {
            red: PackedFormat::RGB565.blue,
            green: PackedFormat::RGB565.green,
            blue: PackedFormat::RGB565.red,
        };
        match (format, bytes_per_pixel) {
            (FirmwareFormat::Rgb, 3..=4) => Some(PixelOrder::Rgb),
            (FirmwareFormat::Bgr, 3..=4) => Some(PixelOrder::Bgr),
            (FirmwareFormat::Bgr, 2) => Some(PixelOrder::Packed(PackedFormat::RGB565)),
            (FirmwareFormat::Rgb, 2) => Some(PixelOrder::Packed(rgb565_reversed)),
            (FirmwareFormat::Grey, 1..=4) => Some(PixelOrder::Grey),
            (FirmwareFormat::BitOffsets { red, green, blue }, 1..=4) => {
                PackedFormat::from_positions(red, green, blue, bytes_per_pixel as u8 * 8)
                    .map(PixelOrder::Packed)
            }
            _ => None,
        }
    }
}

/// The Rec. 601 luma weights in 1/256ths (0.299, 0.587, 0.114): the usual
/// weighting of a colour's brightness to the eye, and what monochrome VGA
/// BIOSes use to sum the DAC to grey. They add up to 256, so white stays 255.
const LUMA_WEIGHTS: [u32; 3] = [77, 150, 29];

/// The grey an RGB colour looks as bright as.
pub fn luma([red, green, blue]: [u8; 3]) -> u8 {
    let [wr, wg, wb] = LUMA_WEIGHTS;
    ((wr * u32::from(red) + wg * u32::from(green) + wb * u32::from(blue) + 128) >> 8) as u8
}

impl PixelOrder {
    /// The first four bytes of a pixel of colour `rgb` (a packed word is
    /// little-endian, as x86 stores it).
    pub fn encode(self, rgb: [u8; 3]) -> [u8; 4] {
        let [red, green, blue] = rgb;
        match self {
            PixelOrder::Rgb => [red, green, blue, 0],
            PixelOrder::Bgr => [blue, green, red, 0],
            PixelOrder::Grey => [luma(rgb); 4],
            PixelOrder::Packed(format) => format.word(rgb).to_le_bytes(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const WHITE: [u8; 3] = [255, 255, 255];

    #[test]
    fn rgb565_puts_red_on_top_and_keeps_six_bits_of_green() {
        let order = PixelOrder::Packed(PackedFormat::RGB565);
        assert_eq!(order.encode([255, 0, 0])[..2], 0xF800u16.to_le_bytes());
        assert_eq!(order.encode([0, 255, 0])[..2], 0x07E0u16.to_le_bytes());
        assert_eq!(order.encode([0, 0, 255])[..2], 0x001Fu16.to_le_bytes());
        assert_eq!(order.encode(WHITE)[..2], 0xFFFFu16.to_le_bytes());
        // EGA brown (0x2A, 0x15, 0) in the DAC, expanded to 8 bits by the
        // presenter: 6-bit green comes back whole, red and blue lose a bit.
        let brown = [0x2A, 0x15, 0x00].map(crate::soft::dac_6_to_8);
        assert_eq!(
            u16::from_le_bytes(order.encode(brown)[..2].try_into().unwrap()),
            (0x2A >> 1) << 11 | 0x15 << 5
        );
    }

    #[test]
    fn rgb555_leaves_the_top_bit_clear() {
        let order = PixelOrder::Packed(PackedFormat::RGB555);
        assert_eq!(order.encode(WHITE)[..2], 0x7FFFu16.to_le_bytes());
        assert_eq!(order.encode([255, 0, 0])[..2], 0x7C00u16.to_le_bytes());
        assert_eq!(order.encode([0, 255, 0])[..2], 0x03E0u16.to_le_bytes());
        assert_eq!(order.encode([0, 0, 8])[..2], 0x0001u16.to_le_bytes());
    }

    #[test]
    fn bit_offsets_alone_name_the_16_bit_formats() {
        assert_eq!(
            PackedFormat::from_positions(11, 5, 0, 16),
            Some(PackedFormat::RGB565)
        );
        assert_eq!(
            PackedFormat::from_positions(10, 5, 0, 16),
            Some(PackedFormat::RGB555)
        );
        // Blue on top: BGR 5-6-5.
        let bgr565 = PackedFormat::from_positions(0, 5, 11, 16).unwrap();
        assert_eq!(bgr565.blue, Channel { shift: 11, bits: 5 });
        assert_eq!(bgr565.red, Channel { shift: 0, bits: 5 });
        assert_eq!(
            PixelOrder::Packed(bgr565).encode([255, 0, 0])[..2],
            0x001Fu16.to_le_bytes()
        );
        // 32-bit 8-8-8 described by offsets: the same bytes as Bgr.
        let xrgb = PackedFormat::from_positions(16, 8, 0, 32).unwrap();
        assert_eq!(
            PixelOrder::Packed(xrgb).encode([1, 2, 3]),
            PixelOrder::Bgr.encode([1, 2, 3])
        );
    }

    #[test]
    fn firmware_formats_become_pixel_orders() {
        use FirmwareFormat::*;
        let order = PixelOrder::for_framebuffer;
        assert_eq!(order(Bgr, 4), Some(PixelOrder::Bgr));
        assert_eq!(order(Rgb, 3), Some(PixelOrder::Rgb));
        assert_eq!(order(Grey, 1), Some(PixelOrder::Grey));
        assert_eq!(
            order(Bgr, 2),
            Some(PixelOrder::Packed(PackedFormat::RGB565))
        );
        let Some(PixelOrder::Packed(rgb_16)) = order(Rgb, 2) else {
            panic!("2-byte RGB is packed");
        };
        assert_eq!(
            PixelOrder::Packed(rgb_16).encode([255, 0, 0])[..2],
            0x001Fu16.to_le_bytes()
        );
        let offsets = |red, green, blue| BitOffsets { red, green, blue };
        assert_eq!(
            order(offsets(11, 5, 0), 2),
            Some(PixelOrder::Packed(PackedFormat::RGB565))
        );
        assert_eq!(
            order(offsets(10, 5, 0), 2),
            Some(PixelOrder::Packed(PackedFormat::RGB555))
        );
        assert_eq!(order(offsets(10, 5, 0), 0), None);
        assert_eq!(order(Other, 4), None);
        assert_eq!(order(Bgr, 1), None);
    }

    #[test]
    fn impossible_offsets_are_refused() {
        assert_eq!(PackedFormat::from_positions(5, 5, 0, 16), None);
        assert_eq!(PackedFormat::from_positions(14, 5, 0, 16), None);
    }
}
