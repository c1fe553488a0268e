//! The renderer timed on the machine itself (boot option `bench`): the same
//! spinning frames drawn by our renderer and by per-pixel Map Mask drawing,
//! without waiting for retrace, timed by the kernel's clock; then our
//! renderer on the crowd of many solids (key X), all depth-tested; then, for
//! the cube and the crowd, where a frame's time goes, phase by phase; and
//! last, the largest grid of solids (`demo::grid`) whose frame still fits one
//! refresh (60 frames a second).

use crate::run::RENDERER;
use crate::serial_println;
use crate::time;
use demo::baseline::PerPixel;
use demo::depth::render_with_depth;
use demo::frame::{FrameDrawer, BACKGROUND};
use demo::grid::Grid;
use demo::scene::{Scene, SceneCommand, SceneFaces};
use engine::DepthBuffer;
use modex::regs::Port;
use modex::{ModeX, Page, PageImage, PageSpans, PageWrites, VgaBus, PAGE_PIXELS};
use spin::Mutex;

const FRAMES: u64 = 120;
/// Frames drawn for each size of the grid.
const GRID_FRAMES: u64 = 30;
/// The grid's sizes: from 16 solids up to this many, well past the 2,116
/// that fit a refresh under icount today (the search's guesses keep it from
/// timing sizes far beyond the answer).
const GRID_START: usize = 16;
const GRID_LIMIT: usize = 4096;

/// The grid's solids (about 1.1 KiB each: 4.5 MiB, so a static; empty, it
/// is all zero, so in .bss and not in the kernel file).
static GRID: Mutex<Grid<GRID_LIMIT>> = Mutex::new(Grid::new());

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
    let start = time::micros();
    for _ in 0..FRAMES {
        scene.tick();
        drawer.draw(vga, &mut scene);
    }
    (time::micros() - start) / FRAMES
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
    let phases = [
        ("cube", time_phases(vga, &[])),
        ("crowd", time_phases(vga, &[SceneCommand::ToggleCrowd])),
    ];
    say_frames(ours, per_pixel, crowd, &phases);
    ps2_poll_cost();
    usb_poll_cost();
    largest_grid_at_60_fps(vga);
    vga.set_mode();
}

/// Says the frame timings: apart from [`run`], which is built once per VGA
/// bus, so that the formatting is built once (`tests/size.rs`).
fn say_frames(ours: u64, per_pixel: u64, crowd: u64, phases: &[(&str, Phases)]) {
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
    for (name, phases) in phases {
        serial_println!(
            "bench: phases of the {} (us/frame): motion {}, transform, projection and culling {}, \
             depth policy and scan conversion {}, comparison and grouping {}, bus writes {}",
            name,
            phases.motion,
            phases.transform,
            phases.scan_conversion,
            phases.comparison,
            phases.bus_writes
        );
    }
}

/// Calls of the PS/2 poll timed together.
const POLL_CALLS: u64 = 100_000;

/// Microseconds [`POLL_CALLS`] calls of `poll` take.
fn time_poll_calls(mut poll: impl FnMut()) -> u64 {
    let start = time::micros();
    for _ in 0..POLL_CALLS {
        poll();
    }
    time::micros() - start
}

/// What the frame loop's poll of the 8042 costs when no key is waiting (one
/// call a frame, and one an idle step): timed over many calls.
fn ps2_poll_cost() {
    let micros = time_poll_calls(crate::input::ps2::poll);
    serial_println!(
        "bench: PS/2 poll with no key waiting: {} ns per call ({} calls in {} us)",
        micros * 1000 / POLL_CALLS,
        POLL_CALLS,
        micros
    );
}

/// What the frame loop's poll of the USB controllers costs when nothing
/// changes (one call a frame, and one an idle step): all of them together
/// as the frame loop polls them, then each alone, with the register and
/// DMA reads its idle poll makes (counted by `input::usb`'s hardware
/// wrapper: at most one per poll is the drivers' promise).
fn usb_poll_cost() {
    let (running, count) = crate::input::usb::running();
    if count == 0 {
        serial_println!("bench: USB poll: no controller running");
        return;
    }
    let micros = time_poll_calls(crate::input::usb::poll);
    serial_println!(
        "bench: USB poll with nothing changing: {} ns per call over {} controller(s) ({} calls in {} us)",
        micros * 1000 / POLL_CALLS,
        count,
        POLL_CALLS,
        micros
    );
    for (kind, function) in running.into_iter().flatten() {
        let start = time::micros();
        let Some(reads) = crate::input::usb::poll_one(function, POLL_CALLS) else {
            continue;
        };
        let micros = time::micros() - start;
        serial_println!(
            "bench: USB idle poll on {} {}: {} ns per call, {}.{:02} register and {}.{:02} DMA reads per poll ({} calls in {} us)",
            kind.name(),
            function,
            micros * 1000 / POLL_CALLS,
            reads.registers / POLL_CALLS,
            reads.registers * 100 / POLL_CALLS % 100,
            reads.dma / POLL_CALLS,
            reads.dma * 100 / POLL_CALLS % 100,
            POLL_CALLS,
            micros
        );
    }
}

/// Grows the grid until a frame (motion, transform, scan conversion with the
/// depth test, comparison, grouping and bus writes: all but the wait for
/// retrace) takes longer than one refresh, and reports the largest size that
/// fits, with every size measured.
fn largest_grid_at_60_fps<B: VgaBus>(vga: &mut ModeX<B>) {
    let mut grid = GRID.lock();
    let mut images = IMAGES.lock();
    let images = &mut *images;
    let found = demo::scale::largest_that_fits(
        GRID_START,
        GRID_LIMIT,
        clock::pacing::FRAME_MICROS,
        |count| {
            vga.set_mode();
            images.blank();
            grid.reset(count);
            let mut page = Page::Zero;
            // One frame: the drawing's TSC cycles and the bytes written.
            let mut frame = || {
                page = page.other();
                let t0 = time::tsc::rdtsc();
                grid.tick();
                grid.render(&mut images.next, &mut images.drawn, &mut images.depths);
                let cycles = time::tsc::rdtsc() - t0;
                (cycles, u64::from(images.update_page(vga, page)))
            };
            // Two frames first, one into each page, so that what is timed is
            // the steady state, not the grid appearing on blank pages.
            frame();
            frame();
            let start = time::micros();
            let (mut drawing, mut written) = (0, 0);
            for _ in 0..GRID_FRAMES {
                let (cycles, bytes) = frame();
                drawing += cycles;
                written += bytes;
            }
            let total = (time::micros() - start) / GRID_FRAMES;
            let drawing = time::cycles_to_micros(drawing) / GRID_FRAMES;
            serial_println!(
                "bench: grid of {} solids, {} us/frame: drawing {}, page update {} ({} bytes)",
                count,
                total,
                drawing,
                total.saturating_sub(drawing),
                written / GRID_FRAMES
            );
            total
        },
    );
    match (found.fits, found.misses) {
        (Some(fits), Some(misses)) => serial_println!(
            "bench: largest grid at 60 fps: {} solids ({} us/frame; {} solids take {} us, over the {} us refresh)",
            fits.count,
            fits.micros,
            misses.count,
            misses.micros,
            clock::pacing::FRAME_MICROS
        ),
        (Some(fits), None) => serial_println!(
            "bench: largest grid at 60 fps: at least {} solids, the most the bench holds ({} us/frame)",
            fits.count,
            fits.micros
        ),
        (None, _) => serial_println!(
            "bench: largest grid at 60 fps: none; {} solids already take over the {} us refresh",
            GRID_START,
            clock::pacing::FRAME_MICROS
        ),
    }
}

/// Mean microseconds per frame in each phase of `Renderer`'s frame.
struct Phases {
    /// `Scene::tick`: the objects' own motion.
    motion: u64,
    /// The scene's faces: transforming and projecting the objects that
    /// moved, their screen rectangles, backface culling and colouring.
    transform: u64,
    /// The depth policy: where the test is needed, and scan conversion of
    /// the faces into the RAM frame.
    scan_conversion: u64,
    /// Comparing the frame with the page's shadow and grouping the changes
    /// by Map Mask: `update_page` on a bus that drops every write.
    comparison: u64,
    /// `update_page` on the real bus, less the comparison: the writes.
    bus_writes: u64,
}

/// The frame, the two pages' shadows, a copy of a shadow for the dry run,
/// the spans drawn into the frame and held by each page and the room for a
/// page update's writes (as `Renderer` keeps them), the depth buffer and the
/// scene's faces: 1,039 KiB (`llvm-nm -S`), kept off the stack.
struct Images {
    next: PageImage,
    drawn: PageSpans,
    shadows: [PageImage; 2],
    held: [PageSpans; 2],
    dry_run_shadow: PageImage,
    writes: PageWrites,
    depths: DepthBuffer,
    faces: SceneFaces,
}

static IMAGES: Mutex<Images> = Mutex::new(Images {
    next: [BACKGROUND; PAGE_PIXELS],
    drawn: PageSpans::none(),
    shadows: [[BACKGROUND; PAGE_PIXELS]; 2],
    held: [PageSpans::none(), PageSpans::none()],
    dry_run_shadow: [BACKGROUND; PAGE_PIXELS],
    writes: PageWrites::new(),
    depths: DepthBuffer::new(),
    faces: SceneFaces::new(),
});

impl Images {
    /// Both pages and the frame blank, as the mode set leaves the pages.
    fn blank(&mut self) {
        for image in self.shadows.iter_mut().chain([&mut self.next]) {
            image.fill(BACKGROUND);
        }
        for spans in self.held.iter_mut().chain([&mut self.drawn]) {
            spans.clear();
        }
    }

    /// Adds to the spans `page` holds those the frame drew: what the page
    /// update compares (as `Renderer` does).
    fn spans_to_compare(&mut self, page: Page) {
        self.held[usize::from(page.index())].add(&self.drawn);
    }

    /// `page` brought up to the frame over the spans, which it then holds.
    fn update_page<B: VgaBus>(&mut self, vga: &mut ModeX<B>, page: Page) -> u32 {
        let index = usize::from(page.index());
        self.spans_to_compare(page);
        let written = vga.update_page_with(
            page,
            &mut self.shadows[index],
            &self.next,
            &self.held[index],
            &mut self.writes,
        );
        self.held[index].clone_from(&self.drawn);
        written
    }
}

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
    images.blank();
    let mut dry_run = ModeX::new(NoBus);
    let mut scene = Scene::new();
    for &command in commands {
        scene.apply(command);
    }
    let mut cycles = [0u64; 5];
    let mut page = Page::Zero;
    for _ in 0..FRAMES {
        page = page.other();
        let index = usize::from(page.index());
        images
            .dry_run_shadow
            .copy_from_slice(&images.shadows[index]);
        let t0 = time::tsc::rdtsc();
        scene.tick();
        let t1 = time::tsc::rdtsc();
        let faces = scene.faces(&mut images.faces);
        let t2 = time::tsc::rdtsc();
        render_with_depth(
            faces,
            &mut images.next,
            &mut images.drawn,
            &mut images.depths,
        );
        let t3 = time::tsc::rdtsc();
        images.spans_to_compare(page);
        let spans = &images.held[index];
        dry_run.update_page_with(
            page,
            &mut images.dry_run_shadow,
            &images.next,
            spans,
            &mut images.writes,
        );
        let t4 = time::tsc::rdtsc();
        images.update_page(vga, page);
        let t5 = time::tsc::rdtsc();
        let comparison = t4 - t3;
        let writes = (t5 - t4).saturating_sub(comparison);
        for (total, spent) in cycles
            .iter_mut()
            .zip([t1 - t0, t2 - t1, t3 - t2, comparison, writes])
        {
            *total += spent;
        }
    }
    let micros = |total: u64| time::cycles_to_micros(total) / FRAMES;
    Phases {
        motion: micros(cycles[0]),
        transform: micros(cycles[1]),
        scan_conversion: micros(cycles[2]),
        comparison: micros(cycles[3]),
        bus_writes: micros(cycles[4]),
    }
}
