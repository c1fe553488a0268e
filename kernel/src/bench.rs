//! The renderer timed on the machine itself (boot option `bench`): the same
//! spinning frames drawn by our renderer and by per-pixel Map Mask drawing,
//! without waiting for retrace, timed with the TSC calibrated against the PIT.

use crate::{pit, serial_println};
use demo::baseline::PerPixel;
use demo::frame::{FrameDrawer, Renderer};
use demo::scene::Scene;
use modex::{ModeX, VgaBus};

const FRAMES: u64 = 120;
const CALIBRATION_TICKS: u64 = 100;

fn rdtsc() -> u64 {
    // SAFETY: RDTSC only reads the time-stamp counter.
    unsafe { core::arch::x86_64::_rdtsc() }
}

/// TSC cycles per microsecond, measured over 100 PIT ticks (about 100 ms).
fn tsc_per_microsecond() -> u64 {
    let start_tick = pit::ticks();
    while pit::ticks() == start_tick {
        core::hint::spin_loop();
    }
    let (tick, tsc) = (pit::ticks(), rdtsc());
    while pit::ticks() < tick + CALIBRATION_TICKS {
        core::hint::spin_loop();
    }
    let elapsed_nanos = CALIBRATION_TICKS * pit::TICK_NANOS;
    ((rdtsc() - tsc) * 1000 / elapsed_nanos).max(1)
}

/// Mean microseconds per frame for `drawer` over the spinning scene.
fn time_frames<B: VgaBus, D: FrameDrawer>(
    vga: &mut ModeX<B>,
    mut drawer: D,
    per_microsecond: u64,
) -> u64 {
    vga.set_mode(); // blank pages and known registers, as every drawer expects
    let mut scene = Scene::new();
    let start = rdtsc();
    for _ in 0..FRAMES {
        scene.tick();
        drawer.draw(vga, &mut scene);
    }
    (rdtsc() - start) / per_microsecond / FRAMES
}

pub fn run<B: VgaBus>(vga: &mut ModeX<B>) {
    let per_microsecond = tsc_per_microsecond();
    let ours = time_frames(vga, Renderer::new(), per_microsecond);
    let per_pixel = time_frames(vga, PerPixel::default(), per_microsecond);
    vga.set_mode();
    serial_println!(
        "bench: {} frames each, TSC {} MHz: ours {} us/frame, per-pixel {} us/frame, per-pixel/ours = {}.{:02}",
        FRAMES,
        per_microsecond,
        ours,
        per_pixel,
        per_pixel / ours.max(1),
        per_pixel * 100 / ours.max(1) % 100
    );
}
