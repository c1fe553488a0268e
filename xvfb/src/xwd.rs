//! X Window Dump files, as `xwd -id WINDOW` writes them, read into an
//! [`Image`]: how the tests see a window.
//!
//! The format (X11's `XWDFile.h`): a header of 25 big-endian 32-bit fields,
//! the window's name, `ncolors` colour entries of 12 bytes, then the pixels in
//! Z format, `bytes_per_line` a row, each pixel `bits_per_pixel` wide in the
//! header's `byte_order`. `xwd` writes the header and colours big-endian
//! whatever the host; only the pixels keep the X server's byte order.

/// A picture read from an XWD file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    /// Pixels a row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Row-major, red, green and blue a pixel.
    pub pixels: Vec<[u8; 3]>,
}

/// Why an XWD file could not be read.
#[derive(Debug, thiserror::Error)]
pub enum XwdError {
    /// Shorter than the fixed part of the header.
    #[error("XWD header is truncated")]
    HeaderTruncated,
    /// Another version of the format, or an XY (plane by plane) pixmap.
    #[error("not a version-7 Z-pixmap XWD (version {version}, format {format})")]
    NotVersion7ZPixmap {
        /// `file_version`.
        version: u32,
        /// `pixmap_format`.
        format: u32,
    },
    /// A pixel size other than 8, 16, 24 or 32 bits.
    #[error("XWD with {0} bits a pixel")]
    BitsPerPixel(usize),
    /// `bytes_per_line` is less than a row of pixels takes.
    #[error("XWD rows of {bytes_per_line} bytes hold no {width} pixels")]
    ShortRows {
        /// `bytes_per_line`.
        bytes_per_line: usize,
        /// `pixmap_width`.
        width: usize,
    },
    /// The file ends inside the colour map.
    #[error("XWD colour map is truncated")]
    ColourMapTruncated,
    /// The file ends before the last row of pixels.
    #[error("XWD pixels are truncated")]
    PixelsTruncated,
}

const HEADER_FIELDS: usize = 25;
const HEADER_BYTES: usize = HEADER_FIELDS * 4;
const COLOUR_BYTES: usize = 12;
const FILE_VERSION: u32 = 7;
const Z_PIXMAP: u32 = 2;
/// `byte_order`: LSBFirst is 0, MSBFirst 1.
const LSB_FIRST: u32 = 0;
/// X visual classes whose pixels hold the colour in the red/green/blue masks;
/// the other classes index the colour map.
const TRUE_COLOR: u32 = 4;
const DIRECT_COLOR: u32 = 5;

/// Header fields, by their index in `XWDFileHeader`.
mod field {
    pub const HEADER_SIZE: usize = 0;
    pub const FILE_VERSION: usize = 1;
    pub const PIXMAP_FORMAT: usize = 2;
    pub const PIXMAP_WIDTH: usize = 4;
    pub const PIXMAP_HEIGHT: usize = 5;
    pub const BYTE_ORDER: usize = 7;
    pub const BITS_PER_PIXEL: usize = 11;
    pub const BYTES_PER_LINE: usize = 12;
    pub const VISUAL_CLASS: usize = 13;
    pub const RED_MASK: usize = 14;
    pub const GREEN_MASK: usize = 15;
    pub const BLUE_MASK: usize = 16;
    pub const NCOLORS: usize = 19;
}

/// Parses an XWD file of a Z-format pixmap of 8, 16, 24 or 32 bits a pixel.
pub fn parse(bytes: &[u8]) -> Result<Image, XwdError> {
    let header: Vec<u32> = bytes
        .get(..HEADER_BYTES)
        .ok_or(XwdError::HeaderTruncated)?
        .as_chunks::<4>()
        .0
        .iter()
        .map(|b| u32::from_be_bytes(*b))
        .collect();
    let value = |i: usize| header[i] as usize;
    if header[field::FILE_VERSION] != FILE_VERSION || header[field::PIXMAP_FORMAT] != Z_PIXMAP {
        return Err(XwdError::NotVersion7ZPixmap {
            version: header[field::FILE_VERSION],
            format: header[field::PIXMAP_FORMAT],
        });
    }
    let (width, height) = (value(field::PIXMAP_WIDTH), value(field::PIXMAP_HEIGHT));
    let bits_per_pixel = value(field::BITS_PER_PIXEL);
    if ![8, 16, 24, 32].contains(&bits_per_pixel) {
        return Err(XwdError::BitsPerPixel(bits_per_pixel));
    }
    let bytes_per_pixel = bits_per_pixel / 8;
    let bytes_per_line = value(field::BYTES_PER_LINE);
    if bytes_per_line < width * bytes_per_pixel {
        return Err(XwdError::ShortRows {
            bytes_per_line,
            width,
        });
    }

    let colours_at = value(field::HEADER_SIZE);
    let colour_count = value(field::NCOLORS);
    // Checked: the sizes come from the file, and a nonsense header must be
    // an error, not an overflow.
    let pixels_at = colour_count
        .checked_mul(COLOUR_BYTES)
        .and_then(|colours| colours.checked_add(colours_at))
        .ok_or(XwdError::ColourMapTruncated)?;
    let colour_map = bytes
        .get(colours_at..pixels_at)
        .ok_or(XwdError::ColourMapTruncated)?;
    let raster = bytes_per_line
        .checked_mul(height)
        .and_then(|raster| raster.checked_add(pixels_at))
        .and_then(|end| bytes.get(pixels_at..end))
        .ok_or(XwdError::PixelsTruncated)?;

    let decode: Box<dyn Fn(u32) -> [u8; 3]> = match header[field::VISUAL_CLASS] {
        TRUE_COLOR | DIRECT_COLOR => {
            let masks = [
                header[field::RED_MASK],
                header[field::GREEN_MASK],
                header[field::BLUE_MASK],
            ];
            Box::new(move |pixel| masks.map(|mask| component(pixel, mask)))
        }
        _ => {
            let map = parse_colour_map(colour_map);
            Box::new(move |pixel| {
                map.iter()
                    .find(|(value, _)| *value == pixel)
                    .map_or([0; 3], |(_, rgb)| *rgb)
            })
        }
    };
    let least_significant_first = header[field::BYTE_ORDER] == LSB_FIRST;
    let mut pixels = Vec::with_capacity(width * height);
    for row in raster.chunks_exact(bytes_per_line) {
        for bytes in row[..width * bytes_per_pixel].chunks_exact(bytes_per_pixel) {
            let pixel = if least_significant_first {
                bytes
                    .iter()
                    .rev()
                    .fold(0u32, |v, &b| (v << 8) | u32::from(b))
            } else {
                bytes.iter().fold(0u32, |v, &b| (v << 8) | u32::from(b))
            };
            pixels.push(decode(pixel));
        }
    }
    Ok(Image {
        width,
        height,
        pixels,
    })
}

/// One colour component under `mask`, widened to 8 bits. With the usual
/// 8-bit masks of a 24-bit visual this is the component itself; narrower
/// masks (a 16-bit visual) are scaled so that their maximum is 255.
fn component(pixel: u32, mask: u32) -> u8 {
    if mask == 0 {
        return 0;
    }
    let value = (pixel & mask) >> mask.trailing_zeros();
    let maximum = mask >> mask.trailing_zeros();
    ((u64::from(value) * 255 + u64::from(maximum) / 2) / u64::from(maximum)) as u8
}

/// XWDColor entries: pixel value (32 bits), then 16-bit red, green and blue.
fn parse_colour_map(bytes: &[u8]) -> Vec<(u32, [u8; 3])> {
    bytes
        .as_chunks::<COLOUR_BYTES>()
        .0
        .iter()
        .map(|c| {
            let pixel = u32::from_be_bytes([c[0], c[1], c[2], c[3]]);
            // The high byte of each 16-bit component is its 8-bit value.
            (pixel, [c[4], c[6], c[8]])
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An XWD as `xwd` writes it for a 24-bit TrueColor window on a
    /// little-endian X server: 32 bits a pixel, rows padded to `bytes_per_line`.
    fn true_colour_xwd(width: u32, pixels: &[u32], bytes_per_line: u32, lsb: bool) -> Vec<u8> {
        let name = b"bochs\0";
        let height = pixels.len() as u32 / width;
        let mut header = [0u32; HEADER_FIELDS];
        header[field::HEADER_SIZE] = (HEADER_BYTES + name.len()) as u32;
        header[field::FILE_VERSION] = FILE_VERSION;
        header[field::PIXMAP_FORMAT] = Z_PIXMAP;
        header[3] = 24; // depth
        header[field::PIXMAP_WIDTH] = width;
        header[field::PIXMAP_HEIGHT] = height;
        header[field::BYTE_ORDER] = if lsb { LSB_FIRST } else { 1 };
        header[field::BITS_PER_PIXEL] = 32;
        header[field::BYTES_PER_LINE] = bytes_per_line;
        header[field::VISUAL_CLASS] = TRUE_COLOR;
        header[field::RED_MASK] = 0xFF0000;
        header[field::GREEN_MASK] = 0x00FF00;
        header[field::BLUE_MASK] = 0x0000FF;
        header[field::NCOLORS] = 1; // xwd lists colours even for TrueColor
        let mut file: Vec<u8> = header.iter().flat_map(|f| f.to_be_bytes()).collect();
        file.extend_from_slice(name);
        file.extend_from_slice(&[0; COLOUR_BYTES]);
        for row in pixels.chunks(width as usize) {
            let mut line: Vec<u8> = row
                .iter()
                .flat_map(|p| {
                    if lsb {
                        p.to_le_bytes()
                    } else {
                        p.to_be_bytes()
                    }
                })
                .collect();
            line.resize(bytes_per_line as usize, 0xEE);
            file.extend_from_slice(&line);
        }
        file
    }

    #[test]
    fn true_colour_in_either_byte_order_with_padded_rows() {
        let pixels = [0x00FC0000, 0x0000FC04, 0x00010203, 0x00FFFFFF];
        for lsb in [true, false] {
            let image = parse(&true_colour_xwd(2, &pixels, 12, lsb)).unwrap();
            assert_eq!((image.width, image.height), (2, 2));
            assert_eq!(
                image.pixels,
                vec![[252, 0, 0], [0, 252, 4], [1, 2, 3], [255, 255, 255]]
            );
        }
    }

    #[test]
    fn narrow_masks_are_widened() {
        assert_eq!(component(0xF800, 0xF800), 255);
        assert_eq!(component(0x07E0, 0x07E0), 255);
        assert_eq!(component(0x0000, 0x001F), 0);
    }

    #[test]
    fn truncated_or_foreign_files_are_errors() {
        let file = true_colour_xwd(2, &[0; 4], 8, true);
        assert!(matches!(
            parse(&file[..file.len() - 1]),
            Err(XwdError::PixelsTruncated)
        ));
        assert!(matches!(parse(&file[..50]), Err(XwdError::HeaderTruncated)));
        let mut version_6 = file.clone();
        version_6[7] = 6;
        assert!(matches!(
            parse(&version_6),
            Err(XwdError::NotVersion7ZPixmap {
                version: 6,
                format: Z_PIXMAP
            })
        ));
        let mut huge_colour_map = file.clone();
        huge_colour_map[field::NCOLORS * 4..][..4].copy_from_slice(&u32::MAX.to_be_bytes());
        assert!(parse(&huge_colour_map).is_err());
    }
}
