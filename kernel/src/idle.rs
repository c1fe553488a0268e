//! Waiting without a wake-up that may never come. `hlt` sleeps until the next
//! interrupt, so the kernel halts only while it sees PIT ticks arrive (at
//! least one in the last 10 ms); on a machine without a PIT it spins with
//! `pause` instead. Either way every wait is bounded by the clock.

use crate::{time, time::pit};

/// `pause`s per idle step without a timer: a few microseconds.
const SPINS: u32 = 200;

/// Gives up the CPU for a moment: until the next interrupt while the PIT is
/// ticking (at most a millisecond), else for a few hundred `pause`s.
pub fn idle() {
    // Keys are taken here too, so that they arrive where IRQ 1 never does.
    crate::input::ps2::poll();
    if pit::ticking() && x86_64::instructions::interrupts::are_enabled() {
        x86_64::instructions::hlt();
    } else {
        for _ in 0..SPINS {
            core::hint::spin_loop();
        }
    }
}

/// Idles until the clock reads `micros`.
pub fn until(micros: u64) {
    while time::micros() < micros {
        idle();
    }
}
