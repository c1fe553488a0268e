//! The page update compares only the spans the frame drew and the spans the
//! page held (`modex::spans`). These tests run the app as the kernel does,
//! through random commands (scene changes, the crowd, help, statistics, the
//! report screen), twice in step: once comparing the spans and once
//! comparing every pixel. The two must make the same bus operations, in the
//! same order, at every step.

use demo::app::App;
use demo::command::Command;
use demo::frame::Renderer;
use demo::scene::{Axis, LightTurn, SceneCommand, Sense};
use modex::record::Recorder;
use modex::ModeX;

const COMMANDS: [Command; 20] = [
    Command::Scene(SceneCommand::MoveLeft),
    Command::Scene(SceneCommand::MoveRight),
    Command::Scene(SceneCommand::MoveUp),
    Command::Scene(SceneCommand::MoveDown),
    Command::Scene(SceneCommand::Away),
    Command::Scene(SceneCommand::Toward),
    Command::Scene(SceneCommand::Rotate(Axis::X, Sense::Positive)),
    Command::Scene(SceneCommand::Rotate(Axis::Z, Sense::Negative)),
    Command::Scene(SceneCommand::ToggleSpin),
    Command::Scene(SceneCommand::ToggleLighting),
    Command::Scene(SceneCommand::TurnLight(LightTurn::Up)),
    Command::Scene(SceneCommand::NextSolid),
    Command::Scene(SceneCommand::ToggleSeveral),
    Command::Scene(SceneCommand::ToggleCrowd),
    Command::Scene(SceneCommand::Reset),
    Command::ToggleHelp,
    Command::ToggleStats,
    Command::ToggleStats,
    Command::ToggleReport,
    Command::Pause,
];

fn app(every_pixel: bool) -> App<Box<Renderer>> {
    let mut renderer = Box::new(Renderer::new());
    renderer.compare_every_pixel(every_pixel);
    App::with_renderer(renderer)
}

#[test]
fn the_spans_make_the_bus_operations_of_comparing_every_pixel() {
    let (mut by_spans, mut by_pixels) = (app(false), app(true));
    let (mut vga_spans, mut vga_pixels) = (
        ModeX::new(Recorder::default()),
        ModeX::new(Recorder::default()),
    );
    let mut state = 0x9e37_79b9_7f4a_7c15u64; // fixed seed: failures reproduce
    let (mut drawn, mut commands) = (0u32, 0u32);
    for step in 0..1_500u64 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        if state.is_multiple_of(4) {
            let command = COMMANDS[((state >> 8) % COMMANDS.len() as u64) as usize];
            by_spans.apply(command);
            by_pixels.apply(command);
            commands += 1;
        }
        // Leave the report as soon as it is up: it never touches pages 0
        // and 1, and the demo's page returns.
        for app in [&mut by_spans, &mut by_pixels] {
            if let Some(scroll) = app.report_to_draw() {
                app.report_drawn(scroll);
                app.apply(Command::ToggleReport);
            }
        }
        // A clock a frame apart, so the statistics change every second.
        let now = step * 16_683;
        let a = by_spans.step(&mut vga_spans, &|| now);
        let b = by_pixels.step(&mut vga_pixels, &|| now);
        assert_eq!(a.is_some(), b.is_some(), "step {step}");
        drawn += u32::from(a.is_some());
        assert!(
            vga_spans.bus().0 == vga_pixels.bus().0,
            "step {step}: the bus operations differ"
        );
        vga_spans.bus_mut().0.clear();
        vga_pixels.bus_mut().0.clear();
    }
    assert!(
        drawn > 400 && commands > 300,
        "{drawn} frames, {commands} commands"
    );
}
