//! The register files of the software VGA and the decoding of its I/O ports.
//!
//! Unimplemented register bits read back as zero, as on QEMU's VGA. The CRTC
//! and Input Status 1 answer at 0x3Dx or 0x3Bx as Misc Output bit 0 selects;
//! the other range is not decoded (writes ignored, reads 0xFF).

use crate::mode::ModeRegisters;
use crate::palette::Rgb6;
use crate::regs::{ac, crtc, misc, vbe};
use crate::regs::{Attribute, Crtc, Graphics, IndexedPair, Port, Sequencer};

/// Implemented bits of each sequencer register.
const SEQUENCER_BITS: [u8; Sequencer::COUNT] = [0x03, 0x3D, 0x0F, 0x3F, 0x0E];
/// Implemented bits of each graphics controller register.
const GRAPHICS_BITS: [u8; Graphics::COUNT] = [0x0F, 0x0F, 0x0F, 0x1F, 0x03, 0x7B, 0x0F, 0x0F, 0xFF];
/// Implemented bits of the index registers.
const SEQUENCER_INDEX_BITS: u8 = 0x07;
const GRAPHICS_INDEX_BITS: u8 = 0x0F;
const ATTRIBUTE_INDEX_BITS: u8 = 0x3F;
/// Misc Output bit 4 does not exist.
const MISC_OUTPUT_BITS: u8 = 0xEF;
/// The DAC stores 6 bits per component.
const DAC_COMPONENT_BITS: u8 = 0x3F;
/// Feature Control: only bit 4 is kept (as QEMU does).
const FEATURE_CONTROL_BITS: u8 = 0x10;
/// DAC state register values: the last index written was the write or the read index.
const DAC_STATE_WRITING: u8 = 0x00;
const DAC_STATE_READING: u8 = 0x03;

/// The monochrome and colour register ranges, 16 ports each.
const MONO_PORT_RANGE: u16 = 0x3B0;
const COLOR_PORT_RANGE: u16 = 0x3D0;
const ADDRESSING_RANGE_OFFSET_BITS: u16 = 0x0F;

/// Implemented bits of an Attribute Controller register.
fn attribute_bits(index: u8) -> u8 {
    match Attribute::from_index(index) {
        Some(Attribute::ModeControl) => 0xEF,
        Some(Attribute::OverscanColor) => 0xFF,
        Some(Attribute::HorizontalPixelPanning | Attribute::ColorSelect) => 0x0F,
        // The palette registers and Color Plane Enable have 6 bits.
        _ => 0x3F,
    }
}

/// The 256-entry colour lookup and its index/data protocol.
#[derive(Clone, Debug)]
pub(super) struct Dac {
    pub(super) palette: [Rgb6; 256],
    pub(super) pixel_mask: u8,
    write_index: u8,
    read_index: u8,
    /// Which of red, green, blue the next data access is (shared by reads and writes).
    component: usize,
    pending: Rgb6,
    state: u8,
}

/// The Bochs VBE (DISPI) interface, modelled only as far as its enable.
#[derive(Clone, Debug, Default)]
pub(super) struct Dispi {
    index: u16,
    pub(super) enable: u16,
}

/// Every VGA register.
#[derive(Clone, Debug)]
pub(super) struct Registers {
    pub(super) misc_output: u8,
    feature_control: u8,
    sequencer_index: u8,
    pub(super) sequencer: [u8; Sequencer::COUNT],
    crtc_index: u8,
    pub(super) crtc: [u8; Crtc::COUNT],
    graphics_index: u8,
    pub(super) graphics: [u8; Graphics::COUNT],
    /// The Attribute Controller index as last written, Palette Address Source included.
    pub(super) attribute_index: u8,
    /// The flip-flop: the next write to 0x3C0 is data (else index).
    attribute_expects_data: bool,
    pub(super) attribute: [u8; Attribute::COUNT],
    pub(super) dac: Dac,
    pub(super) dispi: Dispi,
}

impl Registers {
    /// Every register zero (see [`super::SoftVga::unpowered`]).
    pub(super) const fn unpowered() -> Self {
        Self {
            misc_output: 0,
            feature_control: 0,
            sequencer_index: 0,
            sequencer: [0; Sequencer::COUNT],
            crtc_index: 0,
            crtc: [0; Crtc::COUNT],
            graphics_index: 0,
            graphics: [0; Graphics::COUNT],
            attribute_index: 0,
            attribute_expects_data: false,
            attribute: [0; Attribute::COUNT],
            dac: Dac {
                palette: [[0; 3]; 256],
                pixel_mask: 0,
                write_index: 0,
                read_index: 0,
                component: 0,
                pending: [0; 3],
                state: 0,
            },
            dispi: Dispi {
                index: 0,
                enable: 0,
            },
        }
    }

    /// The registers as `mode` programs them, the DAC loaded with `palette`
    /// from entry 0 and the rest black.
    pub(super) const fn with_mode(mode: &ModeRegisters, palette: &[Rgb6]) -> Self {
        let mut dac_palette = [[0; 3]; 256];
        dac_palette
            .split_at_mut(palette.len())
            .0
            .copy_from_slice(palette);
        Self {
            misc_output: mode.misc_output,
            feature_control: 0,
            sequencer_index: 0,
            sequencer: mode.sequencer_values(),
            crtc_index: 0,
            crtc: mode.crtc_values(),
            graphics_index: 0,
            graphics: mode.graphics_values(),
            attribute_index: ac::PALETTE_ADDRESS_SOURCE,
            attribute_expects_data: false,
            attribute: mode.attribute_values(),
            dac: Dac {
                palette: dac_palette,
                pixel_mask: 0xFF,
                write_index: 0,
                read_index: 0,
                component: 0,
                pending: [0; 3],
                state: DAC_STATE_WRITING,
            },
            dispi: Dispi {
                index: 0,
                enable: 0,
            },
        }
    }

    /// The sequencer register the data port writes now.
    pub(super) fn sequencer_index(&self) -> u8 {
        self.sequencer_index
    }

    /// The register `pair`'s data port writes now.
    pub(super) fn pair_index(&self, pair: IndexedPair) -> u8 {
        match pair {
            IndexedPair::Sequencer => self.sequencer_index,
            IndexedPair::Graphics => self.graphics_index,
            IndexedPair::Crtc => self.crtc_index,
        }
    }

    /// The port of Input Status 1 under the current I/O addressing.
    pub(super) fn input_status_1_port(&self) -> Port {
        if self.color_addressing() {
            Port::INPUT_STATUS_1
        } else {
            Port::INPUT_STATUS_1_MONO
        }
    }

    /// Reading Input Status 1 resets the attribute flip-flop to "index".
    pub(super) fn reset_attribute_flip_flop(&mut self) {
        self.attribute_expects_data = false;
    }

    fn color_addressing(&self) -> bool {
        self.misc_output & misc::COLOR_IO_ADDRESSING != 0
    }

    /// Whether `port` answers: of the monochrome (0x3Bx) and colour (0x3Dx)
    /// ranges, only the one Misc Output selects does.
    fn decodes(&self, port: Port) -> bool {
        let range = port.number() & !ADDRESSING_RANGE_OFFSET_BITS;
        let ignored = if self.color_addressing() {
            MONO_PORT_RANGE
        } else {
            COLOR_PORT_RANGE
        };
        range != ignored
    }

    /// One byte written to `port` (Input Status 1 / Feature Control included).
    pub(super) fn write_port(&mut self, port: Port, value: u8) {
        if !self.decodes(port) {
            return;
        }
        match port {
            Port::ATTRIBUTE_INDEX => self.write_attribute_port(value),
            Port::MISC_OUTPUT_WRITE => self.misc_output = value & MISC_OUTPUT_BITS,
            Port::SEQUENCER_INDEX => self.sequencer_index = value & SEQUENCER_INDEX_BITS,
            Port::SEQUENCER_DATA => {
                let index = usize::from(self.sequencer_index);
                if let (Some(register), Some(bits)) =
                    (self.sequencer.get_mut(index), SEQUENCER_BITS.get(index))
                {
                    *register = value & bits;
                }
            }
            Port::DAC_PIXEL_MASK => self.dac.pixel_mask = value,
            Port::DAC_READ_INDEX => self.dac.start(value, DAC_STATE_READING),
            Port::DAC_WRITE_INDEX => self.dac.start(value, DAC_STATE_WRITING),
            Port::DAC_DATA => self.dac.write(value),
            Port::GRAPHICS_INDEX => self.graphics_index = value & GRAPHICS_INDEX_BITS,
            Port::GRAPHICS_DATA => {
                let index = usize::from(self.graphics_index);
                if let (Some(register), Some(bits)) =
                    (self.graphics.get_mut(index), GRAPHICS_BITS.get(index))
                {
                    *register = value & bits;
                }
            }
            Port::CRTC_INDEX | Port::CRTC_INDEX_MONO => self.crtc_index = value,
            Port::CRTC_DATA | Port::CRTC_DATA_MONO => self.write_crtc(value),
            Port::INPUT_STATUS_1 | Port::INPUT_STATUS_1_MONO => {
                self.feature_control = value & FEATURE_CONTROL_BITS
            }
            Port::VBE_DISPI_INDEX | Port::VBE_DISPI_DATA => self.write_dispi(port, value.into()),
            _ => {}
        }
    }

    /// One byte read from `port`, except Input Status 1, which needs the clock.
    pub(super) fn read_port(&mut self, port: Port) -> u8 {
        if !self.decodes(port) {
            return 0xFF;
        }
        match port {
            Port::ATTRIBUTE_INDEX if !self.attribute_expects_data => self.attribute_index,
            Port::ATTRIBUTE_DATA_READ => self
                .attribute
                .get(usize::from(self.attribute_index & ac::INDEX_MASK))
                .copied()
                .unwrap_or(0),
            Port::INPUT_STATUS_0 => 0,
            Port::SEQUENCER_INDEX => self.sequencer_index,
            Port::SEQUENCER_DATA => self
                .sequencer
                .get(usize::from(self.sequencer_index))
                .copied()
                .unwrap_or(0),
            Port::DAC_PIXEL_MASK => self.dac.pixel_mask,
            Port::DAC_READ_INDEX => self.dac.state,
            Port::DAC_WRITE_INDEX => self.dac.write_index,
            Port::DAC_DATA => self.dac.read(),
            Port::MISC_OUTPUT_READ => self.misc_output,
            Port::GRAPHICS_INDEX => self.graphics_index,
            Port::GRAPHICS_DATA => self
                .graphics
                .get(usize::from(self.graphics_index))
                .copied()
                .unwrap_or(0),
            Port::CRTC_INDEX | Port::CRTC_INDEX_MONO => self.crtc_index,
            Port::CRTC_DATA | Port::CRTC_DATA_MONO => self
                .crtc
                .get(usize::from(self.crtc_index))
                .copied()
                .unwrap_or(0),
            Port::VBE_DISPI_INDEX => self.dispi.index as u8,
            Port::VBE_DISPI_DATA => self.read_dispi() as u8,
            _ => 0,
        }
    }

    /// A 16-bit DISPI register access; VGA ports never get here.
    pub(super) fn write_dispi(&mut self, port: Port, value: u16) {
        match port {
            Port::VBE_DISPI_INDEX => self.dispi.index = value,
            Port::VBE_DISPI_DATA if self.dispi.index == vbe::INDEX_ENABLE => {
                self.dispi.enable = value
            }
            _ => {}
        }
    }

    /// A 16-bit read of a DISPI port: the index, or the indexed register.
    pub(super) fn read_dispi_port(&self, port: Port) -> u16 {
        if port == Port::VBE_DISPI_INDEX {
            self.dispi.index
        } else {
            self.read_dispi()
        }
    }

    fn read_dispi(&self) -> u16 {
        if self.dispi.index == vbe::INDEX_ENABLE {
            self.dispi.enable
        } else {
            0
        }
    }

    fn write_attribute_port(&mut self, value: u8) {
        if self.attribute_expects_data {
            let index = self.attribute_index & ac::INDEX_MASK;
            if let Some(register) = self.attribute.get_mut(usize::from(index)) {
                *register = value & attribute_bits(index);
            }
        } else {
            self.attribute_index = value & ATTRIBUTE_INDEX_BITS;
        }
        self.attribute_expects_data = !self.attribute_expects_data;
    }

    fn write_crtc(&mut self, value: u8) {
        let index = self.crtc_index;
        let protected = self.crtc[Crtc::VerticalRetraceEnd.slot()] & crtc::PROTECT_0_7 != 0;
        if protected && index <= Crtc::Overflow.index() {
            if index == Crtc::Overflow.index() {
                let overflow = &mut self.crtc[Crtc::Overflow.slot()];
                *overflow = (*overflow & !crtc::OVERFLOW_LINE_COMPARE_8)
                    | (value & crtc::OVERFLOW_LINE_COMPARE_8);
            }
            return;
        }
        if let Some(register) = self.crtc.get_mut(usize::from(index)) {
            *register = value;
        }
    }

    pub(super) const fn sequencer(&self, register: Sequencer) -> u8 {
        self.sequencer[register.slot()]
    }

    pub(super) const fn graphics(&self, register: Graphics) -> u8 {
        self.graphics[register.slot()]
    }

    pub(super) const fn crtc(&self, register: Crtc) -> u8 {
        self.crtc[register.slot()]
    }

    /// The CRTC start address registers as they stand (not yet latched).
    pub(super) const fn start_address(&self) -> u16 {
        u16::from_be_bytes([
            self.crtc(Crtc::StartAddressHigh),
            self.crtc(Crtc::StartAddressLow),
        ])
    }

    /// A 10-bit vertical count: the `low` register, with bit 8 from Overflow
    /// and bit 9 from another register (Overflow, or Maximum Scan Line for
    /// line compare).
    const fn vertical_count(&self, low: Crtc, overflow_bit_8: u8, high: (Crtc, u8)) -> u16 {
        let (high_register, bit_9) = high;
        self.crtc(low) as u16
            | self.bit_value(Crtc::Overflow, overflow_bit_8, 1 << 8)
            | self.bit_value(high_register, bit_9, 1 << 9)
    }

    /// `value` if the bits `mask` of CRTC register `register` are set, else 0.
    const fn bit_value(&self, register: Crtc, mask: u8, value: u16) -> u16 {
        if self.crtc(register) & mask != 0 {
            value
        } else {
            0
        }
    }

    /// Vertical Total: lines per frame - 2.
    pub(super) const fn vertical_total(&self) -> u16 {
        self.vertical_count(
            Crtc::VerticalTotal,
            crtc::OVERFLOW_VERTICAL_TOTAL_8,
            (Crtc::Overflow, crtc::OVERFLOW_VERTICAL_TOTAL_9),
        )
    }

    /// Vertical Display End: displayed lines - 1.
    pub(super) const fn vertical_display_end(&self) -> u16 {
        self.vertical_count(
            Crtc::VerticalDisplayEnd,
            crtc::OVERFLOW_VERTICAL_DISPLAY_END_8,
            (Crtc::Overflow, crtc::OVERFLOW_VERTICAL_DISPLAY_END_9),
        )
    }

    /// Vertical Retrace Start: the first line of vertical sync.
    pub(super) const fn vertical_retrace_start(&self) -> u16 {
        self.vertical_count(
            Crtc::VerticalRetraceStart,
            crtc::OVERFLOW_VERTICAL_RETRACE_START_8,
            (Crtc::Overflow, crtc::OVERFLOW_VERTICAL_RETRACE_START_9),
        )
    }

    /// Line Compare: after this scan line the display address restarts at 0.
    pub(super) fn line_compare(&self) -> u16 {
        self.vertical_count(
            Crtc::LineCompare,
            crtc::OVERFLOW_LINE_COMPARE_8,
            (Crtc::MaximumScanLine, crtc::LINE_COMPARE_9),
        )
    }

    /// Bochs VBE owns the display and the memory window.
    pub(super) fn vbe_enabled(&self) -> bool {
        self.dispi.enable & vbe::ENABLED != 0
    }
}

impl Dac {
    fn start(&mut self, index: u8, state: u8) {
        if state == DAC_STATE_READING {
            self.read_index = index;
        } else {
            self.write_index = index;
        }
        self.component = 0;
        self.state = state;
    }

    fn write(&mut self, value: u8) {
        self.pending[self.component] = value & DAC_COMPONENT_BITS;
        self.component += 1;
        if self.component == self.pending.len() {
            self.palette[usize::from(self.write_index)] = self.pending;
            self.write_index = self.write_index.wrapping_add(1);
            self.component = 0;
        }
    }

    fn read(&mut self) -> u8 {
        let value = self.palette[usize::from(self.read_index)][self.component];
        self.component += 1;
        if self.component == self.pending.len() {
            self.read_index = self.read_index.wrapping_add(1);
            self.component = 0;
        }
        value
    }
}
