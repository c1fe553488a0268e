//! The page against the desktop simulator's machine: the same keys and
//! frames give the same picture, panel and GIF.

use super::*;
use sim::inspector::draw_panel;
use sim::record::{record_gif, Script};

fn key(name: &str) -> Scancode {
    scancode_for_name(name).unwrap()
}

/// `0RGB` pixels as RGBA bytes.
fn rgba_of(pixels: &[u32]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|&pixel| {
            let [_, r, g, b] = pixel.to_be_bytes();
            [r, g, b, 255]
        })
        .collect()
}

fn rgba_of_rgb(picture: &[[u8; 3]]) -> Vec<u8> {
    picture
        .iter()
        .flat_map(|&[r, g, b]| [r, g, b, 255])
        .collect()
}

#[test]
fn a_url_replay_is_the_hosts_script_run_frame_for_frame() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=m,left,left,up,l&frames=40&every=3");
        let script = Script {
            keys: ["m", "left", "left", "up", "l"].map(key).to_vec(),
            key_every: 3,
        };
        let mut machine = Machine::new();
        let mut history = History::default();
        assert!(!page.paused());
        for frame in 0..40 {
            if let Some(key) = script.key_before(frame) {
                machine.tap(key);
            }
            history.push(machine.frame());
            assert_eq!(page.step_frames(1), 1);
            assert!(
                page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()),
                "frame {frame}"
            );
        }
        assert!(page.paused(), "the URL's frames are done");
        assert_eq!(page.frames(), 40);
        assert_eq!(page.animation_frame(1e6), 0, "none run by themselves");
        let panel = draw_panel(machine.vga(), &history, INSPECTOR_HEIGHT);
        assert!(page.panel_rgba() == rgba_of(&panel.pixels));
    });
}

#[test]
fn the_animation_frames_run_the_same_frames_as_stepping() {
    crate::with_big_stack(|| {
        let mut paced = Page::new("?keys=x&frames=20");
        let mut stepped = Page::new("?keys=x&paused=1");
        assert!(stepped.paused() && !paced.paused());
        let mut now = 0.0;
        while !paced.paused() {
            paced.animation_frame(now);
            // A slow browser: every call is three frames late.
            now += 4.0 * 1000.0 / 60.0;
        }
        assert_eq!(paced.frames(), 20, "the URL's frames, even in catch-up");
        assert_eq!(stepped.animation_frame(5000.0), 0, "paused");
        stepped.step_frames(20);
        assert!(paced.screen_rgba() == stepped.screen_rgba());
    });
}

#[test]
fn browser_keys_are_the_hosts_scan_codes() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?paused=1");
        let mut machine = Machine::new();
        for (code, name) in [
            ("KeyM", "m"),
            ("ArrowLeft", "left"),
            ("Digit4", "4"),
            ("F1", "f1"),
        ] {
            assert!(page.key_down(code));
            assert!(page.key_up(code));
            machine.tap(key(name));
        }
        // Unknown to a PC keyboard: nothing happens.
        assert!(!page.key_down("F13"));
        assert!(!page.key_up("LaunchApp1"));
        for _ in 0..10 {
            machine.frame();
        }
        page.step_frames(10);
        assert_eq!(page.machine().app().commands(), machine.app().commands());
        assert!(page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()));
    });
}

#[test]
fn keys_held_when_the_focus_leaves_are_released() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?paused=1");
        page.key_down("ArrowLeft");
        page.key_down("ArrowLeft"); // the browser's key repeat
        page.key_down("KeyL");
        page.release_all();
        page.step_frames(1);
        let left = key("left");
        let l = key("l");
        let expected: Vec<u8> = [
            left.make(),
            left.make(),
            l.make(),
            left.release(),
            l.release(),
        ]
        .iter()
        .flat_map(|bytes| bytes.to_vec())
        .collect();
        assert_eq!(page.fed, [(0, expected)]);
        assert!(page.held.is_empty());
    });
}

#[test]
fn v_toggles_the_inspector_and_an_unknown_key_name_is_named() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=v,bogus,v&frames=3");
        assert_eq!(
            page.message(),
            "unknown key name \"bogus\" in the URL's keys"
        );
        assert!(page.inspector_shown());
        page.step_frames(1);
        assert!(!page.inspector_shown() && page.panel_rgba().is_empty());
        page.step_frames(1);
        assert!(page.inspector_shown(), "the bad key was left out");
        assert_eq!(page.panel_rgba().len(), PANEL_WIDTH * INSPECTOR_HEIGHT * 4);
    });
}

#[test]
fn the_gif_is_the_desktop_recorders_for_a_url_script() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=m,spc,left&frames=24&every=4");
        page.step_frames(24);
        let script = Script {
            keys: ["m", "spc", "left"].map(key).to_vec(),
            key_every: 4,
        };
        let mut desktop = Vec::new();
        record_gif(&script, 24, GIF_EVERY, &mut desktop).unwrap();
        let gif = page.gif().unwrap();
        assert!(gif.starts_with(b"GIF89a"));
        assert!(
            gif == desktop,
            "{} bytes against {}",
            gif.len(),
            desktop.len()
        );
    });
}

#[test]
fn slow_motion_steps_into_a_frame_and_the_frame_ends_as_the_machines() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?paused=1&keys=m");
        let mut machine = Machine::new();
        machine.tap(key("m"));
        machine.frame();
        assert_eq!(page.last_op(), "");
        // A step runs the frame on the machine and shows its first operation.
        assert_eq!(page.step_ops(1), 1);
        assert!(page.in_slow_motion() && page.paused());
        assert_eq!(page.frames(), 1);
        assert!(
            page.last_op().starts_with("frame 1, operation 1 of "),
            "{}",
            page.last_op()
        );
        assert!(!page.ops_rgba().is_empty());
        // Until the Map Mask is written, then to the frame's end.
        while !page.last_op().contains("Map Mask") {
            assert_eq!(page.step_ops(1), 1, "{}", page.last_op());
        }
        assert!(page.last_op().contains("from ModeX::update_page"));
        while page.in_slow_motion() {
            page.step_ops(1);
        }
        assert!(page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()));
        // A frame step finishes a frame being stepped and counts it.
        page.step_ops(3);
        assert_eq!(page.step_frames(2), 2);
        assert!(!page.in_slow_motion());
        machine.frame();
        machine.frame();
        assert_eq!(page.frames(), 3);
        assert!(page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()));
    });
}

#[test]
fn esc_ends_the_demo_and_the_page_says_so() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=esc");
        assert_eq!(page.step_frames(3), 0);
        assert!(page.message().starts_with("Esc: the demo has ended"));
        assert_eq!(page.step_ops(1), 0);
        page.play();
        assert!(page.paused());
    });
}

/// The page reads the texts from the module only when their version has
/// changed, so every change of either text must change it, and frames that
/// change neither leave it alone.
#[test]
fn the_texts_version_changes_with_the_texts_and_only_then() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=m,x&frames=0");
        let texts = |page: &Page| (page.last_op().to_string(), page.message().to_string());
        let mut seen = (page.texts_version(), texts(&page));
        page.step_frames(30);
        assert_eq!(page.texts_version(), seen.0, "frames changed no text");
        for op in 0..40 {
            page.step_ops(1);
            let now = (page.texts_version(), texts(&page));
            if now.1 != seen.1 {
                assert_ne!(now.0, seen.0, "op {op} changed {:?}", now.1);
            }
            seen = now;
        }
        page.set_message("no GIF: test".into());
        assert_ne!(page.texts_version(), seen.0, "a new message");
    });
}

#[test]
fn the_mode_set_steps_from_text_mode() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?modeset=1");
        assert!(page.in_slow_motion() && page.paused());
        assert_eq!(
            page.vga().picture_size(),
            (720, 400),
            "text mode, as the BIOS left it"
        );
        page.step_ops(1);
        assert!(
            page.last_op().starts_with("frame 0, operation 1 of "),
            "{}",
            page.last_op()
        );
        assert!(page
            .last_op()
            .ends_with("from ModeX::set_mode > ModeX::program"));
        // A frame step finishes the mode set and its first frame: frame 0.
        page.step_frames(1);
        assert_eq!(page.frames(), 0);
        let machine = Machine::new();
        assert!(page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()));
    });
}

/// The replay URLs `docs/vga.md` gives, with what each must show.
const BOOK_URLS: &[(&str, &[&str])] = &[
    (
        "?modeset=1&ops=3",
        &["Miscellaneous Output = 0xE3", "ModeX::program"],
    ),
    (
        "?modeset=1&ops=4",
        &["Map Mask = 0x0F: planes 0 1 2 3 open"],
    ),
    (
        "?modeset=1&ops=72",
        &["DAC Write Index = 0x00", "ModeX::load_palette"],
    ),
    (
        "?modeset=1&ops=691",
        &["fill 32768 bytes of colour 0", "clear_video_memory"],
    ),
    (
        "?modeset=1&ops=695",
        &["Start Address Low", "ModeX::set_mode > ModeX::show_page"],
    ),
    (
        "?paused=1&ops=229",
        &["Map Mask = 0x0F: planes 0 1 2 3 open", "update_page"],
    ),
    (
        "?paused=1&ops=230",
        &["fill ", "through planes 0 1 2 3", "update_page"],
    ),
    (
        "?paused=1&ops=345",
        &["CRTC Start Address High", "ModeX::show_page"],
    ),
    ("?paused=1&ops=347", &["Input Status 1", "ModeX::show_page"]),
];

#[test]
fn the_books_replay_urls_show_what_the_book_says() {
    crate::with_big_stack(|| {
        let book = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/vga.md"))
            .expect("docs/vga.md");
        for (url, shows) in BOOK_URLS {
            assert!(
                book.contains(&format!("`{url}`")),
                "docs/vga.md lacks {url}"
            );
            let page = Page::new(url);
            assert_eq!(page.message(), "", "{url}");
            for words in *shows {
                assert!(page.last_op().contains(words), "{url}: {}", page.last_op());
            }
        }
    });
}

#[test]
fn the_canvases_take_only_the_rows_that_changed() {
    crate::with_big_stack(|| {
        let mut page = Page::new("?keys=m&paused=1");
        let picture = page.take_changed_rows(Canvas::Picture).to_vec();
        assert_eq!(picture, vec![0..PICTURE_HEIGHT]);
        let panel = page.take_changed_rows(Canvas::Inspector).to_vec();
        assert_eq!(panel, vec![0..INSPECTOR_HEIGHT]);
        page.step_frames(2);
        let picture_rows: usize = page
            .take_changed_rows(Canvas::Picture)
            .iter()
            .map(|run| run.len())
            .sum();
        assert!(
            picture_rows > 0 && picture_rows < PICTURE_HEIGHT,
            "{picture_rows}"
        );
        assert!(!page.take_changed_rows(Canvas::Inspector).is_empty());
        // Drawn again with nothing changed: nothing to take.
        page.set_inspector(true);
        assert_eq!(page.take_changed_rows(Canvas::Picture), []);
        assert_eq!(page.take_changed_rows(Canvas::Inspector), []);
        // Rows not taken add up until they are.
        page.step_frames(1);
        page.step_frames(1);
        let mut machine = Machine::new();
        machine.tap(key("m"));
        for _ in 0..4 {
            machine.frame();
        }
        assert!(page.screen_rgba() == rgba_of_rgb(&machine.scanout_rgb()));
        let runs = page.take_changed_rows(Canvas::Picture).to_vec();
        assert!(!runs.is_empty());
        assert!(
            runs.windows(2)
                .all(|pair| pair[0].end + PAINT_GAP_ROWS <= pair[1].start),
            "{runs:?}"
        );
    });
}

#[test]
fn runs_of_rows_close_together_are_painted_as_one() {
    let gap = PAINT_GAP_ROWS;
    let mut runs = vec![0..2, 2 + gap - 1..30, 30 + gap..40, 200..201];
    merge_close_runs(&mut runs);
    assert_eq!(runs, vec![0..30, 30 + gap..40, 200..201]);
    let mut none = Vec::new();
    merge_close_runs(&mut none);
    assert!(none.is_empty());
}
