//! RGB pictures on the host: QEMU's screendump (binary PPM) in, PNG out, and
//! the comparison of QEMU's doubled 640x480 Mode X picture with a 320x240 one.

use std::fmt;
use std::path::Path;

/// One differing pixel: x, y, this picture's colour, the other's.
pub type PixelDifference = (usize, usize, [u8; 3], [u8; 3]);

#[derive(Clone, PartialEq, Eq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    /// Row-major, three bytes a pixel.
    pub pixels: Vec<[u8; 3]>,
}

impl fmt::Debug for RgbImage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "RgbImage({}x{})", self.width, self.height)
    }
}

impl RgbImage {
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

    pub fn pixel(&self, x: usize, y: usize) -> [u8; 3] {
        self.pixels[y * self.width + x]
    }

    /// Parses a binary PPM (P6, maxval 255), as QEMU's `screendump` writes it.
    pub fn from_ppm(bytes: &[u8]) -> Result<Self, String> {
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
                return Err("PPM header ends early".into());
            }
            fields.push(String::from_utf8_lossy(&bytes[start..at]).into_owned());
        }
        at += 1; // the single whitespace byte before the raster
        if fields[0] != "P6" || fields[3] != "255" {
            return Err(format!(
                "not a binary 8-bit PPM (magic {}, maxval {})",
                fields[0], fields[3]
            ));
        }
        let parse = |s: &str| {
            s.parse::<usize>()
                .map_err(|_| format!("bad PPM size field {s:?}"))
        };
        let (width, height) = (parse(&fields[1])?, parse(&fields[2])?);
        let raster = bytes
            .get(at..at + width * height * 3)
            .ok_or("PPM raster is truncated")?;
        let pixels = raster.as_chunks::<3>().0.to_vec();
        Ok(RgbImage::new(width, height, pixels))
    }

    pub fn write_png(&self, path: &Path) -> Result<(), String> {
        let file = std::fs::File::create(path)
            .map_err(|e| format!("cannot create {}: {e}", path.display()))?;
        let mut encoder = png::Encoder::new(
            std::io::BufWriter::new(file),
            self.width as u32,
            self.height as u32,
        );
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
        writer
            .write_image_data(self.pixels.as_flattened())
            .map_err(|e| e.to_string())
    }

    /// Undoes QEMU's doubling of a 320x240 Mode X picture into 640x480: every
    /// 2x2 block must be one colour, or the picture was not a doubled one.
    pub fn halve(&self) -> Result<RgbImage, String> {
        if !self.width.is_multiple_of(2) || !self.height.is_multiple_of(2) {
            return Err(format!("{}x{} cannot be halved", self.width, self.height));
        }
        let (width, height) = (self.width / 2, self.height / 2);
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let colour = self.pixel(2 * x, 2 * y);
                for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
                    if self.pixel(2 * x + dx, 2 * y + dy) != colour {
                        return Err(format!("2x2 block at ({x}, {y}) is not one colour"));
                    }
                }
                pixels.push(colour);
            }
        }
        Ok(RgbImage::new(width, height, pixels))
    }

    /// Where two pictures of the same size differ: the count and the first few.
    pub fn differences(&self, other: &RgbImage) -> Result<Vec<PixelDifference>, String> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(format!(
                "sizes differ: {}x{} and {}x{}",
                self.width, self.height, other.width, other.height
            ));
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
        assert!(image.halve().is_err());
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
    }

    #[test]
    fn truncated_ppm_is_an_error() {
        assert!(RgbImage::from_ppm(b"P6 4 4 255\n\x00\x00").is_err());
        assert!(RgbImage::from_ppm(b"P3 1 1 255\n0 0 0").is_err());
    }
}
