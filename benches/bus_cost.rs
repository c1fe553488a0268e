//! What every frame costs on the VGA bus, measured on the software VGA.
//!
//! `cargo bench --bench bus_cost` renders a fixed set of frames — a 360-frame
//! spin, then moved, zoomed and partly off-screen states — three ways: our
//! renderer, the seed's method (erase the last extent, fill every visible face
//! with Map Mask spans) and per-pixel drawing with a Map Mask OUT per pixel.
//! Per frame it counts the bus operations of drawing (flips excluded: they
//! cost the same for all three) and the lower bound on video-memory writes:
//! for each address of the page, the number of distinct new colours among its
//! pixels that must change. A second set does the same for the extras: three
//! lit solids circling and spinning, drawn far to near. The last line is
//! machine-readable.

use demo::baseline::{PerPixel, SeedMethod};
use demo::frame::{render_to_image, FrameDrawer, Renderer};
use demo::scene::{Axis, Command, Scene};
use modex::soft::{BusCounts, SoftVga};
use modex::{ModeX, Page, PAGE_PIXELS};
use std::time::{Duration, Instant};

/// One frame of the set: a command first, or none (the spin alone).
fn frame_set() -> Vec<Option<Command>> {
    let mut frames: Vec<Option<Command>> = vec![None; 360];
    let mut repeat =
        |command: Command, times: usize| frames.extend(std::iter::repeat_n(Some(command), times));
    repeat(Command::ToggleSpin, 1);
    repeat(Command::Rotate(Axis::X, true), 4);
    repeat(Command::MoveLeft, 45); // past the left edge
    repeat(Command::MoveUp, 30); // and the top
    repeat(Command::MoveRight, 90); // across to the right edge
    repeat(Command::MoveDown, 60);
    repeat(Command::Toward, 22); // as close as it goes
    repeat(Command::Away, 60); // and far away
    repeat(Command::Rotate(Axis::Z, true), 30);
    frames
}

/// The extras: three objects, lit, spinning and circling for a full orbit of
/// the nearer satellite, then the other solids in the cube's place.
fn extras_set() -> Vec<Option<Command>> {
    let mut frames = vec![Some(Command::ToggleSeveral), Some(Command::ToggleLighting)];
    frames.extend(vec![None; 360]);
    for _ in 0..4 {
        frames.push(Some(Command::NextSolid));
        frames.extend(vec![None; 60]);
    }
    frames
}

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

/// Σ over addresses of the distinct new colours among changed pixels.
fn lower_bound(old: &[u8], new: &[u8]) -> u64 {
    old.as_chunks::<4>()
        .0
        .iter()
        .zip(new.as_chunks::<4>().0)
        .map(|(o, n)| {
            let mut colours: Vec<u8> = (0..4).filter(|&p| o[p] != n[p]).map(|p| n[p]).collect();
            colours.sort_unstable();
            colours.dedup();
            colours.len() as u64
        })
        .sum()
}

/// Renders the set with `drawer`; returns its totals and, if asked, the
/// lower bound summed over the frames.
fn run<D: FrameDrawer>(
    mut drawer: D,
    frames: &[Option<Command>],
    with_bound: bool,
) -> (Totals, u64) {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    let mut scene = Scene::new();
    let mut expected = Box::new([0u8; PAGE_PIXELS]);
    let mut totals = Totals::default();
    let mut bound = 0;
    let mut shown = Page(0);
    for &command in frames {
        if let Some(command) = command {
            scene.apply(command);
        }
        scene.tick();
        let back = Page(1 - shown.0);
        let before_image = with_bound.then(|| page_image(&soft, back));
        let before = soft.counts();
        let start = Instant::now();
        let mut vga = ModeX::new(&mut *soft);
        let page = drawer.draw(&mut vga, &mut scene);
        totals.time += start.elapsed();
        totals.counts = add(totals.counts, sub(soft.counts(), before));
        assert_eq!(page, back);
        // Every method must leave the page showing the frame.
        render_to_image(&mut scene, &mut expected);
        let after_image = page_image(&soft, back);
        assert!(
            after_image == expected.to_vec(),
            "a renderer drew a wrong frame"
        );
        if let Some(before_image) = before_image {
            bound += lower_bound(&before_image, &after_image);
        }
        shown = back;
    }
    (totals, bound)
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

/// Runs the three methods over `frames` and prints a table; returns
/// (ours over the bound, per-pixel over ours, seed method over ours).
fn compare(title: &str, frames: &[Option<Command>]) -> (f64, f64, f64) {
    let (ours, bound) = run(Renderer::new(), frames, true);
    let (seed, _) = run(SeedMethod::default(), frames, false);
    let (per_pixel, _) = run(PerPixel::default(), frames, false);

    println!(
        "{title}: {} frames; per frame, drawing only (flips excluded), on the software VGA:",
        frames.len()
    );
    println!(
        "{:<22} {:>12} {:>12} {:>12} {:>12} {:>12} {:>10}",
        "method", "vram writes", "port writes", "port reads", "vram reads", "bus ops", "host µs"
    );
    report("ours (changes only)", &ours, frames.len());
    report("seed method (b)", &seed, frames.len());
    report("per-pixel (a)", &per_pixel, frames.len());
    println!(
        "{:<22} {:>12.1}",
        "lower bound",
        bound as f64 / frames.len() as f64
    );
    println!();
    (
        ours.counts.vram_writes as f64 / bound as f64,
        per_pixel.bus_ops() as f64 / ours.bus_ops() as f64,
        seed.bus_ops() as f64 / ours.bus_ops() as f64,
    )
}

fn main() {
    let (over_bound, vs_per_pixel, vs_seed) = compare("The cube", &frame_set());
    let (extras_over_bound, extras_vs_per_pixel, extras_vs_seed) =
        compare("Three lit solids", &extras_set());
    println!(
        "SUMMARY vram_writes_over_bound={over_bound:.3} bus_ops_vs_per_pixel={vs_per_pixel:.2} \
         bus_ops_vs_seed_method={vs_seed:.2} extras_vram_writes_over_bound={extras_over_bound:.3} \
         extras_bus_ops_vs_per_pixel={extras_vs_per_pixel:.2} \
         extras_bus_ops_vs_seed_method={extras_vs_seed:.2}"
    );
}
