//! What the window tests need from X: a virtual X server of their own with
//! the simulator running in it, keys typed with `xdotool` and the window's
//! picture captured with `xwd`; the X parts are the `xvfb` crate's, which
//! the Bochs tests use too.

use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};
use xvfb::Xvfb;

/// Room for the simulator's widest window (1040x480 with the inspector): a
/// window must fit on the screen to be captured.
const SCREEN: (u32, u32) = (1280, 1024);

/// A private X server; fails (never skips) when a tool is missing, saying
/// how to get it.
pub struct VirtualDisplay(Xvfb);

impl VirtualDisplay {
    pub fn start(timeout: Duration) -> Self {
        VirtualDisplay(Xvfb::start(SCREEN, timeout).unwrap_or_else(|e| panic!("{e}")))
    }

    /// `:N`
    pub fn name(&self) -> &str {
        self.0.display()
    }

    /// Gives the window the keyboard and types one key (an X keysym name),
    /// both from one client, so the server sees them in that order.
    pub fn type_key(&self, window: u64, keysym: &str) {
        let id = window.to_string();
        self.0
            .run("xdotool", &["windowfocus", &id, "key", keysym])
            .unwrap_or_else(|e| panic!("{e}"));
    }

    /// The window's picture as the X server holds it.
    pub fn capture(&self, window: u64) -> Picture {
        let image = self
            .0
            .capture(&format!("0x{window:x}"))
            .unwrap_or_else(|e| panic!("{e}"));
        Picture {
            width: image.width,
            height: image.height,
            pixels: image
                .pixels
                .iter()
                .map(|&[r, g, b]| u32::from_be_bytes([0, r, g, b]))
                .collect(),
        }
    }
}

/// A window the simulator opened.
#[derive(Clone, Copy, Debug)]
pub struct WindowInfo {
    pub id: u64,
    pub width: usize,
    pub height: usize,
}

impl WindowInfo {
    /// From `sim: window 0x200021 640x480`.
    fn parse(line: &str) -> Option<Self> {
        let rest = line.strip_prefix("sim: window 0x")?;
        let (id, size) = rest.split_once(' ')?;
        let (width, height) = size.split_once('x')?;
        Some(WindowInfo {
            id: u64::from_str_radix(id, 16).ok()?,
            width: width.parse().ok()?,
            height: height.parse().ok()?,
        })
    }
}

/// The simulator binary running in a window on the virtual display.
pub struct Simulator {
    child: Child,
    lines: Receiver<String>,
    seen: Vec<String>,
}

impl Simulator {
    pub fn start(display: &VirtualDisplay, args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_sim"))
            .args(args)
            .env("DISPLAY", display.name())
            .env_remove("WAYLAND_DISPLAY")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .spawn()
            .expect("the simulator did not start");
        let lines = xvfb::lines(child.stdout.take().unwrap());
        Simulator {
            child,
            lines,
            seen: Vec::new(),
        }
    }

    /// Waits for a line that `wanted` accepts; fails after `timeout`, with
    /// every line seen so far.
    pub fn wait_for(&mut self, what: &str, timeout: Duration, wanted: impl Fn(&str) -> bool) {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    let done = wanted(&line);
                    self.seen.push(line);
                    if done {
                        return;
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    panic!(
                        "no {what} within {timeout:?}; the simulator said {:?}",
                        self.seen
                    )
                }
                Err(RecvTimeoutError::Disconnected) => {
                    panic!("the simulator ended before {what}; it said {:?}", self.seen)
                }
            }
        }
    }

    pub fn wait_for_line(&mut self, line: &str, timeout: Duration) {
        self.wait_for(&format!("{line:?}"), timeout, |seen| seen == line);
    }

    /// Waits until the window has shown the effect of command `n` (or a later one).
    pub fn wait_for_command(&mut self, n: u64, timeout: Duration) {
        self.wait_for(&format!("command {n} done"), timeout, |line| {
            line.strip_prefix("sim: command ")
                .and_then(|rest| rest.strip_suffix(" done"))
                .and_then(|count| count.parse::<u64>().ok())
                .is_some_and(|count| count >= n)
        });
    }

    pub fn wait_for_window(&mut self, timeout: Duration) -> WindowInfo {
        self.wait_for("window", timeout, |line| WindowInfo::parse(line).is_some());
        self.last_window()
    }

    /// The window the simulator opened last.
    pub fn last_window(&self) -> WindowInfo {
        self.seen
            .iter()
            .rev()
            .find_map(|line| WindowInfo::parse(line))
            .expect("the simulator has reported no window")
    }

    /// Waits until the simulator closes its output and exits.
    pub fn wait_exit(&mut self, timeout: Duration) -> ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => self.seen.push(line),
                Err(RecvTimeoutError::Disconnected) => break,
                Err(RecvTimeoutError::Timeout) => {
                    panic!("the simulator did not exit within {timeout:?}")
                }
            }
        }
        self.child.wait().expect("waiting for the simulator")
    }
}

impl Drop for Simulator {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// An RGB picture, `0RGB` per pixel as the simulator's window buffer holds it.
pub struct Picture {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<u32>,
}

impl Picture {
    /// The leftmost `columns` columns.
    pub fn left(&self, columns: usize) -> Picture {
        Picture {
            width: columns,
            height: self.height,
            pixels: self
                .pixels
                .chunks_exact(self.width)
                .flat_map(|row| row[..columns].iter().copied())
                .collect(),
        }
    }

    pub fn assert_equals(&self, expected: &[u32], width: usize, height: usize, what: &str) {
        assert_eq!(
            (self.width, self.height),
            (width, height),
            "{what}: the window's size"
        );
        let differences: Vec<(usize, usize, u32, u32)> = (0..self.pixels.len())
            .filter(|&i| self.pixels[i] != expected[i])
            .map(|i| (i % width, i / width, self.pixels[i], expected[i]))
            .collect();
        assert!(
            differences.is_empty(),
            "{what}: {} pixels differ from the software VGA's, first (x, y, shown, expected): {:x?}",
            differences.len(),
            &differences[..differences.len().min(5)]
        );
    }

    pub fn write_png(&self, path: &Path) {
        let file = std::fs::File::create(path).expect("creating the PNG");
        let mut encoder = png::Encoder::new(file, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Rgb);
        encoder.set_depth(png::BitDepth::Eight);
        let rgb: Vec<u8> = self
            .pixels
            .iter()
            .flat_map(|&p| [(p >> 16) as u8, (p >> 8) as u8, p as u8])
            .collect();
        let mut writer = encoder.write_header().expect("writing the PNG");
        writer.write_image_data(&rgb).expect("writing the PNG");
    }
}
