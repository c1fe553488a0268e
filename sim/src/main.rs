//! `cargo run --release -p sim -- [OPTIONS]`: the cube demo in a desktop
//! window on the software VGA, with the VGA inspector on V; or, with
//! `--record`, an animated GIF of it, no window needed.

#![forbid(unsafe_code)]

mod window;

use std::fs::File;
use std::io::BufWriter;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Parser;
use sim::keys::parse_keys;
use sim::record::{record_gif, Script};

/// The modex-cube demo on the software VGA: the kernel's drawing code, keys
/// and frame loop in a window (Esc closes it, V shows the VGA inspector), or
/// recorded as an animated GIF.
#[derive(Parser, Debug)]
#[command(name = "sim")]
struct Args {
    /// Show the VGA inspector beside the picture from the start (V toggles it).
    #[arg(long)]
    inspect: bool,
    /// Write an animated GIF of the scan-out to FILE.gif instead of opening a
    /// window; the same arguments always give the same file.
    #[arg(long, value_name = "FILE.gif")]
    record: Option<PathBuf>,
    /// With --record: frames of the demo to run (one per vertical retrace,
    /// 59.7 a second).
    #[arg(long, default_value_t = 240, value_parser = clap::value_parser!(u32).range(1..))]
    frames: u32,
    /// Keys to type, named as the runner's --keys names them, separated by
    /// spaces: a-z, 0-9, kp_0-kp_9, f1-f12, left, right, up, down, home, end,
    /// pgup, pgdn, spc, esc, ret (e.g. "r 4 4 f1 left spc").
    #[arg(long, default_value = "")]
    keys: String,
    /// Frames from one of the --keys to the next; the first is typed before
    /// the first frame.
    #[arg(long, default_value_t = 30, value_parser = clap::value_parser!(u32).range(1..))]
    key_every: u32,
    /// With --record: keep one frame in EVERY (2 gives 30 images a second).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..))]
    every: u32,
    /// The window shows each VGA pixel as a SCALE x SCALE block (2: 640x480).
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(2..=8))]
    scale: u32,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let script = match parse_keys(&args.keys) {
        Ok(keys) => Script {
            keys,
            key_every: args.key_every,
        },
        Err(message) => {
            eprintln!("error: {message}");
            return ExitCode::from(2);
        }
    };
    let result = match &args.record {
        Some(path) => record(path, &script, &args),
        None => window::run(&window::Options {
            scale: args.scale as usize,
            inspect: args.inspect,
            script,
        })
        .map_err(anyhow::Error::new),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(error) => {
            eprintln!("error: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn record(path: &PathBuf, script: &Script, args: &Args) -> anyhow::Result<()> {
    let file = File::create(path).with_context(|| format!("cannot create {}", path.display()))?;
    let recorded = record_gif(script, args.frames, args.every, BufWriter::new(file))
        .with_context(|| format!("recording {}", path.display()))?;
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    println!(
        "Wrote {} ({} bytes): {} images of 320x240, one every {} of {} frames run, {} cs apart",
        path.display(),
        bytes,
        recorded.images,
        args.every,
        recorded.frames_run,
        recorded.delay_centiseconds
    );
    Ok(())
}
