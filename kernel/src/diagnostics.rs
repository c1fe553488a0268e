//! Screens for checking the VGA itself, chosen by the boot option: the Mode X
//! test pattern (QEMU's picture is compared with the software VGA's) and a
//! measurement of how many page flips a second vertical retrace allows, and
//! a check of the kernel's clock against the host's.

use crate::{input::ps2, input::usb as usb_input, serial_println, time};
use clock::pacing::Pacing;
use keyboard::scancode::{BREAK_BIT, EXTENDED_PREFIX};
use modex::{ModeX, Page, VgaBus};

/// Draws the pattern into pages 0 and 1, shows page 0, and flips to the other
/// page on every key press, saying on serial which page is shown.
pub fn test_pattern<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    demo::pattern::draw(vga, Page::Zero);
    demo::pattern::draw(vga, Page::One);
    let mut shown = Page::Zero;
    vga.show_page(shown);
    serial_println!("pattern: page {} shown", shown.index());
    serial_println!("{}", protocol::line::READY);
    loop {
        crate::idle::idle();
        usb_input::poll();
        let mut pressed = false;
        while let Some(byte) = ps2::SCANCODES.pop() {
            // Only make codes: a release must not flip again.
            pressed |= byte & BREAK_BIT == 0 && byte != EXTENDED_PREFIX;
        }
        if pressed {
            shown = shown.other();
            vga.show_page(shown);
            serial_println!("pattern: page {} shown", shown.index());
        }
    }
}

const FLIP_RATE_MICROS: u64 = 3_000_000;

/// Flips between two pages for three seconds by the clock and reports the
/// rate, and how many retraces went by without a flip (a busy emulator can
/// truly miss some); with QEMU's precise retrace (or real hardware) flips plus
/// missed retraces make the refresh rate.
pub fn flip_rate<B: VgaBus>(vga: &mut ModeX<B>) {
    demo::pattern::draw(vga, Page::Zero);
    demo::pattern::draw(vga, Page::One);
    vga.show_page(Page::Zero);
    let start = time::micros();
    let mut pacing = Pacing::default();
    pacing.flipped(start, false);
    let mut shown = Page::Zero;
    while time::micros() - start < FLIP_RATE_MICROS {
        shown = shown.other();
        let report = vga.show_page(shown);
        pacing.flipped(time::micros(), report.timed_out());
    }
    let elapsed = time::micros() - start;
    let flips = pacing.flips - 1;
    let millihertz = flips * 1_000_000_000 / elapsed.max(1);
    serial_println!(
        "flip-rate: {} flips in {} us = {}.{:03} Hz, {} missed retraces, {} wait timeouts",
        flips,
        elapsed,
        millihertz / 1000,
        millihertz % 1000,
        pacing.missed,
        pacing.wait_timeouts
    );
}

/// Seconds the clock check runs for.
const CLOCK_CHECK_SECONDS: u64 = 10;

/// Prints the clock's reading once a second for ten seconds, so a test can
/// compare the kernel's time with the host's wall clock. Idles between
/// readings, as the demo does.
pub fn clock_check() {
    let start = time::micros();
    serial_println!("clock-check: {} us", start);
    for second in 1..=CLOCK_CHECK_SECONDS {
        // The reading that ends the wait is the one printed, so the first and
        // last lines are at least the whole span apart.
        let now = loop {
            let now = time::micros();
            if now - start >= second * 1_000_000 {
                break now;
            }
            crate::idle::idle();
        };
        serial_println!("clock-check: {} us", now);
    }
}
