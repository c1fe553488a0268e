//! RGB pictures on the host: QEMU's screendump (binary PPM) in, PNG out, and
//! the comparison of QEMU's doubled 640x480 Mode X picture with a 320x240 one.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// Why a picture could not be read, written, halved or compared.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The PPM ends inside its header.
    #[error("PPM header ends early")]
    PpmHeaderEndsEarly,
    /// A PPM, but not P6 with 8-bit components.
    #[error("not a binary 8-bit PPM (magic {magic}, maxval {maxval})")]
    PpmNotBinary8Bit {
        /// The first header field, `P6` in a binary PPM.
        magic: String,
        /// The largest component value; only 255 is read.
        maxval: String,
    },
    /// A width or height that is not a number.
    #[error("bad PPM size field {0:?}")]
    PpmBadSize(String),
    /// Fewer pixels than the header says.
    #[error("PPM raster is truncated")]
    PpmTruncated,
    /// The PNG file could not be created.
    #[error("cannot create {}: {error}", path.display())]
    CreatePng {
        /// The PNG that was to be written.
        path: PathBuf,
        /// Why the file could not be created.
        error: io::Error,
    },
    /// The PNG could not be written into the file.
    #[error("cannot write the PNG {}: {error}", path.display())]
    WritePng {
        /// The PNG being written.
        path: PathBuf,
        /// The encoder's or the file's failure.
        error: png::EncodingError,
    },
    /// Odd sizes cannot be a doubled picture.
    #[error("{width}x{height} cannot be halved")]
    OddSize {
        /// The picture's width in pixels.
        width: usize,
        /// The picture's height in pixels.
        height: usize,
    },
    /// A 2x2 block of two colours: not a doubled picture.
    #[error("2x2 block at ({x}, {y}) is not one colour")]
    NotDoubled {
        /// The block's column in the halved picture.
        x: usize,
        /// The block's row in the halved picture.
        y: usize,
    },
    /// Pictures of different sizes have no pixel-by-pixel differences.
    #[error("sizes differ: {}x{} and {}x{}", .this.0, .this.1, .other.0, .other.1)]
    SizesDiffer {
        /// Width and height of the picture compared.
        this: (usize, usize),
        /// Width and height of the picture it was compared with.
        other: (usize, usize),
    },
}

/// One differing pixel: x, y, this picture's colour, the other's.
pub type PixelDifference = (usize, usize, [u8; 3], [u8; 3]);

/// An 8-bit RGB picture: what QEMU's screendump, Bochs's window capture and
/// the software VGA's scan-out are all turned into to be compared.
#[derive(Clone, PartialEq, Eq)]
pub struct RgbImage {
    /// Pixels a row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Row-major, three bytes a pixel.
    pub pixels: Vec<[u8; 3]>,
}

impl fmt::Debug for RgbImage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RgbImage({}x{})", self.width, self.height)
    }
}

impl From<xvfb::xwd::Image> for RgbImage {
    fn from(image: xvfb::xwd::Image) -> Self {
        RgbImage::new(image.width, image.height, image.pixels)
    }
}

impl RgbImage {
    /// A picture from its row-major pixels.
    ///
    /// # Panics
    ///
    /// If there are not `width * height` pixels.
    pub fn new(width: usize, height: usize, pixels: Vec<[u8; 3]>) -> Self {
        assert_eq!(
            pixels.len(),
            width * height,
            "pixel count must match the size"
        );
        RgbImage {
            width,
            height,
            pixels,
        }
    }

    /// The colour at column `x`, row `y`; panics outside the picture.
    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        self.pixels[y * self.width + x]
    }

    /// Parses a binary PPM (P6, maxval 255), as QEMU's `screendump` writes it.
    pub fn from_ppm(bytes: &[u8]) -> Result<Self, ImageError> {
        let mut fields = Vec::new();
        let mut at = 0;
        while fields.len() < 4 {
            while at < bytes.len() && bytes[at].is_ascii_whitespace() {
                at += 1;
            }
            if at < bytes.len() && bytes[at] == b'#' {
                while at < bytes.len() && bytes[at] != b'\n' {
                    at += 1;
                }
                continue;
            }
            let start = at;
            while at < bytes.len() && !bytes[at].is_ascii_whitespace() {
                at += 1;
            }
            if start == at {
                return Err(ImageError::PpmHeaderEndsEarly);
            }
            fields.push(String::from_utf8_lossy(&bytes[start..at]).into_owned());
        }
        at += 1; // the single whitespace byte before the raster
        if fields[0] != "P6" || fields[3] != "255" {
            return Err(ImageError::PpmNotBinary8Bit {
                magic: fields[0].clone(),
                maxval: fields[3].clone(),
            });
        }
        let parse = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| ImageError::PpmBadSize(s.to_owned()))
        };
        let (width, height) = (parse(&fields[1])?, parse(&fields[2])?);
        let raster = bytes
            .get(at..at + width * height * 3)
            .ok_or(ImageError::PpmTruncated)?;
        let pixels = raster.as_chunks::<3>().0.to_vec();
        Ok(RgbImage::new(width, height, pixels))
    }

    /// Saves the picture as an 8-bit RGB PNG, for a person to look at when a
    /// comparison fails.
    pub fn write_png(&self, path: &Path) -> Result<(), ImageError> {
        let file = std::fs::File::create(path).map_err(|error| ImageError::CreatePng {
            path: path.to_owned(),
            error,
        })?;
        let png_error = |error| ImageError::WritePng {
            path: path.to_owned(),
            error,
        };
        let mut encoder = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(png_error)?;
        writer
            .write_image_data(self.pixels.as_flattened())
            .map_err(png_error)
    }

    /// Undoes QEMU's doubling of a 320x240 Mode X picture into 640x480: every
    /// 2x2 block must be one colour, or the picture was not a doubled one.
    pub fn halve(&self) -> Result<RgbImage, ImageError> {
        if !self.width.is_multiple_of(2) || !self.height.is_multiple_of(2) {
            return Err(ImageError::OddSize {
                width: self.width,
                height: self.height,
            });
        }
        let (width, height) = (self.width / 2, self.height / 2);
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let colour = self.pixel(2 * x, 2 * y);
                for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                    if self.pixel(2 * x + dx, 2 * y + dy) != colour {
                        return Err(ImageError::NotDoubled { x, y });
                    }
                }
                pixels.push(colour);
            }
        }
        Ok(RgbImage::new(width, height, pixels))
    }

    /// Where two pictures of the same size differ: the count and the first few.
    pub fn differences(&self, other: &RgbImage) -> Result<Vec<PixelDifference>, ImageError> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(ImageError::SizesDiffer {
                this: (self.width, self.height),
                other: (other.width, other.height),
            });
        }
        Ok((0..self.pixels.len())
            .filter(|&i| self.pixels[i] != other.pixels[i])
            .map(|i| {
                (
                    i % self.width,
                    i / self.width,
                    self.pixels[i],
                    other.pixels[i],
                )
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ppm_round_trip_and_halving() {
        let mut ppm = b"P6\n# a comment\n4 2\n255\n".to_vec();
        for y in 0..2 {
            for x in 0..4 {
                ppm.extend_from_slice(&[(x / 2) as u8 * 100, y as u8, 7]);
            }
        }
        let image = RgbImage::from_ppm(&ppm).unwrap();
        assert_eq!((image.width, image.height), (4, 2));
        assert_eq!(image.pixel(3, 1), [100, 1, 7]);
        // Rows differ (y is in green), so it is not a doubled picture.
        assert!(matches!(
            image.halve(),
            Err(ImageError::NotDoubled { x: 0, y: 0 })
        ));
    }

    #[test]
    fn halving_recovers_the_small_picture() {
        let small = RgbImage::new(2, 1, vec![[1, 2, 3], [4, 5, 6]]);
        let big = RgbImage::new(
            4,
            2,
            [
                small.pixels[0],
                small.pixels[0],
                small.pixels[1],
                small.pixels[1],
            ]
            .repeat(2),
        );
        assert_eq!(big.halve().unwrap(), small);
        assert_eq!(big.differences(&big).unwrap().len(), 0);
        assert!(matches!(
            big.differences(&small),
            Err(ImageError::SizesDiffer {
                this: (4, 2),
                other: (2, 1)
            })
        ));
    }

    #[test]
    fn truncated_ppm_is_an_error() {
        assert!(matches!(
            RgbImage::from_ppm(b"P6 4 4 255\n\x00\x00"),
            Err(ImageError::PpmTruncated)
        ));
        let error = RgbImage::from_ppm(b"P3 1 1 255\n0 0 0").unwrap_err();
        assert_eq!(
            error.to_string(),
            "not a binary 8-bit PPM (magic P3, maxval 255)"
        );
        assert!(matches!(
            RgbImage::from_ppm(b"P6 4"),
            Err(ImageError::PpmHeaderEndsEarly)
        ));
    }
}
