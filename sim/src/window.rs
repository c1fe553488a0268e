//! The desktop window: host keys become scan codes in the kernel's own
//! scancode queue, the demo runs a frame per retrace of the model, and the
//! scan-out (with the inspector beside it) goes to the window, paced at the
//! model's refresh rate.
//!
//! For tests, it prints a line on stdout when something they wait for has
//! reached the screen (like the kernel's `demo: command N done`): the window
//! (`sim: window 0x... WxH`), each command (`sim: command N done`) and the
//! inspector (`sim: inspector shown` / `hidden`), each one frame after the
//! frame that showed it was presented.

use std::sync::Arc;
use std::thread::sleep;
use std::time::{Duration, Instant};

use demo::keymap::INSPECTOR_KEY;
use keyboard::scancode_queue::ScancodeQueue;
use minifb::{InputCallback, Key, Window, WindowOptions};
use sim::inspector::{draw_panel, History, PANEL_WIDTH};
use sim::keys::{scancode_for_key, scancode_for_name};
use sim::machine::Machine;
use sim::record::Script;
use sim::screen::{compose, window_size};

/// What the window shows and types.
pub struct Options {
    /// Pixels per VGA pixel, each way.
    pub scale: usize,
    /// The inspector is open at start.
    pub inspect: bool,
    /// Keys typed by themselves, as with `--record`.
    pub script: Script,
}

const TITLE: &str = "modex-cube on the software VGA (Esc quits, V: inspector)";
/// Behind by more than this, pacing starts afresh instead of rushing frames.
const MAX_LAG_FRAMES: u32 = 3;
/// The byte before the make code of an extended key.
const EXTENDED_PREFIX: u8 = 0xE0;

/// The keyboard: minifb reports each key event here, in order, and each
/// becomes its make or break code in the queue the frame loop drains, as the
/// kernel's interrupt handler fills its queue. A key held down repeats its
/// make code, as a PC keyboard's typematic repeat does.
struct Keyboard(Arc<ScancodeQueue>);

impl InputCallback for Keyboard {
    fn add_char(&mut self, _character: u32) {}

    fn set_key_state(&mut self, key: Key, down: bool) {
        if let Some(scancode) = scancode_for_key(key) {
            let bytes = if down {
                scancode.make()
            } else {
                scancode.release()
            };
            for &byte in bytes.iter() {
                self.0.push(byte);
            }
        }
    }
}

fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|name| std::env::var_os(name).is_some_and(|value| !value.is_empty()))
}

const NO_WINDOW_HINT: &str = "record the demo without a window instead, e.g.\n  \
     cargo run --release -p sim -- --record cube.gif --frames 240";

/// Why the window could not be shown; the first two say to use `--record`.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// Neither $DISPLAY nor $WAYLAND_DISPLAY is set.
    #[error(
        "no display: $DISPLAY and $WAYLAND_DISPLAY are unset, so there is no window to open; \
         {NO_WINDOW_HINT}"
    )]
    NoDisplay,
    /// A display is set but the window did not open on it.
    #[error("the window did not open ({0:?}); {NO_WINDOW_HINT}")]
    Open(minifb::Error),
    /// The window refused a picture.
    #[error("the window did not take the picture: {0}")]
    Update(minifb::Error),
}

fn open(scale: usize, inspect: bool, queue: &Arc<ScancodeQueue>) -> Result<Window, WindowError> {
    let (width, height) = window_size(scale, inspect.then_some(PANEL_WIDTH));
    let mut window =
        Window::new(TITLE, width, height, WindowOptions::default()).map_err(WindowError::Open)?;
    window.set_input_callback(Box::new(Keyboard(Arc::clone(queue))));
    // The frame loop paces itself by the model's refresh rate.
    window.set_target_fps(0);
    Ok(window)
}

/// The lines tests wait for, each printed once the frame after the one that
/// showed it has been presented too.
#[derive(Default)]
struct Reports {
    due: Vec<String>,
}

impl Reports {
    fn after_next_frame(&mut self, line: String) {
        self.due.push(line);
    }

    fn frame_presented(&mut self) {
        for line in self.due.drain(..) {
            println!("{line}");
        }
    }
}

/// Keeps the loop to the model's refresh rate on the host's clock.
struct Pacer {
    frame_time: Duration,
    deadline: Instant,
}

impl Pacer {
    fn new(frame_time: Duration) -> Self {
        Pacer {
            frame_time,
            deadline: Instant::now(),
        }
    }

    /// Sleeps until the next frame is due; far behind, starts afresh.
    fn wait_for_next_frame(&mut self) {
        self.deadline += self.frame_time;
        let now = Instant::now();
        if self.deadline > now {
            sleep(self.deadline - now);
        } else if now - self.deadline > self.frame_time * MAX_LAG_FRAMES {
            self.deadline = now;
        }
    }
}

/// The keyboard's side of the loop: hands every queued byte to the demo, as
/// the kernel's loop does, and says whether V's make code (not a byte of an
/// E0 sequence) came an odd number of times, which toggles the inspector.
struct KeyReader {
    inspector_code: Option<u8>,
    previous_byte: Option<u8>,
}

impl KeyReader {
    fn new() -> Self {
        KeyReader {
            inspector_code: scancode_for_name(&INSPECTOR_KEY.to_string()).map(|key| key.code),
            previous_byte: None,
        }
    }

    fn drain(&mut self, queue: &ScancodeQueue, machine: &mut Machine) -> bool {
        let mut toggle_inspector = false;
        while let Some(byte) = queue.pop() {
            toggle_inspector ^=
                Some(byte) == self.inspector_code && self.previous_byte != Some(EXTENDED_PREFIX);
            self.previous_byte = Some(byte);
            // The demo gets V too, and ignores it as the kernel does.
            machine.feed(&[byte]);
        }
        toggle_inspector
    }
}

/// Runs the demo in a window until Esc or the window is closed.
pub fn run(options: &Options) -> Result<(), WindowError> {
    if !has_display() {
        return Err(WindowError::NoDisplay);
    }
    let queue = Arc::new(ScancodeQueue::new());
    let mut inspect = options.inspect;
    let mut window = open(options.scale, inspect, &queue)?;
    let mut machine = Machine::new();
    let mut history = History::default();
    let mut keys = KeyReader::new();
    let mut pacer = Pacer::new(Duration::from_nanos(machine.vga().timing().frame_ns()));
    let mut reports = Reports::default();
    let mut reported_commands = machine.app().commands();
    let mut new_window = true;
    let mut frame = 0;
    while window.is_open() {
        if let Some(key) = options.script.key_before(frame) {
            for byte in sim::keys::tap(key) {
                queue.push(byte);
            }
        }
        let toggle_inspector = keys.drain(&queue, &mut machine);
        if machine.app().quit_requested() {
            println!("sim: Esc: goodbye");
            return Ok(());
        }
        history.push(machine.frame());
        if toggle_inspector {
            inspect = !inspect;
            // minifb windows keep their size: a new one fits the panel. It
            // opens before the old one closes, so the X server always has a
            // client (Xvfb, for one, resets when its last client leaves).
            window = open(options.scale, inspect, &queue)?;
            new_window = true;
        }
        let (width, height) = window_size(options.scale, inspect.then_some(PANEL_WIDTH));
        let panel = inspect.then(|| draw_panel(machine.vga(), &history, height));
        let pixels = compose(&machine.scanout_rgb(), options.scale, panel.as_ref());
        window
            .update_with_buffer(&pixels, width, height)
            .map_err(WindowError::Update)?;
        reports.frame_presented();
        if new_window {
            new_window = false;
            let id = window.get_window_handle() as usize;
            reports.after_next_frame(format!("sim: window 0x{id:x} {width}x{height}"));
        }
        if toggle_inspector {
            let state = if inspect { "shown" } else { "hidden" };
            reports.after_next_frame(format!("sim: inspector {state}"));
        }
        if machine.app().commands() != reported_commands {
            reported_commands = machine.app().commands();
            reports.after_next_frame(format!("sim: command {reported_commands} done"));
        }
        frame += 1;
        pacer.wait_for_next_frame();
    }
    Ok(())
}
