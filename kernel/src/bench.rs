//! The renderer timed on the machine itself (boot option `bench`): the same
//! spinning frames drawn by our renderer and by per-pixel Map Mask drawing,
//! without waiting for retrace, timed by the kernel's clock; then our
//! renderer on the crowd of many solids (key X), all depth-tested.

use crate::clock;
use crate::run::RENDERER;
use crate::serial_println;
use demo::baseline::PerPixel;
use demo::frame::FrameDrawer;
use demo::scene::{Scene, SceneCommand};
use modex::{ModeX, VgaBus};

const FRAMES: u64 = 120;

/// Mean microseconds per frame for `drawer` over the spinning scene, with
/// `commands` applied first.
fn time_frames<B: VgaBus, D: FrameDrawer>(
    vga: &mut ModeX<B>,
    mut drawer: D,
    commands: &[SceneCommand],
) -> u64 {
    vga.set_mode(); // blank pages and known registers, as every drawer expects
    let mut scene = Scene::new();
    for &command in commands {
        scene.apply(command);
    }
    let start = clock::micros();
    for _ in 0..FRAMES {
        scene.tick();
        drawer.draw(vga, &mut scene);
    }
    (clock::micros() - start) / FRAMES
}

pub fn run<B: VgaBus>(vga: &mut ModeX<B>) {
    // The static renderer (its images are too big for the stack), reset for
    // each run as the blank pages of its mode set expect.
    let mut renderer = RENDERER.lock();
    renderer.reset();
    let ours = time_frames(vga, &mut *renderer, &[]);
    let per_pixel = time_frames(vga, PerPixel::default(), &[]);
    renderer.reset();
    let crowd = time_frames(vga, &mut *renderer, &[SceneCommand::ToggleCrowd]);
    drop(renderer);
    vga.set_mode();
    serial_println!(
        "bench: {} frames each: ours {} us/frame, per-pixel {} us/frame, per-pixel/ours = {}.{:02}",
        FRAMES,
        ours,
        per_pixel,
        per_pixel / ours.max(1),
        per_pixel * 100 / ours.max(1) % 100
    );
    serial_println!(
        "bench: {} frames of the crowd ({} solids), ours {} us/frame",
        FRAMES,
        demo::scene::MAX_OBJECTS,
        crowd
    );
}
