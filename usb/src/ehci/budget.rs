//! EHCI's periodic schedule budget, in the shape of Linux's `ehci-sched.c`
//! kept small: where an interrupt pipe is polled (the frame phase and the
//! micro-frame), and whether the bus has the time for it.
//!
//! - Every pipe is polled once in each frame `f` with `f % period ==
//!   phase`, in one micro-frame; a new pipe goes to the least-loaded phase
//!   and micro-frame where everything still fits.
//! - High-speed periodic time is at most 80% of each micro-frame (USB 2.0
//!   5.7.4): 100 us.
//! - A full- or low-speed pipe behind a transaction translator is a split
//!   transaction (EHCI 1.0 4.12.2, USB 2.0 11.18): the start-split in
//!   micro-frame N, the full-speed transaction in N+1 (or, behind others,
//!   up to N+3), complete-splits in N+2, N+3 and N+4. N stops at 3 so that
//!   the complete-splits stay inside the frame (no FSTN).
//! - Each translator's full- and low-speed time, from the bus-time formulas
//!   of USB 2.0 5.11.3 (Linux's `usb_calc_bus_time`), is kept per frame,
//!   per translator: one per hub, or one per port of a multi-TT hub. Work
//!   started in N must end by the end of N+3; over a frame that keeps it
//!   under 750 us, inside the 90% (900 us) USB 2.0 5.7.4 allows.
//!
//! The budget is not a table kept beside the pipes: it is summed from the
//! open pipes' bookings whenever a pipe opens, so a pipe closed gives its
//! time back by being closed.

use crate::host::Speed;

/// Frames the budget looks at: periods are powers of two up to this (a
/// slower endpoint is polled this often, which a host may do, USB 2.0 5.7.4).
pub const BUDGET_FRAMES: usize = 32;
/// High-speed periodic time a micro-frame may carry: 80% of 125 us.
pub const MICRO_FRAME_BUDGET_MICROS: u32 = 100;
/// Full- and low-speed periodic time a frame may carry: 90% of 1 ms.
pub const TT_FRAME_BUDGET_MICROS: u32 = 900;
/// Full-speed time a translator runs in one micro-frame.
pub const TT_MICRO_FRAME_MICROS: u32 = 125;
/// The last micro-frame a start-split goes in: its complete-splits in
/// N+2..N+4 then end in micro-frame 7.
pub const LAST_START_SPLIT: u8 = 3;
// What the start-splits may carry stays inside what a frame may.
const _: () =
    assert!(TT_MICRO_FRAME_MICROS * (LAST_START_SPLIT as u32 + 3) <= TT_FRAME_BUDGET_MICROS);
/// A translator's think time between transactions, the longest a hub may
/// declare (32 full-speed bit times, USB 2.0 11.23.2.1): the hub's own
/// figure is not known here, so every hub is taken at its slowest.
const TT_THINK_NANOS: u32 = 2_666;
/// USB 2.0 5.11.3's host delay for full and low speed, and a low-speed
/// transaction's hub set-up (Linux's BW_HOST_DELAY and BW_HUB_LS_SETUP).
const HOST_DELAY_NANOS: u32 = 1_000;
const HUB_LOW_SPEED_SETUP_NANOS: u32 = 333;
/// The high-speed host delay (Linux's USB2_HOST_DELAY).
const HIGH_SPEED_HOST_DELAY_NANOS: u32 = 5;

/// Bits on the wire for `bytes` of data, worst-case bit stuffing (7/6).
const fn bit_time(bytes: u32) -> u32 {
    7 * 8 * bytes / 6
}

/// The time an interrupt IN transaction of `bytes` takes on the bus at
/// `speed`, in nanoseconds (USB 2.0 5.11.3).
pub const fn interrupt_in_nanos(speed: Speed, bytes: u16) -> u32 {
    let bits = 31 + 10 * bit_time(bytes as u32);
    match speed {
        Speed::Low => {
            64_060 + 2 * HUB_LOW_SPEED_SETUP_NANOS + HOST_DELAY_NANOS + 67_667 * bits / 1_000
        }
        Speed::Full => 9_107 + HOST_DELAY_NANOS + 8_354 * bits / 1_000,
        // EHCI never sees SuperSpeed (its ports are USB 2); priced as high
        // speed so the function stays total.
        Speed::High | Speed::Super => {
            (55 * 8 * 2_083 + 2_083 * (3 + bit_time(bytes as u32))) / 1_000
                + HIGH_SPEED_HOST_DELAY_NANOS
        }
    }
}

/// `nanos` in whole microseconds, rounded up.
pub const fn micros(nanos: u32) -> u32 {
    nanos.div_ceil(1_000)
}

/// The high-speed time of a pipe's transactions, in microseconds: a
/// high-speed poll, or a split's start (the token) and each complete
/// (token and the data), as Linux's `qh_make` counts them.
pub const fn high_speed_micros(speed: Speed, max_packet: u16) -> (u32, u32) {
    let data = micros(interrupt_in_nanos(Speed::High, max_packet));
    match speed {
        Speed::High => (data, 0),
        _ => (
            micros(interrupt_in_nanos(Speed::High, 1)),
            data + micros(interrupt_in_nanos(Speed::High, 0)),
        ),
    }
}

/// A split pipe's full- or low-speed time on its translator, in
/// microseconds, think time included.
pub const fn translator_micros(speed: Speed, max_packet: u16) -> u32 {
    micros(interrupt_in_nanos(speed, max_packet) + TT_THINK_NANOS)
}

/// The C-mask of a split whose start-split goes in micro-frame `start`.
pub const fn complete_mask(start: u8) -> u8 {
    0b111 << (start + 2)
}

/// A transaction translator: a hub's one, or one port's of a multi-TT hub.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Translator {
    /// The high-speed hub's address.
    pub hub_address: u8,
    /// The port whose translator it is (0: the hub has one for all).
    pub port: u8,
}

/// How a refused pipe's log line names its translator.
pub struct Through(pub Option<Translator>);

impl core::fmt::Display for Through {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self.0 {
            Some(t) if t.port != 0 => {
                write!(
                    f,
                    ", through hub {}'s port {} translator",
                    t.hub_address, t.port
                )
            }
            Some(t) => write!(f, ", through hub {}'s translator", t.hub_address),
            None => Ok(()),
        }
    }
}

/// An interrupt pipe's place in the periodic schedule and what it costs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Booking {
    /// Frames between polls: a power of two up to [`BUDGET_FRAMES`].
    pub period: u16,
    /// The frame (modulo the period) it is polled in.
    pub phase: u16,
    /// The micro-frame of its transaction or start-split (QH S-mask).
    pub s_mask: u8,
    /// Its complete-splits' micro-frames (QH C-mask; 0 at high speed).
    pub c_mask: u8,
    /// High-speed time in its S-mask micro-frame.
    pub start_micros: u32,
    /// High-speed time in each of its C-mask micro-frames.
    pub complete_micros: u32,
    /// The translator it is split through, if any.
    pub translator: Option<Translator>,
    /// Full- or low-speed time on the translator in each frame it is polled.
    pub translator_micros: u32,
}

impl Booking {
    /// What a pipe of `max_packet` bytes at `speed` every `period` frames
    /// costs, not placed yet.
    pub const fn new(
        speed: Speed,
        max_packet: u16,
        period: u16,
        translator: Option<Translator>,
    ) -> Booking {
        let (start_micros, complete_micros) = high_speed_micros(speed, max_packet);
        Booking {
            period,
            phase: 0,
            s_mask: 0,
            c_mask: 0,
            start_micros,
            complete_micros,
            translator,
            translator_micros: match translator {
                Some(_) => translator_micros(speed, max_packet),
                None => 0,
            },
        }
    }

    /// Whether it is polled in frame `frame`.
    pub fn due(&self, frame: usize) -> bool {
        frame % usize::from(self.period) == usize::from(self.phase)
    }
}

/// What the booked pipes take of each micro-frame of the budget's frames.
struct Load {
    /// High-speed time, by frame and micro-frame.
    high_speed: [[u32; 8]; BUDGET_FRAMES],
    /// Transactions and start-splits, by frame and micro-frame.
    starts: [[u32; 8]; BUDGET_FRAMES],
    /// One translator's full- and low-speed time, by frame and the
    /// micro-frame its start-splits go in.
    translator: [[u32; 8]; BUDGET_FRAMES],
}

impl Load {
    fn of(booked: impl Iterator<Item = Booking>, translator: Option<Translator>) -> Load {
        let mut load = Load {
            high_speed: [[0; 8]; BUDGET_FRAMES],
            starts: [[0; 8]; BUDGET_FRAMES],
            translator: [[0; 8]; BUDGET_FRAMES],
        };
        for pipe in booked {
            for frame in (0..BUDGET_FRAMES).filter(|&f| pipe.due(f)) {
                for micro_frame in 0..8 {
                    let bit = 1u8 << micro_frame;
                    if pipe.s_mask & bit != 0 {
                        load.high_speed[frame][micro_frame] += pipe.start_micros;
                        load.starts[frame][micro_frame] += 1;
                        if translator.is_some() && pipe.translator == translator {
                            load.translator[frame][micro_frame] += pipe.translator_micros;
                        }
                    }
                    if pipe.c_mask & bit != 0 {
                        load.high_speed[frame][micro_frame] += pipe.complete_micros;
                    }
                }
            }
        }
        load
    }
}

/// Whether a translator's work, by the micro-frame its start-splits go
/// in, ends in time: work started in micro-frames `first..=last` runs from
/// `first + 1` and must end by the end of `last + 3`.
pub fn translator_in_time(started: &[u32; 8]) -> bool {
    let last_start = usize::from(LAST_START_SPLIT);
    if started[last_start + 1..].iter().any(|&w| w != 0) {
        return false;
    }
    (0..=last_start).all(|first| {
        let mut work = 0;
        (first..=last_start).all(|last| {
            work += started[last];
            work <= TT_MICRO_FRAME_MICROS * (last - first + 3) as u32
        })
    })
}

/// Places `pipe` beside the `booked` ones: at the phase and micro-frame
/// whose translator time, then start count, then frame time is least,
/// where every budget holds. None if nowhere does.
pub fn place(booked: impl Iterator<Item = Booking>, pipe: Booking) -> Option<Booking> {
    let load = Load::of(booked, pipe.translator);
    let last_start = if pipe.translator.is_some() {
        LAST_START_SPLIT
    } else {
        7
    };
    let mut best: Option<((u32, u32, u32), Booking)> = None;
    for phase in 0..pipe.period {
        for start in 0..=last_start {
            let candidate = Booking {
                phase,
                s_mask: 1 << start,
                c_mask: if pipe.translator.is_some() {
                    complete_mask(start)
                } else {
                    0
                },
                ..pipe
            };
            let mut cost = (0, 0, 0);
            let mut fits = true;
            for frame in (0..BUDGET_FRAMES).filter(|&f| candidate.due(f)) {
                let mut high_speed = load.high_speed[frame];
                let mut translator = load.translator[frame];
                let at = usize::from(start);
                cost.0 = cost.0.max(translator[at]);
                cost.1 = cost.1.max(load.starts[frame][at]);
                cost.2 = cost.2.max(high_speed.iter().sum());
                high_speed[at] += candidate.start_micros;
                translator[at] += candidate.translator_micros;
                for (micro_frame, time) in high_speed.iter_mut().enumerate() {
                    if candidate.c_mask & 1 << micro_frame != 0 {
                        *time += candidate.complete_micros;
                    }
                }
                fits &= high_speed.iter().all(|&t| t <= MICRO_FRAME_BUDGET_MICROS)
                    && translator_in_time(&translator);
            }
            if fits && best.is_none_or(|(least, _)| cost < least) {
                best = Some((cost, candidate));
            }
        }
    }
    best.map(|(_, placed)| placed)
}

#[cfg(test)]
mod tests;
