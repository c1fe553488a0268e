//! The command line without a window: `--record` writes a GIF whose frames
//! are the software VGA's scan-outs of the same run, and with no display the
//! window mode says to use `--record` and fails without panicking.

use sim::keys::scancode_for_name;
use sim::machine::Machine;
use std::path::Path;
use std::process::{Command, Output};

fn run_sim(args: &[&str], display: Option<&str>) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_sim"));
    command.args(args).env_remove("WAYLAND_DISPLAY");
    match display {
        Some(display) => command.env("DISPLAY", display),
        None => command.env_remove("DISPLAY"),
    };
    command.output().expect("the simulator did not run")
}

/// The scan-outs (RGB) a run of `frames` frames shows after every `every`-th
/// frame, `keys` typed one every `key_every` frames from the first: the
/// schedule `--record` documents, run here on the library's machine.
fn scanouts(keys: &[&str], key_every: u32, frames: u32, every: u32) -> Vec<Vec<[u8; 3]>> {
    let mut machine = Machine::new();
    let mut pictures = Vec::new();
    for frame in 0..frames {
        if frame % key_every == 0 {
            if let Some(name) = keys.get((frame / key_every) as usize) {
                machine.tap(scancode_for_name(name).unwrap());
            }
        }
        machine.frame();
        if (frame + 1) % every == 0 {
            pictures.push(machine.scanout_rgb());
        }
    }
    pictures
}

/// The GIF's frames as full pictures: each image drawn over the last.
fn decode(path: &Path) -> (Vec<Vec<[u8; 3]>>, Vec<u16>) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::Indexed);
    let mut decoder = options
        .read_info(std::fs::File::open(path).unwrap())
        .unwrap();
    assert_eq!((decoder.width(), decoder.height()), (320, 240));
    let global = decoder.global_palette().map(<[u8]>::to_vec);
    let mut canvas = vec![[0u8; 3]; 320 * 240];
    let (mut pictures, mut delays) = (Vec::new(), Vec::new());
    while let Some(frame) = decoder.read_next_frame().unwrap() {
        let palette = frame.palette.clone().or(global.clone()).expect("a palette");
        assert_eq!(palette.len(), 256 * 3, "the 256 DAC colours");
        let width = usize::from(frame.width);
        for (i, &index) in frame.buffer.iter().enumerate() {
            let (x, y) = (
                usize::from(frame.left) + i % width,
                usize::from(frame.top) + i / width,
            );
            let colour = &palette[usize::from(index) * 3..][..3];
            canvas[y * 320 + x] = [colour[0], colour[1], colour[2]];
        }
        pictures.push(canvas.clone());
        delays.push(frame.delay);
    }
    (pictures, delays)
}

#[test]
fn the_gif_holds_the_scan_outs_of_the_same_run() {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("recorded.gif");
    let keys = ["m", "l", "n", "spc", "left", "h"];
    let output = run_sim(
        &[
            "--record",
            path.to_str().unwrap(),
            "--frames",
            "90",
            "--keys",
            &keys.join(" "),
            "--key-every",
            "13",
            "--every",
            "2",
        ],
        None,
    );
    assert!(output.status.success(), "{output:?}");
    let (pictures, delays) = decode(&path);
    let expected = scanouts(&keys, 13, 90, 2);
    assert_eq!(pictures.len(), 45);
    assert_eq!(pictures.len(), expected.len());
    for (n, (picture, expected)) in pictures.iter().zip(&expected).enumerate() {
        let differing = picture.iter().zip(expected).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "GIF frame {n}: {differing} pixels differ");
    }
    // Two frames of 16.75 ms: 3.35 hundredths of a second.
    assert!(delays.iter().all(|&delay| delay == 3), "{delays:?}");
    // Something moved, or the test would prove little.
    assert!(
        expected
            .windows(2)
            .filter(|pair| pair[0] != pair[1])
            .count()
            > 15
    );
}

#[test]
fn the_same_arguments_give_the_same_file() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let files = ["same-1.gif", "same-2.gif"].map(|name| dir.join(name));
    for file in &files {
        let args = [
            "--record",
            file.to_str().unwrap(),
            "--frames",
            "40",
            "--keys",
            "m s",
        ];
        assert!(run_sim(&args, None).status.success());
    }
    assert!(std::fs::read(&files[0]).unwrap() == std::fs::read(&files[1]).unwrap());
}

#[test]
fn without_a_display_the_window_mode_points_at_record() {
    let output = run_sim(&[], None);
    assert!(!output.status.success());
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(
        message.contains("no display") && message.contains("--record"),
        "{message}"
    );
    assert!(!message.contains("panicked"), "{message}");
}

#[test]
fn a_display_that_does_not_answer_is_an_error_too() {
    // No X server listens on this display number's socket, in any container.
    let output = run_sim(&[], Some(":65000"));
    assert!(!output.status.success());
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(
        message.contains("did not open") && message.contains("--record"),
        "{message}"
    );
    assert!(!message.contains("panicked"), "{message}");
}

#[test]
fn unknown_key_names_are_refused_with_the_list() {
    let output = run_sim(&["--record", "/dev/null", "--keys", "r bogus"], None);
    assert_eq!(output.status.code(), Some(2));
    let message = String::from_utf8_lossy(&output.stderr);
    assert!(
        message.contains("\"bogus\"") && message.contains("pgdn"),
        "{message}"
    );
}
