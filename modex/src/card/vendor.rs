//! What a card's maker adds on top of the standard VGA, and how to switch it
//! off when no video BIOS can do it for us: the extended (linear, high
//! colour) modes a VBE call turns on live in registers the standard mode set
//! never touches, and while they are on the card shows its own picture,
//! whatever the VGA registers say.
//!
//! Each reset is written only to a card whose PCI ID says it has those
//! registers: the same ports mean other things on other cards (ATI's old
//! extended registers sit at 0x1CE/0x1CF, where Bochs VBE's are).

use crate::regs::{vbe, IndexedPair};

/// The extension family of a VGA card, as told by its PCI vendor and device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Card {
    /// A standard VGA, or one whose extensions we do not know: no resets.
    Standard,
    /// Bochs VBE ("DISPI") ports: QEMU's std VGA, bochs-display, vmware-svga,
    /// qxl-vga and virtio-vga, whose VGA BIOSes all use them.
    BochsDispi,
    /// Cirrus Logic GD54xx: extended sequencer, graphics and CRTC registers
    /// behind the Sequencer index 6 unlock, and a hidden DAC register.
    Cirrus,
    /// ATI Rage 128 / Radeon: the extended CRTC is switched in through
    /// memory-mapped registers; no port reset exists for it here.
    Ati,
}

/// One write of an extension reset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetStep {
    /// A Bochs VBE register: index to 0x1CE, value to 0x1CF (16-bit each).
    Dispi {
        /// DISPI register index.
        index: u16,
        /// Value to write.
        value: u16,
    },
    /// A register of a standard index/data pair, at an index the standard
    /// VGA does not use.
    Indexed {
        /// The pair (Sequencer, Graphics Controller or CRTC).
        pair: IndexedPair,
        /// Register index.
        index: u8,
        /// Value to write.
        value: u8,
    },
    /// Cirrus's hidden DAC register: four reads of the DAC Pixel Mask port
    /// open it for one write.
    CirrusHiddenDac(u8),
}

/// Cirrus Logic register indices (GD5446 technical reference).
pub mod cirrus {
    /// SR6: writing 0x12 unlocks the extended registers.
    pub const UNLOCK: u8 = 0x06;
    /// SR6 value that unlocks them.
    pub const UNLOCK_KEY: u8 = 0x12;
    /// SR7 Extended Sequencer Mode; bit 0 selects the extended (packed or
    /// linear) pixel modes, bits 1-3 their depth.
    pub const EXTENDED_SEQUENCER_MODE: u8 = 0x07;
    /// SR7 bit 0.
    pub const EXTENDED_MODES: u8 = 0x01;
    /// GR9/GRA: the CPU window's offsets into video memory (banking).
    pub const OFFSET_0: u8 = 0x09;
    /// GRA.
    pub const OFFSET_1: u8 = 0x0A;
    /// GRB: Graphics Controller Mode Extensions (banking, extended writes).
    pub const GRAPHICS_EXTENSIONS: u8 = 0x0B;
    /// CR1A: Miscellaneous Control (interlace, extra address bits).
    pub const MISC_CONTROL: u8 = 0x1A;
    /// CR1B: Extended Display Controls (start address and offset bits 16+).
    pub const EXTENDED_DISPLAY: u8 = 0x1B;
    /// CR1D: Overlay Extended Control (start address bit 19).
    pub const OVERLAY_EXTENDED: u8 = 0x1D;
}

const BOCHS_DISPI_RESET: &[ResetStep] = &[ResetStep::Dispi {
    index: vbe::INDEX_ENABLE,
    value: vbe::DISABLED,
}];

const fn indexed(pair: IndexedPair, index: u8, value: u8) -> ResetStep {
    ResetStep::Indexed { pair, index, value }
}

const CIRRUS_RESET: &[ResetStep] = &[
    indexed(IndexedPair::Sequencer, cirrus::UNLOCK, cirrus::UNLOCK_KEY),
    indexed(IndexedPair::Sequencer, cirrus::EXTENDED_SEQUENCER_MODE, 0),
    indexed(IndexedPair::Graphics, cirrus::OFFSET_0, 0),
    indexed(IndexedPair::Graphics, cirrus::OFFSET_1, 0),
    indexed(IndexedPair::Graphics, cirrus::GRAPHICS_EXTENSIONS, 0),
    indexed(IndexedPair::Crtc, cirrus::MISC_CONTROL, 0),
    indexed(IndexedPair::Crtc, cirrus::EXTENDED_DISPLAY, 0),
    indexed(IndexedPair::Crtc, cirrus::OVERLAY_EXTENDED, 0),
    ResetStep::CirrusHiddenDac(0),
];

/// How to read whether a card's extended mode is still on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtensionProbe {
    /// Bochs VBE ENABLE (index 4 at 0x1CE, read 0x1CF): bit 0 clear.
    DispiEnable,
    /// Cirrus SR7 (unlocked): bit 0 clear.
    CirrusExtendedModes,
}

impl Card {
    /// The family of the display controller with these PCI IDs.
    pub fn from_pci_ids(vendor: u16, device: u16) -> Card {
        match (vendor, device) {
            (0x1234, 0x1111) | (0x15AD, 0x0405) | (0x1B36, 0x0100) | (0x1AF4, 0x1050) => {
                Card::BochsDispi
            }
            (0x1013, _) => Card::Cirrus,
            (0x1002, _) => Card::Ati,
            _ => Card::Standard,
        }
    }

    /// The writes that switch this card's extended modes off, in order.
    pub fn extension_reset(self) -> &'static [ResetStep] {
        match self {
            Card::BochsDispi => BOCHS_DISPI_RESET,
            Card::Cirrus => CIRRUS_RESET,
            Card::Standard | Card::Ati => &[],
        }
    }

    /// How to check that the extended modes are off, if we can.
    pub fn extension_probe(self) -> Option<ExtensionProbe> {
        match self {
            Card::BochsDispi => Some(ExtensionProbe::DispiEnable),
            Card::Cirrus => Some(ExtensionProbe::CirrusExtendedModes),
            Card::Standard | Card::Ati => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pci_ids_name_the_extension_family() {
        assert_eq!(Card::from_pci_ids(0x1234, 0x1111), Card::BochsDispi);
        assert_eq!(Card::from_pci_ids(0x15AD, 0x0405), Card::BochsDispi);
        assert_eq!(Card::from_pci_ids(0x1B36, 0x0100), Card::BochsDispi);
        assert_eq!(Card::from_pci_ids(0x1AF4, 0x1050), Card::BochsDispi);
        assert_eq!(Card::from_pci_ids(0x1013, 0x00B8), Card::Cirrus);
        assert_eq!(Card::from_pci_ids(0x1002, 0x5046), Card::Ati);
        assert_eq!(Card::from_pci_ids(0x8086, 0x0166), Card::Standard);
        assert_eq!(Card::from_pci_ids(0x1234, 0x2222), Card::Standard);
    }

    #[test]
    fn only_known_cards_get_resets_and_dispi_ports_only_dispi_cards() {
        for card in [Card::Standard, Card::Ati] {
            assert!(card.extension_reset().is_empty(), "{card:?}");
            assert_eq!(card.extension_probe(), None);
        }
        let touches_dispi = |card: Card| {
            card.extension_reset()
                .iter()
                .any(|step| matches!(step, ResetStep::Dispi { .. }))
        };
        assert!(touches_dispi(Card::BochsDispi));
        assert!(!touches_dispi(Card::Cirrus));
    }

    #[test]
    fn the_cirrus_reset_unlocks_first_and_clears_the_extended_mode() {
        let steps = Card::Cirrus.extension_reset();
        assert_eq!(
            steps[0],
            indexed(IndexedPair::Sequencer, cirrus::UNLOCK, cirrus::UNLOCK_KEY)
        );
        assert!(steps.contains(&indexed(
            IndexedPair::Sequencer,
            cirrus::EXTENDED_SEQUENCER_MODE,
            0
        )));
        // The start address and offset bits above the standard VGA's must go,
        // or the picture starts somewhere else in video memory.
        assert!(steps.contains(&indexed(IndexedPair::Crtc, cirrus::EXTENDED_DISPLAY, 0)));
        assert!(steps.contains(&ResetStep::CirrusHiddenDac(0)));
    }
}
