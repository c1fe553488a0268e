//! The demo's main loop on the machine: drain the scancode queue into the
//! portable `App`, draw when something moved, and idle when nothing did, so
//! an idle cube costs no bus traffic at all. While the cube spins it also
//! keeps count of missed retraces. Ctrl+Alt+Del resets the machine.

use crate::{clock, goodbye, idle, keyboard, power, serial_println, usb};
use demo::app::App;
use machine::pacing::Pacing;
use machine::protocol::line;
use machine::reset_keys::ResetChord;
use modex::{ModeX, VgaBus};

/// A pacing report every this many flips (about ten seconds).
const PACING_REPORT_FLIPS: u64 = 600;

fn count_flip(pacing: &mut Pacing, timed_out: bool) {
    pacing.flipped(clock::micros(), timed_out);
    if pacing.flips.is_multiple_of(PACING_REPORT_FLIPS) {
        serial_println!(
            "pacing: {} flips, {} missed retraces, {} wait timeouts, {} gaps in {} us",
            pacing.flips,
            pacing.missed,
            pacing.wait_timeouts,
            pacing.gaps,
            pacing.gap_micros
        );
    }
}

// Never inlined, for the same reason as `bench::run`: the app (~350 KiB) must
// not share a frame with the other boot options' state.
#[inline(never)]
pub fn run_demo<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    let mut app = App::new();
    app.step(vga, &clock::micros);
    serial_println!("{}", line::READY);
    let mut reported_commands = 0;
    let mut pacing = Pacing::default();
    let mut reset_chord = ResetChord::new();
    loop {
        usb::poll();
        while let Some(byte) = keyboard::SCANCODES.pop() {
            if reset_chord.feed(byte) {
                power::reset();
            }
            app.feed_scancode(byte);
        }
        if app.quit_requested() {
            goodbye::goodbye(vga);
        }
        let flip = app.step(vga, &clock::micros);
        crate::report::show_if_asked(vga, &mut app, &pacing);
        if app.commands() != reported_commands {
            // Tests wait for this line before they look at the screen.
            reported_commands = app.commands();
            serial_println!(
                "{}, paused={}, scancodes dropped={}",
                line::CommandDone(reported_commands),
                app.paused(),
                keyboard::SCANCODES.dropped()
            );
        }
        match flip {
            Some(report) if app.scene().spinning() => count_flip(&mut pacing, report.timed_out()),
            Some(_) => pacing.idle(),
            None => {
                pacing.idle();
                idle::idle();
            }
        }
    }
}
