//! Pages and page flipping: the CRTC start address selects the page shown,
//! and the VGA latches it at the start of vertical retrace.

use crate::regs::{status, Crtc};
use crate::{ModeX, VgaBus, PAGE_BYTES};

/// Pages that fit in the 64 KiB of each plane the CPU window reaches.
pub const PAGE_COUNT: u8 = 3;

/// How long, by the bus's clock ([`VgaBus::now_micros`]), a wait on Input
/// Status 1 may last before it gives up, so a stuck status bit can never hang
/// the kernel: two seconds, about 120 refreshes. The bound is time, not a
/// count of reads: a read takes about 1 µs on an ISA card but far less under
/// emulation, and QEMU times its retrace from the host's clock, so a vCPU
/// kept off a busy host's CPU can miss every short retrace pulse for long
/// stretches (43 refreshes, 0.71 s, the longest seen beside four busy loops,
/// more than a million fast reads).
pub const STATUS_WAIT_MICROS: u64 = 2_000_000;

/// A Mode X page: one of the three screens that fit in video memory. Being an
/// enum, a page cannot name memory past the third; [`Page::base`] is always
/// inside the 64 KiB window.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub enum Page {
    /// Offset 0 in each plane: shown after the mode set.
    Zero,
    /// Offset 19,200.
    One,
    /// Offset 38,400: the spare, outside the flipping.
    Two,
}

impl Page {
    /// Every page, in memory order.
    pub const ALL: [Page; PAGE_COUNT as usize] = [Page::Zero, Page::One, Page::Two];

    /// The page's number, 0 to 2.
    pub const fn index(self) -> u8 {
        self as u8
    }

    /// The page numbered `index`, if there is one.
    pub const fn from_index(index: u8) -> Option<Page> {
        match index {
            0 => Some(Page::Zero),
            1 => Some(Page::One),
            2 => Some(Page::Two),
            _ => None,
        }
    }

    /// The page to draw into while this one is shown. Double buffering flips
    /// between pages 0 and 1, so those two swap; the spare page 2 hands over
    /// to page 0. Never `self`, so drawing never lands on the page on screen.
    pub const fn other(self) -> Page {
        match self {
            Page::Zero => Page::One,
            Page::One | Page::Two => Page::Zero,
        }
    }

    /// The page's first byte in each plane (and in the CPU window).
    pub const fn base(self) -> u16 {
        self.index() as u16 * PAGE_BYTES
    }
}

/// What happened to the waits of a page flip.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct FlipReport {
    /// The wait for active display (to write the start address well before
    /// the latch) lasted [`STATUS_WAIT_MICROS`] without seeing it.
    pub display_wait_timed_out: bool,
    /// The wait for the start of vertical retrace (the latch) lasted
    /// [`STATUS_WAIT_MICROS`] without seeing it.
    pub retrace_wait_timed_out: bool,
}

impl FlipReport {
    /// Whether either wait gave up.
    pub fn timed_out(&self) -> bool {
        self.display_wait_timed_out || self.retrace_wait_timed_out
    }
}

impl<B: VgaBus> ModeX<B> {
    /// Shows `page`, returning once the VGA has latched it, so the page shown
    /// before may be drawn into.
    ///
    /// The start address is written only during active display (Input Status 1
    /// bits 0 and 3 clear, so not in vertical retrace and at least the
    /// blanking lines away from it): the two bytes cannot be latched half old,
    /// half new. Then the flip waits for the start of vertical retrace, where
    /// the VGA latches the start address. Both waits are bounded by the bus's
    /// clock: a retrace missed (a busy emulator's vCPU off the CPU across it)
    /// only makes the flip wait for the next one.
    ///
    /// # Example
    ///
    /// A VGA whose retrace bit never rises: the flip gives up after
    /// [`STATUS_WAIT_MICROS`] by the software VGA's clock and says so, instead
    /// of hanging.
    ///
    /// ```
    /// use modex::soft::SoftVga;
    /// use modex::{ModeX, Page};
    ///
    /// let mut soft = Box::new(SoftVga::new());
    /// ModeX::new(&mut *soft).set_mode();
    /// soft.set_retrace_stuck(Some(false));
    /// let report = ModeX::new(&mut *soft).show_page(Page::One);
    /// assert!(report.retrace_wait_timed_out && !report.display_wait_timed_out);
    /// ```
    pub fn show_page(&mut self, page: Page) -> FlipReport {
        self.issued_by("ModeX::show_page", |vga| {
            let display_wait_timed_out = !vga
                .io
                .poll_status(status::VERTICAL_RETRACE | status::DISPLAY_DISABLED, 0);
            let [high, low] = page.base().to_be_bytes();
            vga.io.write_crtc(Crtc::StartAddressHigh, high);
            vga.io.write_crtc(Crtc::StartAddressLow, low);
            let retrace_wait_timed_out = !vga
                .io
                .poll_status(status::VERTICAL_RETRACE, status::VERTICAL_RETRACE);
            FlipReport {
                display_wait_timed_out,
                retrace_wait_timed_out,
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pages_sit_one_screen_apart_inside_the_window() {
        let bases = Page::ALL.map(Page::base);
        assert_eq!(bases, [0, PAGE_BYTES, 2 * PAGE_BYTES]);
        let last_byte = u32::from(bases[2]) + u32::from(PAGE_BYTES) - 1;
        assert!(last_byte < 0x1_0000, "page 2 ends at {last_byte:#x}");
    }

    #[test]
    fn index_round_trips_and_nothing_past_page_two_exists() {
        for page in Page::ALL {
            assert_eq!(Page::from_index(page.index()), Some(page));
        }
        assert_eq!(Page::from_index(PAGE_COUNT), None);
        assert_eq!(Page::from_index(u8::MAX), None);
    }

    #[test]
    fn the_other_page_is_never_the_one_shown() {
        for page in Page::ALL {
            assert_ne!(page.other(), page);
        }
        assert_eq!(Page::Zero.other().other(), Page::Zero);
        assert_eq!(Page::One.other().other(), Page::One);
    }
}
