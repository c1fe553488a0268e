//! The culled cube, frame by frame: on the host through the software VGA
//! against an independent reference, and in QEMU against the software VGA.

mod common;

use common::{
    after_each_key, assert_same_picture, boot_bios, soft_vga_in_mode_x, BOOT_TIMEOUT, PIXELS,
};
use demo::app::App;
use demo::command::{Axis, Command, SceneCommand, Sense};
use demo::scene::Scene;
use engine::{reference, ClipRect};
use modex::soft::SoftVga;
use modex::{ModeX, PAGE_BYTES};

const SCREEN: ClipRect = ClipRect {
    x0: 0,
    y0: 0,
    x1: 320,
    y1: 240,
};

/// The picture the scene should give, built without the scan converter, the
/// Mode X driver or the VGA model: the reference rasterizer into an array.
fn reference_indices(scene: &Scene) -> Vec<u8> {
    let mut cube = scene.primary().clone();
    let mut picture = vec![0u8; PIXELS];
    cube.visible_faces(|polygon, colour| {
        reference::fill_pixels(polygon, SCREEN, |x, y| {
            picture[(y * 320 + x) as usize] = colour
        });
    });
    picture
}

fn displayed_indices(soft: &SoftVga) -> Vec<u8> {
    let mut indices = vec![0u8; PIXELS];
    assert_eq!(soft.scanout_indices(&mut indices), (320, 240));
    indices
}

/// Draws one frame, with the software VGA refusing (counting) any write
/// outside the page being drawn.
fn step_guarded(app: &mut App, soft: &mut SoftVga) {
    let back = app.shown_page().other();
    let start = back.base();
    soft.set_write_guard(Some(start..start + PAGE_BYTES));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    assert_eq!(
        soft.guard_violations(),
        0,
        "a write landed outside page {}: {:?}",
        back.index(),
        soft.first_violation()
    );
    soft.set_write_guard(None);
}

/// The QEMU key sequence of the issue, as the commands the keys stand for.

#[test]
fn frames_through_the_software_vga_equal_the_reference_rasterizer() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    let mut commands: Vec<Command> = common::CUBE_KEYS.iter().map(|&(_, c)| c).collect();
    // Then off the edges of the screen and back, turning as it goes.
    commands.extend([Command::Scene(SceneCommand::MoveLeft); 40]);
    commands.extend([common::turn(Axis::Y, Sense::Positive); 7]);
    commands.extend([Command::Scene(SceneCommand::MoveUp); 30]);
    commands.extend([Command::Scene(SceneCommand::MoveRight); 70]);
    commands.extend([Command::Scene(SceneCommand::Toward); 25]);
    commands.extend([Command::Scene(SceneCommand::MoveDown); 50]);
    for (i, &command) in commands.iter().enumerate() {
        app.apply(command);
        step_guarded(&mut app, &mut soft);
        assert_eq!(
            displayed_indices(&soft),
            reference_indices(app.scene()),
            "after command {i}: {command:?}"
        );
    }
}

#[test]
fn the_spinning_cube_stays_exact_for_a_full_turn() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new(); // spinning, as at boot
    for frame in 0..720 {
        step_guarded(&mut app, &mut soft);
        if frame % 10 == 0 {
            assert_eq!(
                displayed_indices(&soft),
                reference_indices(app.scene()),
                "frame {frame}"
            );
        }
    }
}

#[test]
fn drawing_never_changes_the_page_on_screen() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let shown = displayed_indices(&soft);
    // Draw a frame into the back page by hand, without flipping.
    let back = app.shown_page().other();
    let mut scene = Scene::initial();
    let mut vga = ModeX::new(&mut *soft);
    scene.visible_faces(|polygon, colour| {
        engine::fill_convex_polygon(polygon, SCREEN, |y, x0, x1| {
            vga.fill_span(back, y, x0, x1, colour)
        });
    });
    assert_eq!(displayed_indices(&soft), shown);
}

#[test]
fn pause_waits_for_a_key_and_escape_quits() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    assert!(app.step(&mut ModeX::new(&mut *soft), &|| 0u64).is_some());
    app.apply(Command::Pause);
    app.apply(Command::Scene(SceneCommand::MoveLeft)); // consumed by the pause, as Abrash's getch()
    assert!(app.step(&mut ModeX::new(&mut *soft), &|| 0u64).is_none());
    assert_eq!(
        app.scene().primary().object_to_world(),
        Scene::initial().primary().object_to_world()
    );
    app.apply(Command::Quit);
    assert!(app.quit_requested());
}

#[test]
fn qemu_shows_what_the_software_vga_shows_after_each_key() {
    after_each_key(&common::CUBE_KEYS, |qemu, model, _, what| {
        assert_same_picture(qemu, model, what)
    });
}

#[test]
fn the_report_key_shows_the_report_and_escape_says_goodbye() {
    let mut qemu = boot_bios(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    // First the report screen and back, on the still starting scene.
    qemu.send_key("r").unwrap();
    qemu.wait_for_serial(&boot::line::CommandDone(1).to_string(), BOOT_TIMEOUT)
        .unwrap();
    common::report_round_trip(&mut qemu, 1, "Bios", |model, _| common::doubled(model));
    qemu.send_key("esc").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("QEMU powered off: {e}"));
    assert_eq!(status.code(), Some(boot::qemu::EXIT_SUCCESS));
    assert!(qemu.serial().contains(boot::line::GOODBYE));
}
