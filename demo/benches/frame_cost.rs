//! What the renderer's frame costs the CPU, on the host, without the bus.
//!
//! `cargo bench -p demo --bench frame_cost` spins four scenes — the starting
//! cube, three lit solids, the letter L (not convex, so the depth test runs
//! on its rows) and the crowd (the depth test everywhere) — and times
//! `Renderer::draw` per frame on a VGA that drops every write: the scene's
//! faces, the depth policy's drawing into the RAM frame, and comparing that
//! frame with the page's shadow, but no bus. Each scene is timed over several
//! runs of 360 frames; the fastest run is the figure least disturbed by other
//! work on the machine, and the median shows the spread. Host figures only:
//! they compare two versions of the code on one machine, not what a PC takes.
//! The last line is machine-readable. A fifth scene, the kernel bench's grid
//! of 1,024 turning solids (`demo::grid`, `Grid::render` into the RAM frame
//! only, as the bench times its drawing), shows a small solid's cost.
//!
//! Timings on a busy machine wander; instruction counts do not.
//! `demo/benches/frame_instructions.sh` runs one scene at a time under
//! Valgrind (`FRAME_COST_SCENE` names it, `FRAME_COST_FRAMES` sets the frames
//! of its single run) and reports the instructions per frame.

use demo::frame::{FrameDrawer, Renderer};
use demo::grid::Grid;
use demo::scene::{Scene, SceneCommand};
use engine::DepthBuffer;
use modex::regs::Port;
use modex::{ModeX, VgaBus};
use modex::{PageSpans, PAGE_PIXELS};
use std::hint::black_box;
use std::time::{Duration, Instant};

const FRAMES: u32 = 360;
const RUNS: usize = 9;
/// The grid's solids: the most the kernel bench holds.
const GRID_SOLIDS: usize = 1024;
/// Frames of a run of the grid, each some thousand times the cube's work.
const GRID_FRAMES: u32 = 60;

/// A VGA that takes every write and answers every read with zero: the
/// renderer's own work without the bus.
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

/// Mean time per frame of one run of `frames` spinning frames.
fn run(renderer: &mut Renderer, commands: &[SceneCommand], frames: u32) -> Duration {
    renderer.reset();
    let mut scene = Scene::new();
    for &command in commands {
        scene.apply(command);
    }
    let mut vga = ModeX::new(NoBus);
    let start = Instant::now();
    for _ in 0..frames {
        scene.tick();
        black_box(renderer.draw(&mut vga, &mut scene));
    }
    start.elapsed() / frames.max(1)
}

/// Mean time per frame of one run of `frames` frames of the grid's drawing.
fn run_grid(grid: &mut Grid<GRID_SOLIDS>, frames: u32) -> Duration {
    let mut image = Box::new([0u8; PAGE_PIXELS]);
    let mut depths = Box::new(DepthBuffer::new());
    let mut drawn = PageSpans::all();
    grid.reset(GRID_SOLIDS);
    let start = Instant::now();
    for _ in 0..frames {
        grid.tick();
        black_box(grid.render(&mut image, &mut drawn, &mut depths));
    }
    start.elapsed() / frames.max(1)
}

/// What a scene of the bench draws: the scene after these commands, through
/// the renderer, or the grid.
#[derive(Clone, Copy)]
enum Workload {
    Scene(&'static [SceneCommand]),
    Grid,
}

/// The fixed state the workloads draw with, built once.
struct Drawers {
    renderer: Box<Renderer>,
    grid: Box<Grid<GRID_SOLIDS>>,
}

impl Drawers {
    /// Mean time per frame of one run of `frames` frames of `workload`.
    fn run(&mut self, workload: Workload, frames: u32) -> Duration {
        match workload {
            Workload::Scene(commands) => run(&mut self.renderer, commands, frames),
            Workload::Grid => run_grid(&mut self.grid, frames),
        }
    }
}

fn main() {
    let scenes: [(&str, &str, Workload); 5] = [
        ("the starting cube", "cube", Workload::Scene(&[])),
        (
            "three lit solids",
            "three",
            Workload::Scene(&[SceneCommand::ToggleSeveral, SceneCommand::ToggleLighting]),
        ),
        (
            "the letter L",
            "letter_l",
            Workload::Scene(&[SceneCommand::NextSolid; 5]),
        ),
        (
            "the crowd",
            "crowd",
            Workload::Scene(&[SceneCommand::ToggleCrowd]),
        ),
        ("grid, 1,024 solids", "grid", Workload::Grid),
    ];
    let mut drawers = Drawers {
        renderer: Box::new(Renderer::new()),
        grid: Box::default(),
    };
    if let Ok(only) = std::env::var("FRAME_COST_SCENE") {
        let frames = match std::env::var("FRAME_COST_FRAMES") {
            Ok(frames) => frames
                .parse()
                .unwrap_or_else(|_| panic!("FRAME_COST_FRAMES={frames:?} is not a count")),
            Err(_) => FRAMES,
        };
        let Some(&(_, _, workload)) = scenes.iter().find(|(_, key, _)| *key == only) else {
            let keys: Vec<&str> = scenes.iter().map(|(_, key, _)| *key).collect();
            panic!("FRAME_COST_SCENE={only:?} is none of {keys:?}");
        };
        drawers.run(workload, frames);
        return;
    }
    println!("CPU time per frame of Renderer::draw (the grid: Grid::render) on this host, no bus ({RUNS} runs of {FRAMES} frames, the grid's of {GRID_FRAMES}):");
    println!("{:<20} {:>12} {:>12}", "scene", "fastest µs", "median µs");
    let mut summary = Vec::new();
    for (name, key, workload) in scenes {
        let frames = match workload {
            Workload::Scene(_) => FRAMES,
            Workload::Grid => GRID_FRAMES,
        };
        let mut runs: Vec<Duration> = (0..RUNS).map(|_| drawers.run(workload, frames)).collect();
        runs.sort();
        let micros = |d: Duration| d.as_secs_f64() * 1e6;
        let (fastest, median) = (micros(runs[0]), micros(runs[RUNS / 2]));
        println!("{name:<20} {fastest:>12.2} {median:>12.2}");
        summary.push(format!("{key}={fastest:.2}/{median:.2}"));
    }
    println!("SUMMARY fastest/median_us {}", summary.join(" "));
}
