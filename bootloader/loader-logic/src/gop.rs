//! Choosing the GOP to draw on. Firmware may offer several: one per display
//! adapter, plus the console splitter's. Some have no framebuffer at all
//! (`PixelBltOnly`, e.g. virtio-gpu under OVMF), and a bit-mask format is only
//! of use when the kernel's presenter can encode it. The choice: only usable
//! ones; of those, the one on the console-output (ConOut) handle, which is
//! the one the firmware shows its own text on; else the largest.

/// A GOP mode's pixel format as UEFI gives it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GopFormat {
    /// 8-bit red, green, blue, reserved in byte order.
    Rgb,
    /// 8-bit blue, green, red, reserved in byte order.
    Bgr,
    /// Components where these masks of the 32-bit pixel put them.
    Bitmask {
        /// Red's mask.
        red: u32,
        /// Green's mask.
        green: u32,
        /// Blue's mask.
        blue: u32,
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
    /// 8-bit components at these bit positions of a 32-bit pixel.
    BitPositions {
        /// Red's lowest bit.
        red: u8,
        /// Green's lowest bit.
        green: u8,
        /// Blue's lowest bit.
        blue: u8,
    },
}

/// Why a GOP's mode cannot be drawn on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Unusable {
    /// `PixelBltOnly`: there is no framebuffer.
    BltOnly,
    /// A bit mask that is not three separate 8-bit fields: the kernel's
    /// presenter takes only components' positions, each 8 bits wide.
    Bitmask,
    /// No pixels (a zero width or height).
    Empty,
}

impl Unusable {
    /// Why, in words.
    pub fn as_str(self) -> &'static str {
        match self {
            Unusable::BltOnly => "Blt-only (no framebuffer)",
            Unusable::Bitmask => "a bit mask other than three 8-bit fields",
            Unusable::Empty => "no pixels",
        }
    }
}

impl core::fmt::Display for Unusable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.as_str())
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

/// The format to hand on for `format`, or why it cannot be used.
pub fn usable_format(format: GopFormat) -> Result<UsableFormat, Unusable> {
    match format {
        GopFormat::Rgb => Ok(UsableFormat::Rgb),
        GopFormat::Bgr => Ok(UsableFormat::Bgr),
        GopFormat::BltOnly => Err(Unusable::BltOnly),
        GopFormat::Bitmask { red, green, blue } => {
            let field = |mask: u32| {
                let low = mask.trailing_zeros();
                (mask != 0 && mask >> low == 0xFF).then_some(low as u8)
            };
            match (field(red), field(green), field(blue)) {
                (Some(r), Some(g), Some(b))
                    if red & green == 0 && green & blue == 0 && red & blue == 0 =>
                {
                    Ok(UsableFormat::BitPositions {
                        red: r,
                        green: g,
                        blue: b,
                    })
                }
                _ => Err(Unusable::Bitmask),
            }
        }
    }
}

/// Whether a candidate can be drawn on, and in which format.
pub fn judge(candidate: &GopCandidate) -> Result<UsableFormat, Unusable> {
    let format = usable_format(candidate.format)?;
    if candidate.width == 0 || candidate.height == 0 {
        return Err(Unusable::Empty);
    }
    Ok(format)
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

    #[test]
    fn bitmasks_of_three_8_bit_fields_become_positions() {
        let xrgb = GopFormat::Bitmask {
            red: 0x00FF_0000,
            green: 0x0000_FF00,
            blue: 0x0000_00FF,
        };
        assert_eq!(
            usable_format(xrgb),
            Ok(UsableFormat::BitPositions {
                red: 16,
                green: 8,
                blue: 0
            })
        );
        let high = GopFormat::Bitmask {
            red: 0xFF00_0000,
            green: 0x00FF_0000,
            blue: 0x0000_FF00,
        };
        assert_eq!(
            usable_format(high),
            Ok(UsableFormat::BitPositions {
                red: 24,
                green: 16,
                blue: 8
            })
        );
    }

    #[test]
    fn other_bitmasks_are_refused() {
        let refused = [
            // 5-6-5 in a 32-bit pixel: fields narrower than 8 bits.
            (0xF800, 0x07E0, 0x001F),
            // 10-bit fields.
            (0x3FF0_0000, 0x000F_FC00, 0x0000_03FF),
            // Overlapping fields.
            (0x00FF_0000, 0x00FF_0000, 0x0000_00FF),
            // A missing field.
            (0x00FF_0000, 0x0000_FF00, 0),
            // A field with a hole.
            (0x00FF_0000, 0x0000_FF00, 0x0000_01FE | 0x8000_0000),
        ];
        for (red, green, blue) in refused {
            let format = GopFormat::Bitmask { red, green, blue };
            assert_eq!(usable_format(format), Err(Unusable::Bitmask), "{format:x?}");
            assert_eq!(choose(&[gop(format, 640, 480)]), None);
        }
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
            gop(
                GopFormat::Bitmask {
                    red: 0xF800,
                    green: 0x07E0,
                    blue: 0x1F,
                },
                640,
                480,
            ),
            gop(GopFormat::Bgr, 0, 0),
        ];
        assert_eq!(choose(&gops), None);
        assert_eq!(judge(&gops[2]), Err(Unusable::Empty));
    }
}
