//! The driver object. It holds the bus only through [`VgaIo`], the one owner
//! of the bus and the register cache, so every method of [`ModeX`] (spread
//! over `draw.rs`, `page.rs`, `mode.rs`, `text.rs`, `update.rs` and `card/`)
//! writes registers by name through the same door.

use crate::card::Card;
use crate::io::VgaIo;
use crate::VgaBus;

/// A VGA in Mode X (or, after [`ModeX::set_text_mode`], 80x25 text).
///
/// The driver assumes it is the only user of the VGA: its register caches
/// describe the hardware only while nobody else writes to it.
///
/// # Example
///
/// Draw into the hidden page, flip to it, and count what it cost on the bus:
///
/// ```
/// use modex::soft::SoftVga;
/// use modex::{ModeX, Page};
///
/// let mut soft = Box::new(SoftVga::new());
/// let mut vga = ModeX::new(&mut *soft);
/// vga.set_mode();
/// let before = vga.bus().counts();
/// vga.fill_span(Page::One, 10, 0, 320, 4); // one line, 80 bytes through all planes
/// let after = vga.bus().counts();
/// assert_eq!(after.vram_writes - before.vram_writes, 80);
/// assert!(!vga.show_page(Page::One).timed_out());
/// assert_eq!(soft.displayed_start(), Page::One.base());
/// ```
pub struct ModeX<B: VgaBus> {
    pub(crate) io: VgaIo<B>,
}

/// Shows what the driver knows of the hardware, not the bus.
impl<B: VgaBus> core::fmt::Debug for ModeX<B> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ModeX").field("io", &self.io).finish()
    }
}

impl<B: VgaBus> ModeX<B> {
    /// Takes the bus of a standard VGA (no extensions to reset) without
    /// touching the hardware; call [`ModeX::set_mode`] first.
    pub fn new(bus: B) -> Self {
        Self::for_card(bus, Card::Standard)
    }

    /// Takes the bus of a `card` whose extended modes every mode set switches
    /// off first (see [`Card::extension_reset`]).
    pub fn for_card(bus: B, card: Card) -> Self {
        ModeX {
            io: VgaIo::new(bus, card),
        }
    }

    /// The card this driver resets extensions for.
    pub fn card(&self) -> Card {
        self.io.card()
    }

    /// The bus, for inspection (a software VGA's counts and picture).
    pub fn bus(&self) -> &B {
        self.io.bus()
    }

    /// The bus, for its own state beside the VGA (a simulator's clock, say).
    /// Its ports are only the VGA's ([`crate::regs::Port`]), but a register
    /// written through it behind the driver's back leaves the register cache
    /// stale until the next mode set or [`ModeX::invalidate_caches`].
    pub fn bus_mut(&mut self) -> &mut B {
        self.io.bus_mut()
    }

    /// Gives the bus back.
    pub fn into_bus(self) -> B {
        self.io.into_bus()
    }

    /// Forgets every cached register value: the hardware may hold anything
    /// (after a video BIOS call, say).
    pub fn invalidate_caches(&mut self) {
        self.io.invalidate_caches();
    }

    /// Makes what has been drawn visible now: a VGA shows it anyway, a
    /// software VGA mirrored to a framebuffer presents (after text, which no
    /// page flip follows).
    pub fn flush(&mut self) {
        self.issued_by("ModeX::flush", |vga| vga.io.flush());
    }

    /// Runs `body` as `function`, telling the bus where it starts and ends
    /// ([`VgaBus::enter`]), so a slow-motion view can name the function
    /// that issued each bus operation. On a bus without the tag (the
    /// kernel's) this is `body(self)`.
    #[inline(always)]
    pub(crate) fn issued_by<R>(
        &mut self,
        function: &'static str,
        body: impl FnOnce(&mut Self) -> R,
    ) -> R {
        self.io.bus_mut().enter(function);
        let result = body(self);
        self.io.bus_mut().leave();
        result
    }
}
