//! Page flips: the picture follows show_page, the latch happens at vertical
//! retrace, drawing into the back page never shows, and the waits are bounded.

use super::{assert_picture, mode_x, power_on, scanout, Picture};
use crate::regs::status;
use crate::regs::{Crtc, Port};
use crate::{FlipReport, ModeX, Page, VgaBus, PAGE_BYTES, STATUS_WAIT_MICROS};

const NANOS_PER_MICRO: u64 = 1_000;

#[test]
fn show_page_shows_that_page() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    for (page, color) in [(Page::Zero, 10), (Page::One, 11), (Page::Two, 12)] {
        vga.clear_page(page, color);
    }
    for page in [Page::One, Page::Two, Page::Zero, Page::Two] {
        assert_eq!(
            vga.show_page(page),
            FlipReport::default(),
            "a wait timed out"
        );
        assert_eq!(vga.bus().displayed_start(), page.base());
        assert_picture(
            &Picture::filled(10 + page.index()),
            &scanout(vga.bus()),
            "the page shown",
        );
    }
}

#[test]
fn show_page_returns_at_the_start_of_vertical_retrace() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    let frames = vga.bus().frame_count();
    vga.show_page(Page::One);
    assert_eq!(vga.bus().frame_count(), frames + 1, "one retrace per flip");
    // Straight after the latch: still in vertical retrace.
    assert_ne!(
        vga.bus_mut().read_port8(Port::INPUT_STATUS_1) & status::VERTICAL_RETRACE,
        0
    );

    // Back-to-back flips are paced by the frame rate.
    let start = vga.bus().now_ns();
    for flip in 0..10u8 {
        vga.show_page(Page::ALL[usize::from(flip % 2)]);
    }
    assert_eq!(vga.bus().frame_count(), frames + 11);
    let frame_ns = vga.bus().timing().frame_ns();
    let elapsed = vga.bus().now_ns() - start;
    assert!(
        elapsed.abs_diff(10 * frame_ns) < frame_ns / 50,
        "10 flips took {elapsed} ns, frames are {frame_ns} ns"
    );
}

#[test]
fn the_start_address_takes_effect_at_the_next_vertical_retrace() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.show_page(Page::Zero);
    // Leave retrace, then write a new start address behind the driver's back.
    vga.bus_mut().advance_ns(1_000_000);
    let [high, low] = PAGE_BYTES.to_be_bytes();
    vga.bus_mut().write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::StartAddressHigh.index(), high]),
    );
    vga.bus_mut().write_port16(
        Port::CRTC_INDEX,
        u16::from_le_bytes([Crtc::StartAddressLow.index(), low]),
    );
    assert_eq!(vga.bus().displayed_start(), 0, "latched before the retrace");
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(frame_ns);
    assert_eq!(vga.bus().displayed_start(), PAGE_BYTES);
}

#[test]
fn drawing_into_the_back_page_never_changes_the_picture() {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::One, 5);
    vga.show_page(Page::One);
    let shown = scanout(vga.bus());
    for step in 0..40 {
        vga.fill_rect(
            Page::Zero,
            step * 7 - 20,
            step * 5,
            step * 7 + 30,
            step * 5 + 20,
            step as u8,
        );
        vga.fill_span(Page::Two, step, -5, 400, 200);
        vga.put_pixel(Page::Zero, step, step, 1);
        assert_picture(
            &shown,
            &scanout(vga.bus()),
            "page 1 while drawing page 0 and 2",
        );
    }
    vga.clear_page(Page::Zero, 99);
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(10 * frame_ns);
    assert_picture(&shown, &scanout(vga.bus()), "page 1 after frames went by");
}

/// A flip with the retrace bit stuck returns within its two bounded waits.
fn flip_with_retrace_stuck(stuck: bool) -> (FlipReport, u64) {
    let mut soft = power_on();
    let mut vga = mode_x(&mut soft);
    vga.clear_page(Page::One, 4);
    vga.bus_mut().set_retrace_stuck(Some(stuck));
    let start = vga.bus().now_ns();
    let report = vga.show_page(Page::One);
    let elapsed = vga.bus().now_ns() - start;
    // The CRT keeps time, so the flip still shows once a retrace comes.
    let frame_ns = vga.bus().timing().frame_ns();
    vga.bus_mut().advance_ns(frame_ns);
    assert_picture(&Picture::filled(4), &scanout(vga.bus()), "page 1");
    (report, elapsed)
}

/// The longest a wait may overrun its bound: the one read that crossed it
/// (a microsecond on the software VGA), with room for a few more.
const OVERRUN_NS: u64 = 10 * NANOS_PER_MICRO;

#[test]
fn show_page_gives_up_when_the_retrace_bit_is_stuck_high() {
    let (report, elapsed) = flip_with_retrace_stuck(true);
    assert!(
        report.display_wait_timed_out && !report.retrace_wait_timed_out,
        "{report:?}"
    );
    let bound = STATUS_WAIT_MICROS * NANOS_PER_MICRO;
    assert!(
        (bound..=bound + OVERRUN_NS).contains(&elapsed),
        "took {elapsed} ns"
    );
}

#[test]
fn show_page_gives_up_when_the_retrace_bit_is_stuck_low() {
    let (report, elapsed) = flip_with_retrace_stuck(false);
    assert!(
        !report.display_wait_timed_out && report.retrace_wait_timed_out,
        "{report:?}"
    );
    assert!(report.timed_out());
    let bound = STATUS_WAIT_MICROS * NANOS_PER_MICRO;
    assert!(
        (bound..=bound + OVERRUN_NS).contains(&elapsed),
        "took {elapsed} ns"
    );
}

/// A VGA whose Input Status 1 reads cost `nanos_per_read` by its clock (tens
/// of nanoseconds, as under emulation, where one read takes far less than
/// the microsecond it takes on an ISA card), showing active display until
/// vertical retrace begins at read `retrace_at_read` (never, if `None`).
/// Everything else it ignores.
struct TimedStatusBus {
    reads: u64,
    nanos_per_read: u64,
    retrace_at_read: Option<u64>,
    has_clock: bool,
}

impl TimedStatusBus {
    fn new(nanos_per_read: u64, retrace_at_read: Option<u64>) -> Self {
        TimedStatusBus {
            reads: 0,
            nanos_per_read,
            retrace_at_read,
            has_clock: true,
        }
    }

    /// Flips once; the report, the reads made and the time they took by the
    /// bus's clock.
    fn flip(self) -> (FlipReport, u64, u64) {
        let mut vga = ModeX::new(self);
        let report = vga.show_page(Page::One);
        let bus = vga.into_bus();
        (report, bus.reads, bus.reads * bus.nanos_per_read)
    }
}

impl VgaBus for TimedStatusBus {
    fn write_port8(&mut self, _port: Port, _value: u8) {}
    fn write_port16(&mut self, _port: Port, _value: u16) {}
    fn read_port8(&mut self, port: Port) -> u8 {
        if port != Port::INPUT_STATUS_1 {
            return 0xFF;
        }
        self.reads += 1;
        match self.retrace_at_read {
            Some(at) if self.reads >= at => status::VERTICAL_RETRACE,
            _ => 0,
        }
    }
    fn write_vram8(&mut self, _offset: u16, _value: u8) {}
    fn read_vram8(&mut self, _offset: u16) -> u8 {
        0xFF
    }
    fn now_micros(&mut self) -> Option<u64> {
        self.has_clock
            .then(|| self.reads * self.nanos_per_read / NANOS_PER_MICRO)
    }
}

#[test]
fn a_retrace_millions_of_fast_reads_away_is_still_waited_for() {
    // 50 ns reads, and the retrace 15 refreshes away (250 ms): QEMU on a busy
    // host, its vCPU off the CPU across every retrace pulse in between. Five
    // million reads, more than any count of reads that is a second on ISA.
    let (report, reads, _) = TimedStatusBus::new(50, Some(5_000_000)).flip();
    assert_eq!(report, FlipReport::default(), "a wait timed out");
    assert_eq!(reads, 5_000_000, "the flip returned before the retrace");
}

#[test]
fn a_missing_retrace_is_given_up_on_by_the_clock_not_by_reads() {
    for nanos_per_read in [50, 10_000_000] {
        let (report, reads, elapsed) = TimedStatusBus::new(nanos_per_read, None).flip();
        assert!(
            !report.display_wait_timed_out && report.retrace_wait_timed_out,
            "{report:?}"
        );
        let bound = STATUS_WAIT_MICROS * NANOS_PER_MICRO;
        assert!(
            (bound..=bound + 2 * nanos_per_read).contains(&elapsed),
            "{reads} reads of {nanos_per_read} ns waited {elapsed} ns"
        );
    }
}

#[test]
fn a_bus_without_a_clock_counts_a_microsecond_a_read() {
    let bus = TimedStatusBus {
        has_clock: false,
        ..TimedStatusBus::new(50, None)
    };
    let (report, reads, _) = bus.flip();
    assert!(report.retrace_wait_timed_out, "{report:?}");
    // One read found active display; the retrace wait read for a "second".
    assert_eq!(reads, 1 + STATUS_WAIT_MICROS);
}
