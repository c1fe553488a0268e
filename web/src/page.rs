//! The page's whole state, as the browser drives it: the demo on the
//! software VGA (`sim::machine::Machine`), the keys from the browser and the
//! URL's script, pacing, slow motion, and the RGBA pictures the JavaScript
//! puts on the canvases. The WebAssembly exports are thin calls into this.

use std::collections::VecDeque;
use std::ops::Range;

use keyboard::keys::{scancode_for_name, Scancode};
use modex::soft::{dac_6_to_8, SoftVga};
use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};
use sim::inspector::{
    redraw_panel, same_bytes, ChangedRows, Encoding, History, Panel, PANEL_WIDTH,
};
use sim::machine::Machine;
use sim::record::{record_gif_with, RecordError};

use crate::hover::hover_text;
use crate::keys::action_for_code;
use crate::lab::{self, Lab, Register};
use crate::pacing::Pacer;
use crate::slow::{self, SlowMotion};
use crate::url::{parse_query, Replay};

/// The picture's size in pixels.
pub const PICTURE_WIDTH: usize = SCREEN_WIDTH as usize;
/// The picture's height in pixels.
pub const PICTURE_HEIGHT: usize = SCREEN_HEIGHT as usize;
/// The inspector panel's height: the picture's at twice its size, as the
/// desktop simulator's window shows it.
pub const INSPECTOR_HEIGHT: usize = 2 * PICTURE_HEIGHT;
/// One GIF image in this many frames (as `sim --record` keeps by default).
pub const GIF_EVERY: u32 = 2;
/// The most frames a GIF holds (a minute of the demo).
pub const GIF_MAX_FRAMES: u32 = 3600;
/// Changed rows this close are painted as one run, unchanged rows between
/// included.
pub const PAINT_GAP_ROWS: usize = 16;
/// CSS pixels of drag for one turn of 6 degrees (a tap of 4, 6, 8 or 2).
pub const DRAG_PIXELS_PER_TURN: f64 = 16.0;
/// Pixels of wheel or pinch for one move of 3 units away or toward (A or T).
pub const ZOOM_PIXELS_PER_MOVE: f64 = 40.0;
/// The byte before the make code of an extended key.
const EXTENDED_PREFIX: u8 = 0xE0;

/// The page.
pub struct Page {
    machine: Machine,
    history: History,
    replay: Replay,
    /// Scan-code bytes from the browser's key events, fed before the next frame.
    queue: VecDeque<u8>,
    /// Keys down now, to release when the page loses the focus.
    held: Vec<Scancode>,
    /// Bytes fed before each frame (by its number), to record the run again.
    fed: Vec<(u32, Vec<u8>)>,
    /// Frames run since the page loaded (the mode set's first frame not counted).
    frames: u32,
    paused: bool,
    ended: bool,
    inspector: bool,
    previous_byte: Option<u8>,
    pacer: Pacer,
    slow: Option<SlowMotion>,
    last_op: String,
    message: String,
    /// Changes whenever `last_op` or `message` does, so the page fetches
    /// the texts across the module's boundary only then.
    texts_version: u32,
    picture: Picture,
    /// The inspector's panel in RGBA, kept between frames: only what
    /// changes is drawn again (`sim::inspector::redraw_panel`), and the
    /// canvas takes its bytes where they lie.
    panel: Panel,
    ops_panel: Vec<u8>,
    /// The runs of rows last taken by [`Page::take_changed_rows`].
    runs: Vec<Range<usize>>,
    /// The register lab's edits.
    lab: Lab,
    /// Drag and zoom not yet a whole turn or move: (x, y, zoom) pixels.
    pointer_rest: (f64, f64, f64),
    /// The pointers down on the picture: (id, x, y).
    pointers: Vec<(i32, f64, f64)>,
}

/// A canvas whose rows the page tracks, so that it takes only those changed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Canvas {
    /// The picture.
    Picture,
    /// The inspector's panel.
    Inspector,
}

impl Page {
    /// The page for URL query `query`: Mode X set and the first frame drawn
    /// (as the kernel does at boot), the script read; a bad token in it is
    /// named in [`Page::message`] and left out.
    pub fn new(query: &str) -> Self {
        let (replay, problem) = parse_query(query);
        let (machine, slow) = if replay.mode_set {
            // The mode set in slow motion, from text mode as the BIOS left it.
            let (machine, log) = Machine::new_logged();
            let slow = SlowMotion::new(Box::new(SoftVga::new()), log, 0);
            (machine, Some(slow))
        } else {
            (Machine::new(), None)
        };
        let pacer = Pacer::new(machine.vga().timing().frame_ns());
        let mut page = Page {
            machine,
            history: History::default(),
            paused: replay.paused || replay.mode_set || replay.ops > 0 || replay.frames == Some(0),
            replay,
            queue: VecDeque::new(),
            held: Vec::new(),
            fed: Vec::new(),
            frames: 0,
            ended: false,
            inspector: true,
            previous_byte: None,
            pacer,
            slow,
            last_op: String::new(),
            message: problem.unwrap_or_default(),
            texts_version: 0,
            picture: Picture::new(),
            panel: Panel::inspector(INSPECTOR_HEIGHT, Encoding::Rgba),
            ops_panel: Vec::new(),
            runs: Vec::new(),
            lab: Lab::default(),
            pointer_rest: (0.0, 0.0, 0.0),
            pointers: Vec::new(),
        };
        for (register, value) in std::mem::take(&mut page.replay.lab) {
            page.edit_register(register, value);
        }
        let ops = page.replay.ops;
        if ops > 0 {
            page.step_ops(ops);
        } else {
            page.render();
        }
        page
    }

    /// A key went down (`KeyboardEvent.code`); held, it repeats its make
    /// code as a PC keyboard does. Returns whether the page took it (then
    /// the browser must not act on it too).
    pub fn key_down(&mut self, code: &str) -> bool {
        let Some(action) = action_for_code(code) else {
            return false;
        };
        if !self.held.contains(&action.scancode) {
            self.held.push(action.scancode);
        }
        self.queue.extend(action.scancode.make().iter());
        action.prevent_default
    }

    /// A key came up. Returns whether the page took it.
    pub fn key_up(&mut self, code: &str) -> bool {
        let Some(action) = action_for_code(code) else {
            return false;
        };
        self.held.retain(|&key| key != action.scancode);
        self.queue.extend(action.scancode.release().iter());
        action.prevent_default
    }

    /// A key pressed and let go, as an on-screen key or a drag makes it.
    fn tap(&mut self, code: &str) {
        self.key_down(code);
        self.key_up(code);
    }

    /// The pointer dragged by (`dx`, `dy`) CSS pixels over the picture:
    /// every [`DRAG_PIXELS_PER_TURN`] across is a tap of 6 (right) or 4,
    /// down of 2 or up of 8, the keys that turn the solid. Returns the taps.
    pub fn drag(&mut self, dx: f64, dy: f64) -> u32 {
        let (x, y, zoom) = self.pointer_rest;
        let (x, x_taps) = whole_steps(x + dx, DRAG_PIXELS_PER_TURN);
        let (y, y_taps) = whole_steps(y + dy, DRAG_PIXELS_PER_TURN);
        self.pointer_rest = (x, y, zoom);
        let x_code = if x_taps > 0 { "Digit6" } else { "Digit4" };
        let y_code = if y_taps > 0 { "Digit2" } else { "Digit8" };
        for _ in 0..x_taps.unsigned_abs() {
            self.tap(x_code);
        }
        for _ in 0..y_taps.unsigned_abs() {
            self.tap(y_code);
        }
        x_taps.unsigned_abs() + y_taps.unsigned_abs()
    }

    /// A wheel turned or a pinch closed by `pixels` (negative: a pinch
    /// opened): every [`ZOOM_PIXELS_PER_MOVE`] is a tap of A (away) or,
    /// negative, T (toward). Returns the taps.
    pub fn zoom(&mut self, pixels: f64) -> u32 {
        let (x, y, zoom) = self.pointer_rest;
        let (zoom, taps) = whole_steps(zoom + pixels, ZOOM_PIXELS_PER_MOVE);
        self.pointer_rest = (x, y, zoom);
        let code = if taps > 0 { "KeyA" } else { "KeyT" };
        for _ in 0..taps.unsigned_abs() {
            self.tap(code);
        }
        taps.unsigned_abs()
    }

    /// A pointer (a finger, a pen, the mouse's button) went down on the
    /// picture at (`x`, `y`), in CSS pixels.
    pub fn pointer_down(&mut self, id: i32, x: f64, y: f64) {
        self.pointers.retain(|&(known, _, _)| known != id);
        self.pointers.push((id, x, y));
    }

    /// Pointer `id` moved to (`x`, `y`): one pointer down drags
    /// ([`Page::drag`]), two pinch ([`Page::zoom`] by how much closer they
    /// came). Returns the keys tapped.
    pub fn pointer_move(&mut self, id: i32, x: f64, y: f64) -> u32 {
        let spread = |pointers: &[(i32, f64, f64)]| match pointers {
            [(_, x0, y0), (_, x1, y1)] => Some((x0 - x1).hypot(y0 - y1)),
            _ => None,
        };
        let before = spread(&self.pointers);
        let Some(pointer) = self.pointers.iter_mut().find(|p| p.0 == id) else {
            return 0;
        };
        let (dx, dy) = (x - pointer.1, y - pointer.2);
        (pointer.1, pointer.2) = (x, y);
        match (self.pointers.len(), before, spread(&self.pointers)) {
            (1, _, _) => self.drag(dx, dy),
            (_, Some(before), Some(after)) => self.zoom(before - after),
            _ => 0,
        }
    }

    /// Pointer `id` came up (or was cancelled); when none is left down,
    /// what was left of the drag or pinch is dropped.
    pub fn pointer_up(&mut self, id: i32) {
        self.pointers.retain(|&(known, _, _)| known != id);
        if self.pointers.is_empty() {
            self.pointer_rest = (0.0, 0.0, 0.0);
        }
    }

    /// Edits the register named `key` (`crtc.13`) to `value` (hex) through
    /// the VGA's ports, as a program would; false, with the reason as the
    /// message, if the key or the value is bad.
    pub fn lab_edit(&mut self, key: &str, value: &str) -> bool {
        let Some(register) = Register::from_key(key) else {
            self.set_message(format!("the register lab has no register {key:?}"));
            return false;
        };
        match register.parse(value) {
            Ok(value) => {
                self.edit_register(register, value);
                self.render();
                true
            }
            Err(line) => {
                self.set_message(line);
                false
            }
        }
    }

    /// Writes `value` to `register` on the demo's VGA and holds it there.
    fn edit_register(&mut self, register: Register, value: u32) {
        // A frame being stepped through is finished first: the edit is
        // made between frames, on the demo's own VGA.
        self.slow = None;
        let before = register.value(self.machine.vga());
        let accesses = lab::port_accesses(self.machine.vga(), register, value);
        self.machine.access_ports(&accesses);
        let now = register.value(self.machine.vga());
        self.lab.note(register, before, now);
        self.machine.hold(&self.lab.held());
        let name = format!("{} {}", register.group_name(), register.name());
        let line = match lab::monitor_problem(&self.machine.vga().timing()) {
            Some(reason) => format!("{name} = {}: {reason}", register.format(now)),
            None if now != value => format!(
                "{name} = {} (of {} written: the other bits are not implemented)",
                register.format(now),
                register.format(value)
            ),
            None => format!("{name} = {}", register.format(now)),
        };
        self.set_message(line);
    }

    /// "Back to Mode X": every register the lab edited gets back, through
    /// the ports, what it held before, and the demo writes them again.
    pub fn lab_restore(&mut self) {
        self.slow = None;
        for (register, value) in self.lab.take_restore() {
            let accesses = lab::port_accesses(self.machine.vga(), register, value);
            self.machine.access_ports(&accesses);
        }
        self.machine.hold(&[]);
        self.set_message("Back to Mode X: every register the lab edited is as it was".into());
        self.render();
    }

    /// The lab's table of every register (`lab::table`).
    pub fn lab_table(&self) -> String {
        lab::table(self.machine.vga(), &self.lab)
    }

    /// The mode as it stands, as a table (`lab::export`).
    pub fn lab_export(&self) -> String {
        lab::export(self.machine.vga(), &self.lab)
    }

    /// The edits as the URL's `lab` parameter's value (empty: none).
    pub fn lab_url_value(&self) -> String {
        self.lab.url_value()
    }

    /// The page lost the focus: every key still down comes up, so none is
    /// left held (the browser sends no key-up to a page without focus).
    pub fn release_all(&mut self) {
        for key in std::mem::take(&mut self.held) {
            self.queue.extend(key.release().iter());
        }
    }

    /// A `requestAnimationFrame` callback at `now_ms`: runs the frames the
    /// model's retrace says are due (none while paused), and returns how
    /// many ran.
    pub fn animation_frame(&mut self, now_ms: f64) -> u32 {
        if self.paused || self.ended {
            return 0;
        }
        let mut due = self.pacer.frames_due(now_ms);
        if let Some(last) = self.replay.frames {
            // The URL's run stops at its last frame, even mid catch-up.
            due = due.min(last.saturating_sub(self.frames));
        }
        let ran = self.run_frames(due);
        if ran > 0 {
            self.render();
        }
        ran
    }

    /// Runs `count` frames now, paused or not, past the URL's last frame too
    /// (a frame being stepped in slow motion is finished first, and counts
    /// as one). Returns frames run.
    pub fn step_frames(&mut self, count: u32) -> u32 {
        let mut ran = 0;
        if count > 0 && self.slow.take().is_some() {
            ran = 1;
        }
        ran += self.run_frames(count - ran);
        self.render();
        ran
    }

    /// Does `count` bus operations in slow motion (the page pauses): each
    /// starts a new frame when the last is done. Returns operations done.
    pub fn step_ops(&mut self, count: u32) -> u32 {
        self.pause();
        let mut done = 0;
        while done < count && !self.ended {
            if self.slow.is_none() && !self.start_slow_frame() {
                break;
            }
            let Some(slow) = &mut self.slow else {
                break;
            };
            if let Some(text) = slow.step() {
                self.last_op.clear();
                self.last_op.push_str(text);
                self.texts_version = self.texts_version.wrapping_add(1);
                done += 1;
            }
            if slow.finished() {
                self.ops_panel = slow.draw_panel();
                self.slow = None;
            }
        }
        self.render();
        done
    }

    /// Runs the next frame with its bus operations logged and starts
    /// stepping through them; false if no frame could run (Esc ended the
    /// demo).
    fn start_slow_frame(&mut self) -> bool {
        let before = Box::new(self.machine.vga().clone());
        let Some(log) = self.run_frame(true) else {
            return false;
        };
        self.slow = Some(SlowMotion::new(before, log, u64::from(self.frames)));
        true
    }

    /// Runs up to `count` frames; returns how many ran.
    fn run_frames(&mut self, count: u32) -> u32 {
        let mut ran = 0;
        while ran < count && self.run_frame(false).is_some() {
            ran += 1;
        }
        ran
    }

    /// One frame: the script's key due and the browser's keys fed, then the
    /// frame run (logged if `logged`). `None` if it did not run.
    fn run_frame(&mut self, logged: bool) -> Option<Vec<sim::oplog::LoggedOp>> {
        if self.ended {
            return None;
        }
        let mut bytes = Vec::new();
        if let Some(key) = self.replay.script.key_before(self.frames) {
            bytes.extend(sim::keys::tap(key));
        }
        bytes.extend(self.queue.drain(..));
        if !bytes.is_empty() {
            self.feed(&bytes);
            self.fed.push((self.frames, bytes));
        }
        if self.machine.app().quit_requested() {
            self.ended = true;
            self.paused = true;
            self.set_message(
                "Esc: the demo has ended, as on the machine; reload the page to start again".into(),
            );
            return None;
        }
        let (cost, log) = if logged {
            self.machine.frame_logged()
        } else {
            (self.machine.frame(), Vec::new())
        };
        self.history.push(cost);
        self.frames += 1;
        if self.replay.frames == Some(self.frames) {
            self.paused = true;
        }
        Some(log)
    }

    /// Feeds scan-code bytes to the demo; V's make code (not a byte of an
    /// E0 sequence) toggles the inspector, as in the desktop simulator.
    fn feed(&mut self, bytes: &[u8]) {
        let inspector_code = scancode_for_name("v").map(|key| key.code);
        for &byte in bytes {
            if Some(byte) == inspector_code && self.previous_byte != Some(EXTENDED_PREFIX) {
                self.inspector = !self.inspector;
            }
            self.previous_byte = Some(byte);
        }
        self.machine.feed(bytes);
    }

    /// Stops the frames (slow motion and stepping still work).
    pub fn pause(&mut self) {
        self.paused = true;
    }

    /// Runs the frames again, on the browser's clock from now; a frame being
    /// stepped through is finished first.
    pub fn play(&mut self) {
        if self.ended {
            return;
        }
        if self.slow.take().is_some() {
            self.render();
        }
        if self.replay.frames.is_some_and(|last| self.frames >= last) {
            // The URL's run is done: play on past it.
            self.replay.frames = None;
        }
        self.paused = false;
        self.pacer.restart();
    }

    /// Whether frames run on the browser's clock.
    pub fn paused(&self) -> bool {
        self.paused
    }

    /// Frames run since the page loaded.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Shows or hides the inspector panel (V toggles it too).
    pub fn set_inspector(&mut self, shown: bool) {
        self.inspector = shown;
        self.render();
    }

    /// Whether the inspector panel is shown.
    pub fn inspector_shown(&self) -> bool {
        self.inspector
    }

    /// The VGA the page shows: in slow motion, the copy the stepped
    /// operations have reached; otherwise the demo's.
    pub fn vga(&self) -> &SoftVga {
        match &self.slow {
            Some(slow) => slow.vga(),
            None => self.machine.vga(),
        }
    }

    /// The demo.
    pub fn machine(&self) -> &Machine {
        &self.machine
    }

    /// The frame costs the inspector plots.
    pub fn history(&self) -> &History {
        &self.history
    }

    /// Whether a frame is being stepped through.
    pub fn in_slow_motion(&self) -> bool {
        self.slow.is_some()
    }

    /// The readout for pixel (x, y) of the picture.
    pub fn hover(&self, x: u16, y: u16) -> String {
        hover_text(self.vga(), x, y)
    }

    /// The last operation stepped in slow motion, described, with the
    /// `modex` function that issued it (empty before the first).
    pub fn last_op(&self) -> &str {
        &self.last_op
    }

    /// The one-line message for the page (empty: none).
    pub fn message(&self) -> &str {
        &self.message
    }

    /// Replaces the one-line message.
    pub fn set_message(&mut self, line: String) {
        self.message = line;
        self.texts_version = self.texts_version.wrapping_add(1);
    }

    /// A number that changes whenever [`Page::last_op`] or
    /// [`Page::message`] does (and seldom else): the page reads the texts
    /// only when it has changed.
    pub fn texts_version(&self) -> u32 {
        self.texts_version
    }

    /// The picture, 320x240 RGBA.
    pub fn screen_rgba(&self) -> &[u8] {
        &self.picture.rgba
    }

    /// The rows of `canvas` changed since they were last taken (all of them
    /// the first time), as runs top down: the canvas showing it needs only
    /// those painted again.
    /// Runs fewer than [`PAINT_GAP_ROWS`] apart come as one: each run is a
    /// `putImageData` call, whose own cost is worth a few unchanged rows.
    pub fn take_changed_rows(&mut self, canvas: Canvas) -> &[Range<usize>] {
        match canvas {
            Canvas::Picture => self.picture.changed.take(&mut self.runs),
            Canvas::Inspector => self.panel.take_changed_rows(&mut self.runs),
        }
        merge_close_runs(&mut self.runs);
        &self.runs
    }

    /// The runs [`Page::take_changed_rows`] took last.
    pub fn changed_runs(&self) -> &[Range<usize>] {
        &self.runs
    }

    /// The inspector panel, [`PANEL_WIDTH`] x [`INSPECTOR_HEIGHT`], each
    /// `u32` the bytes R, G, B, A in memory order; empty while it is hidden.
    pub fn panel_pixels(&self) -> &[u32] {
        if self.inspector {
            &self.panel.pixels
        } else {
            &[]
        }
    }

    /// The inspector panel as RGBA bytes (a copy of [`Page::panel_pixels`]).
    pub fn panel_rgba(&self) -> Vec<u8> {
        self.panel_pixels()
            .iter()
            .flat_map(|pixel| pixel.to_ne_bytes())
            .collect()
    }

    /// The slow-motion panel, RGBA, `slow::PANEL_WIDTH` x
    /// `slow::PANEL_HEIGHT`; empty before the first step.
    pub fn ops_rgba(&self) -> &[u8] {
        &self.ops_panel
    }

    /// The run so far as an animated GIF, made as `sim --record` makes one:
    /// the same keys at the same frames fed to a new machine, one image in
    /// [`GIF_EVERY`] frames, the first [`GIF_MAX_FRAMES`] frames at most.
    pub fn gif(&self) -> Result<Vec<u8>, RecordError> {
        let frames = self.frames.min(GIF_MAX_FRAMES);
        let mut fed = self.fed.iter().peekable();
        let mut out = Vec::new();
        record_gif_with(
            frames,
            GIF_EVERY,
            |machine, frame| {
                while let Some((_, bytes)) = fed.next_if(|(at, _)| *at == frame) {
                    machine.feed(bytes);
                }
            },
            &mut out,
        )?;
        Ok(out)
    }

    /// Draws the picture and the panels from the VGA shown.
    fn render(&mut self) {
        let vga = match &self.slow {
            Some(slow) => slow.vga(),
            None => self.machine.vga(),
        };
        if vga.picture_size() == (PICTURE_WIDTH, PICTURE_HEIGHT) {
            self.picture.scan_out(vga);
        }
        // Any other picture (the goodbye screen's text mode) is not shown:
        // the last Mode X picture stays.
        if self.inspector {
            redraw_panel(&mut self.panel, vga, &self.history);
        }
        if let Some(slow) = &self.slow {
            self.ops_panel = slow.draw_panel();
        }
    }
}

/// The picture as RGBA, exactly as `SoftVga::scanout_rgb` gives it (the
/// DAC's colours widened to 8 bits through the pixel mask, black while video
/// is off), kept between frames with its DAC indices: a row is converted
/// again only when its indices or the colours changed, and noted changed.
struct Picture {
    rgba: Vec<u8>,
    /// The DAC indices `rgba` shows.
    indices: Vec<u8>,
    /// The indices scanned out now, compared with `indices` row by row.
    scanned: Vec<u8>,
    /// The colour of each index that `rgba` shows.
    colours: [[u8; 4]; 256],
    changed: ChangedRows,
}

impl Picture {
    /// Black until the first Mode X picture.
    fn new() -> Self {
        let pixels = PICTURE_WIDTH * PICTURE_HEIGHT;
        Picture {
            rgba: [0, 0, 0, 255].repeat(pixels),
            indices: vec![0; pixels],
            scanned: vec![0; pixels],
            colours: [[0, 0, 0, 255]; 256],
            changed: ChangedRows::all(PICTURE_HEIGHT),
        }
    }

    /// Brings the picture to `vga`'s, which shows Mode X.
    fn scan_out(&mut self, vga: &SoftVga) {
        vga.scanout_indices(&mut self.scanned);
        let enabled = vga.video_enabled();
        let mask = vga.dac_pixel_mask();
        let mut same_colours = true;
        for (index, colour) in self.colours.iter_mut().enumerate() {
            let [r, g, b] = vga.dac_entry(index as u8 & mask).map(dac_6_to_8);
            let new = if enabled {
                [r, g, b, 255]
            } else {
                [0, 0, 0, 255]
            };
            same_colours &= *colour == new;
            *colour = new;
        }
        let rows = self
            .scanned
            .as_chunks::<PICTURE_WIDTH>()
            .0
            .iter()
            .zip(self.indices.as_chunks_mut::<PICTURE_WIDTH>().0)
            .zip(self.rgba.as_chunks_mut::<{ 4 * PICTURE_WIDTH }>().0);
        for (row, ((scanned, shown), rgba)) in rows.enumerate() {
            if same_colours && same_bytes(scanned, shown) {
                continue;
            }
            shown.copy_from_slice(scanned);
            for (pixel, &index) in rgba.as_chunks_mut::<4>().0.iter_mut().zip(scanned.iter()) {
                *pixel = self.colours[usize::from(index)];
            }
            self.changed.mark(row..row + 1);
        }
    }
}

/// `total` pixels as whole steps of `step` (toward zero) and the rest.
fn whole_steps(total: f64, step: f64) -> (f64, i32) {
    let steps = (total / step).trunc();
    (total - steps * step, steps as i32)
}

/// Joins runs of rows (top down, apart) fewer than [`PAINT_GAP_ROWS`]
/// apart into one.
fn merge_close_runs(runs: &mut Vec<Range<usize>>) {
    let mut merged: usize = 0;
    for index in 0..runs.len() {
        let run = runs[index].clone();
        match merged.checked_sub(1).map(|last| &mut runs[last]) {
            Some(last) if run.start - last.end < PAINT_GAP_ROWS => last.end = run.end,
            _ => {
                runs[merged] = run;
                merged += 1;
            }
        }
    }
    runs.truncate(merged);
}

/// The panel's width, for the exports.
pub const INSPECTOR_WIDTH: usize = PANEL_WIDTH;
/// The slow-motion panel's size, for the exports.
pub const OPS_SIZE: (usize, usize) = (slow::PANEL_WIDTH, slow::PANEL_HEIGHT);

#[cfg(test)]
mod tests;
