//! The harness against the real Chromium: pages load, JavaScript runs and
//! throws, key and mouse events arrive as a page sees real ones, waits end
//! at their bound, a trace holds the page's marks, and a dead browser is reported with its stderr.
//! Pages come from `data:` URLs, so no server is needed.

use std::time::{Duration, Instant};

use browser::{Browser, BrowserError, Options};
use serde_json::json;

/// A page that logs every key and mouse event it gets.
const LOGGING_PAGE: &str = "data:text/html,<!doctype html><body style='margin:0'>\
    <button id=b style='position:absolute;left:100px;top:50px;width:40px;height:20px'>b</button>\
    <script>window.seen=[];\
    for (const t of ['keydown','keyup']) addEventListener(t, e => \
      seen.push([e.type, e.code, e.key, e.keyCode, e.location]));\
    addEventListener('mousemove', e => seen.push(['mousemove', e.clientX, e.clientY]));\
    b.addEventListener('click', e => seen.push(['click', e.target.id]));\
    </script>";

#[test]
fn a_page_loads_and_runs_javascript() {
    let browser = Browser::start().unwrap();
    assert!(browser.version().unwrap().contains("Chrome"));
    let page = browser
        .open("data:text/html,<title>hi</title><p id=p>text</p>")
        .unwrap();
    assert_eq!(page.evaluate("document.title").unwrap(), json!("hi"));
    assert_eq!(
        page.evaluate("Promise.resolve(6 * 7)").unwrap(),
        json!(42),
        "promises are awaited"
    );
    assert_eq!(page.evaluate("undefined").unwrap(), json!(null));
    assert_eq!(
        page.evaluate_base64("btoa('\\x00\\x01\\xff')").unwrap(),
        vec![0, 1, 255]
    );
}

#[test]
fn a_thrown_exception_is_an_error_with_its_text() {
    let browser = Browser::start().unwrap();
    let page = browser.open("data:text/html,x").unwrap();
    match page.evaluate("throw new RangeError('bad frame count 7')") {
        Err(BrowserError::Exception { text }) => {
            assert!(text.contains("RangeError: bad frame count 7"), "{text}")
        }
        other => panic!("expected an exception, got {other:?}"),
    }
    match page.evaluate("Promise.reject(new Error('later'))") {
        Err(BrowserError::Exception { text }) => assert!(text.contains("later"), "{text}"),
        other => panic!("expected an exception, got {other:?}"),
    }
    // The page still answers after.
    assert_eq!(page.evaluate("1 + 1").unwrap(), json!(2));
}

#[test]
fn keys_and_the_mouse_arrive_as_real_events() {
    let browser = Browser::start().unwrap();
    let page = browser.open(LOGGING_PAGE).unwrap();
    page.key("KeyL", "l").unwrap();
    page.key("ArrowLeft", "ArrowLeft").unwrap();
    page.key("Numpad4", "4").unwrap();
    page.mouse_move(12.0, 34.0).unwrap();
    page.click("#b").unwrap();
    // Chromium may first move the mouse to the page's corner: a synthetic
    // move, before the first real input.
    let seen = page
        .evaluate("seen.slice(seen.findIndex(e => e[0] === 'keydown'))")
        .unwrap();
    assert_eq!(
        seen,
        json!([
            ["keydown", "KeyL", "l", 76, 0],
            ["keyup", "KeyL", "l", 76, 0],
            ["keydown", "ArrowLeft", "ArrowLeft", 37, 0],
            ["keyup", "ArrowLeft", "ArrowLeft", 37, 0],
            ["keydown", "Numpad4", "4", 100, 3],
            ["keyup", "Numpad4", "4", 100, 3],
            ["mousemove", 12, 34],
            ["mousemove", 120, 60],
            ["click", "b"],
        ])
    );
    assert!(matches!(
        page.key("NoSuchKey", "x"),
        Err(BrowserError::UnknownKeyCode(code)) if code == "NoSuchKey"
    ));
    assert!(matches!(
        page.click("#missing"),
        Err(BrowserError::Exception { text }) if text.contains("no element matches #missing")
    ));
}

#[test]
fn a_wait_ends_when_the_page_says_so_or_at_its_bound() {
    let browser = Browser::start().unwrap();
    let page = browser
        .open("data:text/html,<script>let n = 0; setInterval(() => n++, 1)</script>")
        .unwrap();
    let value = page
        .wait_for("n >= 20 && n", Duration::from_secs(30))
        .unwrap();
    assert!(value.as_u64().unwrap() >= 20, "{value}");
    let started = Instant::now();
    match page.wait_for(
        "n < 0 || console.log('still', n < 0)",
        Duration::from_millis(200),
    ) {
        Err(BrowserError::PageTimeout {
            condition, console, ..
        }) => {
            assert!(condition.contains("n < 0"));
            assert!(console.contains("log: still false"), "{console}");
        }
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert!(started.elapsed() < Duration::from_secs(30));
}

#[test]
fn a_trace_holds_the_marks_with_their_threads_cpu_time() {
    let browser = Browser::start().unwrap();
    let page = browser.open("data:text/html,x").unwrap();
    for round in 0..2 {
        // Twice, so that a trace ends and the tab can trace again.
        let (value, events) = page
            .trace(&["blink.user_timing"], || {
                page.evaluate(
                    "(() => { performance.mark('first'); let s = 0; \
                     for (let i = 0; i < 1e6; i++) s += i; \
                     performance.mark('second'); return s; })()",
                )
            })
            .unwrap();
        assert_eq!(value.as_f64(), Some(499_999_500_000.0), "round {round}");
        let mark = |name: &str| {
            let found: Vec<_> = events.iter().filter(|e| e["name"] == name).collect();
            assert_eq!(
                found.len(),
                1,
                "one {name} mark in round {round}: {found:?}"
            );
            found[0].clone()
        };
        let (first, second) = (mark("first"), mark("second"));
        assert_eq!(first["tid"], second["tid"], "both on the page's thread");
        for field in ["tts", "ts"] {
            let (a, b) = (first[field].as_u64(), second[field].as_u64());
            assert!(a.is_some() && b.is_some(), "{field}: {first} {second}");
            assert!(a <= b, "{field} runs forward: {first} {second}");
        }
        let called = |e: &serde_json::Value| e["args"]["data"]["callTime"].as_u64();
        assert!(called(&first) <= called(&second) && called(&first).is_some());
    }
    // A failing run still ends the trace, and its error comes back.
    assert!(page
        .trace(&["blink.user_timing"], || page.evaluate("throw 1"))
        .is_err());
    assert!(page.trace(&["blink.user_timing"], || Ok(())).is_ok());
}

#[test]
fn a_page_that_cannot_load_is_an_error() {
    let browser = Browser::start().unwrap();
    // Port 1 on loopback: nothing serves there.
    match browser.open("http://127.0.0.1:1/") {
        Err(BrowserError::Navigation { url, error }) => {
            assert_eq!(url, "http://127.0.0.1:1/");
            assert!(error.starts_with("net::"), "{error}");
        }
        Err(other) => panic!("expected a navigation error, got {other:?}"),
        Ok(_) => panic!("a page loaded from port 1"),
    };
}

#[test]
fn the_network_beyond_loopback_is_closed() {
    let browser = Browser::start().unwrap();
    for url in ["http://example.com/", "http://192.0.2.1/"] {
        assert!(
            matches!(browser.open(url), Err(BrowserError::Navigation { .. })),
            "{url} loaded"
        );
    }
}

#[test]
fn a_dead_browser_is_reported_with_its_stderr() {
    let browser = Browser::start().unwrap();
    let page = browser.open("data:text/html,x").unwrap();
    // Crash the browser process itself (the protocol's own way to do so).
    let _ = browser.call(None, "Browser.crash", json!({}));
    match page.evaluate("1") {
        Err(BrowserError::Exited { stderr, status, .. }) => {
            assert!(!stderr.is_empty(), "no stderr kept");
            assert!(status.contains("Chromium exited"), "{status}");
        }
        other => panic!("expected the browser gone, got {other:?}"),
    }
}

#[test]
fn a_missing_or_wrong_program_is_a_clear_error() {
    let missing = Browser::start_with(Options {
        program: Some("/nonexistent/chromium".into()),
        ..Options::default()
    })
    .err()
    .expect("no browser at that path");
    assert!(
        matches!(&missing, BrowserError::Spawn { program, error }
            if program == "/nonexistent/chromium" && error.kind() == std::io::ErrorKind::NotFound),
        "{missing}"
    );
    // A program that exits at once, saying why on stderr.
    let script = tempfile::NamedTempFile::new().unwrap();
    std::fs::write(
        script.path(),
        "#!/bin/sh\necho 'no display, giving up' >&2\nexit 3\n",
    )
    .unwrap();
    let script = script.into_temp_path();
    std::fs::set_permissions(&script, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let gone = Browser::start_with(Options {
        program: Some(script.to_path_buf()),
        ..Options::default()
    })
    .err()
    .expect("the program exits");
    match &gone {
        BrowserError::Exited { stderr, status, .. } => {
            assert!(stderr.contains("no display, giving up"), "{gone}");
            assert!(status.contains("exit status: 3"), "{gone}");
        }
        other => panic!("expected the browser gone, got {other:?}"),
    }
}

#[test]
fn a_browser_without_webassembly_can_be_started() {
    let browser = Browser::start_with(Options {
        // V8 without its compilers has no WebAssembly object, as in
        // browsers that turn the JIT off for security.
        extra_args: vec!["--js-flags=--jitless".into()],
        ..Options::default()
    })
    .unwrap();
    let page = browser.open("data:text/html,x").unwrap();
    assert_eq!(
        page.evaluate("typeof WebAssembly").unwrap(),
        json!("undefined")
    );
    let normal = Browser::start().unwrap();
    let page = normal.open("data:text/html,x").unwrap();
    assert_eq!(
        page.evaluate("typeof WebAssembly").unwrap(),
        json!("object")
    );
}
