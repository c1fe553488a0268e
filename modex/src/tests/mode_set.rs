//! Mode set from the power-on state and from a state left dirty by anything.

use super::{mode_x, power_on, scanout, Picture, XorShift};
use crate::mode::MODE_X;
use crate::palette::DEFAULT_PALETTE;
use crate::regs::{crtc, seq, vbe};
use crate::regs::{Attribute, Crtc, Graphics, Port, Sequencer};
use crate::soft::{dac_6_to_8, SoftVga};
use crate::VgaBus;

/// Everything Mode X means, checked on the model.
#[track_caller]
fn assert_mode_x(soft: &SoftVga) {
    assert!(!soft.vbe_enabled(), "Bochs VBE still on");
    assert_eq!(soft.misc_output(), 0xE3);
    let sequencer: [u8; Sequencer::COUNT] = Sequencer::ALL.map(|register| soft.sequencer(register));
    assert_eq!(sequencer, [0x03, 0x01, 0x0F, 0x00, 0x06], "sequencer");
    let crtc: [u8; Crtc::COUNT] = Crtc::ALL.map(|register| soft.crtc(register));
    assert_eq!(
        crtc,
        [
            0x5F, 0x4F, 0x50, 0x82, 0x54, 0x80, 0x0D, 0x3E, 0x00, 0x41, 0x00, 0x00, 0x00, 0x00,
            0x00, 0x00, 0xEA, 0xAC, 0xDF, 0x28, 0x00, 0xE7, 0x06, 0xE3, 0xFF
        ],
        "CRTC"
    );
    let graphics: [u8; Graphics::COUNT] = Graphics::ALL.map(|register| soft.graphics(register));
    assert_eq!(
        graphics,
        [0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x05, 0x0F, 0xFF],
        "graphics controller"
    );
    let attribute: [u8; Attribute::COUNT] = Attribute::ALL.map(|register| soft.attribute(register));
    let mut expected_attribute = [0; Attribute::COUNT];
    for (i, value) in expected_attribute.iter_mut().take(16).enumerate() {
        *value = i as u8;
    }
    expected_attribute[Attribute::ModeControl.slot()] = 0x41;
    expected_attribute[Attribute::ColorPlaneEnable.slot()] = 0x0F;
    assert_eq!(attribute, expected_attribute, "attribute controller");
    assert!(
        soft.video_enabled(),
        "palette address source off: screen blanked"
    );
    assert_eq!(soft.dac_pixel_mask(), 0xFF);
    for index in [0u8, 9, 15, 16, 31, 32, 248] {
        assert_eq!(
            soft.dac_entry(index),
            DEFAULT_PALETTE[usize::from(index)],
            "DAC entry {index}"
        );
    }
    assert_eq!(soft.dac_entry(9), [0x15, 0x15, 0x3F]);
    assert_eq!(soft.dac_entry(14), [0x3F, 0x3F, 0x15]);
    assert_eq!(soft.displayed_start(), 0, "page 0 not latched");
    for plane in 0..4 {
        assert!(
            soft.plane(plane).iter().all(|&byte| byte == 0),
            "plane {plane} not cleared"
        );
    }
    super::assert_picture(&Picture::filled(0), &scanout(soft), "screen after mode set");
}

#[test]
fn mode_set_from_power_on_gives_mode_x() {
    let mut soft = power_on();
    mode_x(&mut soft);
    assert_mode_x(&soft);
    assert_eq!(MODE_X.crtc_value(Crtc::Offset), 0x28);
}

/// The state a bootloader's VBE framebuffer, a BIOS mode 13h and a crashed
/// driver might leave together: VBE on, monochrome I/O addressing, CRTC 0-7
/// protected, chain-4, random registers, blanked screen, half-written DAC,
/// attribute flip-flop expecting data, garbage in video memory.
fn dirty(soft: &mut SoftVga) {
    let mut random = XorShift(0x1234_5678);
    // Garbage in every plane, written planar through all four.
    soft.write_port16(
        Port::SEQUENCER_INDEX,
        u16::from_le_bytes([Sequencer::MemoryMode.index(), 0x06]),
    );
    soft.write_port16(
        Port::SEQUENCER_INDEX,
        u16::from_le_bytes([Sequencer::MapMask.index(), 0x0F]),
    );
    soft.write_port16(
        Port::GRAPHICS_INDEX,
        u16::from_le_bytes([Graphics::Misc.index(), 0x05]),
    );
    soft.write_port16(
        Port::GRAPHICS_INDEX,
        u16::from_le_bytes([Graphics::Mode.index(), 0x00]),
    );
    for offset in 0..=u16::MAX {
        soft.write_vram8(offset, random.next_u8() | 1);
    }
    soft.write_port16(Port::VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
    soft.write_port16(Port::VBE_DISPI_DATA, vbe::ENABLED);
    for index in 0..Sequencer::COUNT as u8 {
        soft.write_port16(
            Port::SEQUENCER_INDEX,
            u16::from_le_bytes([index, random.next_u8()]),
        );
    }
    soft.write_port8(Port::SEQUENCER_INDEX, Sequencer::MemoryMode.index());
    soft.write_port8(Port::SEQUENCER_DATA, seq::MEMORY_CHAIN_4);
    for index in 0..Graphics::COUNT as u8 {
        soft.write_port8(Port::GRAPHICS_INDEX, index);
        soft.write_port8(Port::GRAPHICS_DATA, random.next_u8());
    }
    for index in 0..Attribute::COUNT as u8 {
        soft.write_port8(Port::ATTRIBUTE_INDEX, index);
        soft.write_port8(Port::ATTRIBUTE_INDEX, random.next_u8());
    }
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x05); // index only: the flip-flop now expects data
    soft.write_port8(Port::DAC_PIXEL_MASK, 0x00);
    soft.write_port8(Port::DAC_WRITE_INDEX, 9);
    soft.write_port8(Port::DAC_DATA, 0x3F); // one of three components
    soft.write_port8(Port::MISC_OUTPUT_WRITE, 0x66); // monochrome addressing: CRTC at 0x3B4
    for index in 0..Crtc::COUNT as u8 {
        soft.write_port16(
            Port::CRTC_INDEX_MONO,
            u16::from_le_bytes([index, random.next_u8()]),
        );
    }
    soft.write_port8(Port::CRTC_INDEX_MONO, Crtc::VerticalRetraceEnd.index());
    soft.write_port8(Port::CRTC_DATA_MONO, crtc::PROTECT_0_7);
}

#[test]
fn mode_set_from_a_dirty_state_gives_mode_x() {
    let mut soft = power_on();
    dirty(&mut soft);
    assert!(soft.vbe_enabled());
    mode_x(&mut soft);
    assert_mode_x(&soft);
}

/// A card without Bochs VBE (by its PCI ID) never has those ports written:
/// on other cards they are other registers.
#[test]
fn a_standard_card_mode_set_leaves_the_vbe_ports_alone() {
    let mut soft = power_on();
    soft.write_port16(Port::VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
    soft.write_port16(Port::VBE_DISPI_DATA, vbe::ENABLED);
    crate::ModeX::new(&mut *soft).set_mode();
    assert!(soft.vbe_enabled());
}

#[test]
fn mode_set_twice_is_the_same_as_once() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.fill_rect(crate::Page::Zero, 10, 10, 100, 100, 7);
    vga.set_mode();
    assert_mode_x(vga.bus());
}

#[test]
fn scanout_expands_the_dac_as_qemu_screendump_does() {
    assert_eq!(dac_6_to_8(0x00), 0x00);
    assert_eq!(dac_6_to_8(0x15), 0x57);
    assert_eq!(dac_6_to_8(0x2A), 0xA8);
    assert_eq!(dac_6_to_8(0x3F), 0xFF);

    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.fill_rect(crate::Page::Zero, 0, 0, 1, 1, 9);
    vga.fill_rect(crate::Page::Zero, 1, 0, 2, 1, 14);
    let mut rgb = std::vec![[0u8; 3]; 320 * 240];
    assert_eq!(vga.bus().scanout_rgb(&mut rgb), (320, 240));
    assert_eq!(rgb[0], [0x57, 0x57, 0xFF]);
    assert_eq!(rgb[1], [0xFF, 0xFF, 0x57]);
    assert_eq!(rgb[2], [0, 0, 0]);
}

#[test]
fn a_blanked_screen_scans_out_black() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(crate::Page::Zero, 15);
    // Writing an attribute index without Palette Address Source blanks video.
    vga.bus_mut().read_port8(Port::INPUT_STATUS_1);
    vga.bus_mut().write_port8(Port::ATTRIBUTE_INDEX, 0x00);
    let mut rgb = std::vec![[1u8; 3]; 320 * 240];
    vga.bus().scanout_rgb(&mut rgb);
    assert!(rgb.iter().all(|&pixel| pixel == [0; 3]));
}
