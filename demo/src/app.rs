//! The demo as the kernel runs it: scancodes in, frames out. Everything here is
//! portable, so the host tests drive exactly what the kernel drives.

use crate::command::{Command, LightTurn, SceneCommand};
use crate::frame::Renderer;
use crate::keymap::command_for;
use crate::osd::{self, Overlay, Stats};
use crate::scene::Scene;
use crate::shading::{ramp_palette, RAMP_FIRST};
use core::borrow::BorrowMut;
use engine::FaceCounts;
use modex::{FlipReport, ModeX, VgaBus};
use pc_keyboard::{layouts::Us104Key, HandleControl, PS2Keyboard as Keyboard, ScancodeSet1};

/// Microseconds from any fixed start: the kernel reads the TSC, tests pass
/// a closure over a counter they advance themselves.
pub trait Clock {
    /// Microseconds since the clock's start.
    fn micros(&self) -> u64;
}

impl<F: Fn() -> u64> Clock for F {
    fn micros(&self) -> u64 {
        self()
    }
}

const MICROS_PER_SECOND: u64 = 1_000_000;

/// Frames drawn per second, counted over windows of at least a second.
#[derive(Default)]
struct FrameRate {
    window_start: Option<u64>,
    frames: u64,
    tenths: Option<u32>,
}

impl FrameRate {
    fn frame_drawn(&mut self, now: u64) {
        let Some(start) = self.window_start else {
            self.window_start = Some(now);
            return;
        };
        self.frames += 1;
        let elapsed = now.saturating_sub(start);
        if elapsed >= MICROS_PER_SECOND {
            let tenths = self.frames * 10 * MICROS_PER_SECOND / elapsed;
            self.tenths = Some(u32::try_from(tenths).unwrap_or(u32::MAX));
            self.window_start = Some(now);
            self.frames = 0;
        }
    }

    /// A second has passed since the figure was last brought up to date.
    fn stale(&self, now: u64) -> bool {
        self.window_start
            .is_some_and(|start| now.saturating_sub(start) >= MICROS_PER_SECOND)
    }
}

/// The demo: keyboard decoding, the scene, the renderer and the overlay,
/// stepped once per frame by the kernel or a test.
///
/// The renderer holds three 75 KiB frame images, the 300 KiB depth buffer,
/// the scene's faces and the page update's list of writes (742 KiB in all). `App` owns it by default (a host test
/// boxes the app or keeps it where it likes); the kernel lends it one in
/// static memory instead ([`App::with_renderer`]), so the images never sit
/// on the kernel stack.
///
/// # Example
///
/// A renderer lent to the app, as the kernel lends its static one; the
/// letter N puts the next solid in the cube's place:
///
/// ```
/// use demo::app::App;
/// use demo::frame::Renderer;
/// use modex::soft::SoftVga;
/// use modex::ModeX;
///
/// let mut soft = Box::new(SoftVga::new());
/// let mut vga = ModeX::new(&mut *soft);
/// vga.set_mode();
/// let mut renderer = Box::new(Renderer::new());
/// let mut app = App::with_renderer(&mut *renderer);
/// assert!(app.step(&mut vga, &|| 0u64).is_some());
/// app.feed_scancode(0x31); // N pressed
/// app.feed_scancode(0xB1); // and released
/// assert_eq!(app.commands(), 1);
/// assert_ne!(app.scene().solid().name, "cube");
/// ```
pub struct App<R: BorrowMut<Renderer> = Renderer> {
    scene: Scene,
    renderer: R,
    keyboard: Keyboard<Us104Key, ScancodeSet1>,
    /// Set by any key that is not a command; the next key only clears it.
    paused: bool,
    quit: bool,
    /// Something changed since the last frame was drawn.
    dirty: bool,
    commands: u64,
    overlay: Overlay,
    frame_rate: FrameRate,
    last_frame_micros: u32,
    last_faces: FaceCounts,
    palette_loaded: bool,
    /// The report screen, while it is up.
    report: Option<ReportView>,
    /// The report was left: show the demo's page again on the next step.
    restore_page: bool,
    frames_drawn: u64,
}

/// The report screen's state in the app: how far its log is scrolled back,
/// and whether the screen shows that yet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReportView {
    /// Log lines scrolled back from the newest (0: the newest line is at the
    /// bottom of the window).
    pub scroll: usize,
    drawn: bool,
}

impl<R: BorrowMut<Renderer>> core::fmt::Debug for App<R> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("App")
            .field("scene", &self.scene)
            .field("renderer", self.renderer.borrow())
            .field("paused", &self.paused)
            .field("quit", &self.quit)
            .field("commands", &self.commands)
            .field("overlay", &self.overlay)
            .finish_non_exhaustive()
    }
}

impl Default for App {
    fn default() -> Self {
        Self::new()
    }
}

impl App {
    /// The demo at boot: the cube spinning, no overlay.
    pub fn new() -> Self {
        App::with_renderer(Renderer::new())
    }
}

impl<R: BorrowMut<Renderer>> App<R> {
    /// The demo at boot, drawing with `renderer` (reset first: both pages
    /// blank, page 0 shown, as `ModeX::set_mode` leaves them).
    pub fn with_renderer(mut renderer: R) -> Self {
        renderer.borrow_mut().reset();
        App {
            scene: Scene::new(),
            renderer,
            keyboard: Keyboard::new(ScancodeSet1::new(), Us104Key, HandleControl::Ignore),
            paused: false,
            quit: false,
            dirty: true,
            commands: 0,
            overlay: Overlay::default(),
            frame_rate: FrameRate::default(),
            last_frame_micros: 0,
            last_faces: FaceCounts::default(),
            palette_loaded: false,
            report: None,
            restore_page: false,
            frames_drawn: 0,
        }
    }

    /// Decodes one byte from the keyboard; a completed key becomes a command.
    pub fn feed_scancode(&mut self, byte: u8) {
        let Ok(Some(event)) = self.keyboard.add_byte(byte) else {
            return;
        };
        if let Some(key) = self.keyboard.process_keyevent(event) {
            if let Some(command) = command_for(key) {
                self.apply(command);
            }
        }
    }

    /// Abrash's rules: while paused, the next key only resumes.
    pub fn apply(&mut self, command: Command) {
        self.commands += 1;
        if self.paused {
            self.paused = false;
            return;
        }
        if let Some(view) = self.report {
            if command != Command::Scene(SceneCommand::Reset) {
                self.report_key(command, view.scroll);
                return;
            }
            // R leaves the report too: back to the starting scene, drawn
            // afresh below.
            self.report = None;
        }
        match command {
            // Neither changes the picture: nothing to redraw.
            Command::Quit => {
                self.quit = true;
                return;
            }
            Command::Pause => {
                self.paused = true;
                return;
            }
            Command::ToggleReport => {
                self.report = Some(ReportView::default());
                return;
            }
            Command::ToggleHelp => self.overlay.help = !self.overlay.help,
            Command::ToggleStats => {
                self.overlay.stats = !self.overlay.stats;
                self.frame_rate = FrameRate::default();
            }
            Command::Scene(SceneCommand::Reset) => {
                // The starting scene has no display over it either.
                self.overlay = Overlay::default();
                self.scene.apply(SceneCommand::Reset);
            }
            Command::Scene(command) => self.scene.apply(command),
        }
        self.dirty = true;
    }

    /// A key while the report is up (other than R): scroll, leave, or quit;
    /// the scene never sees it.
    fn report_key(&mut self, command: Command, scroll: usize) {
        let page = crate::report::LOG_ROWS;
        let scroll = match command {
            Command::ToggleReport => {
                self.report = None;
                self.restore_page = true;
                return;
            }
            Command::Quit => {
                self.quit = true;
                return;
            }
            Command::Scene(SceneCommand::MoveUp) => scroll.saturating_add(1),
            Command::Scene(SceneCommand::MoveDown) => scroll.saturating_sub(1),
            Command::Scene(SceneCommand::TurnLight(LightTurn::Up)) => scroll.saturating_add(page),
            Command::Scene(SceneCommand::TurnLight(LightTurn::Down)) => scroll.saturating_sub(page),
            _ => return,
        };
        self.report = Some(ReportView {
            scroll,
            drawn: false,
        });
    }

    /// The report screen is up and must be drawn, scrolled back this many
    /// lines: the caller gathers the facts, draws it
    /// (`crate::report::show`) and calls [`App::report_drawn`].
    pub fn report_to_draw(&self) -> Option<usize> {
        self.report
            .filter(|view| !view.drawn && !self.paused && !self.quit)
            .map(|view| view.scroll)
    }

    /// The report is on screen, scrolled back `scroll` lines (the caller
    /// clamps the scroll to the log it has).
    pub fn report_drawn(&mut self, scroll: usize) {
        if self.report.is_some() {
            self.report = Some(ReportView {
                scroll,
                drawn: true,
            });
        }
    }

    /// Whether the report screen is up.
    pub fn report_shown(&self) -> bool {
        self.report.is_some()
    }

    /// Frames drawn since the start.
    pub fn frames_drawn(&self) -> u64 {
        self.frames_drawn
    }

    /// Esc was pressed: the caller should leave.
    pub fn quit_requested(&self) -> bool {
        self.quit
    }

    /// Waiting for any key (after a key that is not a command).
    pub fn paused(&self) -> bool {
        self.paused
    }

    /// Commands received so far (including the ones that only paused or resumed).
    pub fn commands(&self) -> u64 {
        self.commands
    }

    /// The scene being drawn.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Which of help and statistics are shown.
    pub fn overlay(&self) -> Overlay {
        self.overlay
    }

    /// What the statistics lines show on the next frame.
    pub fn stats(&self) -> Stats {
        Stats {
            frames_per_second_tenths: self.frame_rate.tenths,
            frame_micros: self.last_frame_micros,
            faces: self.last_faces,
            solid: self.scene.solid().name,
            objects: self.scene.objects().len(),
            lighting: self.scene.lighting(),
        }
    }

    /// The page on screen; the next frame is drawn into the other one.
    pub fn shown_page(&self) -> modex::Page {
        self.renderer.borrow().shown_page()
    }

    /// Advances the spin and draws a frame if anything moved (or, with the
    /// statistics on, once a second to bring them up to date); `None` when
    /// there was nothing to draw (the caller can sleep until the next
    /// interrupt).
    pub fn step<B: VgaBus>(
        &mut self,
        vga: &mut ModeX<B>,
        clock: &impl Clock,
    ) -> Option<FlipReport> {
        if self.paused || self.quit {
            return None;
        }
        if self.restore_page {
            // The report used the spare page only: the demo's page still
            // holds what it showed, and the shadows are still true.
            self.restore_page = false;
            return Some(vga.show_page(self.renderer.borrow().shown_page()));
        }
        if self.report.is_some() {
            return None;
        }
        if !self.palette_loaded {
            // The shading ramps sit in DAC entries nothing else uses, so they
            // are loaded once and stay.
            vga.load_palette(RAMP_FIRST, &ramp_palette());
            self.palette_loaded = true;
        }
        let start = clock.micros();
        if self.scene.spinning() {
            self.scene.tick();
            self.dirty = true;
        }
        if self.overlay.stats && self.frame_rate.stale(start) {
            self.dirty = true;
        }
        if !self.dirty {
            return None;
        }
        self.dirty = false;
        self.frames_drawn += 1;
        self.frame_rate.frame_drawn(start);
        let (overlay, stats) = (self.overlay, self.stats());
        let (page, faces) = self.renderer.borrow_mut().draw_with_overlay(
            vga,
            &mut self.scene,
            |image, drawn, faces| osd::draw(image, drawn, overlay, &Stats { faces, ..stats }),
        );
        self.last_faces = faces;
        let elapsed = clock.micros().saturating_sub(start);
        self.last_frame_micros = u32::try_from(elapsed).unwrap_or(u32::MAX);
        Some(vga.show_page(page))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::osd::{help_box, BAR_ROWS};
    use core::cell::Cell;
    use modex::soft::SoftVga;
    use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};
    use std::boxed::Box;
    use std::vec::Vec;

    const WIDTH: usize = SCREEN_WIDTH as usize;
    use clock::pacing::FRAME_MICROS;

    fn soft_vga_in_mode_x() -> Box<SoftVga> {
        let mut soft = Box::new(SoftVga::new());
        ModeX::new(&mut *soft).set_mode();
        soft
    }

    fn picture(soft: &SoftVga) -> Vec<u8> {
        let mut pixels = std::vec![0; WIDTH * SCREEN_HEIGHT as usize];
        assert_eq!(soft.scanout_indices(&mut pixels), (320, 240));
        pixels
    }

    /// A still cube (spin off), one frame drawn after `commands`.
    fn still_picture(commands: &[Command]) -> Vec<u8> {
        let mut soft = soft_vga_in_mode_x();
        let mut app = App::new();
        app.apply(Command::Scene(SceneCommand::Reset));
        for &command in commands {
            app.apply(command);
        }
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        picture(&soft)
    }

    fn differing_pixels(a: &[u8], b: &[u8]) -> Vec<(usize, usize)> {
        (0..a.len())
            .filter(|&i| a[i] != b[i])
            .map(|i| (i % WIDTH, i / WIDTH))
            .collect()
    }

    #[test]
    fn help_covers_its_box_only_and_goes_away_again() {
        let plain = still_picture(&[]);
        let help = still_picture(&[Command::ToggleHelp]);
        let changed = differing_pixels(&plain, &help);
        assert!(changed.len() > 10_000, "{} pixels changed", changed.len());
        let frame = help_box();
        for (x, y) in changed {
            assert!(frame.contains(embedded_graphics::prelude::Point::new(x as i32, y as i32)));
        }
        let closed = still_picture(&[Command::ToggleHelp, Command::ToggleHelp]);
        assert!(closed == plain);
    }

    #[test]
    fn reset_closes_help_and_statistics_too() {
        let plain = still_picture(&[]);
        let extras = [
            Command::ToggleHelp,
            Command::ToggleStats,
            Command::Scene(SceneCommand::ToggleLighting),
            Command::Scene(SceneCommand::ToggleSeveral),
            Command::Scene(SceneCommand::NextSolid),
            Command::Scene(SceneCommand::Reset),
        ];
        assert!(still_picture(&extras) == plain);
    }

    #[test]
    fn statistics_stay_in_the_top_and_bottom_twelve_rows() {
        // Moved up and toward, so the cube itself reaches into the top rows.
        let moves = [Command::Scene(SceneCommand::MoveUp); 12]
            .into_iter()
            .chain([Command::Scene(SceneCommand::Toward); 10]);
        let plain = still_picture(&moves.clone().collect::<Vec<_>>());
        let with_stats: Vec<Command> = moves.chain([Command::ToggleStats]).collect();
        let stats = still_picture(&with_stats);
        let changed = differing_pixels(&plain, &stats);
        assert!(changed.len() > 200);
        let top = BAR_ROWS as usize;
        let bottom = (SCREEN_HEIGHT - BAR_ROWS) as usize;
        assert!(changed.iter().any(|&(_, y)| y < top));
        assert!(changed.iter().any(|&(_, y)| y >= bottom));
        for (x, y) in changed {
            assert!(y < top || y >= bottom, "({x}, {y})");
        }
    }

    #[test]
    fn frame_rate_and_frame_time_are_measured_with_the_clock() {
        let mut soft = soft_vga_in_mode_x();
        let mut app = App::new(); // spinning: a frame every step
        app.apply(Command::ToggleStats);
        // Each read of the clock moves it on by 300 µs, and each frame starts
        // a Mode X refresh (16,747 µs) after the last.
        let now = Cell::new(0u64);
        let clock = || {
            now.set(now.get() + 300);
            now.get()
        };
        for frame in 0..150u64 {
            now.set(frame * FRAME_MICROS);
            app.step(&mut ModeX::new(&mut *soft), &clock);
        }
        let stats = app.stats();
        assert_eq!(stats.frame_micros, 300);
        // 60 frames in 60 · 16,747 µs: 59.71 per second.
        assert_eq!(stats.frames_per_second_tenths, Some(597));
        assert_eq!(&*stats.top_line(), "59.7 fps  0.30 ms/frame");
        assert_eq!(stats.faces.drawn + stats.faces.culled, 6);
    }

    #[test]
    fn with_statistics_on_an_idle_scene_is_redrawn_once_a_second() {
        let mut soft = soft_vga_in_mode_x();
        let mut app = App::new();
        app.apply(Command::Scene(SceneCommand::Reset)); // still
        let now = Cell::new(0u64);
        let clock = || now.get();
        let mut step = |app: &mut App, at: u64| {
            now.set(at);
            app.step(&mut ModeX::new(&mut *soft), &clock).is_some()
        };
        assert!(step(&mut app, 0), "the first frame");
        assert!(!step(&mut app, 2_000_000), "statistics off: nothing to do");
        app.apply(Command::ToggleStats);
        assert!(step(&mut app, 2_100_000), "switching them on draws");
        assert!(!step(&mut app, 2_600_000));
        assert!(step(&mut app, 3_200_000), "a second later");
        assert!(!step(&mut app, 3_300_000));
    }

    #[test]
    fn the_shading_ramps_are_in_the_dac_before_the_first_frame() {
        let mut soft = soft_vga_in_mode_x();
        let mut app = App::new();
        app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
        for (offset, colour) in ramp_palette().iter().enumerate() {
            assert_eq!(soft.dac_entry(RAMP_FIRST + offset as u8), *colour);
        }
        assert_eq!(soft.dac_entry(9), modex::palette::DEFAULT_PALETTE[9]);
    }
}
