//! Patched (see ../../../CHANGES.md, "The boot path on real firmware"): the
//! A20 line, which stage 2 needs to copy stages 3 and 4 and the kernel above
//! 1 MiB. Upstream's boot sector set port 92h's bit and checked nothing. Here
//! each way is tried only if A20 is still off, and checked after: the BIOS
//! (INT 15h AX=2401h), then the fast gate (port 92h). A20 that stays off
//! stops the loader with a message instead of a copy that wraps to 0.

use crate::bios::{self, Registers};
use core::arch::asm;

/// A word the boot sector left (its 55 AA signature) and the address that
/// aliases it while A20 is off.
const LOW: *mut u16 = 0x7dfe as *mut u16;
const HIGH: *mut u16 = 0x10_7dfe as *mut u16;

fn is_on() -> bool {
    // SAFETY: unreal mode reaches both; 0x107DFE is free memory that stage 3
    // overwrites later, and the low word is put back as it was.
    unsafe {
        let before = LOW.read_volatile();
        HIGH.write_volatile(!before);
        let on = LOW.read_volatile() == before;
        LOW.write_volatile(before);
        on
    }
}

pub fn enable() {
    if is_on() {
        return;
    }
    bios::call(
        0x15,
        Registers {
            eax: 0x2401,
            ..Registers::default()
        },
    );
    if is_on() {
        return;
    }
    // The fast gate: bit 1 on, bit 0 (a reset) never.
    let mut value: u8;
    // SAFETY: port 92h's A20 bit; bit 0 is kept clear.
    unsafe {
        asm!("in al, 0x92", out("al") value, options(nomem, nostack));
        value = (value | 2) & !1;
        asm!("out 0x92, al", in("al") value, options(nomem, nostack));
    }
    if !is_on() {
        crate::serial::stop(format_args!(
            "loader: the A20 line stays off (tried the BIOS and port 92h); this PC cannot be booted"
        ));
    }
}
