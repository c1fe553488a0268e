//! From what firmware says of its framebuffer to the [`FramebufferLayout`]
//! the presenters draw into. The kernel reads the values from the
//! bootloader; everything that decides what they mean is here, so that
//! each format and each impossible report is tested on the host.
//!
//! A framebuffer that cannot be drawn into safely (no pixels, a pixel size
//! no firmware uses, lines that overlap or run past the buffer) is refused
//! with the reason; a well-formed one whose pixel format is not understood
//! is shown in grey, which reads in every 8-bit-per-component layout.

use super::{FirmwareFormat, FramebufferLayout, PixelOrder};

/// A framebuffer as firmware describes it, in plain values (the shape of
/// `bootloader_api`'s `FrameBufferInfo`, without depending on it).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FirmwareFramebuffer {
    /// Bytes of memory the framebuffer covers.
    pub byte_len: usize,
    /// Visible pixels per line.
    pub width: usize,
    /// Visible lines.
    pub height: usize,
    /// Pixels from the start of one line to the start of the next.
    pub stride: usize,
    /// Bytes per pixel.
    pub bytes_per_pixel: usize,
    /// How a pixel's bytes encode a colour, as the firmware names it.
    pub format: FirmwareFormat,
}

/// The layout chosen for a framebuffer firmware described.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayoutChoice {
    /// The layout to present into.
    pub layout: FramebufferLayout,
    /// The pixel format was not understood, so the layout shows grey.
    pub grey_instead: bool,
}

/// Why a framebuffer is not drawn into.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LayoutRefusal {
    /// Bytes per pixel outside 1 to 4 (0 is what a bootloader reports when
    /// it found no video mode).
    BytesPerPixel(usize),
    /// No visible pixels.
    NoPixels {
        /// Visible pixels per line.
        width: usize,
        /// Visible lines.
        height: usize,
    },
    /// Lines shorter than the visible width: each would draw over the next.
    StrideBelowWidth {
        /// Pixels from one line to the next.
        stride: usize,
        /// Visible pixels per line.
        width: usize,
    },
    /// The visible lines reach past the end of the buffer (or their extent
    /// does not even fit in an address).
    BeyondBuffer {
        /// Bytes up to the last visible pixel, if that is a number.
        required: Option<usize>,
        /// Bytes the buffer covers.
        byte_len: usize,
    },
}

impl core::fmt::Display for LayoutRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            LayoutRefusal::BytesPerPixel(bytes) => {
                write!(f, "{bytes} bytes/pixel (1 to 4 are drawn)")
            }
            LayoutRefusal::NoPixels { width, height } => {
                write!(f, "{width}x{height} has no pixels")
            }
            LayoutRefusal::StrideBelowWidth { stride, width } => {
                write!(f, "stride {stride} is less than the width {width}")
            }
            LayoutRefusal::BeyondBuffer {
                required: Some(required),
                byte_len,
            } => write!(
                f,
                "its lines need {required} bytes, the buffer has {byte_len}"
            ),
            LayoutRefusal::BeyondBuffer {
                required: None,
                byte_len,
            } => write!(
                f,
                "its lines need more bytes than an address holds (the buffer has {byte_len})"
            ),
        }
    }
}

impl FramebufferLayout {
    /// A layout with no pixels: presenting into it writes nothing. What a
    /// refused framebuffer gets, so that the demo runs on regardless.
    pub const NOTHING: FramebufferLayout = FramebufferLayout {
        width: 0,
        height: 0,
        stride: 0,
        bytes_per_pixel: 0,
        order: PixelOrder::Grey,
    };
}

impl FirmwareFramebuffer {
    /// The layout to present into, or why there is none. Checks, in order:
    /// the pixel size, that there are pixels, that lines do not overlap, and
    /// that every visible pixel lies inside the buffer; then the pixel format
    /// ([`PixelOrder::for_framebuffer`]), grey when it is not understood.
    pub fn layout(&self) -> Result<LayoutChoice, LayoutRefusal> {
        let &FirmwareFramebuffer {
            byte_len,
            width,
            height,
            stride,
            bytes_per_pixel,
            format,
        } = self;
        if !(1..=4).contains(&bytes_per_pixel) {
            return Err(LayoutRefusal::BytesPerPixel(bytes_per_pixel));
        }
        if width == 0 || height == 0 {
            return Err(LayoutRefusal::NoPixels { width, height });
        }
        if stride < width {
            return Err(LayoutRefusal::StrideBelowWidth { stride, width });
        }
        // Checked: a garbage stride must be refused, not overflow.
        let required = stride
            .checked_mul(bytes_per_pixel)
            .and_then(|line| line.checked_mul(height - 1))
            .and_then(|lines| lines.checked_add(width * bytes_per_pixel));
        if required.is_none_or(|required| required > byte_len) {
            return Err(LayoutRefusal::BeyondBuffer { required, byte_len });
        }
        let order = PixelOrder::for_framebuffer(format, bytes_per_pixel);
        Ok(LayoutChoice {
            layout: FramebufferLayout {
                width,
                height,
                stride,
                bytes_per_pixel,
                order: order.unwrap_or(PixelOrder::Grey),
            },
            grey_instead: order.is_none(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::PackedFormat;
    use std::string::ToString;
    use FirmwareFormat::*;

    /// A 640x480 framebuffer with lines of 1024 pixels and room for them all.
    fn framebuffer(format: FirmwareFormat, bytes_per_pixel: usize) -> FirmwareFramebuffer {
        FirmwareFramebuffer {
            byte_len: 1024 * 480 * bytes_per_pixel,
            width: 640,
            height: 480,
            stride: 1024,
            bytes_per_pixel,
            format,
        }
    }

    fn order_of(format: FirmwareFormat, bytes_per_pixel: usize) -> (PixelOrder, bool) {
        let choice = framebuffer(format, bytes_per_pixel).layout().unwrap();
        assert_eq!(
            (
                choice.layout.width,
                choice.layout.height,
                choice.layout.stride,
                choice.layout.bytes_per_pixel
            ),
            (640, 480, 1024, bytes_per_pixel)
        );
        (choice.layout.order, choice.grey_instead)
    }

    #[test]
    fn byte_orders_of_three_and_four_bytes_are_kept() {
        for bytes in [3, 4] {
            assert_eq!(order_of(Rgb, bytes), (PixelOrder::Rgb, false));
            assert_eq!(order_of(Bgr, bytes), (PixelOrder::Bgr, false));
        }
    }

    #[test]
    fn two_byte_orders_are_5_6_5_with_red_where_the_name_puts_it() {
        assert_eq!(
            order_of(Bgr, 2),
            (PixelOrder::Packed(PackedFormat::RGB565), false)
        );
        let (PixelOrder::Packed(rgb), false) = order_of(Rgb, 2) else {
            panic!("2-byte RGB is a packed format");
        };
        assert_eq!(
            (rgb.red, rgb.blue),
            (PackedFormat::RGB565.blue, PackedFormat::RGB565.red)
        );
    }

    #[test]
    fn grey_is_grey_in_every_size() {
        for bytes in 1..=4 {
            assert_eq!(order_of(Grey, bytes), (PixelOrder::Grey, false));
        }
    }

    #[test]
    fn bit_masks_become_packed_formats() {
        let offsets = |red, green, blue| BitOffsets { red, green, blue };
        assert_eq!(
            order_of(offsets(11, 5, 0), 2),
            (PixelOrder::Packed(PackedFormat::RGB565), false)
        );
        assert_eq!(
            order_of(offsets(10, 5, 0), 2),
            (PixelOrder::Packed(PackedFormat::RGB555), false)
        );
        let (PixelOrder::Packed(xrgb), false) = order_of(offsets(16, 8, 0), 4) else {
            panic!("8-8-8 by offsets is a packed format");
        };
        assert_eq!(PixelOrder::Packed(xrgb).encode([1, 2, 3]), [3, 2, 1, 0]);
    }

    #[test]
    fn formats_not_understood_show_grey() {
        let shared_offset = BitOffsets {
            red: 5,
            green: 5,
            blue: 0,
        };
        let field_past_the_pixel = BitOffsets {
            red: 16,
            green: 8,
            blue: 0,
        };
        for (format, bytes) in [
            (Other, 4),
            (shared_offset, 2),
            (field_past_the_pixel, 2),
            (Rgb, 1),
            (Bgr, 1),
        ] {
            assert_eq!(
                order_of(format, bytes),
                (PixelOrder::Grey, true),
                "{format:?}, {bytes} bytes"
            );
        }
    }

    #[test]
    fn pixel_sizes_outside_one_to_four_bytes_are_refused() {
        for bytes in [0, 5, 8, usize::MAX] {
            let mut bad = framebuffer(Bgr, 4);
            bad.bytes_per_pixel = bytes;
            assert_eq!(bad.layout(), Err(LayoutRefusal::BytesPerPixel(bytes)));
        }
    }

    #[test]
    fn no_video_mode_at_all_is_refused_for_its_pixel_size() {
        // What the BIOS stage reports when it found no VESA mode: all zero.
        let none = FirmwareFramebuffer {
            byte_len: 0,
            width: 0,
            height: 0,
            stride: 0,
            bytes_per_pixel: 0,
            format: Rgb,
        };
        assert_eq!(none.layout(), Err(LayoutRefusal::BytesPerPixel(0)));
    }

    #[test]
    fn an_empty_screen_is_refused() {
        let mut bad = framebuffer(Bgr, 4);
        bad.width = 0;
        assert_eq!(
            bad.layout(),
            Err(LayoutRefusal::NoPixels {
                width: 0,
                height: 480
            })
        );
        let mut bad = framebuffer(Bgr, 4);
        bad.height = 0;
        assert_eq!(
            bad.layout(),
            Err(LayoutRefusal::NoPixels {
                width: 640,
                height: 0
            })
        );
    }

    #[test]
    fn a_zero_or_short_stride_is_refused() {
        for stride in [0, 1, 639] {
            let mut bad = framebuffer(Bgr, 4);
            bad.stride = stride;
            assert_eq!(
                bad.layout(),
                Err(LayoutRefusal::StrideBelowWidth { stride, width: 640 })
            );
        }
        let mut exact = framebuffer(Bgr, 4);
        exact.stride = 640;
        assert!(exact.layout().is_ok());
    }

    #[test]
    fn lines_past_the_buffer_are_refused() {
        // The last visible pixel ends exactly at the buffer's end: fine.
        let mut fits = framebuffer(Bgr, 4);
        fits.byte_len = (1024 * 479 + 640) * 4;
        assert!(fits.layout().is_ok());
        let mut short = fits;
        short.byte_len -= 1;
        assert_eq!(
            short.layout(),
            Err(LayoutRefusal::BeyondBuffer {
                required: Some((1024 * 479 + 640) * 4),
                byte_len: short.byte_len
            })
        );
        // A stride too large for the buffer.
        let mut oversize = framebuffer(Bgr, 4);
        oversize.stride = 4096;
        assert_eq!(
            oversize.layout(),
            Err(LayoutRefusal::BeyondBuffer {
                required: Some((4096 * 479 + 640) * 4),
                byte_len: 1024 * 480 * 4
            })
        );
    }

    #[test]
    fn a_stride_whose_extent_overflows_is_refused_not_wrapped() {
        let mut garbage = framebuffer(Bgr, 4);
        garbage.stride = usize::MAX / 2;
        assert_eq!(
            garbage.layout(),
            Err(LayoutRefusal::BeyondBuffer {
                required: None,
                byte_len: 1024 * 480 * 4
            })
        );
    }

    #[test]
    fn refusals_say_why_in_words() {
        let said = |refusal: LayoutRefusal| refusal.to_string();
        assert_eq!(
            said(LayoutRefusal::BytesPerPixel(0)),
            "0 bytes/pixel (1 to 4 are drawn)"
        );
        assert_eq!(
            said(LayoutRefusal::StrideBelowWidth {
                stride: 0,
                width: 640
            }),
            "stride 0 is less than the width 640"
        );
        assert_eq!(
            said(LayoutRefusal::BeyondBuffer {
                required: Some(10),
                byte_len: 9
            }),
            "its lines need 10 bytes, the buffer has 9"
        );
    }

    #[test]
    fn the_empty_layout_presents_nothing() {
        let mut soft = std::boxed::Box::new(crate::soft::SoftVga::new());
        crate::ModeX::new(&mut *soft).set_mode();
        let mut presenter = std::boxed::Box::new(crate::present::Presenter::new());
        let mut out = [0xEEu8; 64];
        let report = presenter.present(&soft, &FramebufferLayout::NOTHING, &mut out);
        assert_eq!(report.bytes_written, 0);
        assert_eq!(out, [0xEE; 64]);
    }
}
