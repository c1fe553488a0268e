//! Host tests: the driver against the software VGA, and the model against
//! what QEMU's VGA does.

mod canvas;
mod clipping;
mod fills;
mod flip;
mod mode_set;
mod model;
mod palette;
mod text;
mod text_scanout;

use std::boxed::Box;
use std::vec;
use std::vec::Vec;

use crate::soft::SoftVga;
use crate::{ModeX, Page, BYTES_PER_LINE, PAGE_BYTES, SCREEN_HEIGHT, SCREEN_WIDTH};

pub(crate) const WIDTH: usize = SCREEN_WIDTH as usize;
pub(crate) const HEIGHT: usize = SCREEN_HEIGHT as usize;

/// A xorshift generator from `state`: numbers below the bound asked for,
/// the same every run.
pub(crate) fn xorshift(mut state: u64) -> impl FnMut(usize) -> usize {
    move |below| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 16) as usize % below
    }
}

/// A powered-on software VGA, boxed: it is too big to move around freely.
pub(crate) fn power_on() -> Box<SoftVga> {
    Box::new(SoftVga::new())
}

/// A 320x240 picture of DAC indices: the per-pixel reference.
#[derive(Clone, PartialEq, Eq)]
pub(crate) struct Picture(pub Vec<u8>);

impl Picture {
    pub fn filled(color: u8) -> Self {
        Self(vec![color; WIDTH * HEIGHT])
    }

    /// The reference fill: every pixel of [x0, x1) x [y0, y1) on the screen.
    pub fn fill_rect(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, color: u8) {
        for y in y0.max(0)..y1.min(SCREEN_HEIGHT) {
            for x in x0.max(0)..x1.min(SCREEN_WIDTH) {
                self.0[y as usize * WIDTH + x as usize] = color;
            }
        }
    }

    /// The first differing pixel as (x, y, expected, actual).
    pub fn first_difference(&self, actual: &Picture) -> Option<(usize, usize, u8, u8)> {
        let index = self.0.iter().zip(&actual.0).position(|(a, b)| a != b)?;
        Some((index % WIDTH, index / WIDTH, self.0[index], actual.0[index]))
    }
}

/// The displayed picture, which must be 320x240.
pub(crate) fn scanout(soft: &SoftVga) -> Picture {
    let mut pixels = vec![0; WIDTH * HEIGHT];
    assert_eq!(
        soft.scanout_indices(&mut pixels),
        (WIDTH, HEIGHT),
        "not showing 320x240"
    );
    Picture(pixels)
}

/// A page's pixels straight from the planes, shown or not.
pub(crate) fn page_pixels(soft: &SoftVga, page: Page) -> Picture {
    let mut pixels = vec![0; WIDTH * HEIGHT];
    for (index, pixel) in pixels.iter_mut().enumerate() {
        let (x, y) = (index % WIDTH, index / WIDTH);
        let offset = usize::from(page.base()) + y * usize::from(BYTES_PER_LINE) + x / 4;
        *pixel = soft.plane(x % 4)[offset];
    }
    Picture(pixels)
}

/// Asserts `actual` equals `expected`, naming the first difference.
#[track_caller]
pub(crate) fn assert_picture(expected: &Picture, actual: &Picture, what: &str) {
    if let Some((x, y, want, got)) = expected.first_difference(actual) {
        panic!("{what}: pixel ({x}, {y}) is {got}, expected {want}");
    }
}

/// The CPU offsets of a page, for the write guard.
pub(crate) fn page_range(page: Page) -> core::ops::Range<u16> {
    page.base()..page.base() + PAGE_BYTES
}

/// A driver in Mode X on a fresh software VGA.
/// The software VGA models QEMU's std VGA, Bochs VBE ports included.
pub(crate) fn mode_x(soft: &mut SoftVga) -> ModeX<&mut SoftVga> {
    let mut vga = ModeX::for_card(soft, crate::card::Card::BochsDispi);
    vga.set_mode();
    vga
}

/// A small deterministic generator for "random" register values.
pub(crate) struct XorShift(pub u32);

impl XorShift {
    pub fn next_u8(&mut self) -> u8 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 24) as u8
    }
}
