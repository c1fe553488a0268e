//! Screens for checking the VGA itself, chosen by the boot option: the Mode X
//! test pattern (QEMU's picture is compared with the software VGA's) and a
//! measurement of how many page flips a second vertical retrace allows.

use crate::{keyboard, pit, serial_println};
use modex::{ModeX, Page, VgaBus};

/// Draws the pattern into pages 0 and 1, shows page 0, and flips to the other
/// page on every key press, saying on serial which page is shown.
pub fn test_pattern<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    demo::pattern::draw(vga, Page(0));
    demo::pattern::draw(vga, Page(1));
    let mut shown = Page(0);
    vga.show_page(shown);
    serial_println!("pattern: page {} shown", shown.0);
    serial_println!("screen: ready");
    loop {
        x86_64::instructions::hlt();
        let mut pressed = false;
        while let Some(byte) = keyboard::SCANCODES.pop() {
            // Only make codes: a release must not flip again.
            pressed |= byte & 0x80 == 0 && byte != 0xE0;
        }
        if pressed {
            shown = Page(1 - shown.0);
            vga.show_page(shown);
            serial_println!("pattern: page {} shown", shown.0);
        }
    }
}

const FLIP_RATE_MILLIS: u64 = 2000;

/// Flips between two pages for two seconds by the PIT clock and reports the
/// rate; with QEMU's precise retrace (or real hardware) it is the refresh rate.
pub fn flip_rate<B: VgaBus>(vga: &mut ModeX<B>) {
    demo::pattern::draw(vga, Page(0));
    demo::pattern::draw(vga, Page(1));
    vga.show_page(Page(0));
    let start = pit::millis();
    let (mut flips, mut timeouts) = (0u64, 0u64);
    while pit::millis() - start < FLIP_RATE_MILLIS {
        let report = vga.show_page(Page((flips % 2) as u8));
        flips += 1;
        timeouts +=
            u64::from(report.display_wait_timed_out) + u64::from(report.retrace_wait_timed_out);
    }
    let elapsed = pit::millis() - start;
    let millihertz = flips * 1_000_000 / elapsed.max(1);
    serial_println!(
        "flip-rate: {} flips in {} ms = {}.{:03} Hz, {} wait timeouts",
        flips,
        elapsed,
        millihertz / 1000,
        millihertz % 1000,
        timeouts
    );
}
