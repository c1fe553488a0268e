//! Pages and page flipping: the CRTC start address selects the page shown,
//! and the VGA latches it at the start of vertical retrace.

use crate::regs::{crtc, status, INPUT_STATUS_1};
use crate::{ModeX, VgaBus, PAGE_BYTES};

/// Pages that fit in the 64 KiB of each plane the CPU window reaches.
pub const PAGE_COUNT: u8 = 3;

/// How many times a wait reads Input Status 1 before giving up, so a stuck
/// status bit can never hang the kernel. A read costs about 1 µs on an ISA
/// card (the bound is then a second) but well under 100 ns under emulation,
/// where 200,000 reads proved shorter than a frame and flips timed out; a
/// million leaves room for a frame everywhere.
pub const STATUS_POLL_LIMIT: u32 = 1_000_000;

/// A Mode X page: Page(0) at offset 0, Page(1) at 19200, Page(2) at 38400.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
pub struct Page(pub u8);

impl Page {
    /// The page's first byte in each plane (and in the CPU window).
    pub const fn base(self) -> u16 {
        debug_assert!(self.0 < PAGE_COUNT, "Mode X has three pages");
        self.0 as u16 * PAGE_BYTES
    }
}

/// What happened to the waits of a page flip.
#[derive(Clone, Copy, PartialEq, Eq, Debug, Default)]
pub struct FlipReport {
    /// The wait for active display (to write the start address well before
    /// the latch) hit [`STATUS_POLL_LIMIT`].
    pub display_wait_timed_out: bool,
    /// The wait for the start of vertical retrace (the latch) hit [`STATUS_POLL_LIMIT`].
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
    /// the VGA latches the start address. Both waits are bounded.
    pub fn show_page(&mut self, page: Page) -> FlipReport {
        let display_wait_timed_out = !self
            .poll_status(|bits| bits & (status::VERTICAL_RETRACE | status::DISPLAY_DISABLED) == 0);
        let [high, low] = page.base().to_be_bytes();
        self.write_crtc(crtc::START_ADDRESS_HIGH, high);
        self.write_crtc(crtc::START_ADDRESS_LOW, low);
        let retrace_wait_timed_out = !self.poll_status(|bits| bits & status::VERTICAL_RETRACE != 0);
        FlipReport {
            display_wait_timed_out,
            retrace_wait_timed_out,
        }
    }

    /// Reads Input Status 1 until `done` holds or [`STATUS_POLL_LIMIT`] reads
    /// have been made; true if `done` held.
    fn poll_status(&mut self, done: impl Fn(u8) -> bool) -> bool {
        (0..STATUS_POLL_LIMIT).any(|_| done(self.bus.read_port8(INPUT_STATUS_1)))
    }
}
