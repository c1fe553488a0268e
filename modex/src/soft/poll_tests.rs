//! The software VGA's waits on Input Status 1 (`SoftVga::poll_port8`), which
//! take a stretch of reads in one step, against the reads one by one
//! (`poll_by_reads`): the same answer, and a model in the same state after.

use super::*;
use crate::regs::{misc, status};
use crate::{ModeX, STATUS_WAIT_MICROS};
extern crate std;
use std::boxed::Box;
use std::vec::Vec;

/// xorshift64: the same cases on every run.
struct Cases(u64);

impl Cases {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, bound: u64) -> u64 {
        self.next() % bound
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
}

fn write_crtc(vga: &mut SoftVga, register: Crtc, value: u8) {
    vga.write_port8(Port::CRTC_INDEX, register.index());
    vga.write_port8(Port::CRTC_DATA, value);
}

/// A software VGA in one of the timings a wait may meet: text mode at
/// power-on, Mode X, or Mode X with its horizontal and vertical counts, its
/// retrace lines and its dot clock made up (a retrace past the frame's end,
/// one at line 0, frames of a few lines), at a time somewhere in a frame,
/// its retrace bit following the beam or stuck.
fn a_vga(cases: &mut Cases) -> Box<SoftVga> {
    let mut vga = Box::new(SoftVga::new());
    if cases.below(4) != 0 {
        ModeX::new(&mut *vga).set_mode();
    }
    if cases.below(2) == 0 {
        // CRTC 0-7 unprotected (Vertical Retrace End bit 7 clear).
        write_crtc(&mut vga, Crtc::VerticalRetraceEnd, cases.byte() & 0x7F);
        for register in [
            Crtc::HorizontalTotal,
            Crtc::HorizontalDisplayEnd,
            Crtc::VerticalTotal,
            Crtc::Overflow,
            Crtc::VerticalRetraceStart,
            Crtc::VerticalDisplayEnd,
        ] {
            if cases.below(2) == 0 {
                write_crtc(&mut vga, register, cases.byte());
            }
        }
        // Colour addressing kept, any dot clock.
        let clock = cases.byte() & misc::CLOCK_SELECT_MASK;
        vga.write_port8(
            Port::MISC_OUTPUT_WRITE,
            0xE3 & !misc::CLOCK_SELECT_MASK | clock,
        );
    }
    vga.advance_ns(cases.below(3 * 16_700_000));
    vga.set_retrace_stuck(match cases.below(8) {
        0 => Some(true),
        1 => Some(false),
        _ => None,
    });
    vga
}

/// What a wait may have changed that anything can see: the clock, the
/// counts, the frames, the start address they latched, and the next
/// retrace.
fn seen(vga: &SoftVga) -> (u64, BusCounts, u64, u16, u64) {
    (
        vga.now_ns,
        vga.counts,
        vga.frame_count,
        vga.displayed_start,
        vga.next_retrace_ns,
    )
}

/// The reads after a wait: `reads` of Input Status 1, a microsecond apart
/// with now and then a longer pause, as a driver would make them.
fn later_reads(vga: &mut SoftVga, cases: &mut Cases, reads: usize) -> Vec<u8> {
    (0..reads)
        .map(|_| {
            if cases.below(16) == 0 {
                vga.advance_ns(cases.below(40_000_000));
            }
            vga.read_port8(Port::INPUT_STATUS_1)
        })
        .collect()
}

#[test]
fn a_wait_taken_in_steps_ends_where_the_reads_one_by_one_end() {
    let mut cases = Cases(0x9E37_79B9_7F4A_7C15);
    let mut answers = [0u32; 2];
    for case in 0..400 {
        let mut one_by_one = a_vga(&mut cases);
        let mut in_steps = one_by_one.clone();
        let (mask, value) = match cases.below(6) {
            // The flip's two waits, and their opposites.
            0 => (status::VERTICAL_RETRACE | status::DISPLAY_DISABLED, 0),
            1 => (status::VERTICAL_RETRACE, status::VERTICAL_RETRACE),
            2 => (status::VERTICAL_RETRACE, 0),
            3 => (status::DISPLAY_DISABLED, status::DISPLAY_DISABLED),
            4 => (status::VERTICAL_RETRACE, status::VERTICAL_RETRACE | 0x40),
            _ => (cases.byte(), cases.byte()),
        };
        let limit = match cases.below(8) {
            0 => cases.below(4),
            1 => cases.below(100),
            _ => 1 + cases.below(40_000),
        };
        // Now and then the monochrome port, which Input Status 1 is not
        // under colour addressing: read one by one there too.
        let port = if cases.below(16) == 0 {
            Port::INPUT_STATUS_1_MONO
        } else {
            Port::INPUT_STATUS_1
        };
        let expected = poll_by_reads(&mut *one_by_one, port, mask, value, limit);
        let got = in_steps.poll_port8(port, mask, value, limit);
        let context = (case, mask, value, limit, one_by_one.timing);
        assert_eq!(got, expected, "{context:?}");
        assert_eq!(seen(&in_steps), seen(&one_by_one), "{context:?}");
        let mut after = Cases(cases.next() | 1);
        let mut after_too = Cases(after.0);
        assert_eq!(
            later_reads(&mut in_steps, &mut after, 64),
            later_reads(&mut one_by_one, &mut after_too, 64),
            "{context:?}"
        );
        answers[usize::from(got)] += 1;
    }
    // Both answers came up often: waits that found their bits and waits
    // that ran out.
    assert!(answers.iter().all(|&n| n > 40), "{answers:?}");
}

#[test]
fn the_flips_waits_end_as_the_reads_one_by_one_do_at_the_full_limit() {
    let mut cases = Cases(0x2545_F491_4F6C_DD1D);
    for stuck in [None, Some(true), Some(false)] {
        let mut one_by_one = Box::new(SoftVga::new());
        ModeX::new(&mut *one_by_one).set_mode();
        one_by_one.advance_ns(cases.below(16_700_000));
        one_by_one.set_retrace_stuck(stuck);
        let mut in_steps = one_by_one.clone();
        for (mask, value) in [
            (status::VERTICAL_RETRACE | status::DISPLAY_DISABLED, 0),
            (status::VERTICAL_RETRACE, status::VERTICAL_RETRACE),
        ] {
            let expected = poll_by_reads(
                &mut *one_by_one,
                Port::INPUT_STATUS_1,
                mask,
                value,
                STATUS_WAIT_MICROS,
            );
            let got = in_steps.poll_port8(Port::INPUT_STATUS_1, mask, value, STATUS_WAIT_MICROS);
            assert_eq!(got, expected, "{stuck:?} {mask:#x}");
            assert_eq!(seen(&in_steps), seen(&one_by_one), "{stuck:?} {mask:#x}");
        }
    }
}

#[test]
fn a_read_that_falls_exactly_where_the_bits_change_sees_the_change() {
    // The change a few reads after the first: the last read skipped must
    // be the one before it, not the one at it.
    for reads_before in 1..6 {
        for (mask, value) in [
            (status::VERTICAL_RETRACE, status::VERTICAL_RETRACE),
            (status::VERTICAL_RETRACE | status::DISPLAY_DISABLED, 0),
            (status::DISPLAY_DISABLED, status::DISPLAY_DISABLED),
        ] {
            let mut vga = Box::new(SoftVga::new());
            ModeX::new(&mut *vga).set_mode();
            vga.advance_ns(1_234_567);
            // Where the bits under the mask next change, at least six reads
            // on: the retrace's start, or the beam's next edge.
            let (start_bits, change) = loop {
                let bits = vga.read_port8(Port::INPUT_STATUS_1);
                let change = if mask == status::VERTICAL_RETRACE {
                    vga.timing.retrace_bit_until(vga.now_ns)
                } else {
                    vga.status_until_ns
                };
                if change > vga.now_ns + 6 * PORT_ACCESS_NS {
                    break (bits, change);
                }
                vga.advance_ns(change - vga.now_ns);
            };
            let mut one_by_one = vga.clone();
            // The wait's first read `reads_before` µs before the change.
            let first_read = change - reads_before * PORT_ACCESS_NS;
            one_by_one.advance_ns(first_read - PORT_ACCESS_NS - one_by_one.now_ns);
            let mut in_steps = one_by_one.clone();
            let expected =
                poll_by_reads(&mut *one_by_one, Port::INPUT_STATUS_1, mask, value, 40_000);
            let got = in_steps.poll_port8(Port::INPUT_STATUS_1, mask, value, 40_000);
            let context = (reads_before, mask, start_bits);
            assert_eq!(got, expected, "{context:?}");
            assert_eq!(seen(&in_steps), seen(&one_by_one), "{context:?}");
        }
    }
}
