//! The driver object: it owns the bus and remembers what it last wrote to the
//! indexed registers it changes while drawing, so it can skip rewriting them.

use crate::card::Card;
use crate::regs::{gc, seq, ATTRIBUTE_INDEX, CRTC_INDEX, GRAPHICS_INDEX, SEQUENCER_INDEX};
use crate::VgaBus;

/// A VGA in Mode X (or, after [`ModeX::set_text_mode`], 80x25 text).
///
/// The driver assumes it is the only user of the VGA: its register caches
/// describe the hardware only while nobody else writes to it.
pub struct ModeX<B: VgaBus> {
    pub(crate) bus: B,
    /// Whose extensions a mode set switches off first.
    card: Card,
    sequencer: RegisterCache<{ seq::COUNT }>,
    graphics: RegisterCache<{ gc::COUNT }>,
}

/// Shows what the driver knows of the hardware, not the bus: a bus need not be
/// `Debug`, and a software VGA's would be its whole video memory.
impl<B: VgaBus> core::fmt::Debug for ModeX<B> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("ModeX")
            .field("card", &self.card)
            .field("sequencer", &self.sequencer)
            .field("graphics", &self.graphics)
            .finish_non_exhaustive()
    }
}

/// The last value written to each register of an index/data pair, if known.
#[derive(Debug)]
struct RegisterCache<const N: usize>([Option<u8>; N]);

impl<const N: usize> RegisterCache<N> {
    const UNKNOWN: Self = Self([None; N]);

    fn holds(&self, index: u8, value: u8) -> bool {
        self.0.get(usize::from(index)) == Some(&Some(value))
    }

    fn record(&mut self, index: u8, value: u8) {
        if let Some(slot) = self.0.get_mut(usize::from(index)) {
            *slot = Some(value);
        }
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
        Self {
            bus,
            card,
            sequencer: RegisterCache::UNKNOWN,
            graphics: RegisterCache::UNKNOWN,
        }
    }

    /// The card this driver resets extensions for.
    pub fn card(&self) -> Card {
        self.card
    }

    /// The bus, for inspection.
    pub fn bus(&self) -> &B {
        &self.bus
    }

    /// The bus. Writing VGA registers through it behind the driver's back makes
    /// the register caches stale until the next mode set.
    pub fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }

    /// Gives the bus back.
    pub fn into_bus(self) -> B {
        self.bus
    }

    /// Forgets every cached register value: the hardware may hold anything.
    pub fn invalidate_caches(&mut self) {
        self.sequencer = RegisterCache::UNKNOWN;
        self.graphics = RegisterCache::UNKNOWN;
    }

    /// Writes a sequencer register unconditionally.
    pub(crate) fn write_sequencer(&mut self, index: u8, value: u8) {
        write_indexed(&mut self.bus, SEQUENCER_INDEX, index, value);
        self.sequencer.record(index, value);
    }

    /// Writes a graphics controller register unconditionally.
    pub(crate) fn write_graphics(&mut self, index: u8, value: u8) {
        write_indexed(&mut self.bus, GRAPHICS_INDEX, index, value);
        self.graphics.record(index, value);
    }

    /// Writes a CRTC register (colour I/O addressing).
    pub(crate) fn write_crtc(&mut self, index: u8, value: u8) {
        write_indexed(&mut self.bus, CRTC_INDEX, index, value);
    }

    /// Writes an Attribute Controller register with Palette Address Source
    /// clear (screen blanked); the flip-flop must be in its index state.
    pub(crate) fn write_attribute(&mut self, index: u8, value: u8) {
        self.bus.write_port8(ATTRIBUTE_INDEX, index);
        self.bus.write_port8(ATTRIBUTE_INDEX, value);
    }

    /// Selects the planes CPU writes go to, unless they already are selected.
    pub(crate) fn set_map_mask(&mut self, planes: u8) {
        if !self.sequencer.holds(seq::MAP_MASK, planes) {
            self.write_sequencer(seq::MAP_MASK, planes);
        }
    }

    /// The Map Mask as last written, if known.
    pub(crate) fn cached_map_mask(&self) -> Option<u8> {
        self.sequencer.0[usize::from(seq::MAP_MASK)]
    }

    /// Writes a graphics controller register unless it already holds `value`.
    pub(crate) fn set_graphics(&mut self, index: u8, value: u8) {
        if !self.graphics.holds(index, value) {
            self.write_graphics(index, value);
        }
    }
}

/// An index/data register pair written with one 16-bit OUT: the index goes
/// to `index_port`, the value to `index_port + 1`.
fn write_indexed<B: VgaBus>(bus: &mut B, index_port: u16, index: u8, value: u8) {
    bus.write_port16(index_port, u16::from_le_bytes([index, value]));
}
