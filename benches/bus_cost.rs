//! What every frame costs on the VGA bus, measured on the software VGA.
//!
//! `cargo bench --bench bus_cost` renders a fixed set of frames — a 360-frame
//! spin, then moved, zoomed and partly off-screen states — three ways: our
//! renderer, Abrash's method (erase the last extent, fill every visible face
//! with Map Mask spans) and per-pixel drawing with a Map Mask OUT per pixel.
//! Per frame it counts the bus operations of drawing (flips excluded: they
//! cost the same for all three) and the lower bound on video-memory writes:
//! for each address of the page, the number of distinct new colours among its
//! pixels that must change; and the full bound: that plus one Map Mask write
//! for each distinct mask the frame needs (flips are left out of both sides).
//! A second set does the same for the extras: three lit solids circling and
//! spinning. Two more sets, for our renderer only (the other two methods
//! paint far to near, which is wrong there): solids passing through each
//! other, and the crowd of many solids. The last line is machine-readable.

mod frame_sets;

use demo::baseline::{OriginalMethod, PerPixel};
use demo::frame::{render_painter, render_to_image, FrameDrawer, Renderer};
use demo::scene::{Scene, SceneCommand};
use frame_sets::{cube_set, extras_set};
use modex::soft::{BusCounts, SoftVga};
use modex::{ModeX, Page, PAGE_PIXELS};
use sim::inspector::lower_bound;
use std::time::{Duration, Instant};

#[derive(Default, Clone, Copy)]
struct Totals {
    counts: BusCounts,
    time: Duration,
}

impl Totals {
    fn bus_ops(&self) -> u64 {
        self.counts.port_writes
            + self.counts.port_reads
            + self.counts.vram_writes
            + self.counts.vram_reads
    }
}

fn add(a: BusCounts, b: BusCounts) -> BusCounts {
    BusCounts {
        port_writes: a.port_writes + b.port_writes,
        port_reads: a.port_reads + b.port_reads,
        vram_writes: a.vram_writes + b.vram_writes,
        vram_reads: a.vram_reads + b.vram_reads,
    }
}

fn sub(a: BusCounts, b: BusCounts) -> BusCounts {
    BusCounts {
        port_writes: a.port_writes - b.port_writes,
        port_reads: a.port_reads - b.port_reads,
        vram_writes: a.vram_writes - b.vram_writes,
        vram_reads: a.vram_reads - b.vram_reads,
    }
}

/// The page as the VGA holds it, read straight from the model's planes.
fn page_image(soft: &SoftVga, page: Page) -> Vec<u8> {
    (0..PAGE_PIXELS)
        .map(|i| soft.plane(i % 4)[usize::from(page.base()) + i / 4])
        .collect()
}

/// The distinct Map Mask values a frame's writes need, at the fewest: each
/// write's planes are the changed pixels of one new colour at one address.
/// (The writes themselves are counted by `sim::inspector::lower_bound`, the
/// figure the web page's inspector shows.)
fn masks_needed(old: &[u8], new: &[u8]) -> u64 {
    let mut masks = 0u16;
    for (o, n) in old.as_chunks::<4>().0.iter().zip(new.as_chunks::<4>().0) {
        for p in (0..4).filter(|&p| o[p] != n[p]) {
            let planes = (0..4)
                .filter(|&q| o[q] != n[q] && n[q] == n[p])
                .fold(0u16, |m, q| m | 1 << q);
            masks |= 1 << planes;
        }
    }
    u64::from(masks.count_ones())
}

/// Renders the set with `drawer`; returns its totals and, if asked (only for
/// our renderer), the
/// lower bounds summed over the frames: video-memory writes, and those plus
/// one Map Mask write per distinct mask each frame needs.
fn run<D: FrameDrawer>(
    mut drawer: D,
    frames: &[Option<SceneCommand>],
    with_bound: bool,
) -> (Totals, u64, u64) {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    let mut scene = Scene::new();
    let mut expected = Box::new([0u8; PAGE_PIXELS]);
    let mut totals = Totals::default();
    let mut bound = 0;
    let mut full_bound = 0;
    let mut shown = Page::Zero;
    for &command in frames {
        if let Some(command) = command {
            scene.apply(command);
        }
        scene.tick();
        let back = shown.other();
        let before_image = with_bound.then(|| page_image(&soft, back));
        let before = soft.counts();
        let start = Instant::now();
        let mut vga = ModeX::new(&mut *soft);
        let page = drawer.draw(&mut vga, &mut scene);
        totals.time += start.elapsed();
        totals.counts = add(totals.counts, sub(soft.counts(), before));
        assert_eq!(page, back);
        // Every method must leave the page showing the frame: ours the
        // depth-tested one, the other two (run without the bound) the one
        // painted far to near, which they draw.
        if with_bound {
            render_to_image(&mut scene, &mut expected);
        } else {
            render_painter(&mut scene, &mut expected);
        }
        let after_image = page_image(&soft, back);
        assert!(
            after_image == expected.to_vec(),
            "a renderer drew a wrong frame"
        );
        if let Some(before_image) = before_image {
            let writes = lower_bound(&before_image, &after_image);
            let masks = masks_needed(&before_image, &after_image);
            bound += writes;
            full_bound += writes + masks;
        }
        shown = back;
    }
    (totals, bound, full_bound)
}

fn report(name: &str, totals: &Totals, frames: usize) {
    let per = |n: u64| n as f64 / frames as f64;
    println!(
        "{name:<22} {:>12.1} {:>12.1} {:>12.1} {:>12.1} {:>12.1} {:>10.1}",
        per(totals.counts.vram_writes),
        per(totals.counts.port_writes),
        per(totals.counts.port_reads),
        per(totals.counts.vram_reads),
        per(totals.bus_ops()),
        totals.time.as_secs_f64() * 1e6 / frames as f64,
    );
}

/// What one set of frames showed.
struct Outcome {
    /// Our video-memory writes over their lower bound.
    vram_over_bound: f64,
    /// All our bus operations over the full bound (video-memory lower bound
    /// plus the distinct Map Mask values each frame needs).
    bus_over_full_bound: f64,
    /// Per-pixel's and Abrash's method's bus operations over ours, when run.
    vs_per_pixel: f64,
    vs_original: f64,
}

/// Runs our renderer — and, with `baselines`, the two other methods, which
/// paint far to near and so are right only where the painter's order is —
/// over `frames` and prints a table.
fn compare(title: &str, frames: &[Option<SceneCommand>], baselines: bool) -> Outcome {
    let (ours, bound, full_bound) = run(Renderer::new(), frames, true);
    println!(
        "{title}: {} frames; per frame, drawing only (flips excluded), on the software VGA:",
        frames.len()
    );
    println!(
        "{:<22} {:>12} {:>12} {:>12} {:>12} {:>12} {:>10}",
        "method", "vram writes", "port writes", "port reads", "vram reads", "bus ops", "host µs"
    );
    report("ours (changes only)", &ours, frames.len());
    let (mut vs_per_pixel, mut vs_original) = (f64::NAN, f64::NAN);
    if baselines {
        let (original, _, _) = run(OriginalMethod::default(), frames, false);
        let (per_pixel, _, _) = run(PerPixel::default(), frames, false);
        report("Abrash's method (b)", &original, frames.len());
        report("per-pixel (a)", &per_pixel, frames.len());
        vs_per_pixel = per_pixel.bus_ops() as f64 / ours.bus_ops() as f64;
        vs_original = original.bus_ops() as f64 / ours.bus_ops() as f64;
    }
    let per = |n: u64| n as f64 / frames.len() as f64;
    println!("{:<22} {:>12.1}", "lower bound (vram)", per(bound));
    println!(
        "{:<22} {:>12.1} {:>12.1} {:>38.1}",
        "full bound",
        per(bound),
        per(full_bound - bound),
        per(full_bound)
    );
    println!();
    Outcome {
        vram_over_bound: ours.counts.vram_writes as f64 / bound as f64,
        bus_over_full_bound: ours.bus_ops() as f64 / full_bound as f64,
        vs_per_pixel,
        vs_original,
    }
}

/// The three objects with the cube driven into the octahedron's orbit, so
/// that they pass through each other, for two revolutions of the octahedron;
/// then the letter L and the beams in the cube's place.
fn interpenetrating_set() -> Vec<Option<SceneCommand>> {
    let mut frames = vec![Some(SceneCommand::ToggleSeveral)];
    frames.extend(std::iter::repeat_n(Some(SceneCommand::MoveRight), 14));
    frames.extend(vec![None; 720]);
    for _ in 0..6 {
        frames.push(Some(SceneCommand::NextSolid));
    }
    frames.extend(vec![None; 120]);
    frames.push(Some(SceneCommand::NextSolid));
    frames.extend(vec![None; 120]);
    frames
}

/// The crowd (X): 59 solids, flat colours for 300 frames, then lit.
fn crowd_set() -> Vec<Option<SceneCommand>> {
    let mut frames = vec![Some(SceneCommand::ToggleCrowd)];
    frames.extend(vec![None; 300]);
    frames.push(Some(SceneCommand::ToggleLighting));
    frames.extend(vec![None; 300]);
    frames
}

fn main() {
    let cube = compare("The cube", &cube_set(), true);
    let extras = compare("Three lit solids", &extras_set(), true);
    let through = compare("Interpenetrating solids", &interpenetrating_set(), false);
    let crowd = compare("The crowd of 59 solids", &crowd_set(), false);
    println!(
        "SUMMARY vram_writes_over_bound={:.3} bus_ops_over_full_bound={:.3} \
         bus_ops_vs_per_pixel={:.2} bus_ops_vs_abrash_method={:.2} \
         extras_vram_writes_over_bound={:.3} extras_bus_ops_over_full_bound={:.3} \
         extras_bus_ops_vs_per_pixel={:.2} extras_bus_ops_vs_abrash_method={:.2} \
         interpenetrating_vram_writes_over_bound={:.3} \
         interpenetrating_bus_ops_over_full_bound={:.3} \
         crowd_vram_writes_over_bound={:.3} crowd_bus_ops_over_full_bound={:.3}",
        cube.vram_over_bound,
        cube.bus_over_full_bound,
        cube.vs_per_pixel,
        cube.vs_original,
        extras.vram_over_bound,
        extras.bus_over_full_bound,
        extras.vs_per_pixel,
        extras.vs_original,
        through.vram_over_bound,
        through.bus_over_full_bound,
        crowd.vram_over_bound,
        crowd.bus_over_full_bound,
    );
}
