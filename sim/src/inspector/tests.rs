use super::*;
use crate::keys::scancode_for_name;
use crate::machine::Machine;
use modex::regs::{Graphics, Sequencer};

fn tap(machine: &mut Machine, name: &str) {
    machine.tap(scancode_for_name(name).unwrap());
}

#[test]
fn the_figures_are_the_soft_vgas_counts_for_the_same_frames() {
    let mut machine = Machine::new();
    let mut history = History::default();
    let mut drawn_frames = 0;
    for frame in 0..40 {
        match frame {
            10 => tap(&mut machine, "m"),
            20 => tap(&mut machine, "l"),
            30 => tap(&mut machine, "spc"), // the spin stops: idle frames follow
            _ => {}
        }
        let before = machine.vga().counts();
        let cost = machine.frame();
        let after = machine.vga().counts();
        history.push(cost);
        assert_eq!(cost.vram_writes, after.vram_writes - before.vram_writes);
        assert_eq!(cost.port_writes, after.port_writes - before.port_writes);
        assert!(
            cost.lower_bound <= cost.vram_writes,
            "frame {frame}: {cost:?}"
        );
        drawn_frames += u64::from(cost.vram_writes > 0);
        let lines = text_lines(&vga_state(machine.vga()), &history);
        assert!(
            lines[3].contains(&format!("writes {:>6}", cost.vram_writes)),
            "{lines:?}"
        );
        assert!(
            lines[3].contains(&format!("bound {:>6}", cost.lower_bound)),
            "{lines:?}"
        );
        assert!(
            lines[4].ends_with(&format!("{:>6}", cost.port_writes)),
            "{lines:?}"
        );
    }
    // The spin draws every frame until Space (its frame is drawn too).
    assert_eq!(drawn_frames, 31);
    assert_eq!(history.frames(), 40);
    assert_eq!(history.last().vram_writes, 0);
}

#[test]
fn the_lower_bound_counts_distinct_new_colours_per_address() {
    let old = [0, 0, 0, 0, 5, 5, 5, 5, 1, 2, 3, 4];
    let new = [0, 0, 0, 0, 7, 7, 9, 5, 1, 2, 3, 4];
    // Address 1: pixels 0-2 changed to two colours (7, 9); the others none.
    assert_eq!(lower_bound(&old, &new), 2);
    assert_eq!(lower_bound(&[], &[]), 0);
}

fn planes(planes: &[Vec<u8>]) -> [&[u8]; 4] {
    std::array::from_fn(|plane| planes[plane].as_slice())
}

#[test]
fn the_lower_bound_from_the_planes_is_the_page_images() {
    // Pages with a few changed runs of addresses (as a frame changes them),
    // in one plane or all, at every alignment against the sixteen compared
    // at once, and lengths that are not a multiple of sixteen.
    let mut seed = 0x2545_F491_4F6C_DD1Du64;
    let mut random = move |below: usize| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed % below as u64) as usize
    };
    for addresses in [0, 5, 16, 31, 19_200, 1_001] {
        for _ in 0..20 {
            let old: Vec<Vec<u8>> = (0..4)
                .map(|_| (0..addresses).map(|_| random(4) as u8).collect())
                .collect();
            let mut new = old.clone();
            for _ in 0..random(12) {
                let (start, length) = (random(addresses.max(1)), 1 + random(40));
                // Some runs change one plane alone, some all four.
                let plane = random(5);
                let changed = if plane == 4 { 0..4 } else { plane..plane + 1 };
                for plane in changed {
                    for byte in new[plane].iter_mut().skip(start).take(length) {
                        *byte = random(4) as u8;
                    }
                }
            }
            let image = |planes: &[Vec<u8>]| -> Vec<u8> {
                (0..addresses)
                    .flat_map(|address| (0..4).map(move |plane| planes[plane][address]))
                    .collect()
            };
            assert_eq!(
                lower_bound_in_planes(planes(&old), planes(&new)),
                lower_bound(&image(&old), &image(&new)),
                "{addresses} addresses"
            );
        }
    }
}

#[test]
fn the_registers_are_the_soft_vgas() {
    let mut machine = Machine::new();
    for _ in 0..3 {
        machine.frame();
        let vga = machine.vga();
        let state = vga_state(vga);
        assert_eq!(state.start_address, vga.displayed_start());
        assert_eq!(state.shown_page, Some(machine.app().shown_page().index()));
        assert_eq!(state.map_mask, vga.sequencer(Sequencer::MapMask));
        assert_eq!(state.bit_mask, vga.graphics(Graphics::BitMask));
        assert_eq!(state.write_mode, vga.graphics(Graphics::Mode) & 3);
        let lines = text_lines(&state, &History::default());
        assert!(lines[0].contains(&format!("0x{:04X}", state.start_address)));
    }
}

#[test]
fn the_plane_images_are_the_shown_pages_bytes_in_their_colours() {
    let mut machine = Machine::new();
    machine.frame();
    let vga = machine.vga();
    let panel = draw_panel(vga, &History::default(), 480);
    assert_eq!((panel.width, panel.height), (PANEL_WIDTH, 480));
    let start = usize::from(vga.displayed_start());
    let picture = machine.scanout_indices();
    for plane in 0..4 {
        for (x, y) in [(0, 0), (40, 120), (79, 239), (33, 100)] {
            let byte = vga.plane(plane)[start + y * 80 + x];
            // The picture's pixel (4x + plane, y) is that byte.
            assert_eq!(picture[y * 320 + 4 * x + plane], byte);
            let [r, g, b] = vga.dac_entry(byte).map(dac_6_to_8);
            let left = MARGIN as usize + plane * (80 + PLANE_GAP as usize);
            let shown = panel.pixels[(PLANES_TOP as usize + y) * panel.width + left + x];
            assert_eq!(shown, u32::from(r) << 16 | u32::from(g) << 8 | u32::from(b));
        }
    }
}

#[test]
fn the_history_keeps_the_plots_frames() {
    let mut history = History::default();
    for n in 0..(PLOT_FRAMES as u64 + 10) {
        history.push(FrameCost {
            vram_writes: n,
            ..FrameCost::default()
        });
    }
    assert_eq!(history.costs().count(), PLOT_FRAMES);
    assert_eq!(history.costs().next().unwrap().vram_writes, 10);
    assert_eq!(history.frames(), PLOT_FRAMES as u64 + 10);
}

/// A history of `frames` frames, each costing `cost` of everything.
fn history_of(frames: u64, cost: u64) -> History {
    let mut history = History::default();
    for _ in 0..frames {
        history.push(FrameCost {
            vram_writes: cost,
            port_writes: cost / 2,
            lower_bound: cost / 3,
        });
    }
    history
}

#[test]
fn a_panel_redrawn_in_place_is_the_panel_drawn_afresh() {
    let mut machine = Machine::new();
    let mut kept = Panel::inspector(480, Encoding::Xrgb);
    let mut kept_rgba = Panel::inspector(480, Encoding::Rgba);
    // Long figures then short ones, longer text lines then shorter: what
    // the last frame drew must not show through.
    let histories = [
        history_of(PLOT_FRAMES as u64 + 5, 9_876_543),
        history_of(3, 7),
        History::default(),
        history_of(120, 40_000),
    ];
    for (frame, key) in ["m", "x", "l", "spc", "r", "n"].iter().enumerate() {
        tap(&mut machine, key);
        machine.frame();
        let history = &histories[frame % histories.len()];
        let fresh = draw_panel(machine.vga(), history, 480);
        redraw_panel(&mut kept, machine.vga(), history);
        assert!(
            kept.pixels == fresh.pixels,
            "frame {frame}: the kept panel differs"
        );
        redraw_panel(&mut kept_rgba, machine.vga(), history);
        let as_rgba: Vec<u32> = fresh
            .pixels
            .iter()
            .map(|&pixel| {
                let [_, r, g, b] = pixel.to_be_bytes();
                u32::from_ne_bytes([r, g, b, 255])
            })
            .collect();
        assert!(kept_rgba.pixels == as_rgba, "frame {frame}: RGBA differs");
    }
}

#[test]
fn a_redraw_changes_only_the_rows_whose_content_changed() {
    let mut machine = Machine::new();
    tap(&mut machine, "m");
    machine.frame();
    let mut history = History::default();
    history.push(machine.last_cost());
    let mut panel = Panel::inspector(480, Encoding::Rgba);
    let mut runs = Vec::new();
    panel.take_changed_rows(&mut runs);
    assert_eq!(runs, vec![0..480], "a new panel is all to show");
    redraw_panel(&mut panel, machine.vga(), &history);
    panel.take_changed_rows(&mut runs);
    assert!(!runs.is_empty());
    // Nothing changed: nothing drawn again.
    redraw_panel(&mut panel, machine.vga(), &history);
    panel.take_changed_rows(&mut runs);
    assert_eq!(runs, [], "an unchanged VGA and history change no row");
    // A frame of the spinning crowd: some plane rows, the frame's line, the
    // plots; never the title or the labels above the planes.
    machine.frame();
    history.push(machine.last_cost());
    redraw_panel(&mut panel, machine.vga(), &history);
    panel.take_changed_rows(&mut runs);
    let rows: usize = runs.iter().map(|run| run.len()).sum();
    assert!(
        runs.iter().all(|run| run.start >= PLANES_TOP as usize),
        "{runs:?}"
    );
    let frame_line = TEXT_TOP as usize + 2 * LINE_HEIGHT as usize;
    assert!(runs.iter().any(|run| run.contains(&frame_line)), "{runs:?}");
    assert!(rows < 480 - PLANES_TOP as usize, "{rows} rows: {runs:?}");
    assert!(
        runs.iter().any(|run| run.start < TEXT_TOP as usize),
        "{runs:?}"
    );
}

#[test]
fn a_start_address_near_the_planes_end_wraps_to_their_start() {
    use modex::regs::{Crtc, Port};
    use modex::VgaBus;
    let mut vga = Box::new(machine_vga());
    // Video memory wraps at 64 KiB: a start 40 bytes before the end puts
    // offset 0 in the middle of the first row. Byte 0 of each plane gets a colour of its
    // own (Map Mask: one plane at a time).
    let start: u16 = 0x1_0000u32.wrapping_sub(40) as u16;
    for plane in 0..4u8 {
        let map_mask = u16::from(1u8 << plane) << 8 | u16::from(Sequencer::MapMask.index());
        vga.write_port16(Port::SEQUENCER_INDEX, map_mask);
        vga.write_vram8(0, 40 + plane);
    }
    let [high, low] = start.to_be_bytes();
    vga.write_port16(
        Port::CRTC_INDEX,
        u16::from(high) << 8 | u16::from(Crtc::StartAddressHigh.index()),
    );
    vga.write_port16(
        Port::CRTC_INDEX,
        u16::from(low) << 8 | u16::from(Crtc::StartAddressLow.index()),
    );
    vga.let_a_frame_pass();
    assert_eq!(vga.displayed_start(), start);
    let panel = draw_panel(&vga, &History::default(), 480);
    for plane in 0..4u8 {
        let [r, g, b] = vga.dac_entry(40 + plane).map(dac_6_to_8);
        let left = MARGIN as usize + usize::from(plane) * (80 + PLANE_GAP as usize);
        let shown = panel.pixels[PLANES_TOP as usize * panel.width + left + 40];
        assert_eq!(
            shown,
            u32::from(r) << 16 | u32::from(g) << 8 | u32::from(b),
            "plane {plane}"
        );
    }
}

fn machine_vga() -> modex::soft::SoftVga {
    Machine::new().vga().clone()
}

#[test]
fn same_bytes_compares_every_byte() {
    let row: Vec<u8> = (0..83).collect();
    assert!(same_bytes(&row, &row.clone()));
    for at in [0, 7, 8, 79, 80, 82] {
        let mut other = row.clone();
        other[at] ^= 1;
        assert!(!same_bytes(&row, &other), "byte {at}");
    }
    assert!(!same_bytes(&row, &row[..82]));
}

#[test]
fn text_from_the_glyph_rows_is_the_text_renderers() {
    let printable: String = GLYPH_CHARACTERS.map(char::from).collect();
    // Anywhere on the panel, and cut by each of its edges.
    for (x, y) in [(8, 2), (-3, -4), (400 - 6 * 3 - 2, 100), (-7, 470 - 6)] {
        let mut fast = Panel::inspector(470, Encoding::Xrgb);
        let mut rendered = fast.clone();
        fast.text(&printable, x, y, VRAM_COLOUR);
        rendered.text_by_renderer(&printable, x, y, VRAM_COLOUR);
        assert!(fast.pixels == rendered.pixels, "at ({x}, {y})");
        // Each glyph has pixels, so a glyph left out would be seen.
        assert!(glyph_rows()[1..]
            .iter()
            .all(|rows| rows.iter().any(|&bits| bits != 0)));
    }
    // Text outside printable ASCII goes to the renderer, as it did.
    let mut fast = Panel::inspector(470, Encoding::Rgba);
    let mut rendered = fast.clone();
    fast.text("µs ± 5 °", 20, 30, TEXT);
    rendered.text_by_renderer("µs ± 5 °", 20, 30, TEXT);
    assert!(fast.pixels == rendered.pixels);
}

#[test]
fn a_plot_is_a_bar_and_a_point_a_frame_newest_on_the_right() {
    let mut history = History::default();
    // The largest value is the plot's top; the frame before it is half.
    for (vram_writes, lower_bound) in [(550, 110), (1_100, 0)] {
        history.push(FrameCost {
            vram_writes,
            lower_bound,
            ..FrameCost::default()
        });
    }
    let mut panel = Panel::inspector(470, Encoding::Xrgb);
    let vram = |cost: &FrameCost| cost.vram_writes;
    let bound = |cost: &FrameCost| cost.lower_bound;
    draw_plot(
        &mut panel,
        &history,
        BUS_PLOT_TOP,
        [(vram, VRAM_COLOUR), (bound, BOUND_COLOUR)],
    );
    let pack = |colour| Encoding::Xrgb.pack(rgb(colour));
    let bottom = (BUS_PLOT_TOP + PLOT_HEIGHT - 1) as usize;
    let at = |x: usize, y: usize| panel.pixels[y * panel.width + x];
    // Columns with no frame: the axis, nothing above it.
    let first = MARGIN as usize;
    assert_eq!(at(first, bottom), pack(AXIS_COLOUR));
    assert_eq!(at(first, bottom - 1), pack(BACKGROUND));
    // The newest frame, rightmost: a bar of the full height (55 rows over
    // the bottom one), its bound (0) a point on the bottom row over it.
    let newest = first + PLOT_FRAMES - 1;
    assert_eq!(at(newest, bottom), pack(BOUND_COLOUR));
    assert!((bottom - 55..bottom).all(|y| at(newest, y) == pack(VRAM_COLOUR)));
    // The frame before: half the height (27 rows), its bound a fifth of
    // that (550 and 110 of 1,100, of 55 rows: 27 and 5), background above.
    let before = newest - 1;
    assert_eq!(at(before, bottom - 5), pack(BOUND_COLOUR));
    assert!((bottom - 27..=bottom).all(|y| y == bottom - 5 || at(before, y) == pack(VRAM_COLOUR)));
    assert_eq!(at(before, bottom - 28), pack(BACKGROUND));
}
