//! The demo's main loop on the machine: drain the scancode queue into the
//! portable `App`, draw when something moved, and idle when nothing did, so
//! an idle cube costs no bus traffic at all. While the cube spins it also
//! keeps count of missed retraces. Ctrl+Alt+Del resets the machine.

use crate::{
    goodbye, idle, input::ps2, input::usb as usb_input, platform::power, serial_println, stack,
    time,
};
use clock::pacing::Pacing;
use core::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use demo::app::App;
use demo::frame::Renderer;
use keyboard::reset_keys::ResetChord;
use modex::{ModeX, VgaBus};
use protocol::line;
use spin::Mutex;

/// The renderer (742 KiB: three 75 KiB frame images, the depth buffer, the
/// scene's faces and the page update's writes), in static memory rather
/// than on the stack; the demo and the bench take turns.
pub static RENDERER: Mutex<Renderer> = Mutex::new(Renderer::new());

/// Say on serial every scancode byte taken (boot word `scancodes=echo`), so
/// that a test can pace its keys by what the kernel has received.
pub static ECHO_SCANCODES: AtomicBool = AtomicBool::new(false);

/// Bytes said per `scancodes:` line at most.
const ECHO_LINE_BYTES: usize = 32;

/// Scancode bytes taken from the queue since boot, for the echo.
static SCANCODES_TAKEN: AtomicU64 = AtomicU64::new(0);

/// Says `bytes` on serial as a `scancodes: taken ...` line.
fn echo(bytes: &[u8]) {
    if bytes.is_empty() {
        return;
    }
    let total =
        SCANCODES_TAKEN.fetch_add(bytes.len() as u64, Ordering::Relaxed) + bytes.len() as u64;
    serial_println!("{}", line::ScancodesTaken { bytes, total });
}

/// A pacing report every this many flips (about ten seconds).
const PACING_REPORT_FLIPS: u64 = 600;

fn count_flip(pacing: &mut Pacing, timed_out: bool) {
    pacing.flipped(time::micros(), timed_out);
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

/// Set when there is no display at all: the demo runs unseen, and the ready
/// line says so.
pub static NO_DISPLAY: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

pub fn run_demo<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    let mut renderer = RENDERER.lock();
    let mut app = App::with_renderer(&mut *renderer);
    app.step(vga, &time::micros);
    serial_println!(
        "{}",
        if NO_DISPLAY.load(core::sync::atomic::Ordering::Relaxed) {
            line::READY_NO_DISPLAY
        } else {
            line::READY
        }
    );
    let mut reported_commands = 0;
    let mut pacing = Pacing::default();
    let mut reset_chord = ResetChord::new();
    loop {
        usb_input::poll();
        ps2::poll();
        crate::nmi::log_news();
        let echoing = ECHO_SCANCODES.load(Ordering::Relaxed);
        let mut echoed = [0u8; ECHO_LINE_BYTES];
        let mut waiting = 0;
        while let Some(byte) = ps2::SCANCODES.pop() {
            if echoing {
                echoed[waiting] = byte;
                waiting += 1;
                if waiting == ECHO_LINE_BYTES {
                    echo(&echoed);
                    waiting = 0;
                }
            }
            if reset_chord.feed(byte) {
                echo(&echoed[..waiting]);
                power::reset();
            }
            app.feed_scancode(byte);
        }
        echo(&echoed[..waiting]);
        if app.quit_requested() {
            stack::report();
            goodbye::goodbye(vga);
        }
        let flip = app.step(vga, &time::micros);
        crate::report::show_if_asked(vga, &mut app, &pacing);
        if app.commands() != reported_commands {
            // Tests wait for this line before they look at the screen.
            reported_commands = app.commands();
            serial_println!(
                "{}, paused={}, scancodes dropped={}",
                line::CommandDone(reported_commands),
                app.paused(),
                ps2::SCANCODES.dropped()
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
