//! The page's URL as a replay script: `?keys=left,left,up&frames=120` taps
//! the k-th key before frame k (as `sim::record::Script` does with one frame
//! between keys), runs `frames` frames and pauses; `&paused=1` starts paused
//! after the mode set; `&every=N` puts N frames between keys. For the book's
//! step-by-step views: `&modeset=1` starts in slow motion before the mode
//! set, and `&ops=N` steps N bus operations at once (in slow motion).
//!
//! `&lab=crtc.13:50,seq.02:01` makes the register lab's edits once the
//! page is loaded (`crate::lab`), before the first frame runs.
//!
//! A bad token does not stop the page: it is left out, and the first one is
//! named in one line for the page to show.

use keyboard::keys::scancode_for_name;

use crate::lab::{self, Register};
use sim::record::Script;

/// The most frames a URL may ask for: an hour at 59.7 frames a second.
pub const MAX_FRAMES: u32 = 60 * 60 * 60;

/// What the URL asks the page to do.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Replay {
    /// The keys and how many frames apart they are typed.
    pub script: Script,
    /// Stop (pause) after this many frames.
    pub frames: Option<u32>,
    /// Start paused, at frame 0 after the mode set.
    pub paused: bool,
    /// Start in slow motion before the mode set, on the VGA the BIOS leaves.
    pub mode_set: bool,
    /// Bus operations to step in slow motion once loaded.
    pub ops: u32,
    /// The register lab's edits, made in order once loaded.
    pub lab: Vec<(Register, u32)>,
}

impl Default for Replay {
    fn default() -> Self {
        Replay {
            script: Script {
                keys: Vec::new(),
                key_every: 1,
            },
            frames: None,
            paused: false,
            mode_set: false,
            ops: 0,
            lab: Vec::new(),
        }
    }
}

/// The replay in `query` (the URL's search part, with or without its `?`)
/// and, if a token was bad, one line naming the first.
pub fn parse_query(query: &str) -> (Replay, Option<String>) {
    let mut replay = Replay::default();
    let mut problem: Option<String> = None;
    let mut complain = |line: String| {
        problem.get_or_insert(line);
    };
    let query = query.strip_prefix('?').unwrap_or(query);
    for pair in query.split('&').filter(|pair| !pair.is_empty()) {
        let (name, value) = pair.split_once('=').unwrap_or((pair, ""));
        let value = match percent_decode(value) {
            Some(value) => value,
            None => {
                complain(format!("malformed escape in the URL's {name}: {value:?}"));
                continue;
            }
        };
        match name {
            "keys" => {
                for key in value.split(',').filter(|key| !key.is_empty()) {
                    match scancode_for_name(&key.to_ascii_lowercase()) {
                        Some(scancode) => replay.script.keys.push(scancode),
                        None => complain(format!("unknown key name {key:?} in the URL's keys")),
                    }
                }
            }
            "frames" => match count(&value, 0) {
                Some(frames) => replay.frames = Some(frames),
                None => complain(format!(
                    "bad frame count {value:?} in the URL's frames (0 to {MAX_FRAMES})"
                )),
            },
            "every" => match count(&value, 1) {
                Some(every) => replay.script.key_every = every,
                None => complain(format!(
                    "bad frame count {value:?} in the URL's every (1 to {MAX_FRAMES})"
                )),
            },
            "paused" | "modeset" => match (value.as_str(), name) {
                ("1" | "" | "true", "paused") => replay.paused = true,
                ("0" | "false", "paused") => replay.paused = false,
                ("1" | "" | "true", _) => replay.mode_set = true,
                ("0" | "false", _) => replay.mode_set = false,
                _ => complain(format!("bad value {value:?} in the URL's {name} (0 or 1)")),
            },
            "ops" => match count(&value, 0) {
                Some(ops) => replay.ops = ops,
                None => complain(format!(
                    "bad operation count {value:?} in the URL's ops (0 to {MAX_FRAMES})"
                )),
            },
            "lab" => {
                let (edits, problem) = lab::parse_url_value(&value);
                replay.lab.extend(edits);
                if let Some(line) = problem {
                    complain(line);
                }
            }
            _ => complain(format!("unknown URL parameter {name:?}")),
        }
    }
    (replay, problem)
}

/// A whole number of frames from `least` to [`MAX_FRAMES`].
fn count(text: &str, least: u32) -> Option<u32> {
    if text.is_empty() || !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let number: u32 = text.parse().ok()?;
    (least..=MAX_FRAMES).contains(&number).then_some(number)
}

/// `%2C` and the like decoded; `None` if an escape is cut short or not hex,
/// or the bytes are not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut index = 0;
    while index < bytes.len() {
        if bytes[index] == b'%' {
            let hex = text.get(index + 1..index + 3)?;
            decoded.push(u8::from_str_radix(hex, 16).ok()?);
            index += 3;
        } else {
            decoded.push(bytes[index]);
            index += 1;
        }
    }
    String::from_utf8(decoded).ok()
}

/// The URL query that replays `keys` (by name), typed `every` frames apart,
/// for `frames` frames: what [`parse_query`] reads back.
pub fn query_for(keys: &[&str], every: u32, frames: u32) -> String {
    let mut query = format!("?keys={}&frames={frames}", keys.join(","));
    if every != 1 {
        query.push_str(&format!("&every={every}"));
    }
    query
}

#[cfg(test)]
mod tests {
    use super::*;
    use keyboard::keys::Scancode;

    fn key(name: &str) -> Scancode {
        scancode_for_name(name).unwrap()
    }

    #[test]
    fn a_script_reads_as_the_simulators_script() {
        let (replay, problem) = parse_query("?keys=left,left,up&frames=120");
        assert_eq!(problem, None);
        assert_eq!(replay.script.keys, [key("left"), key("left"), key("up")]);
        assert_eq!(replay.script.key_every, 1);
        assert_eq!(replay.frames, Some(120));
        assert!(!replay.paused);
        // The k-th key before frame k.
        assert_eq!(replay.script.key_before(1), Some(key("left")));
        assert_eq!(replay.script.key_before(2), Some(key("up")));
        assert_eq!(replay.script.key_before(3), None);

        let (replay, problem) = parse_query("paused=1&keys=r%2Cf1&every=30");
        assert_eq!(problem, None);
        assert!(replay.paused);
        assert_eq!(replay.script.keys, [key("r"), key("f1")]);
        assert_eq!(replay.script.key_before(30), Some(key("f1")));
        assert_eq!(parse_query(""), (Replay::default(), None));
        let (replay, problem) = parse_query("modeset=1&ops=45");
        assert_eq!(problem, None);
        assert!(replay.mode_set && replay.ops == 45);
        assert_eq!(
            parse_query(&query_for(&["l", "m"], 5, 99)).0.frames,
            Some(99)
        );
        let (replay, problem) = parse_query("lab=crtc.13%3A50,seq.02:01,dac.05:2a1510");
        assert_eq!(problem, None);
        assert_eq!(
            replay.lab,
            [
                (Register::Crtc(modex::regs::Crtc::Offset), 0x50),
                (Register::Sequencer(modex::regs::Sequencer::MapMask), 0x01),
                (Register::DacEntry(5), 0x2A1510),
            ]
        );
    }

    #[test]
    fn a_bad_token_is_named_in_one_line_and_the_rest_is_kept() {
        let (replay, problem) = parse_query("?keys=left,xyz,up&frames=12");
        assert_eq!(
            problem.as_deref(),
            Some("unknown key name \"xyz\" in the URL's keys")
        );
        assert_eq!(replay.script.keys, [key("left"), key("up")]);
        assert_eq!(replay.frames, Some(12));

        let cases = [
            ("frames=12x", "bad frame count \"12x\" in the URL's frames"),
            ("frames=-1", "bad frame count \"-1\" in the URL's frames"),
            ("frames=99999999999", "bad frame count \"99999999999\""),
            ("every=0", "bad frame count \"0\" in the URL's every"),
            ("paused=maybe", "bad value \"maybe\" in the URL's paused"),
            ("modeset=2", "bad value \"2\" in the URL's modeset"),
            ("ops=x", "bad operation count \"x\" in the URL's ops"),
            ("keys=%zz", "malformed escape in the URL's keys: \"%zz\""),
            ("keys=left%2", "malformed escape in the URL's keys"),
            ("colour=red", "unknown URL parameter \"colour\""),
            (
                "lab=crtc.13",
                "\"crtc.13\" in the URL's lab is not register:value",
            ),
            (
                "lab=crtc.99:00",
                "unknown register \"crtc.99\" in the URL's lab",
            ),
            (
                "lab=seq.02:100",
                "Sequencer Map Mask: \"100\" is not a hex value",
            ),
            (
                "lab=dac.01:404040",
                "DAC Entry 0x01 (RRGGBB): \"404040\" is not",
            ),
        ];
        for (query, start) in cases {
            let (_, problem) = parse_query(query);
            let problem = problem.unwrap_or_else(|| panic!("{query} passed"));
            assert!(problem.starts_with(start), "{query}: {problem}");
            assert!(!problem.contains('\n'), "{problem}");
        }
        // Only the first problem is shown.
        let (_, problem) = parse_query("keys=bad1,bad2");
        assert!(problem.unwrap().contains("bad1"));
    }
}
