//! A million frames of random commands through the host pipeline, with the
//! software VGA checking that every write lands inside the page being drawn,
//! and that the spans the page update compared held every change.

mod common;

use common::{soft_vga_in_mode_x, PIXELS};
use demo::app::App;
use demo::frame::{render_to_image, FrameDrawer, Renderer};
use demo::scene::{Axis, LightTurn, Scene, SceneCommand, Sense, NEAREST_Z};
use modex::{ModeX, PAGE_BYTES};

const FRAMES: u64 = 1_000_000;

/// Every command the scene handles (Quit, Pause and the display toggles are
/// the app's).
const COMMANDS: [SceneCommand; 22] = [
    SceneCommand::MoveLeft,
    SceneCommand::MoveRight,
    SceneCommand::MoveUp,
    SceneCommand::MoveDown,
    SceneCommand::Away,
    SceneCommand::Toward,
    SceneCommand::Rotate(Axis::X, Sense::Positive),
    SceneCommand::Rotate(Axis::X, Sense::Negative),
    SceneCommand::Rotate(Axis::Y, Sense::Positive),
    SceneCommand::Rotate(Axis::Y, Sense::Negative),
    SceneCommand::Rotate(Axis::Z, Sense::Positive),
    SceneCommand::Rotate(Axis::Z, Sense::Negative),
    SceneCommand::ToggleSpin,
    SceneCommand::Reset,
    SceneCommand::Toward,
    SceneCommand::ToggleLighting,
    SceneCommand::TurnLight(LightTurn::Up),
    SceneCommand::TurnLight(LightTurn::Down),
    SceneCommand::TurnLight(LightTurn::Right),
    SceneCommand::TurnLight(LightTurn::Left),
    SceneCommand::NextSolid,
    SceneCommand::ToggleSeveral,
];

#[test]
fn a_million_frames_of_random_commands() {
    let mut soft = soft_vga_in_mode_x();
    let mut renderer = Renderer::new();
    let mut scene = Scene::new();
    let mut expected = Box::new([0u8; PIXELS]);
    let mut state = 0x853c_49e6_748f_ea9bu64; // fixed seed: failures reproduce
    let (mut worst_orthonormality, mut drawn_commands) = (0f64, 0u64);
    for frame in 0..FRAMES {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        // Mostly short bursts of movement, so the cube wanders far and wide;
        // Reset is rare, so long runs without it happen.
        if state.is_multiple_of(3) {
            let command = COMMANDS[((state >> 8) % COMMANDS.len() as u64) as usize];
            if command != SceneCommand::Reset || (state >> 32).is_multiple_of(500) {
                scene.apply(command);
                drawn_commands += 1;
            }
        }
        scene.tick();

        let back = renderer.shown_page().other();
        let start = back.base();
        soft.set_write_guard(Some(start..start + PAGE_BYTES));
        renderer.draw(&mut ModeX::new(&mut *soft), &mut scene);
        assert_eq!(
            soft.guard_violations(),
            0,
            "frame {frame}: write outside page {}",
            back.index()
        );
        // The page update compared only the spans drawn and held: had a
        // changed pixel lain outside them, the shadow would still hold the
        // old one. Equal, every change was compared, and so the writes were
        // those of comparing every pixel (`modex`'s update tests).
        assert!(
            renderer.shadow(back)[..] == renderer.frame()[..],
            "frame {frame}: a change outside the spans compared"
        );

        let xform = scene.primary().object_to_world();
        worst_orthonormality = worst_orthonormality.max(xform.orthonormality_error());
        assert!(
            xform.orthonormality_error() < 1e-6,
            "frame {frame}: {}",
            xform.orthonormality_error()
        );
        assert!(
            xform.translation_part().z <= NEAREST_Z,
            "frame {frame}: nearer than allowed"
        );

        if frame % 50_000 == 0 {
            render_to_image(&mut scene, &mut expected);
            let page: Vec<u8> = (0..PIXELS)
                .map(|i| soft.plane(i % 4)[usize::from(start) + i / 4])
                .collect();
            assert!(
                page == expected.to_vec(),
                "frame {frame}: the page does not show the scene"
            );
        }
    }
    println!("{FRAMES} frames, {drawn_commands} commands, worst orthonormality error {worst_orthonormality:e}");
}

/// A VGA whose retrace bit never changes must not stop the loop: each flip
/// gives up after its bounded wait, says so, and the next frame is drawn.
#[test]
fn frames_keep_coming_with_the_retrace_bit_stuck() {
    for stuck in [true, false] {
        let mut soft = soft_vga_in_mode_x();
        soft.set_retrace_stuck(Some(stuck));
        let mut app = App::new();
        for frame in 0..5 {
            let report = app
                .step(&mut ModeX::new(&mut *soft), &|| 0u64)
                .expect("the spinning cube draws every step");
            assert!(
                report.timed_out(),
                "stuck={stuck} frame {frame}: a wait should have given up"
            );
        }
    }
}
