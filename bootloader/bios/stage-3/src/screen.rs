use bootloader_x86_64_bios_common::{BiosFramebufferInfo, PixelFormat, racy_cell::RacyCell};
use core::{fmt, ptr};
use noto_sans_mono_bitmap::{BitmapChar, BitmapHeight, FontWeight, get_bitmap};

static WRITER: RacyCell<Option<ScreenWriter>> = RacyCell::new(None);
pub struct Writer;

impl fmt::Write for Writer {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        // Patched: with no framebuffer there is no writer, and text goes nowhere.
        match unsafe { WRITER.get_mut() }.as_mut() {
            Some(writer) => writer.write_str(s),
            None => Ok(()),
        }
    }
}

pub fn init(info: BiosFramebufferInfo) {
    // Patched: stage 2 hands on a zero-length region when it set no VESA mode.
    if info.region.len == 0 {
        return;
    }
    let framebuffer = unsafe {
        core::slice::from_raw_parts_mut(
            info.region.start as *mut u8,
            info.region.len.try_into().unwrap(),
        )
    };
    let writer = ScreenWriter::new(framebuffer, info);
    *unsafe { WRITER.get_mut() } = Some(writer);
}

/// Additional vertical space between lines
const LINE_SPACING: usize = 0;

struct ScreenWriter {
    framebuffer: &'static mut [u8],
    info: BiosFramebufferInfo,
    x_pos: usize,
    y_pos: usize,
}

impl ScreenWriter {
    pub fn new(framebuffer: &'static mut [u8], info: BiosFramebufferInfo) -> Self {
        let mut logger = Self {
            framebuffer,
            info,
            x_pos: 0,
            y_pos: 0,
        };
        logger.clear();
        logger
    }

    fn newline(&mut self) {
        self.y_pos += 14 + LINE_SPACING;
        self.carriage_return()
    }

    fn carriage_return(&mut self) {
        self.x_pos = 0;
    }

    /// Erases all text on the screen.
    pub fn clear(&mut self) {
        self.x_pos = 0;
        self.y_pos = 0;
        self.framebuffer.fill(0);
    }

    fn width(&self) -> usize {
        self.info.width.into()
    }

    fn height(&self) -> usize {
        self.info.height.into()
    }

    fn write_char(&mut self, c: char) {
        match c {
            '\n' => self.newline(),
            '\r' => self.carriage_return(),
            c => {
                let bitmap_char = get_bitmap(c, FontWeight::Regular, BitmapHeight::Size14).unwrap();
                if self.x_pos + bitmap_char.width() > self.width() {
                    self.newline();
                }
                if self.y_pos + bitmap_char.height() > self.height() {
                    self.clear();
                }
                self.write_rendered_char(bitmap_char);
            }
        }
    }

    fn write_rendered_char(&mut self, rendered_char: BitmapChar) {
        for (y, row) in rendered_char.bitmap().iter().enumerate() {
            for (x, byte) in row.iter().enumerate() {
                self.write_pixel(self.x_pos + x, self.y_pos + y, *byte);
            }
        }
        self.x_pos += rendered_char.width();
    }

    fn write_pixel(&mut self, x: usize, y: usize, intensity: u8) {
        let pixel_offset = y * usize::from(self.info.stride) + x;
        let color = match self.info.pixel_format {
            PixelFormat::Rgb => [intensity, intensity, intensity / 2, 0],
            PixelFormat::Bgr => [intensity / 2, intensity, intensity, 0],
            other => {
                // set a supported (but invalid) pixel format before panicking to avoid a double
                // panic; it might not be readable though
                self.info.pixel_format = PixelFormat::Rgb;
                panic!("pixel format {:?} not supported in logger", other)
            }
        };
        let bytes_per_pixel = self.info.bytes_per_pixel;
        let byte_offset = pixel_offset * usize::from(bytes_per_pixel);
        self.framebuffer[byte_offset..(byte_offset + usize::from(bytes_per_pixel))]
            .copy_from_slice(&color[..usize::from(bytes_per_pixel)]);
        let _ = unsafe { ptr::read_volatile(&self.framebuffer[byte_offset]) };
    }
}

unsafe impl Send for ScreenWriter {}
unsafe impl Sync for ScreenWriter {}

impl fmt::Write for ScreenWriter {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for c in s.chars() {
            self.write_char(c);
        }
        Ok(())
    }
}

/// Patched (issue 48): true when stage 2 set a VESA mode, so that
/// [`Writer`] draws on its framebuffer.
pub fn has_framebuffer() -> bool {
    // SAFETY: stage 3 runs on one CPU, without interrupts; read only.
    unsafe { WRITER.get_mut() }.is_some()
}

/// Patched (issue 48): the VGA's 80x25 text screen at 0xB8000, as stage 2
/// left it when it set no VESA mode (an adapter without VBE linear modes):
/// the stop's message goes on the lines below stage 2's, scrolling up when
/// the screen is full. Light grey on black, wrapped at 80 columns.
pub struct VgaText;

impl VgaText {
    const BUFFER: *mut u16 = 0xb8000 as *mut u16;
    const COLUMNS: usize = 80;
    const ROWS: usize = 25;
    const BLANK: u16 = 0x0720;

    fn cell(at: usize) -> *mut u16 {
        debug_assert!(at < Self::COLUMNS * Self::ROWS);
        Self::BUFFER.wrapping_add(at)
    }

    fn read(at: usize) -> u16 {
        // SAFETY: a cell of the VGA text buffer (`at` below 80x25).
        unsafe { ptr::read_volatile(Self::cell(at)) }
    }

    fn write(at: usize, value: u16) {
        // SAFETY: a cell of the VGA text buffer (`at` below 80x25).
        unsafe { ptr::write_volatile(Self::cell(at), value) }
    }

    /// The first row below every row with text on it.
    fn next_row() -> usize {
        (0..Self::ROWS)
            .rev()
            .find(|row| {
                (0..Self::COLUMNS).any(|column| {
                    Self::read(row * Self::COLUMNS + column) & 0xff != u16::from(b' ')
                        && Self::read(row * Self::COLUMNS + column) & 0xff != 0
                })
            })
            .map_or(0, |row| row + 1)
    }

    fn scroll() {
        for at in Self::COLUMNS..Self::COLUMNS * Self::ROWS {
            Self::write(at - Self::COLUMNS, Self::read(at));
        }
        for column in 0..Self::COLUMNS {
            Self::write((Self::ROWS - 1) * Self::COLUMNS + column, Self::BLANK);
        }
    }
}

/// Patched (issue 61): where the text screen's next character goes, so that
/// a line written in pieces (`write!` writes each argument apart) stays one
/// line; `usize::MAX` until the first write, which starts below the text
/// already there.
static VGA_TEXT_CURSOR: core::sync::atomic::AtomicUsize =
    core::sync::atomic::AtomicUsize::new(usize::MAX);

impl fmt::Write for VgaText {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        use core::sync::atomic::Ordering::Relaxed;
        let cursor = match VGA_TEXT_CURSOR.load(Relaxed) {
            usize::MAX => Self::next_row() * Self::COLUMNS,
            cursor => cursor,
        };
        let (mut row, mut column) = (cursor / Self::COLUMNS, cursor % Self::COLUMNS);
        for byte in s.bytes() {
            if byte == b'\n' || column == Self::COLUMNS {
                row += 1;
                column = 0;
            }
            if row >= Self::ROWS {
                Self::scroll();
                row = Self::ROWS - 1;
            }
            if byte != b'\n' {
                let shown = if byte.is_ascii_graphic() || byte == b' ' {
                    byte
                } else {
                    b'?'
                };
                Self::write(row * Self::COLUMNS + column, 0x0700 | u16::from(shown));
                column += 1;
            }
        }
        VGA_TEXT_CURSOR.store(row * Self::COLUMNS + column, Relaxed);
        Ok(())
    }
}
