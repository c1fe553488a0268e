//! Leaving the demo: the VGA goes back to 80x25 text with a goodbye line, then
//! QEMU is powered off through isa-debug-exit; on a real PC (or a QEMU without
//! that device) the CPU halts with the line on screen.

use crate::{fault, qemu, serial_println};
use modex::{ModeX, VgaBus};

pub fn goodbye<B: VgaBus>(vga: &mut ModeX<B>) -> ! {
    demo::screens::goodbye(vga);
    serial_println!(
        "demo: goodbye ({} scancodes dropped by a full queue, {} serial characters dropped)",
        crate::keyboard::SCANCODES.dropped(),
        crate::serial::dropped()
    );
    qemu::exit(qemu::ExitCode::Success);
    fault::halt_forever()
}
