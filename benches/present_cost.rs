//! What each page flip costs on the framebuffer path, in bytes written to
//! the framebuffer.
//!
//! `cargo bench --bench present_cost` runs the demo (`demo::app::App`, as the
//! kernel does) over the frame sets of `bus_cost` — the cube's spin, moves,
//! zooms and off-screen states, and three lit solids circling — on a
//! software VGA mirrored to two framebuffers of the same layout: one gets a
//! full present each flip (what the kernel did before: every pixel, borders
//! included), the other only the changes (`Presenter`). After every flip the
//! two framebuffers must be equal. It reports, per frame, the bytes each
//! writes, the picture pixels that changed, the picture pixels the presenter
//! scanned out and compared to find them, and the bytes a still scene
//! costs, at 1280x800 and 1920x1080 (4 bytes a pixel, as GOP gives). The
//! last line is machine-readable.

mod frame_sets;

use demo::app::App;
use demo::scene::SceneCommand;
use frame_sets::{cube_set, extras_set};
use modex::present::{present, FramebufferLayout, PixelOrder, Presenter, MAX_PICTURE_PIXELS};
use modex::soft::SoftVga;
use modex::{MirroredVga, ModeX, PAGE_PIXELS};
use std::time::{Duration, Instant};

#[derive(Default)]
struct Costs {
    presents: u64,
    full_bytes: u64,
    changes_bytes: u64,
    changes_max: u64,
    changed_pixels: u64,
    scanned_pixels: u64,
    full_time: Duration,
    changes_time: Duration,
}

/// Runs `frames` at `width` x `height`; returns the costs of the flips after
/// the first present (which writes everything either way) and the bytes a
/// present of the unchanged last frame writes.
fn run(frames: &[Option<SceneCommand>], width: usize, height: usize) -> (Costs, usize) {
    let layout = FramebufferLayout {
        width,
        height,
        stride: width,
        bytes_per_pixel: 4,
        order: PixelOrder::Bgr,
    };
    let mut full_fb = vec![0u8; layout.required_bytes()];
    let mut changes_fb = vec![0u8; layout.required_bytes()];
    let mut scratch = vec![0u8; MAX_PICTURE_PIXELS];
    let mut presenter = Box::new(Presenter::new());
    let mut last_picture = vec![0u8; PAGE_PIXELS];
    let mut picture = vec![0u8; PAGE_PIXELS];
    let mut costs = Costs::default();
    let mut soft = Box::new(SoftVga::new());
    let mut first = true;
    let mirror = MirroredVga::new(&mut soft, |soft: &SoftVga| {
        let start = Instant::now();
        present(soft, &mut scratch, &layout, &mut full_fb);
        let full_time = start.elapsed();
        let start = Instant::now();
        let report = presenter.present(soft, &layout, &mut changes_fb);
        let changes_time = start.elapsed();
        assert!(
            full_fb == changes_fb,
            "presenting changes left another picture"
        );
        soft.scanout_indices(&mut picture);
        if !std::mem::take(&mut first) {
            costs.presents += 1;
            costs.full_bytes += layout.required_bytes() as u64;
            costs.changes_bytes += report.bytes_written as u64;
            costs.changes_max = costs.changes_max.max(report.bytes_written as u64);
            costs.scanned_pixels += report.pixels_scanned as u64;
            costs.changed_pixels += picture
                .iter()
                .zip(&last_picture)
                .filter(|(a, b)| a != b)
                .count() as u64;
            costs.full_time += full_time;
            costs.changes_time += changes_time;
        }
        last_picture.copy_from_slice(&picture);
    });
    let mut vga = ModeX::new(mirror);
    vga.set_mode();
    let mut app = App::new();
    for &command in frames {
        if let Some(command) = command {
            app.apply(command.into());
        }
        app.step(&mut vga, &|| 0u64);
    }
    // The mirror (and with it the closure's borrows) ends here.
    let _ = vga.into_bus();
    let still = presenter
        .present(&soft, &layout, &mut changes_fb)
        .bytes_written;
    (costs, still)
}

fn main() {
    println!("bytes written to the framebuffer per flip (4 bytes a pixel), host software VGA");
    println!(
        "{:<18} {:>10} {:>7} {:>12} {:>12} {:>12} {:>10} {:>10} {:>9} {:>9} {:>7}",
        "set",
        "screen",
        "flips",
        "full",
        "changes",
        "changes max",
        "changed px",
        "scanned px",
        "full µs",
        "chg µs",
        "still"
    );
    let mut summary = Vec::new();
    for (name, frames) in [("cube", cube_set()), ("three lit solids", extras_set())] {
        for (width, height) in [(1280, 800), (1920, 1080)] {
            let (costs, still) = run(&frames, width, height);
            let per = |n: u64| n as f64 / costs.presents as f64;
            let micros = |d: Duration| d.as_secs_f64() * 1e6 / costs.presents as f64;
            println!(
                "{:<18} {:>10} {:>7} {:>12.0} {:>12.0} {:>12} {:>10.0} {:>10.0} {:>9.0} {:>9.0} {:>7}",
                name,
                format!("{width}x{height}"),
                costs.presents,
                per(costs.full_bytes),
                per(costs.changes_bytes),
                costs.changes_max,
                per(costs.changed_pixels),
                per(costs.scanned_pixels),
                micros(costs.full_time),
                micros(costs.changes_time),
                still
            );
            summary.push(format!(
                "{}_{width}x{height}_bytes_full={:.0} {}_{width}x{height}_bytes_changes={:.0} {}_{width}x{height}_still={still}",
                name.replace(' ', "_"),
                per(costs.full_bytes),
                name.replace(' ', "_"),
                per(costs.changes_bytes),
                name.replace(' ', "_"),
            ));
        }
    }
    println!("SUMMARY {}", summary.join(" "));
}
