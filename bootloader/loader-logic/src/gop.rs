//! Choosing the GOP to draw on. Firmware may offer several: one per display
//! adapter, plus the console splitter's. Some have no framebuffer at all
//! (`PixelBltOnly`, e.g. virtio-gpu under OVMF), and a bit-mask format is only
//! of use when the kernel's presenter can encode it. The choice: only usable
//! ones; of those, the one on the console-output (ConOut) handle, which is
//! the one the firmware shows its own text on; else the largest.
//!
//! A bit-mask mode's pixel is as many bytes as its four masks reach: OVMF's
//! 1024x768 mode on a Cirrus is 24-bit (red 0xFF0000, green 0xFF00, blue
//! 0xFF, nothing reserved), 3 bytes a pixel. Then, on the chosen GOP, the
//! mode: the current one unless it is not 4 bytes a pixel and a mode of the
//! same size is ([`choose_mode`]).

/// A GOP mode's pixel format as UEFI gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GopFormat {
    /// 8-bit red, green, blue, reserved in byte order.
    Rgb,
    /// 8-bit blue, green, red, reserved in byte order.
    Bgr,
    /// Components where these masks of the pixel put them.
    Bitmask {
        /// Red's mask.
        red: u32,
        /// Green's mask.
        green: u32,
        /// Blue's mask.
        blue: u32,
        /// Bits that are no colour (they still make the pixel wider).
        reserved: u32,
    },
    /// No framebuffer: drawing only through the Blt call.
    BltOnly,
}

/// A usable format, as the bootloader hands it to the kernel (the shape of
/// `bootloader_api`'s `PixelFormat`: byte orders, or the lowest bit of each
/// 8-bit component).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UsableFormat {
    /// Red, green, blue in byte order.
    Rgb,
    /// Blue, green, red in byte order.
    Bgr,
    /// 8-bit components at these bit positions of the pixel.
    BitPositions {
        /// Red's lowest bit.
        red: u8,
        /// Green's lowest bit.
        green: u8,
        /// Blue's lowest bit.
        blue: u8,
    },
}

/// What the kernel is told of a usable mode's pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelLayout {
    /// Where the components are.
    pub format: UsableFormat,
    /// Bytes a pixel: 4 for the byte orders, 3 or 4 for bit masks.
    pub bytes_per_pixel: usize,
}

/// Why a GOP's mode cannot be drawn on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unusable {
    /// `PixelBltOnly`: there is no framebuffer.
    BltOnly,
    /// A bit mask that is not three separate 8-bit fields (and a reserved
    /// mask apart from them): the kernel is told only components' positions,
    /// so each must be 8 bits wide for it to know their widths.
    Bitmask,
    /// No pixels (a zero width or height).
    Empty,
}

impl Unusable {
    /// Why, in words.
    pub fn as_str(self) -> &'static str {
        match self {
            Unusable::BltOnly => "Blt-only (no framebuffer)",
            Unusable::Bitmask => "a bit mask other than three separate 8-bit fields",
            Unusable::Empty => "no pixels",
        }
    }
}

impl core::fmt::Display for Unusable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A judgement as the loader's GOP line ends: `usable, 3 bytes/pixel`, or
/// why not.
pub struct Verdict(pub Result<PixelLayout, Unusable>);

impl core::fmt::Display for Verdict {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Ok(layout) => write!(f, "usable, {} bytes/pixel", layout.bytes_per_pixel),
            Err(why) => f.write_str(why.as_str()),
        }
    }
}

/// What the loader found on one GOP handle (its current mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GopCandidate {
    /// The pixel format.
    pub format: GopFormat,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Whether the handle is the console-output handle (the system table's
    /// `ConsoleOutHandle`).
    pub on_console: bool,
}

/// The pixel layout to hand on for `format`, or why it cannot be used.
pub fn usable_layout(format: GopFormat) -> Result<PixelLayout, Unusable> {
    let (format, bytes_per_pixel) = match format {
        GopFormat::Rgb => (UsableFormat::Rgb, 4),
        GopFormat::Bgr => (UsableFormat::Bgr, 4),
        GopFormat::BltOnly => return Err(Unusable::BltOnly),
        GopFormat::Bitmask {
            red,
            green,
            blue,
            reserved,
        } => {
            let field = |mask: u32| {
                let low = mask.trailing_zeros();
                (mask != 0 && mask >> low == 0xFF).then_some(low as u8)
            };
            let apart = [green, blue, reserved].iter().all(|&m| red & m == 0)
                && [blue, reserved].iter().all(|&m| green & m == 0)
                && blue & reserved == 0;
            let (Some(r), Some(g), Some(b), true) = (field(red), field(green), field(blue), apart)
            else {
                return Err(Unusable::Bitmask);
            };
            // The pixel reaches the highest bit any mask uses, in whole bytes.
            let bits = u32::BITS - (red | green | blue | reserved).leading_zeros();
            let format = UsableFormat::BitPositions {
                red: r,
                green: g,
                blue: b,
            };
            (format, bits.div_ceil(8) as usize)
        }
    };
    Ok(PixelLayout {
        format,
        bytes_per_pixel,
    })
}

/// Whether a candidate can be drawn on, and with which pixels.
pub fn judge(candidate: &GopCandidate) -> Result<PixelLayout, Unusable> {
    let layout = usable_layout(candidate.format)?;
    if candidate.width == 0 || candidate.height == 0 {
        return Err(Unusable::Empty);
    }
    Ok(layout)
}

/// The index of the candidate to draw on, or None when none is usable: the
/// usable one on the console handle, else the usable one with the most
/// pixels (the first of equals).
pub fn choose(candidates: &[GopCandidate]) -> Option<usize> {
    let usable = || {
        candidates
            .iter()
            .enumerate()
            .filter(|(_, candidate)| judge(candidate).is_ok())
    };
    usable()
        .find(|(_, candidate)| candidate.on_console)
        .or_else(|| {
            usable().fold(
                None,
                |best: Option<(usize, &GopCandidate)>, next| match best {
                    Some(best) if best.1.width * best.1.height >= next.1.width * next.1.height => {
                        Some(best)
                    }
                    _ => Some(next),
                },
            )
        })
        .map(|(index, _)| index)
}

/// One of a GOP's modes, as `QueryMode` describes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GopMode {
    /// The pixel format.
    pub format: GopFormat,
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
}

/// The mode to draw in: the current one, or another of the same size.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModeChoice {
    /// Stay in the current mode, for this reason.
    Keep(KeepReason),
    /// Set this mode (its place among the modes given) instead.
    Set {
        /// Its place in the modes given to [`choose_mode`].
        position: usize,
        /// The mode.
        mode: GopMode,
    },
}

/// Why the current mode stays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeepReason {
    /// It is usable with 4 bytes a pixel already.
    FourBytes,
    /// No usable mode of its size has 4 bytes a pixel (and one of another
    /// size might not show on the monitor at all).
    NoFourByteModeOfItsSize,
}

impl KeepReason {
    /// Why, in words.
    pub fn as_str(self) -> &'static str {
        match self {
            KeepReason::FourBytes => "it has 4 bytes a pixel",
            KeepReason::NoFourByteModeOfItsSize => "no mode of its size has 4 bytes a pixel",
        }
    }
}

/// The mode to draw in, given the current one and all the GOP lists: the
/// current mode (the firmware's screen is in it, so it is known to scan
/// out) unless it is not usable with 4 bytes a pixel and a mode of the same
/// size is, which then is set: the first such. Same size, so the same
/// timing reaches the monitor; only the pixel's depth changes. 4 bytes a
/// pixel is the layout every firmware and every test here draws in, and
/// the presenter's stores are aligned there.
pub fn choose_mode(current: &GopMode, modes: impl IntoIterator<Item = GopMode>) -> ModeChoice {
    let four_bytes = |mode: &GopMode| {
        let candidate = GopCandidate {
            format: mode.format,
            width: mode.width,
            height: mode.height,
            on_console: false,
        };
        judge(&candidate).is_ok_and(|layout| layout.bytes_per_pixel == 4)
    };
    if four_bytes(current) {
        return ModeChoice::Keep(KeepReason::FourBytes);
    }
    modes
        .into_iter()
        .enumerate()
        .find(|(_, mode)| {
            (mode.width, mode.height) == (current.width, current.height) && four_bytes(mode)
        })
        .map_or(
            ModeChoice::Keep(KeepReason::NoFourByteModeOfItsSize),
            |(position, mode)| ModeChoice::Set { position, mode },
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gop(format: GopFormat, width: usize, height: usize) -> GopCandidate {
        GopCandidate {
            format,
            width,
            height,
            on_console: false,
        }
    }

    #[test]
    fn blt_only_is_never_chosen() {
        assert_eq!(choose(&[gop(GopFormat::BltOnly, 1280, 800)]), None);
        assert_eq!(
            judge(&gop(GopFormat::BltOnly, 1280, 800)),
            Err(Unusable::BltOnly)
        );
    }

    #[test]
    fn a_blt_only_gop_first_gives_way_to_a_usable_second() {
        // virtio-gpu (Blt-only) then a VGA: the measured case that panicked.
        let gops = [
            gop(GopFormat::BltOnly, 1280, 800),
            gop(GopFormat::Bgr, 800, 600),
        ];
        assert_eq!(choose(&gops), Some(1));
    }

    fn mask(red: u32, green: u32, blue: u32, reserved: u32) -> GopFormat {
        GopFormat::Bitmask {
            red,
            green,
            blue,
            reserved,
        }
    }

    fn positions(red: u8, green: u8, blue: u8, bytes_per_pixel: usize) -> PixelLayout {
        PixelLayout {
            format: UsableFormat::BitPositions { red, green, blue },
            bytes_per_pixel,
        }
    }

    #[test]
    fn byte_orders_are_4_bytes_a_pixel() {
        for (format, usable) in [
            (GopFormat::Rgb, UsableFormat::Rgb),
            (GopFormat::Bgr, UsableFormat::Bgr),
        ] {
            assert_eq!(
                usable_layout(format),
                Ok(PixelLayout {
                    format: usable,
                    bytes_per_pixel: 4
                })
            );
        }
    }

    #[test]
    fn bitmasks_of_three_8_bit_fields_become_positions() {
        let xrgb = mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0xFF00_0000);
        assert_eq!(usable_layout(xrgb), Ok(positions(16, 8, 0, 4)));
        let high = mask(0xFF00_0000, 0x00FF_0000, 0x0000_FF00, 0);
        assert_eq!(usable_layout(high), Ok(positions(24, 16, 8, 4)));
    }

    #[test]
    fn a_24_bit_mask_is_3_bytes_a_pixel() {
        // OVMF's 1024x768 mode on a Cirrus: blue, green, red in 3 bytes,
        // nothing reserved (its framebuffer is 1024 * 768 * 3 bytes).
        let bgr_24 = mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0);
        assert_eq!(usable_layout(bgr_24), Ok(positions(16, 8, 0, 3)));
        let rgb_24 = mask(0x0000_00FF, 0x0000_FF00, 0x00FF_0000, 0);
        assert_eq!(usable_layout(rgb_24), Ok(positions(0, 8, 16, 3)));
    }

    #[test]
    fn the_reserved_mask_makes_the_pixel_wider() {
        // The colours in the low 3 bytes, a fourth that is no colour.
        let padded = mask(0x0000_00FF, 0x00FF_0000, 0x0000_FF00, 0xFF00_0000);
        assert_eq!(usable_layout(padded), Ok(positions(0, 16, 8, 4)));
        // Even one reserved bit in the top byte takes the whole byte.
        let one_bit = mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0x0100_0000);
        assert_eq!(usable_layout(one_bit), Ok(positions(16, 8, 0, 4)));
    }

    #[test]
    fn other_bitmasks_are_refused() {
        let refused = [
            // 5-6-5 in a 32-bit pixel: fields narrower than 8 bits.
            (0xF800, 0x07E0, 0x001F, 0),
            // 10-bit fields.
            (0x3FF0_0000, 0x000F_FC00, 0x0000_03FF, 0),
            // Overlapping fields.
            (0x00FF_0000, 0x00FF_0000, 0x0000_00FF, 0),
            // A missing field.
            (0x00FF_0000, 0x0000_FF00, 0, 0),
            // A field with a hole.
            (0x00FF_0000, 0x0000_FF00, 0x0000_01FE | 0x8000_0000, 0),
            // Reserved bits over a colour.
            (0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0xFF00_00FF),
        ];
        for (red, green, blue, reserved) in refused {
            let format = mask(red, green, blue, reserved);
            assert_eq!(usable_layout(format), Err(Unusable::Bitmask), "{format:x?}");
            assert_eq!(choose(&[gop(format, 640, 480)]), None);
        }
    }

    #[test]
    fn the_gop_line_says_the_pixel_size_or_why_not() {
        use std::string::ToString;
        let bgr_24 = mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0);
        let verdict = |format| Verdict(judge(&gop(format, 1024, 768))).to_string();
        assert_eq!(verdict(bgr_24), "usable, 3 bytes/pixel");
        assert_eq!(verdict(GopFormat::Bgr), "usable, 4 bytes/pixel");
        assert_eq!(verdict(GopFormat::BltOnly), "Blt-only (no framebuffer)");
    }

    fn mode(format: GopFormat, width: usize, height: usize) -> GopMode {
        GopMode {
            format,
            width,
            height,
        }
    }

    /// OVMF's modes on a Cirrus: 32-bit at 640x480 and 800x600, 24-bit at
    /// 1024x768.
    fn cirrus_modes() -> [GopMode; 3] {
        let bgr_24 = mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0);
        [
            mode(GopFormat::Bgr, 640, 480),
            mode(GopFormat::Bgr, 800, 600),
            mode(bgr_24, 1024, 768),
        ]
    }

    #[test]
    fn a_4_byte_mode_is_kept() {
        let modes = cirrus_modes();
        assert_eq!(
            choose_mode(&modes[1], modes),
            ModeChoice::Keep(KeepReason::FourBytes)
        );
    }

    #[test]
    fn a_3_byte_mode_is_kept_when_no_4_byte_mode_has_its_size() {
        // Smaller 4-byte modes are there, but another size might not show.
        let modes = cirrus_modes();
        assert_eq!(
            choose_mode(&modes[2], modes),
            ModeChoice::Keep(KeepReason::NoFourByteModeOfItsSize)
        );
    }

    #[test]
    fn a_4_byte_mode_of_the_same_size_replaces_a_3_byte_one() {
        let [small, medium, bgr_24] = cirrus_modes();
        let xrgb = mode(
            mask(0x00FF_0000, 0x0000_FF00, 0x0000_00FF, 0xFF00_0000),
            1024,
            768,
        );
        let unusable_same_size = mode(GopFormat::BltOnly, 1024, 768);
        let modes = [small, bgr_24, unusable_same_size, medium, xrgb];
        assert_eq!(
            choose_mode(&bgr_24, modes),
            ModeChoice::Set {
                position: 4,
                mode: xrgb
            }
        );
        // A current mode that cannot be drawn on at all gives way the same.
        let blt_only = mode(GopFormat::BltOnly, 800, 600);
        assert_eq!(
            choose_mode(&blt_only, modes),
            ModeChoice::Set {
                position: 3,
                mode: medium
            }
        );
    }

    #[test]
    fn the_largest_usable_of_several_wins() {
        let gops = [
            gop(GopFormat::Rgb, 640, 480),
            gop(GopFormat::BltOnly, 4096, 2160),
            gop(GopFormat::Bgr, 1280, 800),
            gop(GopFormat::Bgr, 1024, 768),
        ];
        assert_eq!(choose(&gops), Some(2));
        // Equals: the first.
        let equals = [gop(GopFormat::Rgb, 800, 600), gop(GopFormat::Bgr, 800, 600)];
        assert_eq!(choose(&equals), Some(0));
    }

    #[test]
    fn the_console_gop_is_preferred_over_a_larger_one() {
        let mut console = gop(GopFormat::Bgr, 800, 600);
        console.on_console = true;
        let gops = [gop(GopFormat::Bgr, 1920, 1080), console];
        assert_eq!(choose(&gops), Some(1));
    }

    #[test]
    fn an_unusable_console_gop_is_passed_over() {
        let mut console = gop(GopFormat::BltOnly, 1280, 800);
        console.on_console = true;
        let gops = [console, gop(GopFormat::Bgr, 640, 480)];
        assert_eq!(choose(&gops), Some(1));
    }

    #[test]
    fn none_usable_means_no_framebuffer() {
        assert_eq!(choose(&[]), None);
        let gops = [
            gop(GopFormat::BltOnly, 1280, 800),
            gop(mask(0xF800, 0x07E0, 0x1F, 0), 640, 480),
            gop(GopFormat::Bgr, 0, 0),
        ];
        assert_eq!(choose(&gops), None);
        assert_eq!(judge(&gops[2]), Err(Unusable::Empty));
    }
}
