//! The web page's costs in headless Chromium (issue 42's targets: a first
//! frame within 300 ms of page load, every crowd frame with the inspector on
//! under 4 ms, under 1 MiB in all).
//!
//! `cargo bench --bench web_page` builds the page (`web::build_page`), serves
//! it on 127.0.0.1 (`web::serve`) and, in Debian's headless Chromium (the
//! `browser` crate), measures:
//!
//! - the time to the first frame: from the navigation's start (the page's
//!   `performance.now()` origin) to the moment the page's hook turns `ready`,
//!   which it does right after painting its first frame; in a fresh browser
//!   (cold caches) each time, with the load event's time beside it;
//! - the cost of a frame in the crowd scene (M then X: 59 solids, spinning;
//!   and the same lit, L), inspector on and off: the page paused, each frame
//!   run by the hook's `stepFrames(1)`, which does what a frame on
//!   `requestAnimationFrame` does (the module's frame, the picture and panels
//!   rendered, the canvases painted), each between two `performance.mark`s
//!   read from a DevTools trace: how long it lasted, to the microsecond,
//!   and how much of that the page's thread ran (its CPU time), with V8's
//!   work on the module that overlapped the timed frames; and
//!   the crowd with the inspector on once more in a browser that compiles
//!   the module ahead with V8's optimising compiler ([`COMPILED_AHEAD`]),
//!   so that no background compile competes with the frames;
//! - the page's weight: the bytes the browser fetched to show it (the
//!   navigation's and every resource's body, the book included) and the
//!   files the build wrote.
//!
//! It prints a table and a machine-readable last line.
//!
//! With `WEB_PAGE_PACED=1` each timed frame waits for the next display
//! refresh (`requestAnimationFrame`), as a playing page's frames do, instead
//! of following the one before at once; 400 frames take 6.7 s a case.
//!
//! With `WEB_PAGE_PROFILE=1` it profiles instead of timing: each crowd case
//! runs its frames under the DevTools `Profiler` (sampling every
//! [`SAMPLE_US`] µs) and the bench prints, per case, where the frames spent
//! their time (self time by function, garbage collection included) and what
//! the slowest of them were made of. The module's functions have names only
//! in a build that keeps them: `CARGO_PROFILE_WEB_WASM_STRIP=false`.

use std::time::Duration;

use browser::{Browser, Page};
use serde_json::{json, Value};

/// Fresh browsers loading the page, for the first-frame figure.
const COLD_LOADS: usize = 7;
/// Frames timed per case in each round, after [`WARM_UP`] untimed ones;
/// the cases take turns, [`ROUNDS`] times, so that a spell of load on the
/// machine does not fall on one case alone.
const FRAMES: usize = 400;
const ROUNDS: usize = 3;
/// Untimed frames first, one a call as the timed ones: V8 compiles the
/// module with its baseline compiler and then, in the background, each
/// function that turns out hot with its optimising one, and the wrapper of
/// each call from JavaScript on the page's thread. On Chromium 156 the last
/// of that work came about 1,510 frames in (docs/performance.md, "A warm-up
/// that warms what is timed"); the table shows any that overlapped the
/// timed frames.
const WARM_UP: usize = 1600;
/// The flags of the browser for the case "compiled ahead": V8 compiles the
/// module with its optimising compiler (TurboFan) before it runs, rather
/// than with its baseline compiler (Liftoff) and then, in the background,
/// each function that turns out hot. On a 2-core machine those background
/// compiles take the core the page's frames run on for milliseconds at a
/// time (docs/performance.md, "What the slowest frames were"); this case
/// times the page's own work without them.
const COMPILED_AHEAD: &str = "--js-flags=--no-liftoff";
/// The marks around each timed frame.
const START: &str = "frame-start";
const END: &str = "frame-end";
/// The trace's categories: the page's marks, and V8's work on the module.
const TRACED: &[&str] = &[
    "blink.user_timing",
    "v8.wasm",
    "disabled-by-default-v8.wasm.detailed",
];
/// V8's work on the module while it runs, from the trace: a hot function
/// compiled by the optimising compiler (on another thread), the wrapper
/// of a call from JavaScript compiled, code it replaced freed (both on the
/// page's thread).
const V8_WASM_WORK: &[&str] = &[
    "wasm.TopTierCompilation",
    "wasm.CompileJSToWasmWrapper",
    "V8.WasmCodeGC",
];
/// How long the page may take to draw its first frame.
const READY_TIMEOUT: Duration = Duration::from_secs(120);
const MIB: f64 = 1024.0 * 1024.0;
/// The profiler's sampling interval in profile mode, in µs.
const SAMPLE_US: u64 = 50;
/// In profile mode, the slowest frames are this fraction of them.
const SLOWEST: f64 = 0.02;
/// Functions listed for each case in profile mode.
const TOP_FUNCTIONS: usize = 14;

/// Runs before the page's own scripts: records `performance.now()` when the
/// page's hook (`window.modexPage`) first turns `ready`.
const READY_TRAP: &str = "(() => {
    let hook;
    Object.defineProperty(window, 'modexPage', {
        configurable: true,
        get() { return hook; },
        set(value) {
            hook = value;
            let ready = value.ready;
            Object.defineProperty(value, 'ready', {
                configurable: true,
                enumerable: true,
                get() { return ready; },
                set(now) {
                    if (now && !ready) window.firstFrameMs = performance.now();
                    ready = now;
                },
            });
        },
    });
})()";

/// One case of the frame costs: the scene's lighting, the inspector, the
/// browser it runs in, and its frames' costs so far.
struct Case<'browser> {
    name: &'static str,
    lit: bool,
    inspector: bool,
    browser: &'browser Browser,
    costs: FrameCosts,
}

/// One cold load: milliseconds from navigation start to the first frame,
/// and to the load event's start.
fn cold_load(url: &str) -> (f64, f64) {
    let browser = Browser::start().expect("Chromium starts");
    let page = browser.open("about:blank").expect("a tab opens");
    page.call(
        "Page.addScriptToEvaluateOnNewDocument",
        json!({ "source": READY_TRAP }),
    )
    .expect("the trap is installed");
    page.navigate(url).expect("the page loads");
    let first = page
        .wait_for("window.firstFrameMs", READY_TIMEOUT)
        .expect("the page draws its first frame");
    let load = page
        .wait_for(
            "performance.getEntriesByType('navigation')[0].loadEventStart",
            READY_TIMEOUT,
        )
        .expect("the load event");
    (first.as_f64().unwrap(), load.as_f64().unwrap())
}

/// The bytes the browser fetched for the page: each file and its body size.
fn fetched(page: &Page) -> Vec<(String, u64)> {
    let entries = page
        .evaluate(
            "[...performance.getEntriesByType('navigation'), \
              ...performance.getEntriesByType('resource')] \
             .map(e => [e.name, e.encodedBodySize])",
        )
        .unwrap();
    entries
        .as_array()
        .unwrap()
        .iter()
        .map(|entry| {
            let name = entry[0].as_str().unwrap();
            // The page itself is its URL with the query.
            let path = name.split('?').next().unwrap_or(name);
            let name = path
                .rsplit('/')
                .next()
                .filter(|n| !n.is_empty())
                .unwrap_or("index.html");
            (name.to_owned(), entry[1].as_u64().unwrap())
        })
        .collect()
}

/// Timed frames, in ms: how long each lasted, and how much of that the
/// page's thread ran (its CPU time; the rest it waited for a core); and
/// V8's work on the module that overlapped them ([`V8_WASM_WORK`]).
#[derive(Default)]
struct FrameCosts {
    elapsed: Vec<f64>,
    cpu: Vec<f64>,
    v8_work: Vec<String>,
}

impl FrameCosts {
    fn extend(&mut self, more: FrameCosts) {
        self.elapsed.extend(more.elapsed);
        self.cpu.extend(more.cpu);
        self.v8_work.extend(more.v8_work);
    }
}

/// The untimed frames before the timed ones, one `stepFrames(1)` a call as
/// timed: `stepFrames(n)` renders the page only once.
fn warm_up_script() -> String {
    format!("for (let i = 0; i < {WARM_UP}; i++) modexPage.stepFrames(1);")
}

/// Times `FRAMES` frames of the paused page, one `stepFrames(1)` each,
/// after [`WARM_UP`] untimed ones: back to back, or with `paced`
/// (`WEB_PAGE_PACED=1`) one at each display refresh
/// (`requestAnimationFrame`), with the browser rendering between them as it
/// does for a playing page.
///
/// Each frame lies between two `performance.mark`s, read from a DevTools
/// trace: their call times give its length to the microsecond (the page's
/// `performance.now()` counts in steps of 0.1 ms), and their thread
/// timestamps the CPU time of the page's thread between them.
fn frame_costs(page: &Page, paced: bool) -> FrameCosts {
    let run = if paced {
        "const next = () => {
            frame();
            if (++done < FRAMES) requestAnimationFrame(next); else resolve(done);
        };
        requestAnimationFrame(next);"
    } else {
        "while (done < FRAMES) { frame(); done++; }
        resolve(done);"
    };
    let (done, events) = page
        .trace(TRACED, || {
            page.evaluate_within(
                &format!(
                    "new Promise((resolve) => {{
                        const FRAMES = {FRAMES};
                        // In the same evaluation as the timed frames, so
                        // that the browser renders nothing between them.
                        {warm_up}
                        // The marks' first use makes objects of its own.
                        performance.mark('{START}');
                        performance.mark('{END}');
                        performance.clearMarks();
                        let done = 0;
                        const frame = () => {{
                            performance.mark('{START}');
                            modexPage.stepFrames(1);
                            performance.mark('{END}');
                            performance.clearMarks();
                        }};
                        {run}
                    }})",
                    warm_up = warm_up_script(),
                ),
                Duration::from_secs(60),
            )
        })
        .unwrap();
    assert_eq!(done.as_u64(), Some(FRAMES as u64), "every frame ran");

    // Each mark: its name, call time and thread time (µs), on one thread.
    let mut marks: Vec<(&str, f64, f64)> = events
        .iter()
        .filter(|e| e["cat"] == "blink.user_timing" && (e["name"] == START || e["name"] == END))
        .map(|e| {
            let at = |value: &Value| {
                value
                    .as_f64()
                    .unwrap_or_else(|| panic!("a mark's time: {e}"))
            };
            (
                e["name"].as_str().unwrap(),
                at(&e["args"]["data"]["callTime"]),
                at(&e["tts"]),
            )
        })
        .collect();
    let threads: std::collections::HashSet<String> = events
        .iter()
        .filter(|e| e["cat"] == "blink.user_timing")
        .map(|e| e["tid"].to_string())
        .collect();
    assert_eq!(threads.len(), 1, "the marks come from the page's thread");
    // Two marks a frame, after the two of the warm-up.
    assert_eq!(marks.len(), 2 * FRAMES + 2, "two marks a frame");
    marks.sort_by(|a, b| a.1.total_cmp(&b.1));
    let timed = &marks[2..];
    let mut costs = FrameCosts::default();
    for pair in timed.chunks(2) {
        let [(START, start, start_cpu), (END, end, end_cpu)] = pair else {
            panic!("marks in turn, start then end: {pair:?}");
        };
        costs.elapsed.push((end - start) / 1000.0);
        costs.cpu.push((end_cpu - start_cpu) / 1000.0);
    }
    let (first, last) = (timed[0].1, timed[timed.len() - 1].1);
    costs.v8_work = events
        .iter()
        .filter(|e| e["ph"] == "X")
        .filter(|e| {
            // Any that overlaps the timed frames.
            let ts = e["ts"].as_f64().unwrap_or(f64::NAN);
            ts <= last && ts + e["dur"].as_f64().unwrap_or(0.0) >= first
        })
        .filter_map(|e| e["name"].as_str())
        .filter(|name| V8_WASM_WORK.contains(name))
        .map(str::to_owned)
        .collect();
    costs
}

/// Profile mode: runs `FRAMES` frames of the paused page under the DevTools
/// Profiler and prints where they spent their time, over all frames and
/// over the slowest [`SLOWEST`] of them.
///
/// Frames take turns calling `stepFrames(1)` from two functions, `evenFrame`
/// and `oddFrame`, so that each frame's samples lie between two changes of
/// the one in the stack; samples outside either (garbage collection, the
/// loop) belong to the frame they fall in.
fn profile_frames(page: &Page, case: &str, paced: bool) {
    page.evaluate(&warm_up_script()).unwrap();
    page.call("Profiler.enable", json!({})).unwrap();
    page.call(
        "Profiler.setSamplingInterval",
        json!({ "interval": SAMPLE_US }),
    )
    .unwrap();
    page.call("Profiler.start", json!({})).unwrap();
    let frames = if paced {
        // One frame a display refresh, as in `frame_costs`.
        format!(
            "new Promise((resolve) => {{
                let i = 0;
                const frame = () => {{
                    if (i % 2) oddFrame(); else evenFrame();
                    if (++i < {FRAMES}) requestAnimationFrame(frame); else resolve();
                }};
                requestAnimationFrame(frame);
            }})"
        )
    } else {
        format!("(() => {{ for (let i = 0; i < {FRAMES}; i++) {{ if (i % 2) oddFrame(); else evenFrame(); }} }})()")
    };
    page.evaluate_within(
        &format!(
            "function evenFrame() {{ return modexPage.stepFrames(1); }}
             function oddFrame() {{ return modexPage.stepFrames(1); }}
             {frames}"
        ),
        Duration::from_secs(60),
    )
    .unwrap();
    let profile = page.call("Profiler.stop", json!({})).unwrap()["profile"].take();
    page.call("Profiler.disable", json!({})).unwrap();

    // Each node's name, parent and the frame function (1 even, 2 odd)
    // among it and its callers.
    let nodes = profile["nodes"].as_array().expect("profile nodes");
    let mut index = std::collections::HashMap::new();
    for (at, node) in nodes.iter().enumerate() {
        index.insert(node["id"].as_u64().unwrap(), at);
    }
    let mut parent = vec![None; nodes.len()];
    for (at, node) in nodes.iter().enumerate() {
        for child in node["children"].as_array().into_iter().flatten() {
            parent[index[&child.as_u64().unwrap()]] = Some(at);
        }
    }
    let name = |at: usize| -> String {
        let frame = &nodes[at]["callFrame"];
        let function = frame["functionName"].as_str().unwrap_or("");
        let url = frame["url"].as_str().unwrap_or("");
        let file = url.rsplit('/').next().unwrap_or("");
        match (function.is_empty(), file.is_empty()) {
            (false, true) => function.to_owned(),
            (false, false) => format!("{function} ({file})"),
            (true, _) => format!("(anonymous) ({file})"),
        }
    };
    let frame_of = |mut at: usize| -> u8 {
        loop {
            match nodes[at]["callFrame"]["functionName"].as_str() {
                Some("evenFrame") => return 1,
                Some("oddFrame") => return 2,
                _ => {}
            }
            match parent[at] {
                Some(up) => at = up,
                None => return 0,
            }
        }
    };
    let which: Vec<u8> = (0..nodes.len()).map(frame_of).collect();

    // Each sample lasts until the next; a frame is a run of samples.
    let samples: Vec<usize> = profile["samples"]
        .as_array()
        .unwrap()
        .iter()
        .map(|id| index[&id.as_u64().unwrap()])
        .collect();
    let deltas: Vec<f64> = profile["timeDeltas"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_f64().unwrap())
        .collect();
    let mut frames: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut current = 0;
    for (i, &sample) in samples.iter().enumerate() {
        let lasts = deltas.get(i + 1).copied().unwrap_or(0.0);
        if which[sample] != 0 && which[sample] != current {
            current = which[sample];
            frames.push(Vec::new());
        }
        if let Some(frame) = frames.last_mut() {
            frame.push((sample, lasts));
        }
    }
    // The last frame's samples run into the end of the loop: drop it.
    frames.pop();
    let length = |frame: &Vec<(usize, f64)>| frame.iter().map(|s| s.1).sum::<f64>();
    frames.sort_by(|a, b| length(b).total_cmp(&length(a)));
    let slowest = ((frames.len() as f64 * SLOWEST).ceil() as usize).max(1);
    // Samples spaced more than three intervals apart: the thread was not
    // running (the machine's other work), or the sampler was late.
    let gap = 3.0 * SAMPLE_US as f64;
    let report = |title: &str, frames: &[Vec<(usize, f64)>]| {
        let mut by_name: std::collections::HashMap<String, f64> = Default::default();
        let mut total = 0.0;
        for &(sample, lasts) in frames.iter().flatten() {
            total += lasts;
            let label = if lasts > gap {
                format!("(a gap in the samples: over {gap} µs)")
            } else {
                name(sample)
            };
            *by_name.entry(label).or_default() += lasts;
        }
        let mut ranked: Vec<(String, f64)> = by_name.into_iter().collect();
        ranked.sort_by(|a, b| b.1.total_cmp(&a.1));
        let count = frames.len().max(1) as f64;
        println!(
            "\n{case}: {title}: {} frames, {:.3} ms a frame; self time by function:",
            frames.len(),
            total / count / 1000.0
        );
        for (label, micros) in ranked.iter().take(TOP_FUNCTIONS) {
            println!(
                "  {:>8.1} µs a frame {:>5.1} %  {label}",
                micros / count,
                micros / total.max(1.0) * 100.0
            );
        }
    };
    report("all frames", &frames);
    report(
        &format!("the slowest {slowest} frames ({} ms and over)", {
            let shortest = frames.get(slowest - 1).map_or(0.0, length);
            format!("{:.2}", shortest / 1000.0)
        }),
        &frames[..slowest.min(frames.len())],
    );
}

/// The value at `fraction` of the sorted samples (nearest rank).
fn percentile(samples: &[f64], fraction: f64) -> f64 {
    let mut sorted = samples.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((fraction * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

fn max(samples: &[f64]) -> f64 {
    samples.iter().copied().fold(f64::MIN, f64::max)
}

fn key(page: &Page, code: &str, key: &str) {
    page.key(code, key).expect("a key event");
}

fn main() {
    let profiling = std::env::var_os("WEB_PAGE_PROFILE").is_some();
    let paced = std::env::var_os("WEB_PAGE_PACED").is_some();
    let dir = tempfile::tempdir().expect("a scratch directory");
    let built = web::build_page(dir.path()).expect("the page builds");
    let single_dir = tempfile::tempdir().expect("a scratch directory");
    let single = web::build_page_with(single_dir.path(), web::PageFiles { single_file: true })
        .expect("the single-file page builds");
    let server = web::serve(dir.path(), 0).expect("the page is served");
    let url = server.url();

    let browser = Browser::start().expect("Chromium starts");
    let version = browser.version().unwrap();
    println!(
        "The web page in headless Chromium ({version}), {}",
        browser.program().display()
    );

    // Time to the first frame, cold.
    let cold_loads = if profiling { 0 } else { COLD_LOADS };
    let loads: Vec<(f64, f64)> = (0..cold_loads).map(|_| cold_load(&url)).collect();
    let firsts: Vec<f64> = loads.iter().map(|l| l.0).collect();
    let after_load: Vec<f64> = loads.iter().map(|l| l.0 - l.1).collect();

    // Frame costs in the crowd: each case in a fresh tab, so that each
    // times the same frames of the same scene. The last case runs in a
    // browser that compiles the module with V8's optimising compiler
    // before it runs, so that no background compile competes with its
    // frames (see COMPILED_AHEAD).
    let ahead = Browser::start_with(browser::Options {
        extra_args: vec![COMPILED_AHEAD.into()],
        ..browser::Options::default()
    })
    .expect("Chromium starts");
    let case = |name, lit, inspector, browser| Case {
        name,
        lit,
        inspector,
        browser,
        costs: FrameCosts::default(),
    };
    let mut cases = [
        case("crowd, inspector on", false, true, &browser),
        case("crowd, inspector off", false, false, &browser),
        case("crowd lit, inspector on", true, true, &browser),
        case("crowd lit, inspector off", true, false, &browser),
        case("crowd, inspector on, compiled ahead", false, true, &ahead),
    ];
    let mut weight = Vec::new();
    let count = cases.len();
    // One round is enough to profile.
    let rounds = if profiling { 1 } else { ROUNDS };
    for case in (0..rounds).flat_map(|_| 0..count) {
        let Case {
            name,
            lit,
            inspector,
            browser,
            ..
        } = cases[case];
        let page = browser
            .open(&format!("{url}?paused=1"))
            .expect("the page loads");
        page.wait_for("window.modexPage && modexPage.ready", READY_TIMEOUT)
            .expect("the page draws its first frame");
        weight = fetched(&page);
        let before = page.evaluate("modexPage.screenRgba()").unwrap();
        key(&page, "KeyM", "m");
        key(&page, "KeyX", "x");
        if lit {
            key(&page, "KeyL", "l");
        }
        page.evaluate("modexPage.stepFrames(2)").unwrap();
        assert_ne!(
            page.evaluate("modexPage.screenRgba()").unwrap(),
            before,
            "the crowd is on screen"
        );
        page.evaluate(&format!("modexPage.setInspector({inspector})"))
            .unwrap();
        let shown = page.evaluate("modexPage.inspectorRgba() !== null").unwrap();
        assert_eq!(shown, Value::Bool(inspector), "the inspector is as set");
        if profiling {
            profile_frames(&page, name, paced);
            continue;
        }
        cases[case].costs.extend(frame_costs(&page, paced));
    }
    if profiling {
        return;
    }

    println!();
    if paced {
        println!("Frames timed one a display refresh (WEB_PAGE_PACED), not back to back.");
    }
    println!("| measure | median | 99th percentile | worst |");
    println!("|---|---:|---:|---:|");
    println!(
        "| time to the first frame, from navigation start ({COLD_LOADS} cold loads) | {:.0} ms | | {:.0} ms |",
        percentile(&firsts, 0.5),
        max(&firsts)
    );
    println!(
        "| time to the first frame, from the load event | {:.0} ms | | {:.0} ms |",
        percentile(&after_load, 0.5),
        max(&after_load)
    );
    for Case { name, costs, .. } in &cases {
        for (what, times) in [("", &costs.elapsed), (", CPU time", &costs.cpu)] {
            println!(
                "| frame cost{what}, {name} ({} frames) | {:.2} ms | {:.2} ms | {:.2} ms |",
                times.len(),
                percentile(times, 0.5),
                percentile(times, 0.99),
                max(times)
            );
        }
        let mut counted = std::collections::BTreeMap::<&str, usize>::new();
        for work in &costs.v8_work {
            *counted.entry(work).or_default() += 1;
        }
        let counted: Vec<String> = counted
            .iter()
            .map(|(name, n)| format!("{n} {name}"))
            .collect();
        println!(
            "|   V8's work on the module during those frames: {} | | | |",
            if counted.is_empty() {
                "none".to_owned()
            } else {
                counted.join(", ")
            }
        );
    }
    let fetched_total: u64 = weight.iter().map(|(_, bytes)| bytes).sum();
    let files: Vec<String> = weight
        .iter()
        .map(|(name, bytes)| format!("{name} {bytes}"))
        .collect();
    println!();
    println!(
        "page weight as fetched: {} = {fetched_total} bytes ({:.0} % of 1 MiB)",
        files.join(" + "),
        fetched_total as f64 / MIB * 100.0
    );
    println!(
        "as built: {} bytes in {} files; the single-file page: {} bytes; the book in either: {} bytes",
        built.weight(),
        built.files.len(),
        single.weight(),
        single.book_bytes
    );
    println!(
        "(frames timed between two performance.marks, from a DevTools trace: \
         their call times, and the page's thread's CPU time)"
    );
    let summary: Vec<String> = cases
        .iter()
        .map(|Case { name, costs, .. }| {
            let key = name.replace(", ", "_").replace(' ', "_");
            format!(
                "{key}_median_ms={:.2} {key}_p99_ms={:.2} {key}_worst_ms={:.2} {key}_cpu_worst_ms={:.2}",
                percentile(&costs.elapsed, 0.5),
                percentile(&costs.elapsed, 0.99),
                max(&costs.elapsed),
                max(&costs.cpu)
            )
        })
        .collect();
    println!(
        "SUMMARY first_frame_ms={:.0} first_frame_after_load_ms={:.0} {} weight_bytes={fetched_total} single_file_bytes={}",
        percentile(&firsts, 0.5),
        percentile(&after_load, 0.5),
        summary.join(" "),
        single.weight()
    );
}
