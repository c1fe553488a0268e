//! Patched (see ../../../CHANGES.md): the screen and COM1 together, and the
//! loader's stop. The COM1 writer itself is the BIOS common crate's, shared
//! with stage 4.

use core::{arch::asm, fmt};

pub use bootloader_x86_64_bios_common::serial::{Com1, init};

/// The screen and COM1 together.
pub struct Both;

impl fmt::Write for Both {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let _ = crate::screen::Writer.write_str(s);
        Com1.write_str(s)
    }
}

/// Says why on screen and serial and halts for good (interrupts off, so the
/// machine neither reboots nor runs on).
pub fn stop(why: fmt::Arguments) -> ! {
    init();
    let _ = fmt::Write::write_fmt(&mut Both, format_args!("{why}\n"));
    loop {
        // SAFETY: halting with interrupts off stops this CPU; nothing follows.
        unsafe { asm!("cli", "hlt") };
    }
}
