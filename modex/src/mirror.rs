//! The software VGA as the machine's display adapter: a bus that forwards
//! everything to the model and hands its picture to a presenter (a copy to the
//! firmware's framebuffer) each time the model latches a new start address,
//! so the Mode X drawing code runs unchanged where no legacy VGA exists.

use crate::regs::{Crtc, Port};
use crate::soft::SoftVga;
use crate::VgaBus;

/// A [`VgaBus`] over a software VGA that calls `present` once per page flip.
///
/// A flip ([`crate::ModeX::show_page`]) writes the CRTC start address, then
/// polls Input Status 1 until vertical retrace, when the VGA latches it. So
/// the mirror notes every write to Start Address High or Low, and after each
/// Input Status 1 read presents if the model has started a frame since: the
/// address is latched. `show_page` therefore returns with the new page on
/// screen, and the page it left may be drawn into at once.
///
/// Presenting on every latched write, rather than only when the displayed
/// address changes, keeps a flip to the page already shown meaningful: the
/// test pattern draws page 0 while the mode set shows it, then shows it.
pub struct MirroredVga<'a, F: FnMut(&SoftVga)> {
    soft: &'a mut SoftVga,
    present: F,
    /// The CRTC index last written, to recognise start address writes.
    crtc_index: u8,
    /// The model's frame count when the start address was last written, until
    /// a new frame has latched it and it has been presented.
    flip_written_in_frame: Option<u64>,
    presentations: u64,
}

/// Leaves out the presenting closure, which has no `Debug`.
impl<F: FnMut(&SoftVga)> core::fmt::Debug for MirroredVga<'_, F> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MirroredVga")
            .field("soft", &self.soft)
            .field("crtc_index", &self.crtc_index)
            .field("flip_written_in_frame", &self.flip_written_in_frame)
            .field("presentations", &self.presentations)
            .finish_non_exhaustive()
    }
}

impl<'a, F: FnMut(&SoftVga)> MirroredVga<'a, F> {
    /// Mirrors `soft`, calling `present` with it for each new page shown.
    /// Nothing is presented until the first flip (or [`Self::present_now`]).
    pub fn new(soft: &'a mut SoftVga, present: F) -> Self {
        MirroredVga {
            soft,
            present,
            crtc_index: 0,
            flip_written_in_frame: None,
            presentations: 0,
        }
    }

    /// Presents the model's picture now, whatever it shows (after drawing
    /// into the page shown, say, which is no flip).
    pub fn present_now(&mut self) {
        self.flip_written_in_frame = None;
        self.presentations += 1;
        (self.present)(self.soft);
    }

    /// How many times the picture has been presented.
    pub fn presentations(&self) -> u64 {
        self.presentations
    }

    /// The model.
    pub fn soft(&self) -> &SoftVga {
        self.soft
    }

    fn note_port_write(&mut self, port: Port, value: u8) {
        match port {
            Port::CRTC_INDEX | Port::CRTC_INDEX_MONO => self.crtc_index = value,
            Port::CRTC_DATA | Port::CRTC_DATA_MONO
                if matches!(
                    Crtc::from_index(self.crtc_index),
                    Some(Crtc::StartAddressHigh | Crtc::StartAddressLow)
                ) =>
            {
                self.flip_written_in_frame = Some(self.soft.frame_count());
            }
            _ => {}
        }
    }

    fn after_status_read(&mut self) {
        if let Some(frame) = self.flip_written_in_frame {
            if self.soft.frame_count() > frame {
                self.present_now();
            }
        }
    }
}

impl<F: FnMut(&SoftVga)> VgaBus for MirroredVga<'_, F> {
    fn write_port8(&mut self, port: Port, value: u8) {
        self.soft.write_port8(port, value);
        self.note_port_write(port, value);
    }

    fn write_port16(&mut self, port: Port, value: u16) {
        self.soft.write_port16(port, value);
        let [low, high] = value.to_le_bytes();
        self.note_port_write(port, low);
        if let Some(data_port) = port.data() {
            self.note_port_write(data_port, high);
        }
    }

    fn read_port8(&mut self, port: Port) -> u8 {
        let value = self.soft.read_port8(port);
        if port == Port::INPUT_STATUS_1 || port == Port::INPUT_STATUS_1_MONO {
            self.after_status_read();
        }
        value
    }

    fn write_vram8(&mut self, offset: u16, value: u8) {
        self.soft.write_vram8(offset, value);
    }

    fn read_vram8(&mut self, offset: u16) -> u8 {
        self.soft.read_vram8(offset)
    }

    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        self.soft.fill_vram(offset, count, value);
    }

    /// A real VGA shows what was written within a frame; the model needs
    /// that frame to latch the start address (a text mode set after a flip
    /// to page 1 would otherwise still scan out from page 1's address).
    fn flush(&mut self) {
        self.soft.let_a_frame_pass();
        self.present_now();
    }
    /// The model's simulated clock, which times its retraces.
    fn now_micros(&mut self) -> Option<u64> {
        self.soft.now_micros()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::present::{present, FramebufferLayout, PixelOrder};
    use crate::soft::dac_6_to_8;
    use crate::{ModeX, Page, PAGE_PIXELS};
    use std::boxed::Box;
    use std::vec;
    use std::vec::Vec;

    /// Page `page` filled with colour `page + 1`, so each page looks different.
    fn fill_pages(vga: &mut ModeX<impl VgaBus>) {
        for page in Page::ALL {
            vga.fill_rect(page, 0, 0, 320, 240, page.index() + 1);
        }
    }

    #[test]
    fn each_flip_presents_once_with_the_new_page_displayed() {
        let mut soft = Box::new(SoftVga::new());
        let mut presented: Vec<u16> = Vec::new();
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |soft: &SoftVga| {
            presented.push(soft.displayed_start())
        }));
        vga.set_mode();
        fill_pages(&mut vga);
        let before = vga.bus().presentations();
        let flips = [
            Page::Zero,
            Page::One,
            Page::Two,
            Page::One,
            Page::Zero,
            Page::Two,
        ];
        for (done, page) in flips.into_iter().enumerate() {
            vga.show_page(page);
            assert_eq!(vga.bus().presentations(), before + done as u64 + 1);
        }
        let bases: Vec<u16> = flips.iter().map(|page| page.base()).collect();
        assert_eq!(presented[before as usize..], bases);
    }

    #[test]
    fn showing_the_page_already_shown_presents_it_again() {
        let mut soft = Box::new(SoftVga::new());
        let mut count = 0;
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |_: &SoftVga| count += 1));
        vga.set_mode();
        vga.show_page(Page::Zero);
        let after_first_flip = vga.bus().presentations();
        vga.show_page(Page::Zero);
        vga.show_page(Page::Zero);
        assert_eq!(vga.bus().presentations(), after_first_flip + 2);
        assert_eq!(count, after_first_flip + 2);
    }

    #[test]
    fn drawing_without_flipping_presents_nothing() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |_: &SoftVga| {}));
        vga.set_mode();
        let after_mode_set = vga.bus().presentations();
        fill_pages(&mut vga);
        vga.put_pixel(Page::Zero, 5, 5, 9);
        assert_eq!(vga.bus().presentations(), after_mode_set);
    }

    #[test]
    fn the_presented_framebuffer_shows_the_page_just_flipped_to() {
        let layout = FramebufferLayout {
            width: 640,
            height: 480,
            stride: 640,
            bytes_per_pixel: 4,
            order: PixelOrder::Rgb,
        };
        let mut framebuffer = vec![0u8; layout.required_bytes()];
        let mut scratch = vec![0u8; PAGE_PIXELS];
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |soft: &SoftVga| {
            present(soft, &mut scratch, &layout, &mut framebuffer);
        }));
        vga.set_mode();
        fill_pages(&mut vga);
        vga.show_page(Page::Two);
        let [red, green, blue] = soft.dac_entry(3).map(dac_6_to_8);
        let page_2_colour = [red, green, blue, 0];
        assert_ne!(page_2_colour, [0; 4]);
        assert!(framebuffer
            .as_chunks::<4>()
            .0
            .iter()
            .all(|pixel| *pixel == page_2_colour));
    }

    #[test]
    fn text_written_after_a_flip_is_presented_by_a_flush() {
        let layout = FramebufferLayout {
            width: 720,
            height: 400,
            stride: 720,
            bytes_per_pixel: 4,
            order: PixelOrder::Rgb,
        };
        let mut framebuffer = vec![0u8; layout.required_bytes()];
        let mut scratch = vec![0u8; crate::present::MAX_PICTURE_PIXELS];
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |soft: &SoftVga| {
            present(soft, &mut scratch, &layout, &mut framebuffer);
        }));
        vga.set_mode();
        fill_pages(&mut vga);
        vga.show_page(Page::One);
        let font = [[0xFF; 8]; 128];
        vga.set_text_mode(&font);
        vga.write_text(0, 0, "#", 0x0F);
        vga.flush();
        // The first cell's eight lit dots are white, its ninth is black.
        assert_eq!(&framebuffer[..4], &[255, 255, 255, 0]);
        assert_eq!(&framebuffer[8 * 4..9 * 4], &[0, 0, 0, 0]);
    }

    #[test]
    fn every_bus_operation_reaches_the_model() {
        let mut soft = Box::new(SoftVga::new());
        let mut vga = ModeX::new(MirroredVga::new(&mut soft, |_: &SoftVga| {}));
        vga.set_mode();
        fill_pages(&mut vga);
        vga.show_page(Page::One);
        let mut reference = Box::new(SoftVga::new());
        let mut direct = ModeX::new(&mut *reference);
        direct.set_mode();
        fill_pages(&mut direct);
        direct.show_page(Page::One);
        assert_eq!(soft.counts(), reference.counts());
        for plane in 0..4 {
            assert_eq!(soft.plane(plane)[..], reference.plane(plane)[..]);
        }
        assert_eq!(soft.displayed_start(), reference.displayed_start());
    }
}
