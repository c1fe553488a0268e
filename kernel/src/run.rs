//! The demo's main loop on the machine: drain the scancode queue into the
//! portable `App`, draw when something moved, and sleep (`hlt`) until the next
//! interrupt when nothing did, so an idle cube costs no bus traffic at all.

use crate::{goodbye, keyboard, serial_println};
use demo::app::App;
use modex::{ModeX, VgaBus};

pub fn run_demo<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    let mut app = App::new();
    app.step(vga);
    serial_println!("screen: ready");
    let mut reported_commands = 0;
    loop {
        while let Some(byte) = keyboard::SCANCODES.pop() {
            app.feed_scancode(byte);
        }
        if app.quit_requested() {
            goodbye::goodbye(vga);
        }
        let drew = app.step(vga).is_some();
        if app.commands() != reported_commands {
            // Tests wait for this line before they look at the screen.
            reported_commands = app.commands();
            serial_println!(
                "demo: command {} done, paused={}",
                reported_commands,
                app.paused()
            );
        }
        if !drew {
            x86_64::instructions::hlt();
        }
    }
}
