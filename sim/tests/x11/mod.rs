//! What the window tests need from X: a virtual X server (`Xvfb`) of their
//! own, the simulator running in it, keys typed with `xdotool`, and the
//! window's picture captured with `xwd` and read here (XWD is a simple format).

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::thread;
use std::time::{Duration, Instant};

const TOOLS: [&str; 3] = ["Xvfb", "xdotool", "xwd"];

/// Fails (never skips) when a tool is missing, saying how to get it.
fn require_tools() {
    let path = std::env::var_os("PATH").unwrap_or_default();
    for tool in TOOLS {
        let found = std::env::split_paths(&path).any(|dir| dir.join(tool).is_file());
        assert!(
            found,
            "{tool} is not installed: boot/setup.sh installs it \
             (apt packages xvfb xdotool x11-apps)"
        );
    }
}

/// The lines a child prints on stdout, read by a thread as they come.
fn line_reader(stdout: impl Read + Send + 'static) -> Receiver<String> {
    let (sender, receiver) = channel();
    thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if sender.send(line).is_err() {
                break;
            }
        }
    });
    receiver
}

/// A private X server on a display number it picks itself (`-displayfd`
/// tells the number once the server is ready for clients).
pub struct VirtualDisplay {
    server: Child,
    /// `:N`
    pub name: String,
}

impl VirtualDisplay {
    pub fn start(timeout: Duration) -> Self {
        require_tools();
        let mut server = Command::new("Xvfb")
            .args([
                "-displayfd",
                "1",
                "-screen",
                "0",
                "1280x1024x24",
                "-nolisten",
                "tcp",
            ])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("Xvfb did not start");
        let lines = line_reader(server.stdout.take().unwrap());
        let number = match lines.recv_timeout(timeout) {
            Ok(number) => number,
            Err(e) => {
                let _ = server.kill();
                panic!("Xvfb did not report its display number: {e}");
            }
        };
        VirtualDisplay {
            server,
            name: format!(":{}", number.trim()),
        }
    }

    fn run(&self, program: &str, args: &[&str]) -> Vec<u8> {
        let output = Command::new(program)
            .args(args)
            .env("DISPLAY", &self.name)
            .stdin(Stdio::null())
            .output()
            .unwrap_or_else(|e| panic!("{program} did not run: {e}"));
        assert!(
            output.status.success(),
            "{program} {args:?} failed: {}",
            String::from_utf8_lossy(&output.stderr)
        );
        output.stdout
    }

    /// Gives the window the keyboard and types one key (an X keysym name),
    /// both from one client, so the server sees them in that order.
    pub fn type_key(&self, window: u64, keysym: &str) {
        let id = window.to_string();
        self.run("xdotool", &["windowfocus", &id, "key", keysym]);
    }

    /// The window's picture as the X server holds it.
    pub fn capture(&self, window: u64) -> Picture {
        let id = format!("0x{window:x}");
        Picture::from_xwd(&self.run("xwd", &["-silent", "-id", &id]))
    }
}

impl Drop for VirtualDisplay {
    fn drop(&mut self) {
        let _ = self.server.kill();
        let _ = self.server.wait();
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
            .env("DISPLAY", &display.name)
            .env_remove("WAYLAND_DISPLAY")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .spawn()
            .expect("the simulator did not start");
        let lines = line_reader(child.stdout.take().unwrap());
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

/// Reads a big-endian 32-bit header field.
fn field(bytes: &[u8], index: usize) -> u32 {
    u32::from_be_bytes(bytes[index * 4..index * 4 + 4].try_into().unwrap())
}

// XWD header fields (X11 XWDFile.h), each a big-endian CARD32.
const HEADER_SIZE: usize = 0;
const PIXMAP_FORMAT: usize = 2;
const WIDTH: usize = 4;
const HEIGHT: usize = 5;
const BYTE_ORDER: usize = 7;
const BITS_PER_PIXEL: usize = 11;
const BYTES_PER_LINE: usize = 12;
const RED_MASK: usize = 14;
const GREEN_MASK: usize = 15;
const BLUE_MASK: usize = 16;
const COLORMAP_ENTRIES: usize = 19;
const XWD_COLOR_BYTES: usize = 12;
const Z_PIXMAP: u32 = 2;
const LSB_FIRST: u32 = 0;

impl Picture {
    /// A 32-bit TrueColor ZPixmap dump, as `xwd` writes one of a 24-bit
    /// Xvfb screen.
    pub fn from_xwd(bytes: &[u8]) -> Self {
        assert!(bytes.len() >= 100, "xwd wrote {} bytes", bytes.len());
        assert_eq!(field(bytes, PIXMAP_FORMAT), Z_PIXMAP, "not a ZPixmap dump");
        assert_eq!(field(bytes, BITS_PER_PIXEL), 32, "not 32 bits per pixel");
        let width = field(bytes, WIDTH) as usize;
        let height = field(bytes, HEIGHT) as usize;
        let stride = field(bytes, BYTES_PER_LINE) as usize;
        let data_start = field(bytes, HEADER_SIZE) as usize
            + field(bytes, COLORMAP_ENTRIES) as usize * XWD_COLOR_BYTES;
        let masks = [RED_MASK, GREEN_MASK, BLUE_MASK].map(|index| field(bytes, index));
        let little_endian = field(bytes, BYTE_ORDER) == LSB_FIRST;
        let data = &bytes[data_start..];
        assert!(data.len() >= stride * height, "the dump is cut short");
        let mut pixels = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let raw: [u8; 4] = data[y * stride + x * 4..][..4].try_into().unwrap();
                let value = if little_endian {
                    u32::from_le_bytes(raw)
                } else {
                    u32::from_be_bytes(raw)
                };
                let [r, g, b] = masks.map(|mask| (value & mask) >> mask.trailing_zeros());
                pixels.push(r << 16 | g << 8 | b);
            }
        }
        Picture {
            width,
            height,
            pixels,
        }
    }

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
