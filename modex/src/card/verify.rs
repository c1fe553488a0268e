//! Mode sets that prove themselves: the card's extension reset, and a read-back
//! of the registers that decide what the screen shows, so the kernel never
//! reports a mode it has not seen in the hardware.

use super::vendor::{cirrus, ExtensionProbe, ResetStep};
use crate::mode::ModeRegisters;
use crate::regs::{
    ac, crtc, gc, seq, vbe, ATTRIBUTE_DATA_READ, ATTRIBUTE_INDEX, CRTC_DATA, CRTC_INDEX,
    DAC_PIXEL_MASK, GRAPHICS_DATA, GRAPHICS_INDEX, INPUT_STATUS_1, MISC_OUTPUT_READ,
    SEQUENCER_DATA, SEQUENCER_INDEX, VBE_DISPI_DATA, VBE_DISPI_INDEX,
};
use crate::{ModeX, VgaBus};

/// A register that did not read back what the mode set wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Register {
    /// Miscellaneous Output (read at 0x3CC).
    MiscOutput,
    /// A Sequencer register.
    Sequencer(u8),
    /// A CRT Controller register.
    Crtc(u8),
    /// A Graphics Controller register.
    Graphics(u8),
    /// An Attribute Controller register.
    Attribute(u8),
    /// The card's extended-mode switch (Bochs VBE ENABLE, Cirrus SR7).
    Extension(ExtensionProbe),
}

/// What was expected and what was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mismatch {
    /// The register.
    pub register: Register,
    /// The value the mode set wrote (for the extension: its bit clear).
    pub expected: u8,
    /// The value read back.
    pub found: u8,
}

/// Sequencer registers compared: clocking, character map, memory mode (the
/// Map Mask changes while drawing).
const SEQUENCER_CHECKED: [u8; 3] = [
    seq::CLOCKING_MODE,
    seq::CHARACTER_MAP_SELECT,
    seq::MEMORY_MODE,
];
/// Graphics Controller registers compared: the mode and the memory map.
const GRAPHICS_CHECKED: [u8; 2] = [gc::MODE, gc::MISC];
/// Attribute registers compared: mode control and colour plane enable.
const ATTRIBUTE_CHECKED: [u8; 2] = [ac::MODE_CONTROL, ac::COLOR_PLANE_ENABLE];

/// CRTC registers that flips and the cursor change, so not compared.
fn crtc_changes_at_run_time(index: u8) -> bool {
    (crtc::START_ADDRESS_HIGH..=crtc::CURSOR_LOCATION_LOW).contains(&index)
}

impl<B: VgaBus> ModeX<B> {
    /// Writes the card's extension reset (nothing for a standard card).
    pub(crate) fn reset_extensions(&mut self) {
        for step in self.card().extension_reset() {
            match *step {
                ResetStep::Dispi { index, value } => {
                    self.bus.write_port16(VBE_DISPI_INDEX, index);
                    self.bus.write_port16(VBE_DISPI_DATA, value);
                }
                ResetStep::Indexed {
                    index_port,
                    index,
                    value,
                } => self
                    .bus
                    .write_port16(index_port, u16::from_le_bytes([index, value])),
                ResetStep::CirrusHiddenDac(value) => {
                    for _ in 0..4 {
                        self.bus.read_port8(DAC_PIXEL_MASK);
                    }
                    self.bus.write_port8(DAC_PIXEL_MASK, value);
                }
            }
        }
    }

    /// Reads back the registers that decide the picture and compares them
    /// with `mode`; then checks that the card's extended mode is off.
    pub fn verify(&mut self, mode: &ModeRegisters) -> Result<(), Mismatch> {
        let check = |register, expected: u8, found: u8| {
            if expected == found {
                Ok(())
            } else {
                Err(Mismatch {
                    register,
                    expected,
                    found,
                })
            }
        };
        check(
            Register::MiscOutput,
            mode.misc_output,
            self.bus.read_port8(MISC_OUTPUT_READ),
        )?;
        for index in SEQUENCER_CHECKED {
            let found = self.read_indexed(SEQUENCER_INDEX, SEQUENCER_DATA, index);
            check(
                Register::Sequencer(index),
                mode.sequencer[usize::from(index)],
                found,
            )?;
        }
        for index in (0..crtc::COUNT as u8).filter(|&i| !crtc_changes_at_run_time(i)) {
            let found = self.read_indexed(CRTC_INDEX, CRTC_DATA, index);
            check(Register::Crtc(index), mode.crtc[usize::from(index)], found)?;
        }
        for index in GRAPHICS_CHECKED {
            let found = self.read_indexed(GRAPHICS_INDEX, GRAPHICS_DATA, index);
            check(
                Register::Graphics(index),
                mode.graphics[usize::from(index)],
                found,
            )?;
        }
        for index in ATTRIBUTE_CHECKED {
            let found = self.read_attribute(index);
            check(
                Register::Attribute(index),
                mode.attribute[usize::from(index)],
                found,
            )?;
        }
        if let Some(probe) = self.card().extension_probe() {
            let (found, bit) = self.read_extension(probe);
            check(Register::Extension(probe), found & !bit, found)?;
        }
        Ok(())
    }

    fn read_indexed(&mut self, index_port: u16, data_port: u16, index: u8) -> u8 {
        self.bus.write_port8(index_port, index);
        self.bus.read_port8(data_port)
    }

    /// Reads an attribute register with the palette address source kept on
    /// (so the screen stays lit), leaving the flip-flop in its index state.
    fn read_attribute(&mut self, index: u8) -> u8 {
        self.bus.read_port8(INPUT_STATUS_1);
        self.bus
            .write_port8(ATTRIBUTE_INDEX, index | ac::PALETTE_ADDRESS_SOURCE);
        let value = self.bus.read_port8(ATTRIBUTE_DATA_READ);
        self.bus.read_port8(INPUT_STATUS_1);
        value
    }

    /// The extension register's value and the bit that must be clear.
    fn read_extension(&mut self, probe: ExtensionProbe) -> (u8, u8) {
        match probe {
            ExtensionProbe::DispiEnable => {
                self.bus.write_port16(VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
                // Only the low byte holds flags; the port answers 16-bit reads.
                let [enable, _] = self.bus.read_port16(VBE_DISPI_DATA).to_le_bytes();
                (enable, vbe::ENABLED as u8)
            }
            ExtensionProbe::CirrusExtendedModes => {
                self.bus.write_port16(
                    SEQUENCER_INDEX,
                    u16::from_le_bytes([cirrus::UNLOCK, cirrus::UNLOCK_KEY]),
                );
                let sr7 = self.read_indexed(
                    SEQUENCER_INDEX,
                    SEQUENCER_DATA,
                    cirrus::EXTENDED_SEQUENCER_MODE,
                );
                (sr7, cirrus::EXTENDED_MODES)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::card::Card;
    use crate::mode::{MODE_X, TEXT_80X25};
    use crate::soft::SoftVga;
    use std::boxed::Box;

    fn soft_in_mode_x(card: Card) -> Box<SoftVga> {
        let mut soft = Box::new(SoftVga::new());
        ModeX::for_card(&mut *soft, card).set_mode();
        soft
    }

    #[test]
    fn a_mode_set_reads_back_as_set() {
        let mut soft = soft_in_mode_x(Card::BochsDispi);
        assert_eq!(
            ModeX::for_card(&mut *soft, Card::BochsDispi).verify(&MODE_X),
            Ok(())
        );
    }

    #[test]
    fn a_register_the_card_did_not_take_is_caught() {
        let mut soft = soft_in_mode_x(Card::Standard);
        // As if the card ignored the unchaining: chain-4 still on.
        soft.write_port8(SEQUENCER_INDEX, seq::MEMORY_MODE);
        soft.write_port8(SEQUENCER_DATA, 0x0E);
        assert_eq!(
            ModeX::new(&mut *soft).verify(&MODE_X),
            Err(Mismatch {
                register: Register::Sequencer(seq::MEMORY_MODE),
                expected: 0x06,
                found: 0x0E
            })
        );
        // And the wrong mode altogether.
        let mut soft = soft_in_mode_x(Card::Standard);
        assert!(ModeX::new(&mut *soft).verify(&TEXT_80X25).is_err());
    }

    #[test]
    fn an_extended_mode_left_on_is_caught() {
        let mut soft = soft_in_mode_x(Card::BochsDispi);
        soft.write_port16(VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
        soft.write_port16(VBE_DISPI_DATA, vbe::ENABLED);
        let result = ModeX::for_card(&mut *soft, Card::BochsDispi).verify(&MODE_X);
        assert_eq!(
            result.map_err(|m| m.register),
            Err(Register::Extension(ExtensionProbe::DispiEnable))
        );
    }

    #[test]
    fn flips_do_not_fail_the_check() {
        let mut soft = soft_in_mode_x(Card::Standard);
        let mut vga = ModeX::new(&mut *soft);
        vga.show_page(crate::Page::One);
        assert_eq!(vga.verify(&MODE_X), Ok(()));
    }
}
