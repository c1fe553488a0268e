//! The one owner of the bus. Every port access and video-memory access the
//! driver makes goes through a method here, by register name, and the register
//! cache lives here too: to find who writes a register, and whether the write
//! is skipped when the register already holds the value, look in this file.
//!
//! Cached: the Sequencer and Graphics Controller registers (the Map Mask and
//! the text window's memory map change while drawing). Not cached: the CRTC
//! (a flip must write the start address), the Attribute Controller and the DAC
//! (written only by mode sets and palette loads).

use crate::card::vendor::cirrus;
use crate::card::{Card, ExtensionProbe, ResetStep};
use crate::palette::Rgb6;
use crate::regs::{ac, vbe, Attribute, Crtc, Graphics, IndexedPair, PlaneMask, Port, Sequencer};
use crate::{VgaBus, STATUS_WAIT_MICROS};

/// The bus, the card it belongs to, and what the driver last wrote to the
/// registers it caches.
pub(crate) struct VgaIo<B: VgaBus> {
    bus: B,
    /// Whose extensions a mode set switches off first.
    card: Card,
    sequencer: RegisterCache<{ Sequencer::COUNT }>,
    graphics: RegisterCache<{ Graphics::COUNT }>,
}

/// Shows what the driver knows of the hardware, not the bus: a bus need not be
/// `Debug`, and a software VGA's would be its whole video memory.
impl<B: VgaBus> core::fmt::Debug for VgaIo<B> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("VgaIo")
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

    fn get(&self, index: u8) -> Option<u8> {
        self.0.get(usize::from(index)).copied().flatten()
    }

    fn record(&mut self, index: u8, value: u8) {
        if let Some(slot) = self.0.get_mut(usize::from(index)) {
            *slot = Some(value);
        }
    }
}

impl<B: VgaBus> VgaIo<B> {
    pub(crate) fn new(bus: B, card: Card) -> Self {
        VgaIo {
            bus,
            card,
            sequencer: RegisterCache::UNKNOWN,
            graphics: RegisterCache::UNKNOWN,
        }
    }

    pub(crate) fn card(&self) -> Card {
        self.card
    }

    pub(crate) fn bus(&self) -> &B {
        &self.bus
    }

    pub(crate) fn bus_mut(&mut self) -> &mut B {
        &mut self.bus
    }

    pub(crate) fn into_bus(self) -> B {
        self.bus
    }

    /// Forgets every cached register value: the hardware may hold anything.
    pub(crate) fn invalidate_caches(&mut self) {
        self.sequencer = RegisterCache::UNKNOWN;
        self.graphics = RegisterCache::UNKNOWN;
    }

    // Registers, by name.

    /// Writes a Sequencer register unconditionally (and caches the value).
    pub(crate) fn write_sequencer(&mut self, register: Sequencer, value: u8) {
        self.write_indexed(IndexedPair::Sequencer, register.index(), value);
        self.sequencer.record(register.index(), value);
    }

    /// Selects the planes CPU writes go to, unless they already are selected.
    pub(crate) fn set_map_mask(&mut self, planes: PlaneMask) {
        if self.map_mask() != Some(planes) {
            self.write_sequencer(Sequencer::MapMask, planes.bits());
        }
    }

    /// Writes the Map Mask whether or not it holds `planes` already, as a
    /// driver without a register cache does.
    pub(crate) fn write_map_mask(&mut self, planes: PlaneMask) {
        self.write_sequencer(Sequencer::MapMask, planes.bits());
    }

    /// The Map Mask as last written, if known.
    pub(crate) fn map_mask(&self) -> Option<PlaneMask> {
        self.sequencer
            .get(Sequencer::MapMask.index())
            .map(PlaneMask::from_bits_truncate)
    }

    /// Writes a Graphics Controller register unconditionally (and caches it).
    pub(crate) fn write_graphics(&mut self, register: Graphics, value: u8) {
        self.write_indexed(IndexedPair::Graphics, register.index(), value);
        self.graphics.record(register.index(), value);
    }

    /// Writes a Graphics Controller register unless it already holds `value`.
    pub(crate) fn set_graphics(&mut self, register: Graphics, value: u8) {
        if self.graphics.get(register.index()) != Some(value) {
            self.write_graphics(register, value);
        }
    }

    /// Writes a CRTC register (colour I/O addressing); never cached.
    pub(crate) fn write_crtc(&mut self, register: Crtc, value: u8) {
        self.write_indexed(IndexedPair::Crtc, register.index(), value);
    }

    /// Writes Miscellaneous Output.
    pub(crate) fn write_misc_output(&mut self, value: u8) {
        self.bus.write_port8(Port::MISC_OUTPUT_WRITE, value);
    }

    /// Puts the Attribute Controller's flip-flop in its index state (by
    /// reading Input Status 1), ready for [`Self::write_attribute`].
    pub(crate) fn reset_attribute_flip_flop(&mut self) {
        self.bus.read_port8(Port::INPUT_STATUS_1);
    }

    /// Writes an Attribute Controller register with Palette Address Source
    /// clear (screen blanked); the flip-flop must be in its index state, and
    /// is left there.
    pub(crate) fn write_attribute(&mut self, register: Attribute, value: u8) {
        self.bus
            .write_port8(Port::ATTRIBUTE_INDEX, register.index());
        self.bus.write_port8(Port::ATTRIBUTE_INDEX, value);
    }

    /// Sets Palette Address Source again after attribute writes: the screen
    /// shows video again.
    pub(crate) fn show_video(&mut self) {
        self.bus
            .write_port8(Port::ATTRIBUTE_INDEX, ac::PALETTE_ADDRESS_SOURCE);
    }

    /// Opens the DAC Pixel Mask fully and loads DAC entries from `first` on,
    /// the caller having cut `colours` to fit below 256.
    pub(crate) fn load_dac(&mut self, first: u8, colours: &[Rgb6]) {
        self.bus.write_port8(Port::DAC_PIXEL_MASK, 0xFF);
        // DAC Write Index once; it advances by itself after each entry's
        // third component written to DAC Data.
        self.bus.write_port8(Port::DAC_WRITE_INDEX, first);
        for component in colours.iter().flatten() {
            self.bus.write_port8(Port::DAC_DATA, *component);
        }
    }

    /// Reads Input Status 1 until its bits under `mask` are `value`, or
    /// until [`STATUS_WAIT_MICROS`] have passed by the bus's clock (by a
    /// count of reads, a microsecond each, on a bus without one); true if
    /// they were.
    pub(crate) fn poll_status(&mut self, mask: u8, value: u8) -> bool {
        self.bus
            .poll_port8(Port::INPUT_STATUS_1, mask, value, STATUS_WAIT_MICROS)
    }

    // Read-backs, for verifying a mode set.

    /// Miscellaneous Output as the card holds it.
    pub(crate) fn read_misc_output(&mut self) -> u8 {
        self.bus.read_port8(Port::MISC_OUTPUT_READ)
    }

    /// A Sequencer register as the card holds it.
    pub(crate) fn read_sequencer(&mut self, register: Sequencer) -> u8 {
        self.read_indexed(IndexedPair::Sequencer, register.index())
    }

    /// A CRTC register as the card holds it.
    pub(crate) fn read_crtc(&mut self, register: Crtc) -> u8 {
        self.read_indexed(IndexedPair::Crtc, register.index())
    }

    /// A Graphics Controller register as the card holds it.
    pub(crate) fn read_graphics(&mut self, register: Graphics) -> u8 {
        self.read_indexed(IndexedPair::Graphics, register.index())
    }

    /// Reads an attribute register with the palette address source kept on
    /// (so the screen stays lit), leaving the flip-flop in its index state.
    pub(crate) fn read_attribute(&mut self, register: Attribute) -> u8 {
        self.bus.read_port8(Port::INPUT_STATUS_1);
        self.bus.write_port8(
            Port::ATTRIBUTE_INDEX,
            register.index() | ac::PALETTE_ADDRESS_SOURCE,
        );
        let value = self.bus.read_port8(Port::ATTRIBUTE_DATA_READ);
        self.bus.read_port8(Port::INPUT_STATUS_1);
        value
    }

    // The card's extensions.

    /// Writes the card's extension reset (nothing for a standard card).
    pub(crate) fn reset_extensions(&mut self) {
        for step in self.card.extension_reset() {
            match *step {
                ResetStep::Dispi { index, value } => {
                    self.bus.write_port16(Port::VBE_DISPI_INDEX, index);
                    self.bus.write_port16(Port::VBE_DISPI_DATA, value);
                }
                ResetStep::Indexed { pair, index, value } => self.write_indexed(pair, index, value),
                ResetStep::CirrusHiddenDac(value) => {
                    for _ in 0..4 {
                        self.bus.read_port8(Port::DAC_PIXEL_MASK);
                    }
                    self.bus.write_port8(Port::DAC_PIXEL_MASK, value);
                }
            }
        }
    }

    /// The extension register's value and the bit that must be clear.
    pub(crate) fn read_extension(&mut self, probe: ExtensionProbe) -> (u8, u8) {
        match probe {
            ExtensionProbe::DispiEnable => {
                self.bus
                    .write_port16(Port::VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
                // Only the low byte holds flags; the port answers 16-bit reads.
                let [enable, _] = self.bus.read_port16(Port::VBE_DISPI_DATA).to_le_bytes();
                (enable, vbe::ENABLED as u8)
            }
            ExtensionProbe::CirrusExtendedModes => {
                self.write_indexed(IndexedPair::Sequencer, cirrus::UNLOCK, cirrus::UNLOCK_KEY);
                let sr7 =
                    self.read_indexed(IndexedPair::Sequencer, cirrus::EXTENDED_SEQUENCER_MODE);
                (sr7, cirrus::EXTENDED_MODES)
            }
        }
    }

    // Video memory.

    /// One byte to the CPU window, through the current Map Mask.
    pub(crate) fn write_vram8(&mut self, offset: u16, value: u8) {
        self.bus.write_vram8(offset, value);
    }

    /// `count` bytes of `value` from `offset`, through the current Map Mask.
    pub(crate) fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        self.bus.fill_vram(offset, count, value);
    }

    /// Makes what has been written visible now (see [`VgaBus::flush`]).
    pub(crate) fn flush(&mut self) {
        self.bus.flush();
    }

    // The two ways an index/data pair is reached.

    /// Register `index` of `pair` written with one 16-bit OUT: the index to
    /// the index port, the value to the data port after it.
    fn write_indexed(&mut self, pair: IndexedPair, index: u8, value: u8) {
        self.bus
            .write_port16(pair.index_port(), u16::from_le_bytes([index, value]));
    }

    /// The index written to `pair`'s index port, then its data port read.
    fn read_indexed(&mut self, pair: IndexedPair, index: u8) -> u8 {
        self.bus.write_port8(pair.index_port(), index);
        self.bus.read_port8(pair.data_port())
    }
}
