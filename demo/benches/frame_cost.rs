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
//! The last line is machine-readable.
//!
//! Timings on a busy machine wander; instruction counts do not.
//! `demo/benches/frame_instructions.sh` runs one scene at a time under
//! Valgrind (`FRAME_COST_SCENE` names it, `FRAME_COST_FRAMES` sets the frames
//! of its single run) and reports the instructions per frame.

use demo::frame::{FrameDrawer, Renderer};
use demo::scene::{Scene, SceneCommand};
use modex::regs::Port;
use modex::{ModeX, VgaBus};
use std::hint::black_box;
use std::time::{Duration, Instant};

const FRAMES: u32 = 360;
const RUNS: usize = 9;

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

fn main() {
    let scenes: [(&str, &str, &[SceneCommand]); 4] = [
        ("the starting cube", "cube", &[]),
        (
            "three lit solids",
            "three",
            &[SceneCommand::ToggleSeveral, SceneCommand::ToggleLighting],
        ),
        ("the letter L", "letter_l", &[SceneCommand::NextSolid; 5]),
        ("the crowd", "crowd", &[SceneCommand::ToggleCrowd]),
    ];
    let mut renderer = Box::new(Renderer::new());
    if let Ok(only) = std::env::var("FRAME_COST_SCENE") {
        let frames = match std::env::var("FRAME_COST_FRAMES") {
            Ok(frames) => frames
                .parse()
                .unwrap_or_else(|_| panic!("FRAME_COST_FRAMES={frames:?} is not a count")),
            Err(_) => FRAMES,
        };
        let Some((_, _, commands)) = scenes.iter().find(|(_, key, _)| *key == only) else {
            let keys: Vec<&str> = scenes.iter().map(|(_, key, _)| *key).collect();
            panic!("FRAME_COST_SCENE={only:?} is none of {keys:?}");
        };
        run(&mut renderer, commands, frames);
        return;
    }
    println!("CPU time per frame of Renderer::draw on this host, no bus ({RUNS} runs of {FRAMES} frames):");
    println!("{:<20} {:>12} {:>12}", "scene", "fastest µs", "median µs");
    let mut summary = Vec::new();
    for (name, key, commands) in scenes {
        let mut runs: Vec<Duration> = (0..RUNS)
            .map(|_| run(&mut renderer, commands, FRAMES))
            .collect();
        runs.sort();
        let micros = |d: Duration| d.as_secs_f64() * 1e6;
        let (fastest, median) = (micros(runs[0]), micros(runs[RUNS / 2]));
        println!("{name:<20} {fastest:>12.2} {median:>12.2}");
        summary.push(format!("{key}={fastest:.2}/{median:.2}"));
    }
    println!("SUMMARY fastest/median_us {}", summary.join(" "));
}
