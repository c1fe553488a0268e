//! The demo as the kernel runs it: scancodes in, frames out. Everything here is
//! portable, so the host tests drive exactly what the kernel drives.

use crate::frame::{FrameDrawer, Renderer};
use crate::keymap::command_for;
use crate::scene::{Command, Scene};
use modex::{FlipReport, ModeX, VgaBus};
use pc_keyboard::{layouts::Us104Key, HandleControl, PS2Keyboard as Keyboard, ScancodeSet1};

pub struct App {
    scene: Scene,
    renderer: Renderer,
    keyboard: Keyboard<Us104Key, ScancodeSet1>,
    /// Set by any key that is not a command; the next key only clears it.
    paused: bool,
    quit: bool,
    /// The scene changed since the last frame was drawn.
    dirty: bool,
    commands: u64,
}

impl Default for App {
    fn default() -> Self {
        Self::new()
    }
}

impl App {
    pub fn new() -> Self {
        App {
            scene: Scene::new(),
            renderer: Renderer::new(),
            keyboard: Keyboard::new(ScancodeSet1::new(), Us104Key, HandleControl::Ignore),
            paused: false,
            quit: false,
            dirty: true,
            commands: 0,
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

    /// The seed's rules: while paused, the next key only resumes.
    pub fn apply(&mut self, command: Command) {
        self.commands += 1;
        if self.paused {
            self.paused = false;
            return;
        }
        match command {
            Command::Quit => self.quit = true,
            Command::Pause => self.paused = true,
            other => {
                self.scene.apply(other);
                self.dirty = true;
            }
        }
    }

    pub fn quit_requested(&self) -> bool {
        self.quit
    }

    pub fn paused(&self) -> bool {
        self.paused
    }

    /// Commands received so far (including the ones that only paused or resumed).
    pub fn commands(&self) -> u64 {
        self.commands
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The page on screen; the next frame is drawn into the other one.
    pub fn shown_page(&self) -> modex::Page {
        self.renderer.shown_page()
    }

    /// Advances the spin and draws a frame if anything moved; `None` when there
    /// was nothing to draw (the caller can sleep until the next interrupt).
    pub fn step<B: VgaBus>(&mut self, vga: &mut ModeX<B>) -> Option<FlipReport> {
        if self.paused || self.quit {
            return None;
        }
        if self.scene.spinning() {
            self.scene.tick();
            self.dirty = true;
        }
        if !self.dirty {
            return None;
        }
        self.dirty = false;
        Some(self.renderer.draw_frame(vga, &mut self.scene))
    }
}
