//! The demo's main loop on the machine: drain the scancode queue into the
//! portable `App`, draw when something moved, and sleep (`hlt`) until the next
//! interrupt when nothing did, so an idle cube costs no bus traffic at all.
//! While the cube spins it also keeps count of missed retraces.

use crate::{clock, goodbye, keyboard, pit, serial_println};
use demo::app::App;
use modex::{ModeX, VgaBus};

/// Two flips further apart than this skipped at least one retrace (a frame
/// lasts 16.7 ms at 60 Hz; the PIT clock has 1 ms steps).
const MISSED_RETRACE_MILLIS: u64 = 25;
const FRAME_MICROS: u64 = 16_683;
/// A pacing report every this many flips (about ten seconds).
const PACING_REPORT_FLIPS: u64 = 600;

#[derive(Default)]
struct Pacing {
    flips: u64,
    missed: u64,
    wait_timeouts: u64,
    last_flip_millis: Option<u64>,
}

impl Pacing {
    fn flipped(&mut self, timed_out: bool) {
        let now = pit::millis();
        if let Some(last) = self.last_flip_millis {
            let interval = now - last;
            if interval > MISSED_RETRACE_MILLIS {
                self.missed += (interval * 1000 + FRAME_MICROS / 2) / FRAME_MICROS - 1;
            }
        }
        self.last_flip_millis = Some(now);
        self.flips += 1;
        self.wait_timeouts += u64::from(timed_out);
        if self.flips.is_multiple_of(PACING_REPORT_FLIPS) {
            serial_println!(
                "pacing: {} flips, {} missed retraces, {} wait timeouts",
                self.flips,
                self.missed,
                self.wait_timeouts
            );
        }
    }

    /// Nothing to draw: the next flip starts a new run, not a late frame.
    fn idle(&mut self) {
        self.last_flip_millis = None;
    }
}

pub fn run_demo<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    let mut app = App::new();
    app.step(vga, &clock::micros);
    serial_println!("screen: ready");
    let mut reported_commands = 0;
    let mut pacing = Pacing::default();
    loop {
        while let Some(byte) = keyboard::SCANCODES.pop() {
            app.feed_scancode(byte);
        }
        if app.quit_requested() {
            goodbye::goodbye(vga);
        }
        let flip = app.step(vga, &clock::micros);
        if app.commands() != reported_commands {
            // Tests wait for this line before they look at the screen.
            reported_commands = app.commands();
            serial_println!(
                "demo: command {} done, paused={}, scancodes dropped={}",
                reported_commands,
                app.paused(),
                keyboard::SCANCODES.dropped()
            );
        }
        match flip {
            Some(report) if app.scene().spinning() => pacing.flipped(report.timed_out()),
            Some(_) => pacing.idle(),
            None => {
                pacing.idle();
                x86_64::instructions::hlt();
            }
        }
    }
}
