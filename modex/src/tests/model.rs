//! The software VGA on its own: write and read paths as QEMU's VGA does them,
//! port decoding, the DAC protocol, timing and the probes.

use super::power_on;
use crate::regs::{crtc, gc, seq, status};
use crate::regs::{Attribute, Crtc, Graphics, Port, Sequencer};
use crate::soft::{SoftVga, PORT_ACCESS_NS, VRAM_ACCESS_NS};
use crate::VgaBus;

fn sequencer(soft: &mut SoftVga, index: u8, value: u8) {
    soft.write_port16(Port::SEQUENCER_INDEX, u16::from_le_bytes([index, value]));
}

fn graphics(soft: &mut SoftVga, index: u8, value: u8) {
    soft.write_port16(Port::GRAPHICS_INDEX, u16::from_le_bytes([index, value]));
}

/// Planar addressing at A0000, write mode 0, everything pass-through.
fn planar() -> std::boxed::Box<SoftVga> {
    let mut soft = power_on();
    sequencer(&mut soft, Sequencer::MemoryMode.index(), 0x06);
    sequencer(&mut soft, Sequencer::MapMask.index(), 0x0F);
    for (index, value) in [0x00, 0x00, 0x00, 0x00, 0x00, 0x40, 0x05, 0x0F, 0xFF]
        .into_iter()
        .enumerate()
    {
        graphics(&mut soft, index as u8, value);
    }
    soft
}

/// Writes `values[p]` into plane p at `offset`.
fn write_planes(soft: &mut SoftVga, offset: u16, values: [u8; 4]) {
    for (plane, value) in values.into_iter().enumerate() {
        sequencer(soft, Sequencer::MapMask.index(), 1 << plane);
        soft.write_vram8(offset, value);
    }
    sequencer(soft, Sequencer::MapMask.index(), 0x0F);
}

fn planes_at(soft: &SoftVga, offset: u16) -> [u8; 4] {
    core::array::from_fn(|plane| soft.plane(plane)[usize::from(offset)])
}

#[test]
fn map_mask_selects_the_planes_written() {
    let mut soft = planar();
    sequencer(&mut soft, Sequencer::MapMask.index(), 0b1010);
    soft.write_vram8(100, 0xAB);
    assert_eq!(planes_at(&soft, 100), [0, 0xAB, 0, 0xAB]);
}

#[test]
fn reads_load_all_latches_and_return_the_read_map() {
    let mut soft = planar();
    write_planes(&mut soft, 7, [0x11, 0x22, 0x33, 0x44]);
    for plane in 0..4u8 {
        graphics(&mut soft, Graphics::ReadMapSelect.index(), plane);
        assert_eq!(soft.read_vram8(7), 0x11 * (plane + 1));
        assert_eq!(soft.latches(), [0x11, 0x22, 0x33, 0x44]);
    }
}

#[test]
fn write_mode_1_copies_the_latches() {
    let mut soft = planar();
    write_planes(&mut soft, 10, [1, 2, 3, 4]);
    soft.read_vram8(10);
    graphics(&mut soft, Graphics::Mode.index(), 0x41);
    soft.write_vram8(2000, 0xEE); // the CPU's byte is ignored
    assert_eq!(planes_at(&soft, 2000), [1, 2, 3, 4]);
    sequencer(&mut soft, Sequencer::MapMask.index(), 0b0101);
    soft.write_vram8(3000, 0xEE);
    assert_eq!(planes_at(&soft, 3000), [1, 0, 3, 0]);
}

#[test]
fn write_mode_0_applies_set_reset_function_rotate_and_bit_mask() {
    let mut soft = planar();
    write_planes(&mut soft, 0, [0xF0, 0xF0, 0xF0, 0xF0]);
    soft.read_vram8(0);
    // Set/Reset on planes 0 and 1 (plane 0 set, plane 1 reset); XOR; bit mask 0x3C.
    graphics(&mut soft, Graphics::SetReset.index(), 0b0001);
    graphics(&mut soft, Graphics::EnableSetReset.index(), 0b0011);
    graphics(
        &mut soft,
        Graphics::DataRotate.index(),
        3 << gc::FUNCTION_SHIFT,
    );
    graphics(&mut soft, Graphics::BitMask.index(), 0x3C);
    soft.write_vram8(0, 0x0F);
    // plane 0: 0xFF ^ 0xF0 = 0x0F; plane 1: 0x00 ^ 0xF0 = 0xF0; planes 2, 3: 0x0F ^ 0xF0 = 0xFF;
    // then bits 2-5 from those, the rest from the latch 0xF0.
    assert_eq!(planes_at(&soft, 0), [0xCC, 0xF0, 0xFC, 0xFC]);

    // Rotate right by 4, AND with the latch (0xCC in plane 0).
    soft.read_vram8(0);
    graphics(&mut soft, Graphics::EnableSetReset.index(), 0);
    graphics(
        &mut soft,
        Graphics::DataRotate.index(),
        (1 << gc::FUNCTION_SHIFT) | 4,
    );
    graphics(&mut soft, Graphics::BitMask.index(), 0xFF);
    sequencer(&mut soft, Sequencer::MapMask.index(), 0b0001);
    soft.write_vram8(0, 0x3F);
    assert_eq!(soft.plane(0)[0], 0xF3 & 0xCC);
}

#[test]
fn write_modes_2_and_3_take_colours() {
    let mut soft = planar();
    graphics(&mut soft, Graphics::Mode.index(), 0x42);
    soft.read_vram8(50);
    soft.write_vram8(50, 0b0110);
    assert_eq!(planes_at(&soft, 50), [0x00, 0xFF, 0xFF, 0x00]);
    graphics(&mut soft, Graphics::Mode.index(), 0x43);
    graphics(&mut soft, Graphics::SetReset.index(), 0b1001);
    soft.read_vram8(50);
    soft.write_vram8(50, 0x0F); // bit mask 0xFF & 0x0F
    assert_eq!(planes_at(&soft, 50), [0x0F, 0xF0, 0xF0, 0x0F]);
}

#[test]
fn read_mode_1_compares_colours() {
    let mut soft = planar();
    write_planes(&mut soft, 0, [0b1010_1010, 0b1100_1100, 0, 0xFF]);
    graphics(&mut soft, Graphics::Mode.index(), 0x48);
    graphics(&mut soft, Graphics::ColorCompare.index(), 0b1011);
    graphics(&mut soft, Graphics::ColorDontCare.index(), 0x0F);
    assert_eq!(soft.read_vram8(0), 0b1000_1000);
    graphics(&mut soft, Graphics::ColorDontCare.index(), 0b0001); // only plane 0 counts
    assert_eq!(soft.read_vram8(0), 0b1010_1010);
}

#[test]
fn chain_4_maps_addresses_as_qemu_does() {
    let mut soft = planar();
    sequencer(
        &mut soft,
        Sequencer::MemoryMode.index(),
        seq::MEMORY_CHAIN_4 | seq::MEMORY_ODD_EVEN_DISABLE,
    );
    for address in 0..8u16 {
        soft.write_vram8(address, address as u8 + 1);
    }
    assert_eq!(planes_at(&soft, 0), [1, 2, 3, 4]);
    assert_eq!(planes_at(&soft, 1), [5, 6, 7, 8]);
    assert_eq!(soft.read_vram8(6), 7);
}

#[test]
fn crtc_0_to_7_are_protected_by_vertical_retrace_end_bit_7() {
    let mut soft = power_on();
    let write = |soft: &mut SoftVga, index: u8, value: u8| {
        soft.write_port16(Port::CRTC_INDEX, u16::from_le_bytes([index, value]));
    };
    write(
        &mut soft,
        Crtc::VerticalRetraceEnd.index(),
        crtc::PROTECT_0_7,
    );
    write(&mut soft, Crtc::HorizontalTotal.index(), 0x12);
    write(&mut soft, Crtc::Overflow.index(), 0xFF);
    assert_eq!(soft.crtc(Crtc::HorizontalTotal), 0x5F);
    assert_eq!(
        soft.crtc(Crtc::Overflow),
        0x1F | crtc::OVERFLOW_LINE_COMPARE_8
    );
    write(&mut soft, Crtc::VerticalRetraceEnd.index(), 0);
    write(&mut soft, Crtc::HorizontalTotal.index(), 0x12);
    assert_eq!(soft.crtc(Crtc::HorizontalTotal), 0x12);
}

#[test]
fn misc_output_selects_colour_or_monochrome_crtc_ports() {
    let mut soft = power_on();
    soft.write_port8(Port::MISC_OUTPUT_WRITE, 0x66);
    soft.write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::Offset.index(), 0x11]),
    );
    assert_eq!(
        soft.crtc(Crtc::Offset),
        0x28,
        "colour port decoded in monochrome addressing"
    );
    assert_eq!(soft.read_port8(Port::CRTC_DATA), 0xFF);
    soft.write_port16(
        Port::CRTC_INDEX_MONO,
        u16::from_le_bytes([Crtc::Offset.index(), 0x11]),
    );
    assert_eq!(soft.read_port8(Port::CRTC_DATA_MONO), 0x11);
}

#[test]
fn the_attribute_flip_flop_alternates_and_input_status_1_resets_it() {
    let mut soft = power_on();
    soft.read_port8(Port::INPUT_STATUS_1);
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x01);
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x3A);
    assert_eq!(soft.attribute(Attribute::Palette1), 0x3A);
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x02); // index; now expecting data
    soft.read_port8(Port::INPUT_STATUS_1);
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x23); // an index again, with video on
    soft.write_port8(Port::ATTRIBUTE_INDEX, 0x15);
    assert_eq!(soft.attribute(Attribute::Palette3), 0x15);
    assert_eq!(soft.read_port8(Port::ATTRIBUTE_DATA_READ), 0x15);
    assert!(soft.video_enabled());
}

#[test]
fn the_dac_takes_and_gives_three_components_per_entry() {
    let mut soft = power_on();
    soft.write_port8(Port::DAC_WRITE_INDEX, 200);
    for component in [1, 2, 3, 4, 5, 0xFF] {
        soft.write_port8(Port::DAC_DATA, component);
    }
    assert_eq!(soft.dac_entry(200), [1, 2, 3]);
    assert_eq!(soft.dac_entry(201), [4, 5, 0x3F], "components are 6 bits");
    soft.write_port8(Port::DAC_READ_INDEX, 200);
    let read: [u8; 6] = core::array::from_fn(|_| soft.read_port8(Port::DAC_DATA));
    assert_eq!(read, [1, 2, 3, 4, 5, 0x3F]);
}

#[test]
fn mode_x_timing_is_the_640x480_frame() {
    let mut soft = power_on();
    crate::ModeX::new(&mut *soft).set_mode();
    let timing = soft.timing();
    assert_eq!(
        (timing.dot_clock_hz, timing.dots_per_character),
        (25_175_000, 8)
    );
    assert_eq!(
        (timing.characters_per_line, timing.display_characters),
        (100, 80)
    );
    // Abrash's Vertical Total 0x20D counts 527 lines.
    assert_eq!((timing.lines_per_frame, timing.display_lines), (527, 480));
    assert_eq!((timing.retrace_start_line, timing.retrace_lines), (490, 2));
    assert!((16_700_000..16_800_000).contains(&timing.frame_ns()));
}

#[test]
fn input_status_1_follows_the_beam() {
    let mut soft = power_on();
    crate::ModeX::new(&mut *soft).set_mode();
    let timing = soft.timing();
    // Sample a frame about four times a line, at phases that sweep the line
    // evenly (a step of 101/400 line), and count where the bits are set.
    const STEP_PER_LINE: (u64, u64) = (101, 400);
    let step_ns = timing.frame_ns() * STEP_PER_LINE.0 / STEP_PER_LINE.1 / timing.lines_per_frame;
    let samples = timing.lines_per_frame * STEP_PER_LINE.1 / STEP_PER_LINE.0;
    let (mut retrace_samples, mut blank_samples) = (0, 0);
    for _ in 0..samples {
        soft.advance_ns(step_ns - PORT_ACCESS_NS);
        let bits = soft.read_port8(Port::INPUT_STATUS_1);
        retrace_samples += u64::from(bits & status::VERTICAL_RETRACE != 0);
        blank_samples += u64::from(bits & status::DISPLAY_DISABLED != 0);
    }
    // Retrace: 2 lines, about 8 samples.
    assert!(
        (7..=9).contains(&retrace_samples),
        "retrace seen {retrace_samples} times"
    );
    // Blanking: 47 of 527 lines, and 20 of 100 characters on the others.
    let expected_blank = samples * 47 / 527 + samples * 480 / 527 / 5;
    assert!(
        blank_samples.abs_diff(expected_blank) < samples / 50,
        "{blank_samples} vs {expected_blank}"
    );
}

/// The bits the model keeps between reads (`CrtTiming::status_until`)
/// are the beam's at every read, through steps of every size and changes
/// of the dot clock, which re-time the beam at once.
#[test]
fn input_status_1_is_the_beams_at_every_read_across_timing_changes() {
    let mut soft = power_on();
    crate::ModeX::new(&mut *soft).set_mode();
    let misc = soft.read_port8(Port::MISC_OUTPUT_READ);
    let mut random = super::xorshift(0x9e37_79b9);
    for read in 0..200_000u32 {
        if read % 5_000 == 0 {
            // Between the 25 and 28 MHz clocks: the beam jumps.
            let clock = ((read / 5_000) % 2) as u8;
            soft.write_port8(
                Port::MISC_OUTPUT_WRITE,
                misc & !crate::regs::misc::CLOCK_SELECT_MASK
                    | clock << crate::regs::misc::CLOCK_SELECT_SHIFT,
            );
        }
        soft.advance_ns((random(4) * random(4_096)) as u64);
        let bits = soft.read_port8(Port::INPUT_STATUS_1);
        let beam = soft.timing().status_at(soft.now_ns());
        assert_eq!(bits, beam, "read {read} at {} ns", soft.now_ns());
    }
}

#[test]
fn counts_charge_one_operation_per_out_and_one_per_byte() {
    let mut soft = power_on();
    let start = soft.now_ns();
    soft.write_port16(Port::SEQUENCER_INDEX, 0x0F02);
    soft.write_port8(Port::SEQUENCER_INDEX, 2);
    soft.read_port8(Port::INPUT_STATUS_1);
    soft.fill_vram(0xFFF0, 100, 1); // 16 bytes fit before the window ends
    soft.write_vram8(5, 1);
    soft.read_vram8(5);
    let counts = soft.counts();
    assert_eq!(
        (
            counts.port_writes,
            counts.port_reads,
            counts.vram_writes,
            counts.vram_reads
        ),
        (2, 1, 17, 1)
    );
    assert_eq!(
        soft.now_ns() - start,
        3 * PORT_ACCESS_NS + 18 * VRAM_ACCESS_NS
    );
    soft.reset_counts();
    assert_eq!(soft.counts(), Default::default());
}

#[test]
fn a_graphics_mode_other_than_256_colours_scans_out_nothing() {
    let mut soft = power_on();
    // Graphics rather than text, but 16-colour planar shifting: not modelled.
    crate::VgaBus::write_port16(&mut *soft, Port::GRAPHICS_INDEX, 0x0506);
    crate::VgaBus::write_port16(&mut *soft, Port::GRAPHICS_INDEX, 0x0005);
    let mut pixels = std::vec![0; 720 * 400];
    assert_eq!(soft.picture_size(), (0, 0));
    assert_eq!(soft.scanout_indices(&mut pixels), (0, 0));
}
