//! The web page (issue 42) in a real browser: built once with
//! `web::build_page`, served by `web::serve` on 127.0.0.1, and driven in
//! Debian's headless Chromium over the DevTools pipe (the `browser` crate)
//! with real key and mouse events. What the page shows is checked against
//! the host: `sim::machine::Machine` fed the same scan codes, the
//! inspector's `draw_panel`, the software VGA's memory, `run_script` and
//! the desktop GIF recorder.
//!
//! The page is driven through its test hook, `window.modexPage`. Pages open
//! with `?paused=1`, so that frames run only when a test steps them; a test
//! that needs the page to run on waits for its frame count with a deadline
//! (the page polls itself: no sleeps).

use std::path::PathBuf;
use std::sync::mpsc;
use std::sync::OnceLock;
use std::time::Duration;

use browser::{Browser, Options, Page};
use keyboard::keys::scancode_for_name;
use modex::regs::{Port, Sequencer};
use modex::soft::{dac_6_to_8, SoftVga};
use modex::PAGE_BYTES;
use sim::inspector::{draw_panel, History, PANEL_MIN_HEIGHT, PANEL_WIDTH};
use sim::machine::{Machine, PICTURE_PIXELS};
use sim::oplog::BusOp;
use sim::record::{record_gif, recorded, run_script, Script};

const WIDTH: usize = 320;
const HEIGHT: usize = 240;
/// How long the page may take to load its module and draw its first frame,
/// or to reach a frame count it runs to on its own: generous, for a machine
/// with busy loops beside the tests.
const PAGE_TIMEOUT: Duration = Duration::from_secs(120);
/// How long the page's build may take: the first builds the WebAssembly
/// from scratch.
const BUILD_TIMEOUT: Duration = Duration::from_secs(1200);
/// The stack a test's host machines run on: a frame of the demo needs about
/// 2 MiB in a test build, as much as a test thread has.
const STACK_BYTES: usize = 32 << 20;

/// Runs `test` on a thread with a big stack and passes its panic on.
fn with_big_stack(test: impl FnOnce() + Send + 'static) {
    let thread = std::thread::Builder::new()
        .stack_size(STACK_BYTES)
        .spawn(test)
        .expect("a test thread starts");
    if let Err(panic) = thread.join() {
        std::panic::resume_unwind(panic);
    }
}

/// Builds the page into `out` within [`BUILD_TIMEOUT`].
fn built_within(out: PathBuf, files: web::PageFiles) -> web::Built {
    let (done, built) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = done.send(web::build_page_with(&out, files).map_err(|e| e.to_string()));
    });
    built
        .recv_timeout(BUILD_TIMEOUT)
        .expect("the page is built within the bound")
        .expect("the page builds")
}

/// The page's URL, served once for the whole test binary: built into the
/// test's target scratch directory (no temporary directory left behind),
/// served from a thread until the binary ends.
fn page_url() -> &'static str {
    static SERVED: OnceLock<(web::Server, String)> = OnceLock::new();
    let (_, url) = SERVED.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("web_page");
        let built = built_within(dir.clone(), web::PageFiles::default());
        assert!(built.weight() > 0);
        let server = web::serve(&dir, 0).expect("the page is served");
        let url = server.url();
        (server, url)
    });
    url
}

/// The single-file page, as `cargo run --release -p web -- --out DIR
/// --single-file` writes it, opened from disk (a `file://` URL: offline, no
/// server), with what the build said.
fn single_file() -> &'static (String, web::Built) {
    static BUILT: OnceLock<(String, web::Built)> = OnceLock::new();
    BUILT.get_or_init(|| {
        let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("web_single");
        let built = built_within(dir.clone(), web::PageFiles { single_file: true });
        let url = format!("file://{}", dir.join("index.html").display());
        (url, built)
    })
}

/// The page opened with `query`, once its hook says the first frame is up.
fn open<'b>(browser: &'b Browser, query: &str) -> Page<'b> {
    open_url(browser, &format!("{}{query}", page_url()))
}

/// The page at `url`, once its hook says the first frame is up.
fn open_url<'b>(browser: &'b Browser, url: &str) -> Page<'b> {
    let page = browser.open(url).expect("the page loads");
    page.wait_for("window.modexPage && modexPage.ready", PAGE_TIMEOUT)
        .expect("the page draws its first frame");
    page
}

fn evaluate_u64(page: &Page, expression: &str) -> u64 {
    let value = page.evaluate(expression).unwrap();
    value
        .as_u64()
        .unwrap_or_else(|| panic!("{expression} gave {value}"))
}

fn evaluate_string(page: &Page, expression: &str) -> String {
    let value = page.evaluate(expression).unwrap();
    value
        .as_str()
        .unwrap_or_else(|| panic!("{expression} gave {value}"))
        .to_owned()
}

/// RGBA bytes as RGB pixels; every alpha must be opaque.
fn rgb_of(rgba: &[u8], what: &str) -> Vec<[u8; 3]> {
    assert_eq!(rgba.len() % 4, 0, "{what}: {} bytes", rgba.len());
    rgba.as_chunks::<4>()
        .0
        .iter()
        .enumerate()
        .map(|(i, &[r, g, b, a])| {
            assert_eq!(a, 255, "{what}: pixel {i} is not opaque");
            [r, g, b]
        })
        .collect()
}

/// The picture as the page holds it (the hook reads the module's memory).
fn page_screen(page: &Page) -> Vec<[u8; 3]> {
    let rgba = page.evaluate_base64("modexPage.screenRgba()").unwrap();
    assert_eq!(rgba.len(), PICTURE_PIXELS * 4, "screenRgba's length");
    rgb_of(&rgba, "screenRgba")
}

/// A canvas's pixels as the browser painted them (`getImageData`, at the
/// canvas's own resolution).
fn canvas_pixels(page: &Page, id: &str) -> (usize, usize, Vec<[u8; 3]>) {
    let size = page
        .evaluate(&format!(
            "(() => {{ const c = document.getElementById('{id}'); return [c.width, c.height]; }})()"
        ))
        .unwrap();
    let (width, height) = (
        size[0].as_u64().unwrap() as usize,
        size[1].as_u64().unwrap() as usize,
    );
    let rgba = page
        .evaluate_base64(&format!(
            "(() => {{
                const data = document.getElementById('{id}').getContext('2d').getImageData(0, 0, {width}, {height}).data;
                let binary = '';
                for (let i = 0; i < data.length; i += 0x8000)
                    binary += String.fromCharCode.apply(null, data.subarray(i, i + 0x8000));
                return btoa(binary);
            }})()"
        ))
        .unwrap();
    (width, height, rgb_of(&rgba, id))
}

/// The inspector panel as the page holds it: width, height, pixels.
fn page_panel(page: &Page) -> (usize, usize, Vec<[u8; 3]>) {
    let size = page
        .evaluate(
            "(() => { const p = modexPage.inspectorRgba(); return p && [p.width, p.height]; })()",
        )
        .unwrap();
    let width = size[0].as_u64().expect("the inspector is shown") as usize;
    let height = size[1].as_u64().unwrap() as usize;
    let rgba = page
        .evaluate_base64("modexPage.inspectorRgba().rgba")
        .unwrap();
    assert_eq!(rgba.len(), width * height * 4, "inspectorRgba's length");
    (width, height, rgb_of(&rgba, "inspectorRgba"))
}

/// Where two pictures differ, for a failure message: the count and the first.
fn assert_same_pixels(what: &str, width: usize, page: &[[u8; 3]], host: &[[u8; 3]]) {
    assert_eq!(page.len(), host.len(), "{what}: sizes differ");
    let differing: Vec<usize> = (0..page.len()).filter(|&i| page[i] != host[i]).collect();
    if let Some(&first) = differing.first() {
        panic!(
            "{what}: {} of {} pixels differ; the first at ({}, {}): page {:?}, host {:?}",
            differing.len(),
            page.len(),
            first % width,
            first / width,
            page[first],
            host[first]
        );
    }
}

/// The host's side: the demo on the software VGA as `sim` runs it, with the
/// inspector's history of frame costs, as the page keeps its own.
struct Host {
    machine: Machine,
    history: History,
}

impl Host {
    fn new() -> Self {
        Host {
            machine: Machine::new(),
            history: History::default(),
        }
    }

    fn tap(&mut self, name: &str) {
        let key = scancode_for_name(name).unwrap_or_else(|| panic!("no key named {name}"));
        self.machine.tap(key);
    }

    fn frames(&mut self, count: u32) {
        for _ in 0..count {
            let cost = self.machine.frame();
            self.history.push(cost);
        }
    }

    fn panel(&self, height: usize) -> Vec<[u8; 3]> {
        panel_rgb(self.machine.vga(), &self.history, height)
    }
}

fn panel_rgb(vga: &SoftVga, history: &History, height: usize) -> Vec<[u8; 3]> {
    draw_panel(vga, history, height)
        .pixels
        .iter()
        .map(|&pixel| {
            let [_, r, g, b] = pixel.to_be_bytes();
            [r, g, b]
        })
        .collect()
}

/// The page's picture and inspector equal the host's.
fn assert_page_is_host(page: &Page, host: &Host, when: &str) {
    assert_same_pixels(
        &format!("the picture {when}"),
        WIDTH,
        &page_screen(page),
        &host.machine.scanout_rgb(),
    );
    let (width, height, panel) = page_panel(page);
    assert_eq!(width, PANEL_WIDTH, "the inspector's width");
    assert!(
        height >= PANEL_MIN_HEIGHT,
        "the inspector's height {height}"
    );
    assert_same_pixels(
        &format!("the inspector {when}"),
        width,
        &panel,
        &host.panel(height),
    );
}

fn step_frames(page: &Page, count: u32) {
    let ran = evaluate_u64(page, &format!("modexPage.stepFrames({count})"));
    assert_eq!(ran, u64::from(count), "frames stepped");
}

/// Keys of the README as the browser names them (`KeyboardEvent.code` and
/// `.key`) with the runner's names the host is fed.
const README_KEYS: [(&str, &str, &str); 14] = [
    ("KeyL", "l", "l"),
    ("ArrowLeft", "ArrowLeft", "left"),
    ("ArrowUp", "ArrowUp", "up"),
    ("KeyA", "a", "a"),
    ("KeyT", "t", "t"),
    ("F1", "F1", "f1"),
    ("Digit6", "6", "6"),
    ("Numpad8", "8", "kp_8"),
    ("Home", "Home", "home"),
    ("PageDown", "PageDown", "pgdn"),
    ("Space", " ", "spc"),
    ("KeyM", "m", "m"),
    ("KeyX", "x", "x"),
    ("KeyH", "h", "h"),
];

#[test]
fn the_starting_cube_is_the_hosts_on_the_page_and_its_canvases() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        assert_eq!(evaluate_u64(&page, "modexPage.frames()"), 0);
        let host = Host::new();
        assert_page_is_host(&page, &host, "at the start");
        // What the browser painted: the canvases hold the same pixels.
        assert_canvases_are_host(&page, &host);
        // On screen: scaled by a whole number, without smoothing. The
        // browser's own composited picture of the canvas is the host's
        // picture with each pixel a square of scale x scale.
        let box_ = page
            .evaluate(
                "(() => { const b = document.getElementById('screen').getBoundingClientRect(); \
                 return [b.left, b.top, b.width, b.height]; })()",
            )
            .unwrap();
        let [left, top, shown_width, shown_height] =
            [0, 1, 2, 3].map(|i| box_[i].as_f64().unwrap());
        let scale = shown_width / WIDTH as f64;
        assert!(scale >= 1.0 && scale.fract() == 0.0, "scaled by {scale}");
        assert_eq!(shown_height, scale * HEIGHT as f64);
        let png = page
            .screenshot_png(Some([left, top, shown_width, shown_height]))
            .unwrap();
        let (shot_width, shot) = decode_png(&png);
        assert_eq!(shot_width, shown_width as usize);
        let scale = scale as usize;
        let picture = host.machine.scanout_rgb();
        let scaled: Vec<[u8; 3]> = (0..HEIGHT * scale)
            .flat_map(|y| (0..WIDTH * scale).map(move |x| (x, y)))
            .map(|(x, y)| picture[(y / scale) * WIDTH + x / scale])
            .collect();
        assert_same_pixels(
            "the picture as the browser shows it",
            shot_width,
            &shot,
            &scaled,
        );
    });
}

/// What the browser painted on the #screen and #inspector canvases
/// (`getImageData`) is the host's picture and panel.
fn assert_canvases_are_host(page: &Page, host: &Host) {
    let (width, height, screen) = canvas_pixels(page, "screen");
    assert_eq!((width, height), (WIDTH, HEIGHT));
    assert_same_pixels(
        "the #screen canvas",
        WIDTH,
        &screen,
        &host.machine.scanout_rgb(),
    );
    let (width, height, inspector) = canvas_pixels(page, "inspector");
    assert_eq!(width, PANEL_WIDTH);
    assert_same_pixels(
        "the #inspector canvas",
        width,
        &inspector,
        &host.panel(height),
    );
}

/// A PNG's width and RGB pixels.
fn decode_png(png: &[u8]) -> (usize, Vec<[u8; 3]>) {
    let mut decoder = png::Decoder::new(std::io::Cursor::new(png));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().expect("a PNG");
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).expect("a PNG image");
    let channels = info.color_type.samples();
    let pixels = buffer[..info.buffer_size()]
        .chunks_exact(channels)
        .map(|p| [p[0], p[1], p[2]])
        .collect();
    (info.width as usize, pixels)
}

#[test]
fn readme_keys_typed_in_the_browser_give_the_hosts_pictures() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        let mut host = Host::new();
        for (code, key, name) in README_KEYS {
            page.key(code, key).unwrap();
            step_frames(&page, 2);
            host.tap(name);
            host.frames(2);
            assert_page_is_host(&page, &host, &format!("after {code}"));
            // The canvases took only the rows that changed (`changed_rows`),
            // and still hold the host's whole picture and panel.
            assert_canvases_are_host(&page, &host);
        }
        assert_eq!(
            evaluate_u64(&page, "modexPage.frames()"),
            2 * README_KEYS.len() as u64
        );
        assert_eq!(host.machine.app().commands(), README_KEYS.len() as u64);
    });
}

#[test]
fn keys_the_page_does_not_use_do_nothing() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        let mut host = Host::new();
        // The cube spins from the start: a key that reached the demo would
        // pause it ("any other key" on the machine), and the picture stop.
        assert!(host.machine.app().scene().spinning());
        step_frames(&page, 3);
        host.frames(3);
        for (code, key) in [
            ("F13", "F13"),
            ("IntlBackslash", "\\"),
            ("PrintScreen", "PrintScreen"),
            ("Pause", "Pause"),
        ] {
            page.key(code, key).unwrap();
            let taken = page
                .evaluate("document.activeElement && document.activeElement.id")
                .unwrap();
            assert_eq!(taken, "screen", "the picture keeps the focus after {code}");
        }
        step_frames(&page, 3);
        host.frames(3);
        assert_page_is_host(&page, &host, "after keys the page does not use");
        assert!(!host.machine.app().paused());
        assert_eq!(evaluate_string(&page, "modexPage.message()"), "");
    });
}

/// The planes a Map Mask value opens, as the page names them.
fn planes_named(mask: u8) -> String {
    let planes: Vec<String> = (0..4u8)
        .filter(|plane| mask & (1 << plane) != 0)
        .map(|plane| plane.to_string())
        .collect();
    match planes.len() {
        0 => "no plane".into(),
        1 => format!("plane {}", planes[0]),
        _ => format!("planes {}", planes.join(" ")),
    }
}

#[test]
fn slow_motion_steps_name_each_map_mask_write_and_its_function() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        // The host's next frame, every bus operation logged.
        let mut host = Machine::new();
        let (_, log) = host.frame_logged();
        let map_mask = |op: BusOp| match op {
            BusOp::WritePort16 { port, value }
                if port == Port::SEQUENCER_INDEX
                    && value.to_le_bytes()[0] == Sequencer::MapMask.index() =>
            {
                Some(value.to_le_bytes()[1])
            }
            _ => None,
        };
        let first = log
            .iter()
            .position(|entry| map_mask(entry.op).is_some())
            .expect("a frame writes the Map Mask");
        // Step until the page names a Map Mask write: the host's first.
        let found = page
            .evaluate(
                "(() => {
                    for (let step = 1; step <= 100000; step++) {
                        if (modexPage.stepOps(1) !== 1) return null;
                        const text = modexPage.lastOp();
                        if (text.includes('Map Mask')) return [step, text];
                    }
                    return null;
                })()",
            )
            .unwrap();
        let steps = found[0]
            .as_u64()
            .expect("the page stepped to a Map Mask write");
        assert_eq!(steps, first as u64 + 1, "steps to the first Map Mask write");
        assert_eq!(
            evaluate_string(&page, "document.getElementById('last-op').textContent"),
            found[1].as_str().unwrap(),
            "#last-op shows the step"
        );
        assert!(!page.evaluate("modexPage.opsRgba()").unwrap().is_null());
        // The rest of the frame, one step at a time: each Map Mask write
        // names the planes it opens and the functions that issued it.
        let rest = page
            .evaluate(&format!(
                "(() => {{
                    const texts = [];
                    for (let i = 0; i < {}; i++) {{
                        if (modexPage.stepOps(1) !== 1) break;
                        texts.push(modexPage.lastOp());
                    }}
                    return texts;
                }})()",
                log.len() - steps as usize
            ))
            .unwrap();
        let texts: Vec<&str> = std::iter::once(found[1].as_str().unwrap())
            .chain(rest.as_array().unwrap().iter().map(|t| t.as_str().unwrap()))
            .collect();
        assert_eq!(texts.len(), log.len() - first, "one step per operation");
        let mut masks = std::collections::BTreeSet::new();
        for (index, (entry, text)) in log[first..].iter().zip(&texts).enumerate() {
            let number = first + index + 1;
            let head = format!("frame 1, operation {number} of {}: ", log.len());
            assert!(text.starts_with(&head), "{text:?} is not {head:?}");
            let Some(mask) = map_mask(entry.op) else {
                assert!(!text.contains("Map Mask ="), "{text}");
                continue;
            };
            let named = planes_named(mask);
            assert!(
                text.contains(&format!("Map Mask = 0x{mask:02X}: {named} open")),
                "{text} does not name {named}"
            );
            let callers = entry.callers.names().join(" > ");
            assert!(callers.starts_with("ModeX::"), "issued by {callers}");
            assert!(text.ends_with(&format!("; from {callers}")), "{text}");
            masks.insert(mask);
        }
        assert!(
            masks.len() > 2,
            "the frame opens several plane sets: {masks:?}"
        );
        // The frame is done: the next step starts the next.
        assert_eq!(evaluate_u64(&page, "modexPage.stepOps(1)"), 1);
        assert!(evaluate_string(&page, "modexPage.lastOp()").starts_with("frame 2, operation 1 of"));
    });
}

/// The page's hover readout, split into its numbers: "x 13, y 7: plane 1,
/// offset 0x0233 (563) on page 0, colour 15, DAC 63 63 63 = #FFFFFF".
#[derive(Debug, PartialEq, Eq)]
struct Readout {
    x: u16,
    y: u16,
    plane: u8,
    offset: u16,
    page: Option<u16>,
    colour: u8,
    dac: [u8; 3],
    rgb: [u8; 3],
}

fn parse_readout(text: &str) -> Readout {
    let fail = || -> ! { panic!("not a readout: {text:?}") };
    let words: Vec<&str> = text
        .split([' ', ',', ':', '(', ')', '='])
        .filter(|w| !w.is_empty())
        .collect();
    let after = |label: &str| -> &str {
        let at = words
            .iter()
            .position(|w| *w == label)
            .unwrap_or_else(|| fail());
        words.get(at + 1).unwrap_or_else(|| fail())
    };
    let number = |text: &str| -> u16 { text.parse().unwrap_or_else(|_| fail()) };
    let hex = after("offset").strip_prefix("0x").unwrap_or_else(|| fail());
    let offset = u16::from_str_radix(hex, 16).unwrap_or_else(|_| fail());
    let decimal = words[words.iter().position(|w| *w == "offset").unwrap() + 2];
    assert_eq!(number(decimal), offset, "hex and decimal offsets: {text}");
    let page = match after("on") {
        "page" => Some(number(after("page"))),
        "no" => None,
        _ => fail(),
    };
    let dac_at = words
        .iter()
        .position(|w| *w == "DAC")
        .unwrap_or_else(|| fail());
    let dac = [1, 2, 3].map(|i| number(words[dac_at + i]) as u8);
    let colour_hex = words[dac_at + 4]
        .strip_prefix('#')
        .unwrap_or_else(|| fail());
    let rgb =
        [0, 2, 4].map(|i| u8::from_str_radix(&colour_hex[i..i + 2], 16).unwrap_or_else(|_| fail()));
    Readout {
        x: number(after("x")),
        y: number(after("y")),
        plane: number(after("plane")) as u8,
        offset,
        page,
        colour: number(after("colour")) as u8,
        dac,
        rgb,
    }
}

/// What the host reads for pixel (x, y) from the software VGA's memory.
fn host_readout(vga: &SoftVga, x: u16, y: u16) -> Readout {
    let start = vga.displayed_start();
    let offset = start.wrapping_add(y * 80).wrapping_add(x / 4);
    let plane = (x % 4) as u8;
    let colour = vga.plane(usize::from(plane))[usize::from(offset)];
    let dac = vga.dac_entry(colour);
    let page = (offset / PAGE_BYTES < 3).then_some(offset / PAGE_BYTES);
    Readout {
        x,
        y,
        plane,
        offset,
        page,
        colour,
        dac,
        rgb: dac.map(dac_6_to_8),
    }
}

#[test]
fn hovering_twenty_random_pixels_reads_the_vgas_memory() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        // Three objects, lit, a few frames on: many colours, page 1 shown.
        let mut host = Host::new();
        for (code, key, name) in [("KeyM", "m", "m"), ("KeyL", "l", "l")] {
            page.key(code, key).unwrap();
            host.tap(name);
        }
        step_frames(&page, 5);
        host.frames(5);
        let picture = host.machine.scanout_rgb();
        let canvas = page
            .evaluate(
                "(() => { const b = document.getElementById('screen').getBoundingClientRect(); \
                 return [b.left, b.top, b.width / 320, b.height / 240]; })()",
            )
            .unwrap();
        let [left, top, scale_x, scale_y] = [0, 1, 2, 3].map(|i| canvas[i].as_f64().unwrap());
        // A fixed xorshift sequence: the same pixels every run.
        let mut state: u32 = 0x9E37_79B9;
        let mut colours = std::collections::BTreeSet::new();
        for _ in 0..20 {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let (x, y) = ((state % 320) as u16, ((state >> 16) % 240) as u16);
            // The mouse on the middle of the picture's pixel.
            page.mouse_move(
                left + (f64::from(x) + 0.5) * scale_x,
                top + (f64::from(y) + 0.5) * scale_y,
            )
            .unwrap();
            let shown = evaluate_string(&page, "document.getElementById('hover').textContent");
            let expected = host_readout(host.machine.vga(), x, y);
            assert_eq!(parse_readout(&shown), expected, "{shown}");
            assert_eq!(
                evaluate_string(&page, &format!("modexPage.hover({x}, {y})")),
                shown
            );
            // And the readout's colour is the one on screen there.
            assert_eq!(
                expected.rgb,
                picture[usize::from(y) * WIDTH + usize::from(x)]
            );
            colours.insert(expected.colour);
        }
        assert!(
            colours.len() > 2,
            "the pixels cross the solids: {colours:?}"
        );
    });
}

/// A GIF's images composed onto its canvas, one RGB picture per image.
fn gif_pictures(bytes: &[u8]) -> (Vec<Vec<[u8; 3]>>, Vec<u16>) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options.read_info(bytes).expect("a GIF");
    assert_eq!(
        (decoder.width() as usize, decoder.height() as usize),
        (WIDTH, HEIGHT)
    );
    let mut canvas = vec![[0u8; 3]; PICTURE_PIXELS];
    let (mut pictures, mut delays) = (Vec::new(), Vec::new());
    while let Some(frame) = decoder.read_next_frame().expect("a GIF image") {
        let (left, top) = (usize::from(frame.left), usize::from(frame.top));
        let width = usize::from(frame.width);
        for (i, &[r, g, b, a]) in frame.buffer.as_chunks::<4>().0.iter().enumerate() {
            if a == 0 {
                continue; // transparent: the image below shows through
            }
            let (x, y) = (left + i % width, top + i / width);
            assert!(x < WIDTH && y < HEIGHT, "an image past the canvas");
            canvas[y * WIDTH + x] = [r, g, b];
        }
        pictures.push(canvas.clone());
        delays.push(frame.delay);
    }
    (pictures, delays)
}

#[test]
fn a_replay_url_and_its_gif_are_the_hosts() {
    with_big_stack(|| {
        let names = ["m", "left", "left", "up", "spc", "l", "x", "f2"];
        let frames = 40;
        let browser = Browser::start().unwrap();
        let page = open(
            &browser,
            &format!("?keys={}&frames={frames}", names.join(",")),
        );
        page.wait_for(
            &format!("modexPage.paused() && modexPage.frames() === {frames}"),
            PAGE_TIMEOUT,
        )
        .expect("the replay runs its frames and pauses");
        let script = Script {
            keys: names
                .iter()
                .map(|n| scancode_for_name(n).unwrap())
                .collect(),
            key_every: 1,
        };
        let mut history = History::default();
        let mut pictures = Vec::new();
        let mut last = None;
        let ran = run_script(&script, frames, |machine, frame| {
            history.push(machine.last_cost());
            if recorded(frame, web::page::GIF_EVERY) {
                pictures.push(machine.scanout_rgb());
            }
            if frame + 1 == frames {
                last = Some((machine.scanout_rgb(), machine.vga().clone()));
            }
        });
        assert_eq!(ran, frames);
        let (picture, vga) = last.unwrap();
        assert_same_pixels("the replayed picture", WIDTH, &page_screen(&page), &picture);
        let (width, height, panel) = page_panel(&page);
        assert_same_pixels(
            "the replayed inspector",
            width,
            &panel,
            &panel_rgb(&vga, &history, height),
        );
        // The GIF button's file against the desktop recorder's.
        let from_page = page.evaluate_base64("modexPage.gif()").unwrap();
        let mut from_desktop = Vec::new();
        record_gif(&script, frames, web::page::GIF_EVERY, &mut from_desktop).unwrap();
        let (page_images, page_delays) = gif_pictures(&from_page);
        let (desktop_images, desktop_delays) = gif_pictures(&from_desktop);
        assert_eq!(page_images.len(), (frames / web::page::GIF_EVERY) as usize);
        assert_eq!(page_images.len(), desktop_images.len());
        assert_eq!(page_delays, desktop_delays);
        for (index, ((page, desktop), host)) in page_images
            .iter()
            .zip(&desktop_images)
            .zip(&pictures)
            .enumerate()
        {
            assert_same_pixels(&format!("GIF image {index}"), WIDTH, page, desktop);
            assert_same_pixels(
                &format!("GIF image {index} and the scan-out"),
                WIDTH,
                page,
                host,
            );
        }
    });
}

#[test]
fn bad_url_scripts_are_named_and_the_page_runs_on() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        // An unknown key name is left out: the script is the other keys.
        let page = open(&browser, "?keys=left,xyz,up&frames=30");
        page.wait_for(
            "modexPage.paused() && modexPage.frames() === 30",
            PAGE_TIMEOUT,
        )
        .expect("the page runs its frames");
        let message = evaluate_string(&page, "document.getElementById('message').textContent");
        assert_eq!(message, "unknown key name \"xyz\" in the URL's keys");
        let script = Script {
            keys: ["left", "up"]
                .map(|n| scancode_for_name(n).unwrap())
                .to_vec(),
            key_every: 1,
        };
        let mut picture = Vec::new();
        run_script(&script, 30, |machine, _| picture = machine.scanout_rgb());
        assert_same_pixels(
            "the picture without the bad key",
            WIDTH,
            &page_screen(&page),
            &picture,
        );
        drop(page);
        // Malformed counts and escapes: named, and the frames keep coming.
        for (query, token) in [
            ("?keys=left&frames=2x0", "\"2x0\""),
            ("?keys=left,%ZZ", "\"left,%ZZ\""),
            ("?keys=spc&every=0", "\"0\""),
        ] {
            let page = open(&browser, query);
            let message = evaluate_string(&page, "document.getElementById('message').textContent");
            assert!(message.contains(token), "{query}: {message:?}");
            assert_eq!(message.lines().count(), 1, "{query}: one line");
            page.wait_for("modexPage.frames() >= 20", PAGE_TIMEOUT)
                .unwrap_or_else(|e| panic!("{query}: the page stopped: {e}"));
        }
    });
}

#[test]
fn a_browser_without_webassembly_gets_a_message() {
    with_big_stack(|| {
        // V8 without its compilers (as in browsers that turn the JIT off
        // for security) has no WebAssembly object.
        let browser = Browser::start_with(Options {
            extra_args: vec!["--js-flags=--jitless".into()],
            ..Options::default()
        })
        .unwrap();
        let page = browser.open(page_url()).unwrap();
        assert_eq!(page.evaluate("typeof WebAssembly").unwrap(), "undefined");
        // The loader checks first thing, as it runs: by the load event the
        // message is up.
        assert_stopped_saying(&page, "WebAssembly");
    });
}

#[test]
fn a_browser_without_webassembly_simd_gets_a_message() {
    with_big_stack(|| {
        let probe = simd_probe();
        let browser = Browser::start().unwrap();
        let page = browser.open("about:blank").unwrap();
        // This Chromium has SIMD: the loader's probe module is valid here.
        // (If the probe were malformed, every browser would be told it
        // lacks SIMD and every other test of the page would fail.)
        assert_eq!(
            page.evaluate(&format!("WebAssembly.validate(new Uint8Array({probe}))"))
                .unwrap(),
            true
        );
        // A browser without SIMD says no to that module and to no other.
        run_before_the_page(
            &page,
            &format!(
                "(() => {{ const validate = WebAssembly.validate; \
                   WebAssembly.validate = (bytes) => \
                     bytes.join() === {probe}.join() ? false : validate(bytes); }})()"
            ),
        );
        page.navigate(page_url()).unwrap();
        assert_stopped_saying(&page, "WebAssembly SIMD");
    });
}

#[test]
fn a_paused_page_asks_for_no_refreshes_and_playing_asks_again() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = browser.open("about:blank").unwrap();
        // The page's requestAnimationFrame calls, counted; the test's own
        // go to the browser's, uncounted.
        run_before_the_page(
            &page,
            "(() => { \
                const request = window.requestAnimationFrame.bind(window); \
                window.uncountedFrame = request; \
                window.frameRequests = 0; \
                window.requestAnimationFrame = (callback) => { \
                    window.frameRequests++; return request(callback); }; })()",
        );
        page.navigate(&format!("{}?paused=1", page_url())).unwrap();
        page.wait_for("window.modexPage && modexPage.ready", PAGE_TIMEOUT)
            .unwrap();
        // Twenty refreshes of the display, counted by the test itself.
        let twenty_refreshes = "new Promise((done) => { let n = 0; \
            const next = () => (++n >= 20 ? done(n) : uncountedFrame(next)); \
            uncountedFrame(next); })";
        let requests_over_twenty_refreshes = || {
            let before = evaluate_u64(&page, "frameRequests");
            page.evaluate(twenty_refreshes).unwrap();
            evaluate_u64(&page, "frameRequests") - before
        };
        // Paused from the start: no frame runs, and none is asked for.
        assert_eq!(requests_over_twenty_refreshes(), 0);
        assert_eq!(evaluate_u64(&page, "modexPage.frames()"), 0);
        // Play: frames run on the refreshes again.
        page.evaluate("document.getElementById('play').click()")
            .unwrap();
        page.wait_for("modexPage.frames() >= 10", PAGE_TIMEOUT)
            .expect("frames run after Play");
        assert!(requests_over_twenty_refreshes() >= 10);
        // Pause: at most the refresh already asked for, then nothing.
        page.evaluate("document.getElementById('play').click()")
            .unwrap();
        assert!(evaluate_string(&page, "document.getElementById('play').textContent") == "Play");
        requests_over_twenty_refreshes();
        let frames = evaluate_u64(&page, "modexPage.frames()");
        assert_eq!(requests_over_twenty_refreshes(), 0);
        assert_eq!(evaluate_u64(&page, "modexPage.frames()"), frames);
        // The hook's play asks again too.
        page.evaluate("modexPage.play()").unwrap();
        page.wait_for(
            &format!("modexPage.frames() >= {}", frames + 10),
            PAGE_TIMEOUT,
        )
        .expect("frames run after the hook's play");
    });
}

/// The page shows a message with `words` in it and never got ready.
fn assert_stopped_saying(page: &Page, words: &str) {
    let message = evaluate_string(page, "document.getElementById('message').textContent");
    assert!(message.contains(words), "{message:?}");
    assert_eq!(page.evaluate("window.modexPage.ready").unwrap(), false);
}

/// Has `script` run in `page` before each document's own scripts, from
/// its next navigation on.
fn run_before_the_page(page: &Page, script: &str) {
    page.call(
        "Page.addScriptToEvaluateOnNewDocument",
        serde_json::json!({ "source": script }),
    )
    .expect("the script is installed");
}

/// The loader's SIMD probe, as written in `web/page/modex.js`: the bytes
/// of a module whose one function uses a SIMD instruction, as a JavaScript
/// array.
fn simd_probe() -> String {
    let loader = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/web/page/modex.js"))
        .expect("web/page/modex.js");
    let (_, rest) = loader
        .split_once("const simdProbe = new Uint8Array(")
        .expect("modex.js has a SIMD probe");
    let (bytes, _) = rest.split_once(");").expect("the probe's bytes end");
    bytes.split_whitespace().collect()
}

/// The book's chapters: the names of `docs/*.md`.
fn chapter_names() -> Vec<String> {
    let docs = concat!(env!("CARGO_MANIFEST_DIR"), "/docs");
    let mut names: Vec<String> = std::fs::read_dir(docs)
        .expect("docs/")
        .filter_map(|entry| {
            let name = entry.unwrap().file_name().into_string().unwrap();
            name.strip_suffix(".md").map(String::from)
        })
        .collect();
    names.sort();
    names
}

fn strings_of(value: &serde_json::Value) -> Vec<String> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("not a list: {value}"))
        .iter()
        .map(|v| v.as_str().unwrap().to_owned())
        .collect()
}

/// The `href` of each link `selector` matches, as written.
fn hrefs(page: &Page, selector: &str) -> Vec<String> {
    let quoted = serde_json::Value::from(selector).to_string();
    strings_of(
        &page
            .evaluate(&format!(
                "[...document.querySelectorAll({quoted})].map(a => a.getAttribute('href'))"
            ))
            .unwrap(),
    )
}

/// The single-file page opened from disk, paused, once its first frame is up.
fn open_single_file(browser: &Browser) -> Page<'_> {
    open_url(browser, &format!("{}?paused=1", single_file().0))
}

#[test]
fn caption_links_scroll_to_their_chapter_in_the_single_file() {
    let browser = Browser::start().unwrap();
    let page = open_single_file(&browser);
    let links = hrefs(&page, "figcaption a");
    assert!(links.len() >= 5, "the captions' links: {links:?}");
    assert!(links.contains(&"#vga/step-by-step-in-the-browser".to_owned()));
    for href in &links {
        let id = href
            .strip_prefix('#')
            .unwrap_or_else(|| panic!("the caption link {href:?} leaves the page"));
        let target = format!("document.getElementById({})", serde_json::Value::from(id));
        assert_eq!(
            page.evaluate(&format!("{target} !== null")).unwrap(),
            true,
            "the caption link {href} has no target"
        );
        page.evaluate("window.scrollTo(0, 0)").unwrap();
        let selector = format!("figcaption a[href=\"{href}\"]");
        let before = page.evaluate("window.scrollY").unwrap();
        page.click(&selector).unwrap();
        // The fragment is followed and the target is in the window, from
        // wherever the caption was.
        page.wait_for(
            &format!(
                "location.hash === {hash} && (() => {{
                    const box = {target}.getBoundingClientRect();
                    return box.top >= -1 && box.top < innerHeight;
                }})()",
                hash = serde_json::Value::from(href.as_str())
            ),
            PAGE_TIMEOUT,
        )
        .unwrap_or_else(|e| panic!("{href}: the target is not scrolled into view: {e}"));
        assert_ne!(
            page.evaluate("window.scrollY").unwrap(),
            before,
            "{href}: no scroll"
        );
    }
}

#[test]
fn the_book_in_the_single_file_has_headings_tables_code_and_pictures() {
    let browser = Browser::start().unwrap();
    let page = open_single_file(&browser);
    let sections = strings_of(
        &page
            .evaluate("[...document.querySelectorAll('#book > section')].map(s => s.id).sort()")
            .unwrap(),
    );
    assert_eq!(sections, chapter_names(), "one section per chapter");
    let count = |selector: &str| {
        evaluate_u64(
            &page,
            &format!("document.querySelectorAll('{selector}').length"),
        )
    };
    assert_eq!(
        count("#book > section > h2:first-child"),
        sections.len() as u64,
        "each chapter's title"
    );
    assert!(count("#book h3") > 50, "the chapters' headings");
    assert!(count("#book table td") > 100, "the chapters' tables");
    assert!(count("#book pre code") > 10, "the chapters' code");
    let pictures = count("#book img");
    assert!(pictures >= 10, "{pictures} pictures");
    // Every picture decodes, from inside the file.
    page.wait_for(
        "[...document.querySelectorAll('#book img')].every(i => i.complete && i.naturalWidth > 0 && i.src.startsWith('data:'))",
        PAGE_TIMEOUT,
    )
    .expect("every picture of the book loads");
    // At its own size: the crowd's screenshot is 640x480.
    let crowd = page
        .evaluate(
            "(() => { const i = [...document.querySelectorAll('#book img')].find(i => i.alt.startsWith('The crowd')); \
             return [i.naturalWidth, i.naturalHeight]; })()",
        )
        .unwrap();
    assert_eq!(crowd, serde_json::json!([640, 480]));
}

#[test]
fn vgas_step_by_step_urls_open_the_page_in_their_state() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open_single_file(&browser);
        let links = hrefs(&page, "#vga a.live");
        assert!(links.len() >= 5, "vga's live links: {links:?}");
        for query in &links {
            let selector = format!("#vga a.live[href=\"{query}\"]");
            page.click(&selector).unwrap();
            let session = page.session().to_owned();
            browser
                .wait_event(
                    &format!("the page opened at {query}"),
                    PAGE_TIMEOUT,
                    |event| {
                        event["sessionId"] == session.as_str()
                            && event["method"] == "Page.frameNavigated"
                            && event["params"]["frame"]["url"]
                                .as_str()
                                .is_some_and(|url| url.ends_with(query.as_str()))
                    },
                )
                .unwrap();
            page.wait_for(
                &format!(
                    "location.search === {} && window.modexPage && modexPage.ready",
                    serde_json::Value::from(query.as_str())
                ),
                PAGE_TIMEOUT,
            )
            .unwrap_or_else(|e| panic!("{query}: the page did not open: {e}"));
            // The page's canvases in that state: the operation the host's
            // page names for the same URL, in the slow-motion panel.
            let host = web::page::Page::new(query);
            assert_eq!(
                evaluate_string(&page, "modexPage.lastOp()"),
                host.last_op(),
                "{query}"
            );
            assert_eq!(
                page.evaluate("document.getElementById('ops').hidden")
                    .unwrap(),
                false,
                "{query}: the slow-motion panel is shown"
            );
            assert_same_pixels(
                query,
                WIDTH,
                &page_screen(&page),
                &rgb_of(host.screen_rgba(), "host"),
            );
        }
    });
}

#[test]
fn the_page_with_the_book_weighs_under_1_mib() {
    let (_, single) = single_file();
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("web_weight");
    let files = built_within(dir, web::PageFiles::default());
    for (what, built) in [("the single file", single), ("the page's files", &files)] {
        println!(
            "{what}: {} bytes, {} of them the book ({:.0} % of 1 MiB)",
            built.weight(),
            built.book_bytes,
            built.weight() as f64 * 100.0 / web::PAGE_BUDGET_BYTES as f64
        );
        assert!(built.book_bytes > 100_000, "{what}: the book is in it");
        assert!(
            built.weight() <= web::PAGE_BUDGET_BYTES,
            "{what}: {} bytes, over the budget of {}",
            built.weight(),
            web::PAGE_BUDGET_BYTES
        );
    }
}

/// The page as a phone shows it: 390x844 CSS pixels at three device
/// pixels each, a mobile viewport, touch events on.
fn emulate_phone(page: &Page) {
    page.call(
        "Emulation.setDeviceMetricsOverride",
        serde_json::json!({"width": 390, "height": 844, "deviceScaleFactor": 3, "mobile": true}),
    )
    .unwrap();
    page.call(
        "Emulation.setTouchEmulationEnabled",
        serde_json::json!({"enabled": true, "maxTouchPoints": 5}),
    )
    .unwrap();
    assert_eq!(
        evaluate_u64(page, "document.documentElement.clientWidth"),
        390
    );
}

/// The middle of the picture, in CSS pixels from the viewport's top left.
fn screen_centre(page: &Page) -> (f64, f64) {
    let centre = page
        .evaluate(
            "(() => { const s = document.getElementById('screen'); s.scrollIntoView({block: 'center'});
               const b = s.getBoundingClientRect(); return [b.left + b.width / 2, b.top + b.height / 2]; })()",
        )
        .unwrap();
    (centre[0].as_f64().unwrap(), centre[1].as_f64().unwrap())
}

/// The page's picture after `keys` (KeyboardEvent code and key) typed
/// and one frame, on a new page.
fn picture_after_keys(browser: &Browser, keys: &[(&str, &str)]) -> Vec<[u8; 3]> {
    let page = open(browser, "?paused=1");
    for &(code, key) in keys {
        page.key(code, key).unwrap();
    }
    step_frames(&page, 1);
    page_screen(&page)
}

#[test]
fn on_a_phone_a_drag_and_the_on_screen_keys_do_what_the_keys_do() {
    with_big_stack(|| {
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        emulate_phone(&page);
        // The cube spins by itself: a frame with no input is the baseline.
        let still = picture_after_keys(&browser, &[]);

        // Nothing lies past the screen's sides: the page does not scroll
        // sideways, and every box shown is inside the viewport (or inside
        // a box that scrolls, such as a wide table of the book).
        let outside = page
            .evaluate(
                "(() => {
                    const width = document.documentElement.clientWidth;
                    const scrolls = (e) => { for (let a = e.parentElement; a; a = a.parentElement) {
                        const x = getComputedStyle(a).overflowX; if (x === 'auto' || x === 'scroll' || x === 'hidden') return true; }
                        return false; };
                    const out = [];
                    for (const e of document.querySelectorAll('body *')) {
                        const b = e.getBoundingClientRect();
                        if (b.width > 0 && (b.left < -0.5 || b.right > width + 0.5) && !scrolls(e))
                            out.push(e.tagName + '#' + e.id + '.' + e.className + ' ' + Math.round(b.left) + '..' + Math.round(b.right));
                    }
                    return [width, document.documentElement.scrollWidth, out.slice(0, 8), matchMedia('(max-width: 720px)').matches, getComputedStyle(document.getElementById('inspector')).width, getComputedStyle(document.querySelector('.row')).flexDirection, getComputedStyle(document.getElementById('inspector').parentElement).width];
                })()",
            )
            .unwrap();
        assert_eq!(outside[0], 390, "{outside}");
        assert_eq!(outside[1], 390, "the page scrolls sideways: {outside}");
        assert_eq!(
            outside[2],
            serde_json::json!([]),
            "boxes past the sides: {outside}"
        );
        // The picture first, at the screen's width; the inspector below it.
        let layout = page
            .evaluate(
                "(() => { const s = document.getElementById('screen').getBoundingClientRect();
                   const i = document.getElementById('inspector').getBoundingClientRect();
                   return [s.width, s.height, i.top - s.bottom]; })()",
            )
            .unwrap();
        let (width, height) = (layout[0].as_f64().unwrap(), layout[1].as_f64().unwrap());
        assert!(width > 360.0 && width <= 390.0, "{layout}");
        assert!(
            (height * 4.0 / 3.0 - width).abs() < 1.0,
            "4:3 kept: {layout}"
        );
        assert!(
            layout[2].as_f64().unwrap() > 0.0,
            "the inspector below: {layout}"
        );

        // A finger dragged 64 pixels right in four moves: four turns of 6
        // degrees about Y, as four presses of 6 give.
        let (x, y) = screen_centre(&page);
        page.touch("touchStart", &[(x - 40.0, y)]).unwrap();
        for step in 1..=4 {
            page.touch("touchMove", &[(x - 40.0 + 16.0 * f64::from(step), y)])
                .unwrap();
        }
        page.touch("touchEnd", &[]).unwrap();
        step_frames(&page, 1);
        let dragged = page_screen(&page);
        assert!(dragged != still, "the drag turned nothing");
        let keyed = picture_after_keys(&browser, &[("Digit6", "6"); 4]);
        assert_same_pixels("a drag and four 6s", WIDTH, &dragged, &keyed);

        // Two fingers pinched from 120 pixels apart to 40: two moves away (A).
        let page = open(&browser, "?paused=1");
        emulate_phone(&page);
        let (x, y) = screen_centre(&page);
        page.touch("touchStart", &[(x - 60.0, y), (x + 60.0, y)])
            .unwrap();
        page.touch("touchMove", &[(x - 20.0, y), (x + 20.0, y)])
            .unwrap();
        page.touch("touchEnd", &[]).unwrap();
        step_frames(&page, 1);
        let pinched = page_screen(&page);
        assert!(pinched != still, "the pinch moved nothing");
        let keyed = picture_after_keys(&browser, &[("KeyA", "a"); 2]);
        assert_same_pixels("a pinch and two As", WIDTH, &pinched, &keyed);

        // A tap on the on-screen N and on the on-screen 8: the keys' pictures.
        let page = open(&browser, "?paused=1");
        emulate_phone(&page);
        page.tap("#keypad button[data-code=KeyN]").unwrap();
        page.tap("#keypad button[data-code=Digit8]").unwrap();
        step_frames(&page, 1);
        let tapped = page_screen(&page);
        assert!(tapped != still, "the on-screen keys did nothing");
        let keyed = picture_after_keys(&browser, &[("KeyN", "n"), ("Digit8", "8")]);
        assert_same_pixels("on-screen N and 8", WIDTH, &tapped, &keyed);
    });
}

/// Types `value` into the register lab's field for `key` (`crtc.13`) and
/// presses Enter, as a reader does.
fn type_in_lab(page: &Page, key: &str, value: &str) {
    page.evaluate(&format!(
        "(() => {{ const i = document.querySelector('#lab input[data-key=\"{key}\"]');
           i.scrollIntoView({{block: 'center'}}); i.focus(); i.select(); }})()"
    ))
    .unwrap();
    for c in value.chars() {
        let code = if c.is_ascii_digit() {
            format!("Digit{c}")
        } else {
            format!("Key{}", c.to_ascii_uppercase())
        };
        page.key(&code, &c.to_string()).unwrap();
    }
    // Enter types a carriage return, which commits the field (its change).
    for kind in ["keyDown", "keyUp"] {
        page.call(
            "Input.dispatchKeyEvent",
            serde_json::json!({"type": kind, "code": "Enter", "key": "Enter",
                "windowsVirtualKeyCode": 13, "text": "\r"}),
        )
        .unwrap();
    }
    let changed = page
        .evaluate(&format!(
            "document.querySelector('#lab input[data-key=\"{key}\"]').value"
        ))
        .unwrap();
    let shown = changed.as_str().unwrap_or_default();
    assert!(
        shown.eq_ignore_ascii_case(value),
        "typed {value} into {key}: {changed}"
    );
}

/// The lab's field for `key`: its value, and the reason its row is marked.
fn lab_row(page: &Page, key: &str) -> (String, String) {
    let row = page
        .evaluate(&format!(
            "(() => {{ const i = document.querySelector('#lab input[data-key=\"{key}\"]');
               const tr = i.closest('tr');
               return [i.value, tr.classList.contains('harm') ? tr.lastChild.textContent : ''];
            }})()"
        ))
        .unwrap();
    (
        row[0].as_str().unwrap().to_owned(),
        row[1].as_str().unwrap().to_owned(),
    )
}

#[test]
fn the_register_lab_edits_the_vga_by_its_ports_and_goes_back_to_mode_x() {
    with_big_stack(|| {
        use modex::VgaBus;
        let browser = Browser::start().unwrap();
        let page = open(&browser, "?paused=1");
        let host = Host::new();
        let start = page_screen(&page);
        page.click("#lab summary").unwrap();
        page.wait_for(
            "document.querySelectorAll('#lab input').length > 300",
            PAGE_TIMEOUT,
        )
        .unwrap();
        assert_eq!(lab_row(&page, "crtc.13"), ("28".into(), String::new()));

        // Offset 0x50 (160 bytes a line) and start address 0x1234, typed;
        // on the host, the same VGA given the same writes by hand.
        type_in_lab(&page, "crtc.13", "50");
        type_in_lab(&page, "crtc.0c", "12");
        type_in_lab(&page, "crtc.0d", "34");
        assert_eq!(
            evaluate_string(&page, "modexPage.labUrlValue()"),
            "crtc.13:50,crtc.0c:12,crtc.0d:34",
            "{}",
            evaluate_string(&page, "modexPage.message()")
        );
        let mut by_hand = Box::new(host.machine.vga().clone());
        for (index, value) in [(0x13u8, 0x50u8), (0x0C, 0x12), (0x0D, 0x34)] {
            by_hand.write_port16(Port::CRTC_INDEX, u16::from_le_bytes([index, value]));
        }
        by_hand.let_a_frame_pass();
        let mut expected = vec![[0; 3]; PICTURE_PIXELS];
        assert_eq!(by_hand.scanout_rgb(&mut expected), (WIDTH, HEIGHT));
        assert_same_pixels(
            "offset and start address",
            WIDTH,
            &page_screen(&page),
            &expected,
        );
        let (width, _, painted) = canvas_pixels(&page, "screen");
        assert_same_pixels("the canvas", width, &painted, &expected);
        assert_eq!(lab_row(&page, "crtc.0d").0, "34");
        assert_eq!(
            evaluate_string(&page, "document.getElementById('lab-url').search"),
            "?paused=1&lab=crtc.13%3A50%2Ccrtc.0c%3A12%2Ccrtc.0d%3A34"
        );
        let export = evaluate_string(&page, "modexPage.labExport()");
        assert!(export.contains("\nCRTC Offset,0x13,0x50\n"), "{export}");

        page.click("#lab-restore").unwrap();
        assert_same_pixels("back to Mode X", WIDTH, &page_screen(&page), &start);
        assert_eq!(lab_row(&page, "crtc.13").0, "28");

        // Map Mask 0x01, held while a frame draws: the page is the host's
        // page given the same edits, and not the plain demo's
        // (web/src/lab/tests.rs checks that such a frame writes plane 0 only).
        type_in_lab(&page, "seq.02", "01");
        assert_eq!(
            evaluate_string(&page, "modexPage.message()"),
            "Sequencer Map Mask = 01"
        );
        step_frames(&page, 1);
        let mut host_page = web::page::Page::new("?paused=1");
        for (key, value) in [("crtc.13", "50"), ("crtc.0c", "12"), ("crtc.0d", "34")] {
            assert!(host_page.lab_edit(key, value));
        }
        host_page.lab_restore();
        assert!(host_page.lab_edit("seq.02", "01"));
        host_page.step_frames(1);
        assert_same_pixels(
            "a held Map Mask",
            WIDTH,
            &page_screen(&page),
            &rgb_of(host_page.screen_rgba(), "the host page"),
        );
        let mut plain = Host::new();
        plain.frames(1);
        assert!(page_screen(&page) != plain.machine.scanout_rgb());

        // Horizontal Total 0x2F: 60.5 kHz, marked with the reason.
        type_in_lab(&page, "crtc.00", "2f");
        let (value, reason) = lab_row(&page, "crtc.00");
        assert_eq!(value, "2F");
        assert!(
            reason.starts_with("would harm a real monitor: horizontal 60.52 kHz"),
            "{reason}"
        );
        assert!(evaluate_string(&page, "modexPage.message()").contains("would harm"));

        // A value that is not one is named, and nothing changes.
        type_in_lab(&page, "seq.02", "fff");
        assert_eq!(
            evaluate_string(&page, "modexPage.message()"),
            "Sequencer Map Mask: \"fff\" is not a hex value from 0 to FF"
        );
        assert_eq!(
            lab_row(&page, "seq.02").0,
            "fff",
            "the field keeps the typing"
        );
    });
}
