//! What the window tests need from X, shared by the Bochs harness
//! (`boot/bochs.rs`) and the simulator's window tests (`sim/tests/`): a
//! virtual X server of their own ([`Xvfb`]), X clients run on it (`xdotool`
//! to type keys and find windows), and windows captured with `xwd` and read
//! by [`xwd::parse`].
//!
//! One crate of its own because both sides need it and neither should
//! depend on the other: the runner's package builds the kernel, and the
//! simulator pulls in a window library.
//!
//! Reading a window dump needs no X server. A 2x1 dump as `xwd` writes one
//! from a 24-bit TrueColor window on an x86 X server:
//!
//! ```
//! // 25 big-endian header fields; the parser reads these.
//! let mut header = [0u32; 25];
//! header[0] = 100; // header_size: no window name follows
//! header[1] = 7; // file_version
//! header[2] = 2; // pixmap_format: ZPixmap
//! header[4] = 2; // pixmap_width
//! header[5] = 1; // pixmap_height
//! header[7] = 0; // byte_order: LSBFirst
//! header[11] = 32; // bits_per_pixel
//! header[12] = 8; // bytes_per_line
//! header[13] = 4; // visual_class: TrueColor
//! header[14..17].copy_from_slice(&[0xFF0000, 0x00FF00, 0x0000FF]); // masks
//! let mut dump: Vec<u8> = header.iter().flat_map(|f| f.to_be_bytes()).collect();
//! for pixel in [0x00FC_0000u32, 0x0001_0203] {
//!     dump.extend_from_slice(&pixel.to_le_bytes());
//! }
//!
//! let image = xvfb::xwd::parse(&dump)?;
//! assert_eq!((image.width, image.height), (2, 1));
//! assert_eq!(image.pixels, vec![[252, 0, 0], [1, 2, 3]]);
//! # Ok::<(), xvfb::xwd::XwdError>(())
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod xwd;

use std::io::{self, BufRead, BufReader, Read};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, Receiver};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The programs an X test runs, and the Debian packages that hold them.
pub const TOOLS: [(&str, &str); 3] = [
    ("Xvfb", "xvfb"),
    ("xdotool", "xdotool"),
    ("xwd", "x11-apps"),
];

/// How often a stopping server is looked at.
const POLL_INTERVAL: Duration = Duration::from_millis(20);
/// How long a server has to go after SIGTERM before it is killed.
const STOP_TIMEOUT: Duration = Duration::from_secs(1);

/// What went wrong with the X server or an X client.
#[derive(Debug, thiserror::Error)]
pub enum X11Error {
    /// Tools are missing: the Debian packages that hold them.
    #[error(
        "the X tests need the Debian packages {}: install them with `boot/setup.sh` \
         (or `sudo apt-get install xvfb xdotool x11-apps`)",
        .missing.join(", ")
    )]
    NotInstalled {
        /// The packages to install.
        missing: Vec<&'static str>,
    },
    /// A program could not be started at all.
    #[error("cannot start {program}: {error}")]
    Spawn {
        /// The program's name.
        program: String,
        /// Why not.
        error: io::Error,
    },
    /// Xvfb did not say which display it serves (it failed, or took too long).
    #[error("Xvfb gave no display number ({outcome}); its log:\n{log}")]
    NoDisplayNumber {
        /// What was read instead, or that nothing was.
        outcome: String,
        /// What Xvfb wrote on stderr.
        log: String,
    },
    /// An X client ran and failed.
    #[error("{command} failed ({status}): {stderr}")]
    ClientFailed {
        /// The program and its arguments.
        command: String,
        /// How it ended.
        status: ExitStatus,
        /// What it said.
        stderr: String,
    },
    /// `xwd` wrote something that is not a picture this crate reads.
    #[error("cannot read xwd's dump of window {window}: {error}")]
    Dump {
        /// The window, as it was named to `xwd`.
        window: String,
        /// What is wrong with the dump.
        error: xwd::XwdError,
    },
}

/// Whether `program` is an executable file in a directory of `$PATH`.
pub fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|path| std::env::split_paths(&path).any(|dir| dir.join(program).is_file()))
}

/// The Debian packages of [`TOOLS`] whose programs are not on `$PATH`.
pub fn missing_packages() -> Vec<&'static str> {
    TOOLS
        .iter()
        .filter(|(tool, _)| !on_path(tool))
        .map(|&(_, package)| package)
        .collect()
}

/// The lines a child prints, read by a thread as they come; the channel
/// closes when the child closes its end.
pub fn lines(output: impl Read + Send + 'static) -> Receiver<String> {
    let (sender, receiver) = channel();
    std::thread::spawn(move || {
        for line in BufReader::new(output).lines().map_while(Result::ok) {
            if sender.send(line).is_err() {
                break;
            }
        }
    });
    receiver
}

/// A private X server, on a display number it picks itself. Dropping it
/// stops the server.
pub struct Xvfb {
    server: Child,
    /// `:N`
    display: String,
    /// What the server has written on stderr.
    log: Arc<Mutex<Vec<u8>>>,
}

impl Xvfb {
    /// Starts Xvfb with one screen of `width` x `height` at 24 bits a pixel
    /// (TrueColor, which [`xwd::parse`] reads exactly). A window must fit on
    /// the screen to be captured.
    ///
    /// With `-displayfd` the server picks the first free display number and
    /// writes it to us once it accepts clients, so neither a guessed number
    /// nor a wait is needed. `-noreset`: by default the server resets
    /// whenever its last client leaves, and a short-lived `xdotool` leaving
    /// while Bochs connected made Bochs fail with "cannot connect to X server".
    pub fn start(screen: (u32, u32), timeout: Duration) -> Result<Xvfb, X11Error> {
        Self::start_with(Command::new("Xvfb"), screen, timeout)
    }

    /// [`Xvfb::start`] with the caller's command for the server, which must
    /// run `Xvfb` (through a wrapper that becomes it, say, so that the server
    /// dies with the process that started it); the arguments are added here.
    pub fn start_with(
        mut command: Command,
        screen: (u32, u32),
        timeout: Duration,
    ) -> Result<Xvfb, X11Error> {
        let missing = missing_packages();
        if !missing.is_empty() {
            return Err(X11Error::NotInstalled { missing });
        }
        let mut server = command
            .args(["-displayfd", "1", "-noreset", "-nolisten", "tcp"])
            .args(["-screen", "0", &format!("{}x{}x24", screen.0, screen.1)])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|error| X11Error::Spawn {
                program: "Xvfb".into(),
                error,
            })?;
        // Read stderr all along: a full pipe would stop the server.
        let log = Arc::new(Mutex::new(Vec::new()));
        let mut stderr = server.stderr.take().expect("stderr is piped");
        let sink = Arc::clone(&log);
        std::thread::spawn(move || {
            let mut chunk = [0; 4096];
            while let Ok(read @ 1..) = stderr.read(&mut chunk) {
                sink.lock().unwrap().extend_from_slice(&chunk[..read]);
            }
        });
        let numbers = lines(server.stdout.take().expect("stdout is piped"));
        let mut xvfb = Xvfb {
            server,
            display: String::new(),
            log,
        };
        match numbers.recv_timeout(timeout) {
            Ok(line) if line.trim().parse::<u32>().is_ok() => {
                xvfb.display = format!(":{}", line.trim());
                Ok(xvfb)
            }
            // Dropping `xvfb` stops the server.
            outcome => Err(X11Error::NoDisplayNumber {
                outcome: format!("{outcome:?}"),
                log: xvfb.log(),
            }),
        }
    }

    /// The display, `:N`, for `$DISPLAY`.
    pub fn display(&self) -> &str {
        &self.display
    }

    /// What the server has written on stderr so far.
    pub fn log(&self) -> String {
        String::from_utf8_lossy(&self.log.lock().unwrap()).into_owned()
    }

    /// Runs an X client on this display; returns its stdout.
    pub fn run(&self, program: &str, args: &[&str]) -> Result<Vec<u8>, X11Error> {
        let output = Command::new(program)
            .args(args)
            .env("DISPLAY", &self.display)
            .stdin(Stdio::null())
            .output()
            .map_err(|error| X11Error::Spawn {
                program: program.into(),
                error,
            })?;
        if !output.status.success() {
            return Err(X11Error::ClientFailed {
                command: format!("{program} {}", args.join(" ")),
                status: output.status,
                stderr: String::from_utf8_lossy(&output.stderr).trim().to_owned(),
            });
        }
        Ok(output.stdout)
    }

    /// The window's picture as the server holds it, without the X border
    /// (`window` as xdotool prints it, or `0x...`).
    pub fn capture(&self, window: &str) -> Result<xwd::Image, X11Error> {
        let dump = self.run("xwd", &["-silent", "-nobdrs", "-id", window])?;
        xwd::parse(&dump).map_err(|error| X11Error::Dump {
            window: window.into(),
            error,
        })
    }
}

impl X11Error {
    /// `xwd` lost a race with the window changing size: it read the window's
    /// geometry, the window shrank, and the image request no longer fitted
    /// (X answers `BadMatch`). The window is being resized, not broken.
    pub fn window_resized_during_capture(&self) -> bool {
        matches!(self, X11Error::ClientFailed { command, stderr, .. }
            if command.starts_with("xwd") && stderr.contains("BadMatch"))
    }
}

impl Drop for Xvfb {
    /// Stops the server with SIGTERM, on which it removes its socket and
    /// lock file (SIGKILL would leave them in /tmp), and kills it if it has
    /// not gone within a second.
    fn drop(&mut self) {
        let asked = Command::new("kill")
            .args(["-TERM", &self.server.id().to_string()])
            .status()
            .is_ok_and(|s| s.success());
        let deadline = Instant::now() + STOP_TIMEOUT;
        while asked && Instant::now() < deadline {
            if let Ok(Some(_)) = self.server.try_wait() {
                return;
            }
            std::thread::sleep(POLL_INTERVAL);
        }
        let _ = self.server.kill();
        let _ = self.server.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::process::ExitStatusExt;

    fn failed(command: &str, stderr: &str) -> X11Error {
        X11Error::ClientFailed {
            command: command.into(),
            status: ExitStatus::from_raw(256),
            stderr: stderr.into(),
        }
    }

    #[test]
    fn only_xwds_badmatch_is_a_resize_race() {
        let race = "X Error of failed request:  BadMatch (invalid parameter attributes)\n  \
                    Major opcode of failed request:  73 (X_GetImage)";
        assert!(failed("xwd -silent -nobdrs -id 2097153", race).window_resized_during_capture());
        assert!(
            !failed("xwd -silent -id 7", "BadWindow (invalid Window parameter)")
                .window_resized_during_capture()
        );
        assert!(!failed("xdotool key Escape", race).window_resized_during_capture());
    }
}
