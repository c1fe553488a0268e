//! Where 60 fps breaks on the simulator's ISA-speed VGA: the kernel bench's
//! growing grid (`demo::grid`), its pages brought up to date on the software
//! VGA, whose clock charges every port access 1 µs and every byte of video
//! memory 100 ns (`modex::soft::timing`), as the simulator's statistics do.
//! The host's own time does not count: this is the bus alone, the same on
//! any machine.
//!
//! `cargo bench --bench grid_on_isa` prints each size measured and the
//! largest whose frame's bus time fits one refresh, by the same search as
//! the kernel's (`demo::scale`).

use demo::frame::BACKGROUND;
use demo::grid::Grid;
use engine::DepthBuffer;
use modex::soft::SoftVga;
use modex::{ModeX, Page, PageSpans, PAGE_PIXELS};

const LIMIT: usize = 1024;
const FRAMES: u64 = 30;

fn main() {
    let mut grid: Box<Grid<LIMIT>> = Box::default();
    let mut depths = Box::new(DepthBuffer::new());
    let mut next = Box::new([BACKGROUND; PAGE_PIXELS]);
    let mut drawn = Box::new(PageSpans::none());
    let mut soft = Box::new(SoftVga::new());
    let found = demo::scale::largest_that_fits(16, LIMIT, clock::pacing::FRAME_MICROS, |count| {
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut shadows = Box::new([[BACKGROUND; PAGE_PIXELS]; 2]);
        let mut held = Box::new([PageSpans::none(), PageSpans::none()]);
        next.fill(BACKGROUND);
        drawn.clear();
        grid.reset(count);
        let mut page = Page::Zero;
        let mut frame = |vga: &mut ModeX<&mut SoftVga>| {
            page = page.other();
            grid.tick();
            grid.render(&mut next, &mut drawn, &mut depths);
            // What the page held and what the frame drew: as the renderer.
            let held = &mut held[usize::from(page.index())];
            held.add(&drawn);
            let written =
                vga.update_page(page, &mut shadows[usize::from(page.index())], &next, held);
            held.clone_from(&drawn);
            written
        };
        // As in the kernel: two frames onto the blank pages first.
        frame(&mut vga);
        frame(&mut vga);
        let start = vga.bus().now_ns();
        let mut bytes = 0u64;
        let mut slowest = 0;
        for _ in 0..FRAMES {
            let before = vga.bus().now_ns();
            bytes += u64::from(frame(&mut vga));
            slowest = slowest.max(vga.bus().now_ns() - before);
        }
        let mean = (vga.bus().now_ns() - start) / FRAMES / 1000;
        println!(
            "grid of {count:4} solids: bus {mean:5} us/frame (slowest {:5} us), {} bytes",
            slowest / 1000,
            bytes / FRAMES
        );
        mean
    });
    match (found.fits, found.misses) {
        (Some(fits), Some(misses)) => println!(
            "SUMMARY largest_grid_at_60fps_isa={} (next measured: {} solids, {} us)",
            fits.count, misses.count, misses.micros
        ),
        (Some(fits), None) => println!(
            "SUMMARY largest_grid_at_60fps_isa>={} (every size up to the bench's {LIMIT} fits; {} us at {})",
            fits.count, fits.micros, fits.count
        ),
        (None, _) => println!("SUMMARY largest_grid_at_60fps_isa=0"),
    }
}
