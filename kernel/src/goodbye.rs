//! Leaving the demo: the VGA goes back to 80x25 text with a goodbye line (by
//! the video BIOS's mode 3 where it can be called), then QEMU ends through
//! isa-debug-exit if it is fitted (for the tests' exit status), and otherwise
//! the machine powers off through ACPI S5, on a real PC as in QEMU. Where
//! neither works the CPU halts with the line on screen.

use crate::{fault, idle, platform::power, platform::qemu, serial_println, time};

/// How long the goodbye line stays up before the machine switches off.
const GOODBYE_SHOWN_MICROS: u64 = 2_000_000;
use modex::{ModeX, VgaBus};

pub fn goodbye<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    if crate::legacy_vga::bios_text_mode() {
        // The card's BIOS set mode 3 and its own font, behind the driver's back.
        vga.invalidate_caches();
        serial_println!("demo: text mode 3 set by the video BIOS");
        demo::screens::goodbye_line(vga);
    } else {
        demo::screens::goodbye(vga);
    }
    let (by_irq, by_poll) = crate::input::ps2::taken();
    serial_println!(
        "ps2: {} keyboard bytes taken by IRQ 1, {} by the poll",
        by_irq,
        by_poll
    );
    serial_println!(
        "{} ({} scancodes dropped by a full queue, {} serial characters dropped)",
        protocol::line::GOODBYE,
        crate::input::ps2::SCANCODES.dropped(),
        crate::serial::dropped()
    );
    qemu::exit(protocol::Exit::Success);
    idle::until(time::micros() + GOODBYE_SHOWN_MICROS);
    power::off();
    fault::halt_forever()
}
