//! The report screen in the app, on the host's software VGA: the key shows
//! it on the spare page and leaves the demo's pages alone, the arrows scroll
//! its log and never reach the scene, the key again brings back the picture
//! from before, and a fault while it is up still ends in the whole panel.

use demo::app::App;
use demo::command::{Command, LightTurn, SceneCommand};
use demo::report::{LogPosition, Report, LOG_ROWS, REPORT_PAGE};
use demo::screens::{fault_panel, REPORT_LINES};
use modex::soft::SoftVga;
use modex::{ModeX, Page, PAGE_BYTES, PAGE_PIXELS};

fn soft_vga_in_mode_x() -> Box<SoftVga> {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    soft
}

fn screen(soft: &SoftVga) -> Vec<u8> {
    let mut pixels = vec![0; PAGE_PIXELS];
    soft.scanout_indices(&mut pixels);
    pixels
}

fn plane_bytes(soft: &SoftVga, page: Page) -> Vec<u8> {
    let range = usize::from(page.base())..usize::from(page.base() + PAGE_BYTES);
    (0..4)
        .flat_map(|p| soft.plane(p)[range.clone()].to_vec())
        .collect()
}

const FACTS: [&str; 3] = ["modex-cube 0.1.0 commit test", "cpu: test", "clock: test"];

/// Draws the report as the kernel does when the app asks, scrolled as asked;
/// the log has `log_lines` lines.
fn draw_if_asked(app: &mut App, soft: &mut SoftVga, log_lines: usize) -> Option<LogPosition> {
    let scroll = app.report_to_draw()?;
    let log: Vec<String> = (1..=log_lines).map(|n| format!("line {n}")).collect();
    let scroll = scroll.min(log_lines.saturating_sub(LOG_ROWS));
    let end = log_lines - scroll;
    let window: Vec<&str> = log[end.saturating_sub(LOG_ROWS)..end]
        .iter()
        .map(String::as_str)
        .collect();
    let position = LogPosition {
        first: end.saturating_sub(LOG_ROWS) + 1,
        last: end,
        total: log_lines,
    };
    let report = Report {
        facts: &FACTS,
        log: &window,
        position,
    };
    let mut image = Box::new([0u8; PAGE_PIXELS]);
    demo::report::show(&mut ModeX::new(&mut *soft), &mut image, &report);
    app.report_drawn(scroll);
    Some(position)
}

#[test]
fn the_report_key_shows_the_report_and_brings_the_picture_back() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let before = screen(&soft);
    let pages_before = [
        plane_bytes(&soft, Page::Zero),
        plane_bytes(&soft, Page::One),
    ];
    let scene_before = *app.scene().primary().object_to_world();

    app.apply(Command::ToggleReport);
    assert!(app.report_shown());
    assert!(app.step(&mut ModeX::new(&mut *soft), &|| 0u64).is_none());
    let position = draw_if_asked(&mut app, &mut soft, 40).expect("the report is asked for");
    let top = 40 - LOG_ROWS + 1;
    assert_eq!((position.first, position.last), (top, 40));
    assert_eq!(soft.displayed_start(), REPORT_PAGE.base());
    assert_ne!(screen(&soft), before);
    assert!(
        draw_if_asked(&mut app, &mut soft, 40).is_none(),
        "drawn once"
    );

    // Arrows and Page Up/Down scroll the log, and the scene stays put.
    app.apply(Command::Scene(SceneCommand::MoveUp));
    assert_eq!(app.report_to_draw(), Some(1));
    let position = draw_if_asked(&mut app, &mut soft, 40).unwrap();
    assert_eq!((position.first, position.last), (top - 1, 39));
    app.apply(Command::Scene(SceneCommand::TurnLight(LightTurn::Up)));
    app.apply(Command::Scene(SceneCommand::TurnLight(LightTurn::Up)));
    app.apply(Command::Scene(SceneCommand::TurnLight(LightTurn::Up)));
    // Clamped to the oldest full window by the drawer.
    let position = draw_if_asked(&mut app, &mut soft, 40).unwrap();
    assert_eq!((position.first, position.last), (1, LOG_ROWS));
    app.apply(Command::Scene(SceneCommand::MoveDown));
    assert_eq!(app.report_to_draw(), Some(40 - LOG_ROWS - 1));
    draw_if_asked(&mut app, &mut soft, 40).unwrap();
    for other in [
        Command::Scene(SceneCommand::MoveLeft),
        Command::Scene(SceneCommand::Away),
        Command::ToggleHelp,
        Command::Pause,
    ] {
        app.apply(other);
        assert_eq!(app.report_to_draw(), None, "{other:?} changes nothing");
    }
    assert_eq!(*app.scene().primary().object_to_world(), scene_before);
    assert!(!app.paused());
    assert_eq!(plane_bytes(&soft, Page::Zero), pages_before[0]);
    assert_eq!(plane_bytes(&soft, Page::One), pages_before[1]);

    app.apply(Command::ToggleReport);
    assert!(!app.report_shown());
    assert!(app.step(&mut ModeX::new(&mut *soft), &|| 0u64).is_some());
    assert!(screen(&soft) == before, "the picture from before is back");
    // And the demo goes on from there: the next command draws as if the
    // report had never been up.
    app.apply(Command::Scene(SceneCommand::MoveLeft));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    let mut fresh = soft_vga_in_mode_x();
    let mut plain = App::new();
    plain.apply(Command::Scene(SceneCommand::Reset));
    plain.step(&mut ModeX::new(&mut *fresh), &|| 0u64);
    plain.apply(Command::Scene(SceneCommand::MoveLeft));
    plain.step(&mut ModeX::new(&mut *fresh), &|| 0u64);
    assert!(screen(&soft) == screen(&fresh));
}

#[test]
fn r_leaves_the_report_for_the_starting_scene() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new(); // spinning
    for _ in 0..5 {
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    }
    app.apply(Command::ToggleReport);
    draw_if_asked(&mut app, &mut soft, 10).unwrap();
    app.apply(Command::Scene(SceneCommand::Reset));
    assert!(!app.report_shown());
    assert!(app.step(&mut ModeX::new(&mut *soft), &|| 0u64).is_some());
    let mut fresh = soft_vga_in_mode_x();
    let mut plain = App::new();
    plain.apply(Command::Scene(SceneCommand::Reset));
    plain.step(&mut ModeX::new(&mut *fresh), &|| 0u64);
    assert!(screen(&soft) == screen(&fresh));
}

#[test]
fn the_report_is_written_to_its_page_only() {
    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    app.apply(Command::ToggleReport);
    let start = REPORT_PAGE.base();
    soft.set_write_guard(Some(start..start + PAGE_BYTES));
    draw_if_asked(&mut app, &mut soft, 1000).unwrap();
    assert_eq!(soft.guard_violations(), 0, "{:?}", soft.first_violation());
}

#[test]
fn a_fault_while_the_report_is_shown_ends_in_the_whole_panel() {
    let lines: [&str; REPORT_LINES] = ["EXCEPTION: PAGE FAULT", "  rip=0x1234", "", ""];
    let log = ["kernel: initialised", "demo: command 1 done"];
    let mut expected = soft_vga_in_mode_x();
    fault_panel(
        &mut ModeX::new(&mut *expected),
        &lines,
        &log,
        b"EXCEPTION: PAGE FAULT",
    );

    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    app.apply(Command::ToggleReport);
    draw_if_asked(&mut app, &mut soft, 100).unwrap();
    assert_eq!(soft.displayed_start(), REPORT_PAGE.base());
    // As the kernel's fault path on the framebuffer: the panel straight
    // onto the model the report was drawn on.
    fault_panel(
        &mut ModeX::new(&mut *soft),
        &lines,
        &log,
        b"EXCEPTION: PAGE FAULT",
    );

    let text_picture = |soft: &SoftVga| {
        let mut pixels = vec![0u8; 640 * 400];
        assert_eq!(soft.scanout_indices(&mut pixels), (640, 400));
        pixels
    };
    assert!(text_picture(&soft) == text_picture(&expected));
}
