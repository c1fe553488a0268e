//! The simulated clock's view of the CRT: frame timing derived from the
//! registers, the beam position at a given time, and the Input Status 1 bits.
//!
//! The beam starts at the top left at time 0 and runs continuously; a change
//! of timing registers re-times the whole history (as QEMU's precise retrace
//! does), which may move the beam.

use crate::regs::{crtc, misc, seq, status, Crtc, Sequencer};

use super::registers::Registers;

/// Simulated cost of one port access (IN or OUT, 8 or 16 bits): ISA-speed I/O.
pub const PORT_ACCESS_NS: u64 = 1000;
/// Simulated cost of one byte of video memory access.
pub const VRAM_ACCESS_NS: u64 = 100;

const NANOS_PER_SECOND: u64 = 1_000_000_000;
/// The dot clocks Misc Output selects; 2 and 3 are card-specific, and like
/// QEMU the model gives them the 25 MHz clock.
const DOT_CLOCK_HZ: [u64; 4] = [25_175_000, 28_322_000, 25_175_000, 25_175_000];
/// Horizontal Total counts characters - 5.
const HORIZONTAL_TOTAL_BIAS: u64 = 5;
/// Vertical Total counts lines - 2.
const VERTICAL_TOTAL_BIAS: u64 = 2;
/// Vertical retrace ends on the line whose low 4 bits match Vertical Retrace
/// End, so it lasts 1 to 16 lines.
const RETRACE_END_COMPARE_LINES: u64 = 16;

/// Frame timing in dots, characters and lines.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CrtTiming {
    /// Dot clock, Hz.
    pub dot_clock_hz: u64,
    /// Dots per character clock (8 or 9).
    pub dots_per_character: u64,
    /// Characters per scan line, blanking included.
    pub characters_per_line: u64,
    /// Characters displayed per line.
    pub display_characters: u64,
    /// Scan lines per frame, blanking included.
    pub lines_per_frame: u64,
    /// Scan lines displayed.
    pub display_lines: u64,
    /// First line of vertical retrace.
    pub retrace_start_line: u64,
    /// Lines of vertical retrace.
    pub retrace_lines: u64,
}

impl CrtTiming {
    pub(super) const fn from_registers(registers: &Registers) -> Self {
        let clock_select =
            (registers.misc_output & misc::CLOCK_SELECT_MASK) >> misc::CLOCK_SELECT_SHIFT;
        let eight_dot = registers.sequencer(Sequencer::ClockingMode) & seq::CLOCKING_8_DOT != 0;
        let retrace_start_line = registers.vertical_retrace_start() as u64;
        let retrace_end_bits =
            (registers.crtc(Crtc::VerticalRetraceEnd) & crtc::VERTICAL_RETRACE_END_MASK) as u64;
        let retrace_lines =
            match retrace_end_bits.wrapping_sub(retrace_start_line) % RETRACE_END_COMPARE_LINES {
                0 => RETRACE_END_COMPARE_LINES,
                lines => lines,
            };
        Self {
            dot_clock_hz: DOT_CLOCK_HZ[clock_select as usize],
            dots_per_character: if eight_dot { 8 } else { 9 },
            characters_per_line: registers.crtc(Crtc::HorizontalTotal) as u64
                + HORIZONTAL_TOTAL_BIAS,
            display_characters: registers.crtc(Crtc::HorizontalDisplayEnd) as u64 + 1,
            lines_per_frame: registers.vertical_total() as u64 + VERTICAL_TOTAL_BIAS,
            display_lines: registers.vertical_display_end() as u64 + 1,
            retrace_start_line,
            retrace_lines,
        }
    }

    fn dots_per_line(&self) -> u64 {
        self.characters_per_line * self.dots_per_character
    }

    fn dots_per_frame(&self) -> u64 {
        self.dots_per_line() * self.lines_per_frame
    }

    /// Length of a frame, rounded down to a nanosecond.
    /// (At most 260 characters of 9 dots by 1,025 lines: 2.4 million dots,
    /// times 10^9 stays below 2^52.)
    pub fn frame_ns(&self) -> u64 {
        self.dots_per_frame() * NANOS_PER_SECOND / self.dot_clock_hz
    }

    /// Dots since time 0, exactly `ns * dot_clock_hz / 10^9` rounded down,
    /// in u64 arithmetic: whole seconds and the rest are scaled apart, so no
    /// product exceeds 2^60. (u128 division is a library call in wasm32 and
    /// on 32-bit targets, and this runs on every port read of a wait loop.)
    fn dots_at(&self, ns: u64) -> u64 {
        let (seconds, rest) = (ns / NANOS_PER_SECOND, ns % NANOS_PER_SECOND);
        seconds * self.dot_clock_hz + rest * self.dot_clock_hz / NANOS_PER_SECOND
    }

    /// (line, character) of the beam at `ns`.
    fn beam_at(&self, ns: u64) -> (u64, u64) {
        let dot_in_frame = self.dots_at(ns) % self.dots_per_frame();
        (
            dot_in_frame / self.dots_per_line(),
            dot_in_frame % self.dots_per_line() / self.dots_per_character,
        )
    }

    /// Input Status 1 bits 0 (display disabled) and 3 (vertical retrace) at `ns`.
    pub(crate) fn status_at(&self, ns: u64) -> u8 {
        let (line, character) = self.beam_at(ns);
        let retrace =
            (self.retrace_start_line..self.retrace_start_line + self.retrace_lines).contains(&line);
        let blanking = line >= self.display_lines || character >= self.display_characters;
        (if retrace { status::VERTICAL_RETRACE } else { 0 })
            | (if blanking {
                status::DISPLAY_DISABLED
            } else {
                0
            })
    }

    /// Vertical retraces started in (0, `ns`]. A retrace start line beyond
    /// the frame never comes.
    /// The earliest time at which `retraces_started_by` passes its value at
    /// `ns`: when the next vertical retrace starts (`u64::MAX` when these
    /// registers never start one). `dots_at` is the product rounded down, so
    /// the first time at a dot count is the quotient rounded up.
    pub(super) fn next_retrace_ns(&self, ns: u64) -> u64 {
        if self.retrace_start_line >= self.lines_per_frame {
            return u64::MAX;
        }
        let first = self.retrace_start_line * self.dots_per_line();
        self.first_ns_at_dot(first + self.retraces_started_by(ns) * self.dots_per_frame())
    }

    /// The first nanosecond at which `dots_at` reaches `dot`: the quotient
    /// `dot * 10^9 / dot_clock_hz` rounded up, with whole seconds and the
    /// rest scaled apart as in `dots_at`, so nothing overflows u64 and no
    /// u128 library call runs.
    fn first_ns_at_dot(&self, dot: u64) -> u64 {
        let (seconds, rest) = (dot / self.dot_clock_hz, dot % self.dot_clock_hz);
        seconds
            .saturating_mul(NANOS_PER_SECOND)
            .saturating_add((rest * NANOS_PER_SECOND).div_ceil(self.dot_clock_hz))
    }

    /// Input Status 1's bits at `ns` ([`CrtTiming::status_at`]) and a time
    /// before which they cannot change: the beam's next crossing of the
    /// display's right edge, or of its line's end. A wait on the status
    /// reads it every microsecond, about 32 times a line, so the software
    /// VGA keeps the bits until then rather than divide its way to the beam
    /// at every read, and a wait takes the reads before then in one step.
    pub(super) fn status_until(&self, ns: u64) -> (u8, u64) {
        let dots = self.dots_at(ns);
        let dots_per_line = self.dots_per_line();
        // A line's dots: a frame is whole lines, so this is the beam's
        // place in its line.
        let into_line = dots % dots_per_line;
        let display_end = (self.display_characters * self.dots_per_character).min(dots_per_line);
        let next_edge = if into_line < display_end {
            display_end
        } else {
            dots_per_line
        };
        (
            self.status_at(ns),
            self.first_ns_at_dot(dots - into_line + next_edge),
        )
    }

    /// A time before which Input Status 1's vertical retrace bit cannot
    /// change from its value at `ns`: the start of the next line on which
    /// the retrace starts or ends, or of the next frame. A wait for the
    /// retrace, which looks at that bit alone, skips to it.
    pub(super) fn retrace_bit_until(&self, ns: u64) -> u64 {
        let dots = self.dots_at(ns);
        let (dots_per_line, dots_per_frame) = (self.dots_per_line(), self.dots_per_frame());
        let into_frame = dots % dots_per_frame;
        let line = into_frame / dots_per_line;
        let retrace_end_line = self.retrace_start_line + self.retrace_lines;
        let next_line = [self.retrace_start_line, retrace_end_line]
            .into_iter()
            .filter(|&edge| edge > line && edge < self.lines_per_frame)
            .min()
            .unwrap_or(self.lines_per_frame);
        self.first_ns_at_dot(dots - into_frame + next_line * dots_per_line)
    }

    pub(super) fn retraces_started_by(&self, ns: u64) -> u64 {
        if self.retrace_start_line >= self.lines_per_frame {
            return 0;
        }
        let first = self.retrace_start_line * self.dots_per_line();
        let dots = self.dots_at(ns);
        if dots < first {
            0
        } else {
            (dots - first) / self.dots_per_frame() + 1
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The u64 split gives what the exact u128 product gives, at every
    /// scale of time and for every dot clock.
    #[test]
    fn dots_at_is_the_exact_product_rounded_down() {
        for &hz in &DOT_CLOCK_HZ {
            let timing = CrtTiming {
                dot_clock_hz: hz,
                dots_per_character: 8,
                characters_per_line: 100,
                display_characters: 80,
                lines_per_frame: 525,
                display_lines: 480,
                retrace_start_line: 490,
                retrace_lines: 2,
            };
            let mut ns: u64 = 1;
            while ns < u64::MAX / 4 {
                for probe in [ns - 1, ns, ns + 999_999_999, ns.wrapping_mul(7) / 3] {
                    let exact = u128::from(probe) * u128::from(hz) / 1_000_000_000;
                    assert_eq!(
                        u128::from(timing.dots_at(probe)),
                        exact,
                        "{probe} ns at {hz} Hz"
                    );
                }
                ns = ns * 3 + 1;
            }
        }
    }

    /// The next retrace's time is the first at which one more retrace has
    /// started: a nanosecond earlier, none has. So the clock that skips to
    /// it (`SoftVga::advance_ns`) latches the start address at the same
    /// steps as one that asks the timing at every step.
    #[test]
    fn the_next_retrace_is_the_first_nanosecond_a_retrace_starts() {
        for (&hz, retrace_start_line) in DOT_CLOCK_HZ.iter().zip([490, 0, 524, 241]) {
            let timing = CrtTiming {
                dot_clock_hz: hz,
                dots_per_character: 9,
                characters_per_line: 100,
                display_characters: 80,
                lines_per_frame: 525,
                display_lines: 480,
                retrace_start_line,
                retrace_lines: 2,
            };
            let mut ns: u64 = 0;
            while ns < u64::MAX / 1_000_000 {
                for probe in [ns, ns + 1, ns.wrapping_mul(7) / 3] {
                    let next = timing.next_retrace_ns(probe);
                    let before = timing.retraces_started_by(probe);
                    assert!(next > probe, "{probe} ns at {hz} Hz");
                    assert_eq!(timing.retraces_started_by(next), before + 1, "{probe} ns");
                    assert_eq!(timing.retraces_started_by(next - 1), before, "{probe} ns");
                }
                ns = ns * 3 + 1;
            }
        }
        let never = CrtTiming {
            retrace_start_line: 600,
            ..CrtTiming::from_registers(&Registers::with_mode(
                &crate::mode::TEXT_80X25,
                &crate::palette::EGA_PALETTE,
            ))
        };
        assert_eq!(never.next_retrace_ns(12_345), u64::MAX);
    }

    /// The bits `status_until` gives hold from its time to the time it
    /// gives, and that time is a dot boundary's first nanosecond, at every
    /// dot clock and at display edges past the line's end.
    #[test]
    fn the_status_holds_until_the_time_given() {
        let mut random = crate::tests::xorshift(0x2545_f491_4f6c_dd1d);
        let mut next = move |below: u64| random(below as usize) as u64;
        for (&hz, display_characters) in DOT_CLOCK_HZ.iter().zip([80, 100, 120, 1]) {
            let timing = CrtTiming {
                dot_clock_hz: hz,
                dots_per_character: 8 + (hz % 2),
                characters_per_line: 100,
                display_characters,
                lines_per_frame: 525,
                display_lines: 480,
                retrace_start_line: 490,
                retrace_lines: 2,
            };
            let mut ns = next(1 << 40);
            for _ in 0..2_000 {
                let (bits, until) = timing.status_until(ns);
                assert!(until > ns, "{ns} ns at {hz} Hz");
                for probe in [ns, until - 1, ns + next(until - ns)] {
                    assert_eq!(
                        timing.status_at(probe),
                        bits,
                        "{probe} ns, from {ns} at {hz} Hz"
                    );
                }
                assert!(
                    timing.dots_at(until) > timing.dots_at(until - 1),
                    "{until} ns"
                );
                ns = until + next(3) * next(40_000);
            }
        }
    }
}
