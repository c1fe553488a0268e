//! The module's exports: plain `extern "C"` functions over one [`Page`] and
//! two byte buffers in linear memory, so the page needs no bindings
//! generator. Strings go in through the input buffer (the JavaScript asks
//! for `input_buffer(len)` and writes UTF-8 there); text and bytes come out
//! through the output buffer (a call returns the length, `output_ptr()`
//! the address). Pictures are read in place at `screen_ptr()` and the like.
//!
//! The module is single-threaded, so the state lives in thread-locals.
//!
//! Not one `unsafe` block: the lint is allowed here only because it counts
//! `#[no_mangle]` (an exported symbol's name is global to the module).

#![allow(unsafe_code)]

use std::cell::RefCell;

use crate::page::{Canvas, Page, INSPECTOR_HEIGHT, INSPECTOR_WIDTH, OPS_SIZE};

thread_local! {
    static PAGE: RefCell<Option<Page>> = const { RefCell::new(None) };
    static INPUT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
    static OUTPUT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Runs `action` on the page, if `init` has made one.
fn with_page<T: Default>(action: impl FnOnce(&mut Page) -> T) -> T {
    PAGE.with(|page| page.borrow_mut().as_mut().map(action).unwrap_or_default())
}

/// The first `len` bytes of the input buffer as text (invalid UTF-8 is
/// replaced, and a length past the buffer is cut to it).
fn input(len: usize) -> String {
    INPUT.with(|input| {
        let input = input.borrow();
        String::from_utf8_lossy(&input[..len.min(input.len())]).into_owned()
    })
}

/// Puts `bytes` in the output buffer; returns their length.
fn output(bytes: &[u8]) -> usize {
    OUTPUT.with(|out| {
        let mut out = out.borrow_mut();
        out.clear();
        out.extend_from_slice(bytes);
        out.len()
    })
}

/// The address of an input buffer of `len` bytes, for the page to write
/// a string into before the call that reads it.
#[no_mangle]
pub extern "C" fn input_buffer(len: usize) -> *mut u8 {
    INPUT.with(|input| {
        let mut input = input.borrow_mut();
        input.resize(len, 0);
        input.as_mut_ptr()
    })
}

/// The output buffer's address (valid until the next call that fills it).
#[no_mangle]
pub extern "C" fn output_ptr() -> *const u8 {
    OUTPUT.with(|out| out.borrow().as_ptr())
}

/// Makes the page for the URL query in the input buffer's first `len`
/// bytes: Mode X set, the first frame drawn.
#[no_mangle]
pub extern "C" fn init(len: usize) {
    let page = Page::new(&input(len));
    PAGE.with(|slot| *slot.borrow_mut() = Some(page));
}

/// A key down, its `KeyboardEvent.code` in the input buffer; 1 if the
/// browser must not act on it too.
#[no_mangle]
pub extern "C" fn key_down(len: usize) -> u32 {
    let code = input(len);
    with_page(|page| u32::from(page.key_down(&code)))
}

/// A key up, its `KeyboardEvent.code` in the input buffer; 1 if the
/// browser must not act on it too.
#[no_mangle]
pub extern "C" fn key_up(len: usize) -> u32 {
    let code = input(len);
    with_page(|page| u32::from(page.key_up(&code)))
}

/// The page lost the focus: keys held are released.
#[no_mangle]
pub extern "C" fn release_keys() {
    with_page(Page::release_all);
}

/// A `requestAnimationFrame` callback: the frames due run; returns how many.
#[no_mangle]
pub extern "C" fn frame(now_ms: f64) -> u32 {
    with_page(|page| page.animation_frame(now_ms))
}

/// Runs `count` frames now; returns how many ran.
#[no_mangle]
pub extern "C" fn step_frames(count: u32) -> u32 {
    with_page(|page| page.step_frames(count))
}

/// Does `count` bus operations in slow motion; returns how many were done.
#[no_mangle]
pub extern "C" fn step_ops(count: u32) -> u32 {
    with_page(|page| page.step_ops(count))
}

/// Stops the frames.
#[no_mangle]
pub extern "C" fn pause() {
    with_page(Page::pause);
}

/// Runs the frames on the browser's clock.
#[no_mangle]
pub extern "C" fn play() {
    with_page(Page::play);
}

/// 1 while paused.
#[no_mangle]
pub extern "C" fn paused() -> u32 {
    with_page(|page| u32::from(page.paused()))
}

/// Frames run since the page loaded.
#[no_mangle]
pub extern "C" fn frames() -> u32 {
    with_page(|page| page.frames())
}

/// Shows (1) or hides (0) the inspector.
#[no_mangle]
pub extern "C" fn set_inspector(shown: u32) {
    with_page(|page| page.set_inspector(shown != 0));
}

/// 1 while the inspector is shown.
#[no_mangle]
pub extern "C" fn inspector_shown() -> u32 {
    with_page(|page| u32::from(page.inspector_shown()))
}

/// 1 while a frame is being stepped through.
#[no_mangle]
pub extern "C" fn in_slow_motion() -> u32 {
    with_page(|page| u32::from(page.in_slow_motion()))
}

/// The picture: 320x240 RGBA.
#[no_mangle]
pub extern "C" fn screen_ptr() -> *const u8 {
    PAGE.with(|page| {
        page.borrow()
            .as_ref()
            .map_or(core::ptr::null(), |page| page.screen_rgba().as_ptr())
    })
}

/// The inspector panel, RGBA (null while hidden).
#[no_mangle]
pub extern "C" fn panel_ptr() -> *const u8 {
    PAGE.with(|page| {
        page.borrow().as_ref().map_or(core::ptr::null(), |page| {
            let panel = page.panel_pixels();
            if panel.is_empty() {
                core::ptr::null()
            } else {
                panel.as_ptr().cast()
            }
        })
    })
}

/// Takes the rows of a canvas (0: the picture, 1: the inspector panel)
/// changed since they were last taken, as runs top down; returns how many.
/// `run_top(i)` and `run_rows(i)` give run `i`: the canvas needs only
/// those rows painted again.
#[no_mangle]
pub extern "C" fn changed_rows(canvas: u32) -> usize {
    let canvas = if canvas == 0 {
        Canvas::Picture
    } else {
        Canvas::Inspector
    };
    with_page(|page| page.take_changed_rows(canvas).len())
}

/// The first row of run `index` of the last `changed_rows` (0 past them).
#[no_mangle]
pub extern "C" fn run_top(index: usize) -> usize {
    with_page(|page| page.changed_runs().get(index).map_or(0, |run| run.start))
}

/// The rows in run `index` of the last `changed_rows` (0 past them).
#[no_mangle]
pub extern "C" fn run_rows(index: usize) -> usize {
    with_page(|page| page.changed_runs().get(index).map_or(0, |run| run.len()))
}

/// The inspector panel's width.
#[no_mangle]
pub extern "C" fn panel_width() -> usize {
    INSPECTOR_WIDTH
}

/// The inspector panel's height.
#[no_mangle]
pub extern "C" fn panel_height() -> usize {
    INSPECTOR_HEIGHT
}

/// The slow-motion panel, RGBA (null before the first step).
#[no_mangle]
pub extern "C" fn ops_ptr() -> *const u8 {
    PAGE.with(|page| {
        page.borrow().as_ref().map_or(core::ptr::null(), |page| {
            let panel = page.ops_rgba();
            if panel.is_empty() {
                core::ptr::null()
            } else {
                panel.as_ptr()
            }
        })
    })
}

/// The slow-motion panel's width.
#[no_mangle]
pub extern "C" fn ops_width() -> usize {
    OPS_SIZE.0
}

/// The slow-motion panel's height.
#[no_mangle]
pub extern "C" fn ops_height() -> usize {
    OPS_SIZE.1
}

/// The readout for picture pixel (x, y), into the output buffer.
#[no_mangle]
pub extern "C" fn hover(x: u32, y: u32) -> usize {
    let text = with_page(|page| match (u16::try_from(x), u16::try_from(y)) {
        (Ok(x), Ok(y)) => page.hover(x, y),
        _ => String::new(),
    });
    output(text.as_bytes())
}

/// The page's one-line message, into the output buffer.
#[no_mangle]
pub extern "C" fn message() -> usize {
    let text = with_page(|page| page.message().to_string());
    output(text.as_bytes())
}

/// A number that changes whenever `last_op` or `message` would give
/// another text: the page fetches them only then.
#[no_mangle]
pub extern "C" fn texts_version() -> u32 {
    with_page(|page| page.texts_version())
}

/// The last operation stepped, described, into the output buffer.
#[no_mangle]
pub extern "C" fn last_op() -> usize {
    let text = with_page(|page| page.last_op().to_string());
    output(text.as_bytes())
}

/// The run as an animated GIF, into the output buffer (0: it failed, and
/// the reason is the message).
#[no_mangle]
pub extern "C" fn gif() -> usize {
    let bytes = with_page(|page| match page.gif() {
        Ok(bytes) => bytes,
        Err(error) => {
            page.set_message(format!("no GIF: {error}"));
            Vec::new()
        }
    });
    output(&bytes)
}

/// A pointer went down on the picture at (`x`, `y`) CSS pixels.
#[no_mangle]
pub extern "C" fn pointer_down(id: i32, x: f64, y: f64) {
    with_page(|page| page.pointer_down(id, x, y));
}

/// Pointer `id` moved to (`x`, `y`); returns the keys tapped.
#[no_mangle]
pub extern "C" fn pointer_move(id: i32, x: f64, y: f64) -> u32 {
    with_page(|page| page.pointer_move(id, x, y))
}

/// Pointer `id` came up or was cancelled.
#[no_mangle]
pub extern "C" fn pointer_up(id: i32) {
    with_page(|page| page.pointer_up(id));
}

/// The wheel turned by `pixels`; returns the keys tapped.
#[no_mangle]
pub extern "C" fn zoom(pixels: f64) -> u32 {
    with_page(|page| page.zoom(pixels))
}

/// The register lab's table of inputs, as HTML, into the output buffer.
#[no_mangle]
pub extern "C" fn lab_html() -> usize {
    output(crate::lab::html().as_bytes())
}

/// A register lab edit, `key=value` (`crtc.13=50`) in the input buffer;
/// 1 if made, 0 if refused (the message says why).
#[no_mangle]
pub extern "C" fn lab_edit(len: usize) -> u32 {
    let edit = input(len);
    let (key, value) = edit.split_once('=').unwrap_or((&edit, ""));
    with_page(|page| u32::from(page.lab_edit(key, value)))
}

/// "Back to Mode X": the lab's edits undone.
#[no_mangle]
pub extern "C" fn lab_restore() {
    with_page(Page::lab_restore);
}

/// The lab's table of every register, into the output buffer.
#[no_mangle]
pub extern "C" fn lab_table() -> usize {
    let text = with_page(|page| page.lab_table());
    output(text.as_bytes())
}

/// The mode as a table (CSV), into the output buffer.
#[no_mangle]
pub extern "C" fn lab_export() -> usize {
    let text = with_page(|page| page.lab_export());
    output(text.as_bytes())
}

/// The edits as the URL's `lab` value, into the output buffer.
#[no_mangle]
pub extern "C" fn lab_url_value() -> usize {
    let text = with_page(|page| page.lab_url_value());
    output(text.as_bytes())
}
