//! The renderer timed on the machine itself (boot option `bench`): the same
//! spinning frames drawn by our renderer and by per-pixel Map Mask drawing,
//! without waiting for retrace, timed by the kernel's clock; then our
//! renderer on the crowd of many solids (key X), all depth-tested; then, for
//! the cube and the crowd, where a frame's time goes, phase by phase.

use crate::clock;
use crate::run::RENDERER;
use crate::serial_println;
use demo::baseline::PerPixel;
use demo::depth::{render_with_depth, rows_needing_depth_test};
use demo::frame::{FrameDrawer, BACKGROUND};
use demo::scene::{Scene, SceneCommand};
use engine::DepthBand;
use modex::regs::Port;
use modex::{ModeX, Page, PageImage, VgaBus, PAGE_PIXELS};
use spin::Mutex;

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
    for (name, commands) in [
        ("cube", &[][..]),
        ("crowd", &[SceneCommand::ToggleCrowd][..]),
    ] {
        let phases = time_phases(vga, commands);
        serial_println!(
            "bench: phases of the {} (us/frame): motion {}, transform and projection {}, \
             culling and scan conversion {}, comparison and grouping {}, bus writes {}",
            name,
            phases.motion,
            phases.transform,
            phases.scan_conversion,
            phases.comparison,
            phases.bus_writes
        );
    }
    vga.set_mode();
}

/// Mean microseconds per frame in each phase of `Renderer`'s frame.
struct Phases {
    /// `Scene::tick`: the objects' own motion.
    motion: u64,
    /// Transforming and projecting the objects that moved, and their screen
    /// rectangles (which decide where the depth test is needed).
    transform: u64,
    /// Backface culling and scan conversion into the RAM frame.
    scan_conversion: u64,
    /// Comparing the frame with the page's shadow and grouping the changes
    /// by Map Mask: `update_page` on a bus that drops every write.
    comparison: u64,
    /// `update_page` on the real bus, less the comparison: the writes.
    bus_writes: u64,
}

/// The frame, the two pages' shadows, a copy of a shadow for the dry run,
/// and the depth band: ~360 KiB, kept off the stack.
struct Images {
    next: PageImage,
    shadows: [PageImage; 2],
    dry_run_shadow: PageImage,
    band: DepthBand,
}

static IMAGES: Mutex<Images> = Mutex::new(Images {
    next: [BACKGROUND; PAGE_PIXELS],
    shadows: [[BACKGROUND; PAGE_PIXELS]; 2],
    dry_run_shadow: [BACKGROUND; PAGE_PIXELS],
    band: DepthBand::new(),
});

/// A VGA that takes every write and answers every read with zero: the
/// driver's own work without the bus.
struct NoBus;

impl VgaBus for NoBus {
    fn write_port8(&mut self, _port: Port, _value: u8) {}
    fn write_port16(&mut self, _port: Port, _value: u16) {}
    fn read_port8(&mut self, _port: Port) -> u8 {
        0
    }
    fn write_vram8(&mut self, _offset: u16, _value: u8) {}
    fn read_vram8(&mut self, _offset: u16) -> u8 {
        0
    }
    fn fill_vram(&mut self, _offset: u16, _count: u16, _value: u8) {}
}

/// Draws `FRAMES` spinning frames the way `Renderer` does, with `commands`
/// applied first, timing each phase by the TSC.
fn time_phases<B: VgaBus>(vga: &mut ModeX<B>, commands: &[SceneCommand]) -> Phases {
    vga.set_mode();
    let mut images = IMAGES.lock();
    let images = &mut *images;
    images.shadows = [[BACKGROUND; PAGE_PIXELS]; 2];
    let mut dry_run = ModeX::new(NoBus);
    let mut scene = Scene::new();
    for &command in commands {
        scene.apply(command);
    }
    let mut cycles = [0u64; 5];
    let mut page = Page::Zero;
    for _ in 0..FRAMES {
        page = page.other();
        let shadow = &mut images.shadows[usize::from(page.index())];
        images.dry_run_shadow.copy_from_slice(shadow);
        let t0 = clock::rdtsc();
        scene.tick();
        let t1 = clock::rdtsc();
        let _ = rows_needing_depth_test(&mut scene);
        let t2 = clock::rdtsc();
        render_with_depth(&mut scene, &mut images.next, &mut images.band);
        let t3 = clock::rdtsc();
        dry_run.update_page(page, &mut images.dry_run_shadow, &images.next);
        let t4 = clock::rdtsc();
        vga.update_page(page, shadow, &images.next);
        let t5 = clock::rdtsc();
        let comparison = t4 - t3;
        let writes = (t5 - t4).saturating_sub(comparison);
        for (total, spent) in cycles
            .iter_mut()
            .zip([t1 - t0, t2 - t1, t3 - t2, comparison, writes])
        {
            *total += spent;
        }
    }
    let micros = |total: u64| clock::cycles_to_micros(total) / FRAMES;
    Phases {
        motion: micros(cycles[0]),
        transform: micros(cycles[1]),
        scan_conversion: micros(cycles[2]),
        comparison: micros(cycles[3]),
        bus_writes: micros(cycles[4]),
    }
}
