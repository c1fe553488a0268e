//! Mode sets that prove themselves: the card's extension reset, and a read-back
//! of the registers that decide what the screen shows, so the kernel never
//! reports a mode it has not seen in the hardware.

use super::vendor::ExtensionProbe;
use crate::mode::ModeRegisters;
use crate::regs::{Attribute, Crtc, Graphics, Sequencer};
use crate::{ModeX, VgaBus};

/// A register that did not read back what the mode set wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Register {
    /// Miscellaneous Output (read at 0x3CC).
    MiscOutput,
    /// A Sequencer register.
    Sequencer(Sequencer),
    /// A CRT Controller register.
    Crtc(Crtc),
    /// A Graphics Controller register.
    Graphics(Graphics),
    /// An Attribute Controller register.
    Attribute(Attribute),
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
const SEQUENCER_CHECKED: [Sequencer; 3] = [
    Sequencer::ClockingMode,
    Sequencer::CharacterMapSelect,
    Sequencer::MemoryMode,
];
/// Graphics Controller registers compared: the mode and the memory map.
const GRAPHICS_CHECKED: [Graphics; 2] = [Graphics::Mode, Graphics::Misc];
/// Attribute registers compared: mode control and colour plane enable.
const ATTRIBUTE_CHECKED: [Attribute; 2] = [Attribute::ModeControl, Attribute::ColorPlaneEnable];

/// CRTC registers that flips and the cursor change, so not compared.
fn crtc_changes_at_run_time(register: Crtc) -> bool {
    (Crtc::StartAddressHigh.index()..=Crtc::CursorLocationLow.index()).contains(&register.index())
}

impl<B: VgaBus> ModeX<B> {
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
        let io = &mut self.io;
        check(
            Register::MiscOutput,
            mode.misc_output,
            io.read_misc_output(),
        )?;
        for register in SEQUENCER_CHECKED {
            let found = io.read_sequencer(register);
            check(
                Register::Sequencer(register),
                mode.sequencer_value(register),
                found,
            )?;
        }
        for register in Crtc::ALL
            .into_iter()
            .filter(|&r| !crtc_changes_at_run_time(r))
        {
            let found = io.read_crtc(register);
            check(Register::Crtc(register), mode.crtc_value(register), found)?;
        }
        for register in GRAPHICS_CHECKED {
            let found = io.read_graphics(register);
            check(
                Register::Graphics(register),
                mode.graphics_value(register),
                found,
            )?;
        }
        for register in ATTRIBUTE_CHECKED {
            let found = io.read_attribute(register);
            check(
                Register::Attribute(register),
                mode.attribute_value(register),
                found,
            )?;
        }
        if let Some(probe) = io.card().extension_probe() {
            let (found, bit) = io.read_extension(probe);
            check(Register::Extension(probe), found & !bit, found)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::card::Card;
    use crate::mode::{MODE_X, TEXT_80X25};
    use crate::regs::{vbe, Port};
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
        soft.write_port8(Port::SEQUENCER_INDEX, Sequencer::MemoryMode.index());
        soft.write_port8(Port::SEQUENCER_DATA, 0x0E);
        assert_eq!(
            ModeX::new(&mut *soft).verify(&MODE_X),
            Err(Mismatch {
                register: Register::Sequencer(Sequencer::MemoryMode),
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
        soft.write_port16(Port::VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
        soft.write_port16(Port::VBE_DISPI_DATA, vbe::ENABLED);
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
