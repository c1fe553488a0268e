//! The register lab against the software VGA driven by hand: the same
//! port writes give the same registers and picture.

use super::*;
use crate::page::Page;
use modex::regs::Sequencer;
use modex::VgaBus;
use sim::machine::Machine;

/// The picture of `vga` as RGBA, as the page shows it.
fn rgba(vga: &SoftVga) -> Vec<u8> {
    let mut pixels = vec![[0; 3]; 320 * 240];
    assert_eq!(vga.scanout_rgb(&mut pixels), (320, 240));
    pixels
        .iter()
        .flat_map(|&[r, g, b]| [r, g, b, 255])
        .collect()
}

fn all_values(vga: &SoftVga) -> Vec<u32> {
    Register::all().map(|r| r.value(vga)).collect()
}

#[test]
fn every_register_has_one_key_that_names_it_again() {
    let registers: Vec<Register> = Register::all().collect();
    // Misc, 5 + 25 + 9 + 21, the pixel mask and 256 DAC entries.
    assert_eq!(registers.len(), 1 + 5 + 25 + 9 + 21 + 1 + 256);
    let mut keys: Vec<String> = registers.iter().map(|r| r.key()).collect();
    for (register, key) in registers.iter().zip(&keys) {
        assert_eq!(Register::from_key(key), Some(*register), "{key}");
    }
    keys.sort();
    keys.dedup();
    assert_eq!(keys.len(), registers.len());
    assert_eq!(Register::Crtc(Crtc::Offset).key(), "crtc.13");
    assert_eq!(Register::Sequencer(Sequencer::MapMask).name(), "Map Mask");
    for bad in ["crtc.19", "misc.01", "seq", "seq.2", "xyz.00", "dac.100"] {
        assert_eq!(Register::from_key(bad), None, "{bad}");
    }
}

#[test]
fn mode_x_syncs_and_timings_a_monitor_would_not_take_are_named() {
    let mut vga = Box::new(SoftVga::new());
    modex::ModeX::new(&mut *vga).set_mode();
    let (horizontal, vertical) = sync_rates(&vga.timing());
    assert!((31_400.0..31_500.0).contains(&horizontal), "{horizontal}");
    assert!((59.0..61.0).contains(&vertical), "{vertical}");
    assert_eq!(monitor_problem(&vga.timing()), None);
    let lab = Lab::default();
    assert!(!table(&vga, &lab)
        .lines()
        .any(|line| line.ends_with("monitor")));

    // The 28 MHz clock on Mode X's 800-dot lines: 35.4 kHz.
    let mut fast = vga.clone();
    for access in port_accesses(&fast, Register::MiscOutput, 0xE7) {
        if let PortAccess::Write(port, value) = access {
            fast.write_port8(port, value);
        }
    }
    let problem = monitor_problem(&fast.timing()).expect("28 MHz is marked");
    assert!(problem.contains("horizontal 35.40 kHz"), "{problem}");

    // Horizontal Total 0x2F: 52 characters a line, 60.5 kHz and 114.8 Hz.
    let mut lab = Lab::default();
    let before = Register::Crtc(Crtc::HorizontalTotal).value(&vga);
    for access in port_accesses(&vga, Register::Crtc(Crtc::HorizontalTotal), 0x2F) {
        if let PortAccess::Write(port, value) = access {
            vga.write_port8(port, value);
        }
    }
    assert_eq!(
        vga.crtc(Crtc::HorizontalTotal),
        0x2F,
        "written past the protection"
    );
    lab.note(Register::Crtc(Crtc::HorizontalTotal), before, 0x2F);
    let table = table(&vga, &lab);
    let marked: Vec<&str> = table.lines().filter(|line| !line.ends_with('\t')).collect();
    assert_eq!(marked.len(), 1, "{marked:?}");
    assert!(marked[0].starts_with("crtc.00\tCRTC\t00\tHorizontal Total\t2F\t"));
    assert!(marked[0].contains("vertical 114.8 Hz"), "{}", marked[0]);
}

#[test]
fn an_edit_is_the_port_writes_a_program_makes_and_back_to_mode_x_undoes_it() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?paused=1");
        let before_values = all_values(page.vga());
        let before_picture = page.screen_rgba().to_vec();
        // By hand on a copy of the same VGA: Offset 0x50 (a line of 160
        // bytes), start address 0x1234, with 16-bit OUTs to the CRTC.
        let mut by_hand = Box::new(page.vga().clone());
        for (index, value) in [(0x13u8, 0x50u8), (0x0C, 0x12), (0x0D, 0x34)] {
            by_hand.write_port16(Port::CRTC_INDEX, u16::from_le_bytes([index, value]));
        }
        by_hand.let_a_frame_pass();
        let writes_before = page.vga().counts().port_writes;
        assert!(page.lab_edit("crtc.13", "50"));
        assert!(page.lab_edit("crtc.0c", "0x12"));
        assert!(page.lab_edit("crtc.0d", "34"));
        assert_eq!(page.vga().counts().port_writes - writes_before, 6);
        assert_eq!(page.vga().displayed_start(), 0x1234);
        assert!(
            page.screen_rgba() == rgba(&by_hand),
            "the picture is the VGA's by hand"
        );
        assert!(page.screen_rgba() != before_picture);
        assert_eq!(page.lab_url_value(), "crtc.13:50,crtc.0c:12,crtc.0d:34");
        let export = page.lab_export();
        assert!(export.starts_with("register,index,value\n"));
        assert!(export.contains("\nCRTC Offset,0x13,0x50\n"), "{export}");

        page.lab_restore();
        assert_eq!(
            all_values(page.vga()),
            before_values,
            "every register as it was"
        );
        assert!(
            page.screen_rgba() == before_picture,
            "the picture as it was"
        );
        assert_eq!(page.lab_url_value(), "");
    });
}

#[test]
fn a_bad_edit_is_named_and_changes_nothing() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?paused=1");
        let before = all_values(page.vga());
        assert!(!page.lab_edit("crtc.13", "1FF"));
        assert_eq!(
            page.message(),
            "CRTC Offset: \"1FF\" is not a hex value from 0 to FF"
        );
        assert!(!page.lab_edit("crtc.40", "00"));
        assert!(page.message().contains("no register \"crtc.40\""));
        assert!(!page.lab_edit("dac.03", "404040"));
        assert_eq!(all_values(page.vga()), before);
    });
}

#[test]
fn a_held_map_mask_keeps_the_demos_writes_out_of_the_other_planes() {
    crate::with_big_stack(|| {
        // The cube spins from the start, so that every frame draws and flips.
        let mut page = Page::new("?frames=1");
        while !page.paused() {
            page.animation_frame(1e9);
        }
        assert!(page.lab_edit("seq.02", "01"));
        let before: Vec<Vec<u8>> = (0..4).map(|p| page.vga().plane(p).to_vec()).collect();
        let shown_before = page.vga().displayed_start();
        page.step_frames(1);
        assert_eq!(page.vga().sequencer(Sequencer::MapMask), 0x01, "held");
        let changed: Vec<bool> = (0..4)
            .map(|p| page.vga().plane(p)[..] != before[p][..])
            .collect();
        assert_eq!(changed, [true, false, false, false]);
        assert_ne!(
            page.vga().displayed_start(),
            shown_before,
            "the flips go on"
        );

        // Without the lab the frames reach every plane.
        let mut machine = Machine::new();
        machine.frame();
        let before: Vec<Vec<u8>> = (0..4).map(|p| machine.vga().plane(p).to_vec()).collect();
        machine.frame();
        assert!((0..4).all(|p| machine.vga().plane(p)[..] != before[p][..]));
    });
}

#[test]
fn the_url_carries_the_edits() {
    crate::with_big_stack(|| {
        let mut edited = Page::new("?paused=1");
        assert!(edited.lab_edit("crtc.13", "30"));
        assert!(edited.lab_edit("ac.10", "41"));
        assert!(edited.lab_edit("dac.00", "3F0000"));
        let query = format!("?paused=1&lab={}", edited.lab_url_value());
        let replayed = Page::new(&query);
        assert_eq!(replayed.message(), edited.message());
        assert!(replayed.screen_rgba() == edited.screen_rgba());
        assert_eq!(all_values(replayed.vga()), all_values(edited.vga()));
    });
}

#[test]
fn a_drag_and_a_wheel_are_the_keys_that_turn_and_move() {
    crate::with_big_stack(|| {
        let mut dragged = Page::new("?paused=1");
        // 3.5 turns right, 1 down; the half turn is dropped when the
        // pointer comes up.
        assert_eq!(dragged.drag(40.0, 0.0), 2);
        assert_eq!(dragged.drag(16.0, 17.0), 2);
        dragged.pointer_up(0);
        assert_eq!(dragged.drag(8.0, 0.0), 0, "the rest was dropped");
        // Two fingers from 120 pixels apart to 35: 85 pixels closer, two
        // moves away (A); the rest (5 pixels) goes with the fingers.
        dragged.pointer_down(1, 0.0, 0.0);
        dragged.pointer_down(2, 120.0, 0.0);
        assert_eq!(dragged.pointer_move(2, 35.0, 0.0), 2);
        dragged.pointer_up(1);
        dragged.pointer_up(2);
        // One finger: a drag, 16 pixels up, an 8.
        dragged.pointer_down(3, 50.0, 50.0);
        assert_eq!(dragged.pointer_move(3, 50.0, 34.0), 1);
        dragged.pointer_up(3);
        dragged.step_frames(1);
        let mut keyed = Page::new("?paused=1");
        for code in [
            "Digit6", "Digit6", "Digit6", "Digit2", "KeyA", "KeyA", "Digit8",
        ] {
            keyed.key_down(code);
            keyed.key_up(code);
        }
        keyed.step_frames(1);
        assert!(dragged.screen_rgba() == keyed.screen_rgba());
        let still = Page::new("?paused=1");
        assert!(dragged.screen_rgba() != still.screen_rgba());
    });
}

#[test]
fn the_fields_are_in_the_tables_order() {
    let html = html();
    let keys: Vec<&str> = html
        .split("data-key=\"")
        .skip(1)
        .map(|rest| &rest[..rest.find('"').unwrap()])
        .collect();
    let vga = SoftVga::new();
    let table = table(&vga, &Lab::default());
    let table_keys: Vec<&str> = table
        .lines()
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    assert_eq!(keys, table_keys);
    assert_eq!(html.matches("<table>").count(), 6);
}
