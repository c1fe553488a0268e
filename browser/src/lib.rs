//! What the web page's tests and benchmark need from a browser: Debian's
//! headless Chromium ([`Browser`]) driven over the DevTools protocol on a
//! pipe, and its tabs ([`Page`]): open a URL and wait for its load event,
//! run JavaScript, type keys and move the mouse as real input events.
//!
//! Chromium is started with `--remote-debugging-pipe`: it reads commands on
//! its file descriptor 3 and writes answers and events on 4, each message a
//! JSON object ended by a NUL byte ([`framing`]). No port is opened, so
//! parallel tests cannot collide. Every wait is bounded: a thread reads the
//! pipe into a channel that the caller reads with a deadline, and when
//! Chromium dies the error carries the end of what it wrote on stderr.
//!
//! Messages are framed and read without a browser:
//!
//! ```
//! use browser::framing::{decode, encode, Splitter};
//! use serde_json::json;
//!
//! let mut stream = encode(&json!({"id": 1, "result": {}}));
//! stream.extend(encode(&json!({"method": "Page.loadEventFired", "params": {}})));
//! // However the reads cut the stream, the same messages come out.
//! let mut splitter = Splitter::default();
//! let mut frames = splitter.push(&stream[..5])?;
//! frames.extend(splitter.push(&stream[5..])?);
//! assert_eq!(frames.len(), 2);
//! assert_eq!(decode(&frames[1])?["method"], "Page.loadEventFired");
//! # Ok::<(), browser::framing::FramingError>(())
//! ```

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod framing;
pub mod keys;

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::os::unix::fs::MetadataExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::{Duration, Instant};

use base64::Engine as _;
use serde_json::{json, Value};

use framing::{FramingError, Splitter};

/// The programs tried, in order, and the Debian packages that hold them:
/// the headless shell is the smaller (no GTK), the full browser also works.
pub const PROGRAMS: [(&str, &str); 2] = [
    ("chromium-headless-shell", "chromium-headless-shell"),
    ("chromium", "chromium"),
];

/// How long any one step may take by default: starting, loading a page,
/// one command. Generous, because the tests run beside busy loops.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(60);
/// How much of Chromium's stderr an error quotes.
const STDERR_TAIL_BYTES: usize = 4096;
/// How much of Chromium's stderr is kept.
const STDERR_KEPT_BYTES: usize = 64 << 10;
/// Events kept for a later wait; beyond this the oldest are dropped.
const EVENTS_KEPT: usize = 10_000;
/// Console lines and exceptions kept for errors and [`Page::console`].
const CONSOLE_KEPT: usize = 500;
/// How long a closing browser has to exit before it is killed.
const CLOSE_TIMEOUT: Duration = Duration::from_secs(5);
/// How long a browser that closed its pipe has to exit and close its
/// stderr before the error is made without them.
const EXIT_WAIT: Duration = Duration::from_secs(2);
/// How often a closing browser is looked at.
const POLL_INTERVAL: Duration = Duration::from_millis(20);
/// A page's poll of its own state (see [`Page::wait_for`]), in milliseconds.
const PAGE_POLL_MS: u32 = 5;

/// What went wrong with the browser or a page.
#[derive(Debug, thiserror::Error)]
pub enum BrowserError {
    /// No Chromium on `$PATH`.
    #[error(
        "the web page tests need Debian's Chromium ({}, none on $PATH): install it with \
         `boot/setup.sh` (or `sudo apt-get install chromium-headless-shell`)",
        PROGRAMS.map(|(program, _)| program).join(" or ")
    )]
    NotInstalled,
    /// Chromium or its profile directory could not be set up.
    #[error("cannot start {program}: {error}")]
    Spawn {
        /// What was being started.
        program: String,
        /// Why not.
        error: io::Error,
    },
    /// Nothing came within the deadline.
    #[error("no {waiting_for} within {after:?}; Chromium's stderr ends:\n{stderr}")]
    Timeout {
        /// What was awaited.
        waiting_for: String,
        /// The deadline.
        after: Duration,
        /// The end of Chromium's stderr.
        stderr: String,
    },
    /// A page's own condition did not hold within the deadline.
    #[error("the page never made {condition} true within {after:?} (last value {last}); its console:\n{console}")]
    PageTimeout {
        /// The JavaScript expression.
        condition: String,
        /// The deadline.
        after: Duration,
        /// What the expression gave last.
        last: Value,
        /// The page's console and uncaught exceptions.
        console: String,
    },
    /// Chromium closed the pipe or exited.
    #[error(
        "Chromium went away ({status}) while waiting for {waiting_for}; its stderr ends:\n{stderr}"
    )]
    Exited {
        /// What was awaited.
        waiting_for: String,
        /// How it ended, if it has.
        status: String,
        /// The end of Chromium's stderr.
        stderr: String,
    },
    /// The pipe carried something that is not a message.
    #[error("Chromium sent a broken message: {0}")]
    Framing(#[from] FramingError),
    /// Chromium answered a command with an error.
    #[error("{method} failed: {message} (code {code})")]
    Command {
        /// The command.
        method: String,
        /// The protocol's error code.
        code: i64,
        /// The protocol's error message.
        message: String,
    },
    /// The page could not be loaded.
    #[error("cannot load {url}: {error}")]
    Navigation {
        /// The URL.
        url: String,
        /// Chromium's net error, e.g. `net::ERR_CONNECTION_REFUSED`.
        error: String,
    },
    /// JavaScript threw.
    #[error("JavaScript threw: {text}")]
    Exception {
        /// The exception as the console would show it.
        text: String,
    },
    /// An answer did not have the shape the protocol promises.
    #[error("unexpected {what}: {value}")]
    Unexpected {
        /// What was read.
        what: String,
        /// The value, as JSON.
        value: String,
    },
    /// A key this crate cannot type.
    #[error("no virtual-key code for the key code {0:?}")]
    UnknownKeyCode(String),
}

/// The result of everything here.
pub type Result<T, E = BrowserError> = std::result::Result<T, E>;

/// How to start the browser.
#[derive(Clone, Debug)]
pub struct Options {
    /// The bound on each step: start, each command, each page load.
    pub timeout: Duration,
    /// Flags added to Chromium's, e.g. `--js-flags=--noexpose_wasm`.
    pub extra_args: Vec<String>,
    /// The program to run instead of the first of [`PROGRAMS`] on `$PATH`.
    pub program: Option<PathBuf>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            timeout: DEFAULT_TIMEOUT,
            extra_args: Vec::new(),
            program: None,
        }
    }
}

/// What the pipe's reader thread hands over.
enum Incoming {
    Message(Value),
    Broken(FramingError),
    /// The pipe closed (or failed); bytes of a message it cut short.
    Closed {
        cut_off: usize,
        error: Option<io::Error>,
    },
}

/// The end of a child's stderr, kept as it is written, and whether the
/// child (and every process that shares its stderr) has closed it.
#[derive(Clone, Default)]
struct StderrTail(Arc<(Mutex<Kept>, Condvar)>);

/// The bytes kept, and whether the end was reached.
type Kept = (Vec<u8>, bool);

impl StderrTail {
    fn collect(&self, mut stderr: impl Read + Send + 'static) {
        let sink = self.clone();
        std::thread::spawn(move || {
            let mut chunk = [0; 4096];
            while let Ok(read @ 1..) = stderr.read(&mut chunk) {
                let mut kept = sink.0 .0.lock().unwrap();
                kept.0.extend_from_slice(&chunk[..read]);
                let excess = kept.0.len().saturating_sub(STDERR_KEPT_BYTES);
                kept.0.drain(..excess);
            }
            sink.0 .0.lock().unwrap().1 = true;
            sink.0 .1.notify_all();
        });
    }

    fn tail(&self) -> String {
        let kept = self.0 .0.lock().unwrap();
        let start = kept.0.len().saturating_sub(STDERR_TAIL_BYTES);
        String::from_utf8_lossy(&kept.0[start..]).into_owned()
    }

    /// The tail once stderr has closed, or after `timeout` (Chromium's
    /// helpers may hold it open a while after the browser has gone).
    fn tail_at_close(&self, timeout: Duration) -> String {
        let (kept, closed) = &*self.0;
        let guard = kept.lock().unwrap();
        drop(
            closed
                .wait_timeout_while(guard, timeout, |kept| !kept.1)
                .unwrap(),
        );
        self.tail()
    }
}

/// The pipe's two ends and what has come in but not yet been asked for.
struct Connection {
    child: Child,
    /// Chromium's fd 3; `None` once closed.
    commands: Option<ChildStdin>,
    /// Chromium's fd 4, as messages.
    messages: Receiver<Incoming>,
    next_id: u64,
    /// Events no wait has taken yet, oldest first.
    events: VecDeque<Value>,
    /// Console lines and exceptions, each with its session.
    console: VecDeque<(String, String)>,
    /// Why the pipe can no longer be read, once it cannot.
    closed: Option<String>,
}

/// A headless Chromium with its own throw-away profile. Dropping it closes
/// the browser (and kills it if it does not go).
pub struct Browser {
    connection: Mutex<Connection>,
    stderr: StderrTail,
    timeout: Duration,
    program: PathBuf,
    /// Removed after Chromium has gone (fields drop in order).
    _profile: tempfile::TempDir,
}

/// The first of [`PROGRAMS`] found on `$PATH`.
pub fn find_chromium() -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    PROGRAMS.iter().find_map(|(program, _)| {
        std::env::split_paths(&path)
            .map(|dir| dir.join(program))
            .find(|candidate| candidate.is_file())
    })
}

/// Whether this process runs as root, where Chromium's sandbox refuses to
/// start.
fn running_as_root() -> bool {
    std::fs::metadata("/proc/self").is_ok_and(|meta| meta.uid() == 0)
}

/// Chromium's flags: headless, the pipe, a private profile, and nothing
/// that would reach past 127.0.0.1 or wait for a user.
fn chromium_args(profile: &Path, as_root: bool) -> Vec<String> {
    let mut args: Vec<String> = [
        "--headless",
        "--remote-debugging-pipe",
        "--disable-gpu",
        "--no-first-run",
        "--no-default-browser-check",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-default-apps",
        "--disable-extensions",
        "--disable-sync",
        "--disable-breakpad",
        "--no-pings",
        "--mute-audio",
        "--hide-scrollbars",
        "--window-size=1600,1000",
        // Names resolve to nothing and every other address goes to a proxy
        // that is not there; loopback always bypasses the proxy.
        "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
        "--proxy-server=http://127.0.0.1:1",
        // Tabs not in front still run their timers and frames at full rate.
        "--disable-background-timer-throttling",
        "--disable-renderer-backgrounding",
        "--disable-backgrounding-occluded-windows",
    ]
    .map(String::from)
    .to_vec();
    args.push(format!("--user-data-dir={}", profile.display()));
    if as_root {
        args.push("--no-sandbox".into());
    }
    args.push("about:blank".into());
    args
}

impl Browser {
    /// Starts Chromium with the default [`Options`].
    pub fn start() -> Result<Browser> {
        Self::start_with(Options::default())
    }

    /// Starts Chromium and waits (bounded) until it answers on the pipe.
    pub fn start_with(options: Options) -> Result<Browser> {
        let program = match options.program {
            Some(program) => program,
            None => find_chromium().ok_or(BrowserError::NotInstalled)?,
        };
        let spawn_error = |error| BrowserError::Spawn {
            program: program.display().to_string(),
            error,
        };
        // The shell would say so too, but only on stderr after the fact.
        if !program.is_file() {
            return Err(spawn_error(io::Error::new(
                io::ErrorKind::NotFound,
                "no such file",
            )));
        }
        let profile = tempfile::Builder::new()
            .prefix("chromium-profile-")
            .tempdir()
            .map_err(spawn_error)?;
        let mut args = chromium_args(profile.path(), running_as_root());
        let page = args.pop().expect("the start page is last");
        args.extend(options.extra_args);
        args.push(page);
        // The pipe is Chromium's fds 3 and 4. The standard library maps only
        // 0-2, so a shell moves our stdin and stdout pipes there and then
        // becomes Chromium (exec): stdin reads nothing, stdout joins stderr.
        let mut child = Command::new("sh")
            .arg("-c")
            .arg(r#"exec "$0" "$@" 3<&0 4>&1 </dev/null >&2"#)
            .arg(&program)
            .args(&args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            // Its own process group, so that Drop can end its helpers too.
            .process_group(0)
            .spawn()
            .map_err(spawn_error)?;
        let stderr = StderrTail::default();
        stderr.collect(child.stderr.take().expect("stderr is piped"));
        let messages = read_messages(child.stdout.take().expect("stdout is piped"));
        let commands = child.stdin.take();
        let browser = Browser {
            connection: Mutex::new(Connection {
                child,
                commands,
                messages,
                next_id: 1,
                events: VecDeque::new(),
                console: VecDeque::new(),
                closed: None,
            }),
            stderr,
            timeout: options.timeout,
            program,
            _profile: profile,
        };
        browser.call(None, "Browser.getVersion", json!({}))?;
        Ok(browser)
    }

    /// The program that runs.
    pub fn program(&self) -> &Path {
        &self.program
    }

    /// The bound on each step.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// The browser's product and version, e.g. `HeadlessChrome/156.0...`.
    pub fn version(&self) -> Result<String> {
        let version = self.call(None, "Browser.getVersion", json!({}))?;
        string_field(&version, "product")
    }

    /// A new tab showing `url`, once its load event has fired.
    pub fn open(&self, url: &str) -> Result<Page<'_>> {
        let target = self.call(None, "Target.createTarget", json!({"url": "about:blank"}))?;
        let target = string_field(&target, "targetId")?;
        let attached = self.call(
            None,
            "Target.attachToTarget",
            json!({"targetId": target, "flatten": true}),
        )?;
        let page = Page {
            browser: self,
            session: string_field(&attached, "sessionId")?,
            target,
        };
        page.call("Page.enable", json!({}))?;
        page.call("Page.setLifecycleEventsEnabled", json!({"enabled": true}))?;
        page.call("Runtime.enable", json!({}))?;
        // Each tab behaves as the focused one, so that key events reach the
        // focused element whichever tab was opened last.
        page.call(
            "Emulation.setFocusEmulationEnabled",
            json!({"enabled": true}),
        )?;
        page.navigate(url)?;
        Ok(page)
    }

    /// Sends a command (to a page's session, or to the browser) and waits
    /// for its answer.
    pub fn call(&self, session: Option<&str>, method: &str, params: Value) -> Result<Value> {
        self.call_within(session, method, params, self.timeout)
    }

    /// [`Browser::call`] with its own bound.
    pub fn call_within(
        &self,
        session: Option<&str>,
        method: &str,
        params: Value,
        timeout: Duration,
    ) -> Result<Value> {
        let deadline = Instant::now() + timeout;
        let mut connection = self.lock();
        let id = connection.next_id;
        connection.next_id += 1;
        let mut message = json!({"id": id, "method": method, "params": params});
        if let Some(session) = session {
            message["sessionId"] = session.into();
        }
        let written = match connection.commands.as_mut() {
            Some(commands) => commands
                .write_all(&framing::encode(&message))
                .and_then(|()| commands.flush()),
            None => Err(io::Error::new(
                io::ErrorKind::BrokenPipe,
                "the pipe is closed",
            )),
        };
        if let Err(error) = written {
            let reason = format!("writing to its pipe failed: {error}");
            connection.closed = Some(reason.clone());
            return Err(self.exited(&mut connection, method, reason));
        }
        loop {
            let message = self.receive(&mut connection, deadline, timeout, method)?;
            if message.get("id").and_then(Value::as_u64) != Some(id) {
                // An event, or the late answer to a command given up on.
                connection.keep_event(message);
                continue;
            }
            if let Some(error) = message.get("error") {
                return Err(BrowserError::Command {
                    method: method.into(),
                    code: error.get("code").and_then(Value::as_i64).unwrap_or(0),
                    message: error
                        .get("message")
                        .and_then(Value::as_str)
                        .unwrap_or("(no message)")
                        .into(),
                });
            }
            return Ok(message.get("result").cloned().unwrap_or(json!({})));
        }
    }

    /// Waits for the first event for which `wanted` holds (events that came
    /// before are looked at first) and takes it.
    pub fn wait_event(
        &self,
        waiting_for: &str,
        timeout: Duration,
        mut wanted: impl FnMut(&Value) -> bool,
    ) -> Result<Value> {
        let deadline = Instant::now() + timeout;
        let mut connection = self.lock();
        if let Some(index) = connection.events.iter().position(&mut wanted) {
            return Ok(connection
                .events
                .remove(index)
                .expect("the index was found"));
        }
        loop {
            let message = self.receive(&mut connection, deadline, timeout, waiting_for)?;
            if message.get("method").is_some() && wanted(&message) {
                return Ok(message);
            }
            connection.keep_event(message);
        }
    }

    fn lock(&self) -> MutexGuard<'_, Connection> {
        // A panic elsewhere while holding the lock leaves the connection as
        // it was; the pipe itself is still in step.
        self.connection.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The next message, within the deadline.
    fn receive(
        &self,
        connection: &mut Connection,
        deadline: Instant,
        timeout: Duration,
        waiting_for: &str,
    ) -> Result<Value> {
        if let Some(reason) = &connection.closed {
            return Err(self.exited(connection, waiting_for, reason.clone()));
        }
        let left = deadline.saturating_duration_since(Instant::now());
        match connection.messages.recv_timeout(left) {
            Ok(Incoming::Message(message)) => Ok(message),
            Ok(Incoming::Broken(error)) => {
                connection.closed = Some(format!("broken message: {error}"));
                Err(error.into())
            }
            Ok(Incoming::Closed { cut_off, error }) => {
                let mut reason = "it closed the pipe".to_owned();
                if cut_off > 0 {
                    reason += &format!(", {cut_off} bytes into a message");
                }
                if let Some(error) = error {
                    reason += &format!(" (read error: {error})");
                }
                connection.closed = Some(reason.clone());
                Err(self.exited(connection, waiting_for, reason))
            }
            Err(RecvTimeoutError::Disconnected) => {
                let reason = "the pipe's reader stopped".to_owned();
                connection.closed = Some(reason.clone());
                Err(self.exited(connection, waiting_for, reason))
            }
            Err(RecvTimeoutError::Timeout) => match connection.child.try_wait() {
                Ok(Some(status)) => Err(self.exited(connection, waiting_for, describe(status))),
                _ => Err(BrowserError::Timeout {
                    waiting_for: waiting_for.into(),
                    after: timeout,
                    stderr: self.stderr.tail(),
                }),
            },
        }
    }

    /// The error for a browser that has gone: once it has exited (or
    /// [`EXIT_WAIT`] has passed), with its exit status and its stderr.
    fn exited(
        &self,
        connection: &mut Connection,
        waiting_for: &str,
        reason: String,
    ) -> BrowserError {
        let deadline = Instant::now() + EXIT_WAIT;
        let status = loop {
            match connection.child.try_wait() {
                Ok(Some(status)) => break format!("{reason}; {}", describe(status)),
                Ok(None) if Instant::now() < deadline => std::thread::sleep(POLL_INTERVAL),
                _ => break reason,
            }
        };
        BrowserError::Exited {
            waiting_for: waiting_for.into(),
            status,
            stderr: self.stderr.tail_at_close(EXIT_WAIT),
        }
    }

    fn console(&self, session: &str) -> Vec<String> {
        self.lock()
            .console
            .iter()
            .filter(|(from, _)| from == session)
            .map(|(_, line)| line.clone())
            .collect()
    }
}

impl Connection {
    /// Keeps an event for a later wait; console lines go to the console.
    fn keep_event(&mut self, message: Value) {
        let Some(method) = message.get("method").and_then(Value::as_str) else {
            return; // a late answer
        };
        let session = message
            .get("sessionId")
            .and_then(Value::as_str)
            .unwrap_or("")
            .to_owned();
        let line = match method {
            "Runtime.consoleAPICalled" => Some(console_line(&message["params"])),
            "Runtime.exceptionThrown" => Some(format!(
                "uncaught: {}",
                exception_text(&message["params"]["exceptionDetails"])
            )),
            _ => None,
        };
        if let Some(line) = line {
            if self.console.len() == CONSOLE_KEPT {
                self.console.pop_front();
            }
            self.console.push_back((session, line));
            return;
        }
        if self.events.len() == EVENTS_KEPT {
            self.events.pop_front();
        }
        self.events.push_back(message);
    }
}

impl Drop for Browser {
    /// Asks Chromium to close, closes the pipe, and kills its process group
    /// if it has not gone within five seconds.
    fn drop(&mut self) {
        let _ = self.call_within(None, "Browser.close", json!({}), CLOSE_TIMEOUT);
        let connection = self.connection.get_mut().unwrap_or_else(|e| e.into_inner());
        connection.commands = None;
        let deadline = Instant::now() + CLOSE_TIMEOUT;
        while Instant::now() < deadline {
            if let Ok(Some(_)) = connection.child.try_wait() {
                return;
            }
            std::thread::sleep(POLL_INTERVAL);
        }
        // The group is Chromium's own (process_group(0) above).
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", connection.child.id())])
            .status();
        let _ = connection.child.kill();
        let _ = connection.child.wait();
    }
}

/// A thread that reads the pipe and hands over its messages in order.
fn read_messages(mut events: impl Read + Send + 'static) -> Receiver<Incoming> {
    let (sender, receiver) = channel();
    std::thread::spawn(move || {
        let mut splitter = Splitter::default();
        let mut chunk = vec![0; 1 << 16];
        loop {
            let read = match events.read(&mut chunk) {
                Ok(0) => 0,
                Ok(read) => read,
                Err(error) if error.kind() == io::ErrorKind::Interrupted => continue,
                Err(error) => {
                    let cut_off = splitter.pending();
                    let _ = sender.send(Incoming::Closed {
                        cut_off,
                        error: Some(error),
                    });
                    return;
                }
            };
            if read == 0 {
                let cut_off = splitter.pending();
                let _ = sender.send(Incoming::Closed {
                    cut_off,
                    error: None,
                });
                return;
            }
            let frames = match splitter.push(&chunk[..read]) {
                Ok(frames) => frames,
                Err(error) => {
                    let _ = sender.send(Incoming::Broken(error));
                    return;
                }
            };
            for frame in frames {
                let incoming = match framing::decode(&frame) {
                    Ok(message) => Incoming::Message(message),
                    Err(error) => Incoming::Broken(error),
                };
                let broken = matches!(incoming, Incoming::Broken(_));
                if sender.send(incoming).is_err() || broken {
                    return;
                }
            }
        }
    });
    receiver
}

fn describe(status: ExitStatus) -> String {
    format!("Chromium exited: {status}")
}

fn string_field(value: &Value, field: &str) -> Result<String> {
    value
        .get(field)
        .and_then(Value::as_str)
        .map(str::to_owned)
        .ok_or_else(|| BrowserError::Unexpected {
            what: format!("answer without a string {field:?}"),
            value: value.to_string(),
        })
}

/// A console call as one line: its type and its arguments' values.
fn console_line(params: &Value) -> String {
    let kind = params["type"].as_str().unwrap_or("log");
    let args: Vec<String> = params["args"]
        .as_array()
        .map(|args| {
            args.iter()
                .map(|arg| match (&arg["value"], &arg["description"]) {
                    (Value::String(text), _) => text.clone(),
                    (Value::Null, Value::String(text)) => text.clone(),
                    (value, _) => value.to_string(),
                })
                .collect()
        })
        .unwrap_or_default();
    format!("{kind}: {}", args.join(" "))
}

/// An exception as the console shows it: its description (message and
/// stack) if it has one, else the protocol's text.
fn exception_text(details: &Value) -> String {
    details["exception"]["description"]
        .as_str()
        .or_else(|| details["exception"]["value"].as_str())
        .or_else(|| details["text"].as_str())
        .unwrap_or("(no text)")
        .to_owned()
}

/// One tab of the browser. Dropping it closes the tab.
pub struct Page<'b> {
    browser: &'b Browser,
    session: String,
    target: String,
}

impl Page<'_> {
    /// Sends a command to this page and waits for its answer.
    pub fn call(&self, method: &str, params: Value) -> Result<Value> {
        self.browser.call(Some(&self.session), method, params)
    }

    /// Loads `url` and waits for its load event.
    pub fn navigate(&self, url: &str) -> Result<()> {
        let navigated = self.call("Page.navigate", json!({"url": url}))?;
        if let Some(error) = navigated["errorText"].as_str().filter(|e| !e.is_empty()) {
            return Err(BrowserError::Navigation {
                url: url.into(),
                error: error.into(),
            });
        }
        let loader = string_field(&navigated, "loaderId")?;
        let session = self.session.clone();
        self.browser.wait_event(
            &format!("load event of {url}"),
            self.browser.timeout,
            |event| {
                event["sessionId"] == session.as_str()
                    && event["method"] == "Page.lifecycleEvent"
                    && event["params"]["name"] == "load"
                    && event["params"]["loaderId"] == loader.as_str()
            },
        )?;
        Ok(())
    }

    /// Runs `expression` in the page (awaiting it if it is a promise) and
    /// returns its value as JSON; `undefined` is `null`. A thrown exception
    /// is [`BrowserError::Exception`] with its text.
    pub fn evaluate(&self, expression: &str) -> Result<Value> {
        self.evaluate_within(expression, self.browser.timeout)
    }

    /// [`Page::evaluate`] with its own bound.
    pub fn evaluate_within(&self, expression: &str, timeout: Duration) -> Result<Value> {
        let answer = self.browser.call_within(
            Some(&self.session),
            "Runtime.evaluate",
            json!({
                "expression": expression,
                "awaitPromise": true,
                "returnByValue": true,
                "userGesture": true,
            }),
            timeout,
        )?;
        if let Some(details) = answer.get("exceptionDetails") {
            return Err(BrowserError::Exception {
                text: exception_text(details),
            });
        }
        Ok(answer["result"]
            .get("value")
            .cloned()
            .unwrap_or(Value::Null))
    }

    /// Runs `expression`, which must give a base64 string, and decodes it.
    pub fn evaluate_base64(&self, expression: &str) -> Result<Vec<u8>> {
        let value = self.evaluate(expression)?;
        let text = value.as_str().ok_or_else(|| BrowserError::Unexpected {
            what: format!("value of {expression} (not a string)"),
            value: truncated(&value),
        })?;
        base64::engine::general_purpose::STANDARD
            .decode(text)
            .map_err(|error| BrowserError::Unexpected {
                what: format!("value of {expression} (not base64: {error})"),
                value: truncated(&value),
            })
    }

    /// Waits until the JavaScript expression `condition` is truthy in the
    /// page and returns its value. The page polls it itself (every few
    /// milliseconds, on its own timers), so the answer comes as soon as it
    /// holds; past `timeout` this is [`BrowserError::PageTimeout`].
    pub fn wait_for(&self, condition: &str, timeout: Duration) -> Result<Value> {
        let millis = timeout.as_millis();
        let poll = format!(
            "new Promise((resolve, reject) => {{
                const end = performance.now() + {millis};
                const poll = () => {{
                    let value;
                    try {{ value = (() => ({condition}))(); }} catch (e) {{ reject(e); return; }}
                    if (value) resolve({{ done: true, value }});
                    else if (performance.now() >= end) resolve({{ done: false, value }});
                    else setTimeout(poll, {PAGE_POLL_MS});
                }};
                poll();
            }})"
        );
        // The page gives up first; the pipe's bound is a backstop.
        let answer = self.evaluate_within(&poll, timeout + self.browser.timeout)?;
        if answer["done"] == true {
            return Ok(answer["value"].clone());
        }
        Err(BrowserError::PageTimeout {
            condition: condition.into(),
            after: timeout,
            last: answer.get("value").cloned().unwrap_or(Value::Null),
            console: self.console().join("\n"),
        })
    }

    /// A key pressed and released, as a keyboard sends it: `code` is
    /// `KeyboardEvent.code` (`"KeyL"`, `"ArrowLeft"`), `key` its
    /// `KeyboardEvent.key` (`"l"`, `"ArrowLeft"`).
    pub fn key(&self, code: &str, key: &str) -> Result<()> {
        self.key_down(code, key)?;
        self.key_up(code, key)
    }

    /// A key pressed (and held).
    pub fn key_down(&self, code: &str, key: &str) -> Result<()> {
        self.key_event("keyDown", code, key)
    }

    /// A key released.
    pub fn key_up(&self, code: &str, key: &str) -> Result<()> {
        self.key_event("keyUp", code, key)
    }

    fn key_event(&self, kind: &str, code: &str, key: &str) -> Result<()> {
        let vk = keys::virtual_key_code(code)
            .ok_or_else(|| BrowserError::UnknownKeyCode(code.into()))?;
        let mut event = json!({
            "type": kind,
            "code": code,
            "key": key,
            "windowsVirtualKeyCode": vk,
            "nativeVirtualKeyCode": vk,
            "location": keys::location(code),
            "isKeypad": keys::is_keypad(code),
        });
        // A printable key also types its character, as a real one does.
        if kind == "keyDown" && key.chars().count() == 1 {
            event["text"] = key.into();
            event["unmodifiedText"] = key.into();
        }
        self.call("Input.dispatchKeyEvent", event)?;
        Ok(())
    }

    /// The mouse moved to (`x`, `y`) in CSS pixels from the viewport's
    /// top left.
    pub fn mouse_move(&self, x: f64, y: f64) -> Result<()> {
        self.call(
            "Input.dispatchMouseEvent",
            json!({"type": "mouseMoved", "x": x, "y": y, "button": "none"}),
        )?;
        Ok(())
    }

    /// A touch event: `kind` is `touchStart`, `touchMove`, `touchEnd` or
    /// `touchCancel`, `points` the fingers down in CSS pixels from the
    /// viewport's top left (none for the end). The page must have touch
    /// emulation on (`Emulation.setTouchEmulationEnabled`) to take it.
    pub fn touch(&self, kind: &str, points: &[(f64, f64)]) -> Result<()> {
        let points: Vec<Value> = points
            .iter()
            .enumerate()
            .map(|(id, &(x, y))| json!({"x": x, "y": y, "id": id}))
            .collect();
        self.call(
            "Input.dispatchTouchEvent",
            json!({"type": kind, "touchPoints": points}),
        )?;
        Ok(())
    }

    /// A finger's tap on the middle of the first element `selector`
    /// matches, scrolled into the window first if it is out of it.
    pub fn tap(&self, selector: &str) -> Result<()> {
        let (x, y) = self.centre_of(selector)?;
        self.touch("touchStart", &[(x, y)])?;
        self.touch("touchEnd", &[])
    }

    /// A left click on the first element `selector` matches, as a reader
    /// makes it: the element scrolled to the middle of the window if it is
    /// out of it, the mouse on the middle of its first line box (a link
    /// that wraps has a gap, or other text, in the middle of its whole box).
    pub fn click(&self, selector: &str) -> Result<()> {
        let (x, y) = self.centre_of(selector)?;
        self.mouse_move(x, y)?;
        for kind in ["mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1}),
            )?;
        }
        Ok(())
    }

    /// The middle of the first line box of the first element `selector`
    /// matches (a link that wraps has a gap, or other text, in the middle
    /// of its whole box), scrolled to the middle of the window first if it
    /// is out of it.
    fn centre_of(&self, selector: &str) -> Result<(f64, f64)> {
        let quoted = Value::from(selector).to_string();
        let centre = self.evaluate(&format!(
            "(() => {{
                const element = document.querySelector({quoted});
                if (!element) throw new Error('no element matches ' + {quoted});
                const whole = element.getBoundingClientRect();
                if (whole.top < 0 || whole.bottom > innerHeight || whole.left < 0 || whole.right > innerWidth)
                    element.scrollIntoView({{block: 'center', inline: 'center'}});
                const box = element.getClientRects()[0] || element.getBoundingClientRect();
                return [box.left + box.width / 2, box.top + box.height / 2];
            }})()"
        ))?;
        let (Some(x), Some(y)) = (centre[0].as_f64(), centre[1].as_f64()) else {
            return Err(BrowserError::Unexpected {
                what: format!("centre of {selector}"),
                value: centre.to_string(),
            });
        };
        Ok((x, y))
    }

    /// The page as the browser composites it, a PNG: the region `clip`
    /// (left, top, width, height in CSS pixels) or the whole viewport.
    pub fn screenshot_png(&self, clip: Option<[f64; 4]>) -> Result<Vec<u8>> {
        let mut params = json!({"format": "png", "fromSurface": true});
        if let Some([x, y, width, height]) = clip {
            params["clip"] = json!({"x": x, "y": y, "width": width, "height": height, "scale": 1});
        }
        let shot = self.call("Page.captureScreenshot", params)?;
        let data = string_field(&shot, "data")?;
        base64::engine::general_purpose::STANDARD
            .decode(&data)
            .map_err(|error| BrowserError::Unexpected {
                what: format!("screenshot (not base64: {error})"),
                value: truncated(&Value::from(data)),
            })
    }

    /// What the page wrote to its console, and its uncaught exceptions, so
    /// far (the last few hundred lines).
    pub fn console(&self) -> Vec<String> {
        self.browser.console(&self.session)
    }

    /// Runs `run` while the browser records a trace of the event
    /// `categories` (DevTools `Tracing`), and returns what `run` gave with
    /// the trace's events, in Chrome's JSON trace format: each with its
    /// `name`, `cat`, `ph`, `pid`, `tid`, `ts` (µs, the monotonic clock) and,
    /// for most, `tts` (µs of its thread's CPU time) and `args`.
    pub fn trace<T>(
        &self,
        categories: &[&str],
        run: impl FnOnce() -> Result<T>,
    ) -> Result<(T, Vec<Value>)> {
        self.call(
            "Tracing.start",
            json!({
                "traceConfig": { "includedCategories": categories },
                "transferMode": "ReturnAsStream",
            }),
        )?;
        let ran = run();
        // End the trace whatever `run` gave, so that the tab can trace again.
        self.call("Tracing.end", json!({}))?;
        let session = self.session.clone();
        let complete =
            self.browser
                .wait_event("the end of a trace", self.browser.timeout, |event| {
                    event["sessionId"] == session.as_str()
                        && event["method"] == "Tracing.tracingComplete"
                })?;
        let ran = ran?;
        let stream = string_field(&complete["params"], "stream")?;
        let mut text = String::new();
        loop {
            let chunk = self.call("IO.read", json!({"handle": stream, "size": 1 << 20}))?;
            if chunk["base64Encoded"] == true {
                return Err(BrowserError::Unexpected {
                    what: "a trace in base64 (asked for JSON)".into(),
                    value: truncated(&chunk),
                });
            }
            text += &string_field(&chunk, "data")?;
            if chunk["eof"] == true {
                break;
            }
        }
        self.call("IO.close", json!({"handle": stream}))?;
        let trace: Value =
            serde_json::from_str(&text).map_err(|error| BrowserError::Unexpected {
                what: format!("a trace (not JSON: {error})"),
                value: truncated(&Value::from(text.clone())),
            })?;
        match trace {
            Value::Object(mut trace) => match trace.remove("traceEvents") {
                Some(Value::Array(events)) => Ok((ran, events)),
                other => Err(BrowserError::Unexpected {
                    what: "a trace's traceEvents".into(),
                    value: truncated(&other.unwrap_or(Value::Null)),
                }),
            },
            Value::Array(events) => Ok((ran, events)),
            other => Err(BrowserError::Unexpected {
                what: "a trace".into(),
                value: truncated(&other),
            }),
        }
    }

    /// The session this page's commands go to.
    pub fn session(&self) -> &str {
        &self.session
    }
}

impl Drop for Page<'_> {
    fn drop(&mut self) {
        let _ = self.browser.call_within(
            None,
            "Target.closeTarget",
            json!({"targetId": self.target}),
            CLOSE_TIMEOUT,
        );
    }
}

/// A value for an error message: its start if it is long.
fn truncated(value: &Value) -> String {
    let text = value.to_string();
    match text.char_indices().nth(200) {
        Some((end, _)) => format!("{}...", &text[..end]),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sandbox_is_off_only_as_root_and_the_page_is_last() {
        let profile = Path::new("/tmp/p");
        let user = chromium_args(profile, false);
        let root = chromium_args(profile, true);
        assert!(!user.contains(&"--no-sandbox".to_owned()));
        assert!(root.contains(&"--no-sandbox".to_owned()));
        for args in [&user, &root] {
            assert!(args.contains(&"--remote-debugging-pipe".to_owned()));
            assert!(args.contains(&"--user-data-dir=/tmp/p".to_owned()));
            assert_eq!(args.last().map(String::as_str), Some("about:blank"));
        }
    }

    #[test]
    fn console_lines_show_values_and_descriptions() {
        let params = json!({"type": "error", "args": [
            {"type": "string", "value": "frame"},
            {"type": "number", "value": 3},
            {"type": "object", "description": "Error: boom"},
        ]});
        assert_eq!(console_line(&params), "error: frame 3 Error: boom");
    }

    #[test]
    fn exceptions_read_their_description_first() {
        let details = json!({"text": "Uncaught", "exception": {"description": "Error: x\n at f"}});
        assert_eq!(exception_text(&details), "Error: x\n at f");
        assert_eq!(exception_text(&json!({"text": "Uncaught"})), "Uncaught");
    }
}
