//! Animated GIFs of the software VGA's scan-out, made without a window: the
//! demo runs on the model's clock with keys typed at fixed frames, so the
//! same arguments always give the same file.

use std::borrow::Cow;
use std::io::Write;

use gif::{DisposalMethod, Encoder, Frame, Repeat};
use modex::soft::dac_6_to_8;
use modex::{SCREEN_HEIGHT, SCREEN_WIDTH};

use crate::keys::Scancode;
use crate::machine::Machine;

const WIDTH: usize = SCREEN_WIDTH as usize;
const HEIGHT: usize = SCREEN_HEIGHT as usize;
/// GIF delays count hundredths of a second.
const NANOS_PER_CENTISECOND: u64 = 10_000_000;

/// Why no GIF, or only part of one, was written.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The GIF's header could not be written.
    #[error("starting the GIF: {0}")]
    Start(gif::EncodingError),
    /// An image could not be written (the disk is full, say).
    #[error("writing the GIF: {0}")]
    Write(gif::EncodingError),
    /// The GIF's end could not be written or flushed: the file is cut short.
    #[error("finishing the GIF: {0}")]
    Finish(std::io::Error),
    /// The run ended (Esc) before the first frame that is kept.
    #[error("no frame recorded: {frames_run} frames run, one in {every} kept")]
    NothingRecorded {
        /// Frames the demo ran.
        frames_run: u32,
        /// One frame kept in this many.
        every: u32,
    },
}

/// Keys typed into a run, one every `key_every` frames from the first.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Script {
    /// Tapped (pressed and released) in order.
    pub keys: Vec<Scancode>,
    /// Frames from one key to the next (at least 1).
    pub key_every: u32,
}

impl Script {
    /// The key typed just before frame `frame` (counted from 0), if any.
    pub fn key_before(&self, frame: u32) -> Option<Scancode> {
        let every = self.key_every.max(1);
        if !frame.is_multiple_of(every) {
            return None;
        }
        self.keys.get((frame / every) as usize).copied()
    }
}

/// Runs `frames` frames of the demo, typing the script's keys, and hands
/// the machine to `after_frame` after each with the frame's number; stops
/// early when a key (Esc) ends the demo. Returns the frames run.
pub fn run_script(script: &Script, frames: u32, after_frame: impl FnMut(&Machine, u32)) -> u32 {
    run_with(frames, script_keys(script), after_frame)
}

/// Types the script's key due before each frame.
fn script_keys(script: &Script) -> impl FnMut(&mut Machine, u32) + '_ {
    move |machine, frame| {
        if let Some(key) = script.key_before(frame) {
            machine.tap(key);
        }
    }
}

/// Runs `frames` frames of the demo on a new machine: `before_frame` gets
/// the machine and the frame's number before each (to feed it keys), and
/// `after_frame` after it. Stops early when a key (Esc) ends the demo.
/// Returns the frames run.
pub fn run_with(
    frames: u32,
    mut before_frame: impl FnMut(&mut Machine, u32),
    mut after_frame: impl FnMut(&Machine, u32),
) -> u32 {
    let mut machine = Machine::new();
    for frame in 0..frames {
        before_frame(&mut machine, frame);
        if machine.app().quit_requested() {
            return frame;
        }
        machine.frame();
        after_frame(&machine, frame);
    }
    frames
}

/// What [`record_gif`] wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Recorded {
    /// Frames of the demo run.
    pub frames_run: u32,
    /// Images in the GIF.
    pub images: u32,
    /// Each image's delay, in hundredths of a second.
    pub delay_centiseconds: u16,
}

/// Whether frame `frame` of a run is recorded when one in `every` is: the
/// last of each group of `every`.
pub fn recorded(frame: u32, every: u32) -> bool {
    (frame + 1).is_multiple_of(every.max(1))
}

/// Runs the script for `frames` frames and writes the scan-out after every
/// `every`-th as a 320x240 GIF image, its palette the 256 DAC colours as the
/// scan-out shows them. Each image after the first holds only the rectangle
/// that changed (drawn over the last), which keeps a spinning cube small.
pub fn record_gif(
    script: &Script,
    frames: u32,
    every: u32,
    out: impl Write,
) -> Result<Recorded, RecordError> {
    record_gif_with(frames, every, script_keys(script), out)
}

/// As [`record_gif`], with the keys fed by `before_frame` (see
/// [`run_with`]): for a run whose keys were pressed and released at any
/// frame (the web page's), not typed to a script.
pub fn record_gif_with(
    frames: u32,
    every: u32,
    before_frame: impl FnMut(&mut Machine, u32),
    out: impl Write,
) -> Result<Recorded, RecordError> {
    let mut encoder: Option<Encoder<_>> = None;
    let mut out = Some(out);
    let mut previous: Option<(Vec<u8>, Vec<u8>)> = None;
    let mut images = 0;
    let mut delay = 0;
    let mut failure = None;
    let frames_run = run_with(frames, before_frame, |machine, frame| {
        if !recorded(frame, every) || failure.is_some() {
            return;
        }
        let frame_ns = machine.vga().timing().frame_ns();
        delay = ((u64::from(every.max(1)) * frame_ns + NANOS_PER_CENTISECOND / 2)
            / NANOS_PER_CENTISECOND) as u16;
        let indices = machine.scanout_indices();
        let palette = dac_palette(machine);
        let result = match (&mut encoder, out.take()) {
            (None, Some(out)) => start(out, &palette).map(|started| encoder = Some(started)),
            _ => Ok(()),
        }
        .and_then(|()| {
            let encoder = encoder.as_mut().expect("started above");
            let image = changed_image(&indices, &palette, previous.as_ref(), delay);
            encoder.write_frame(&image).map_err(RecordError::Write)
        });
        match result {
            Ok(()) => {
                images += 1;
                previous = Some((indices, palette));
            }
            Err(e) => failure = Some(e),
        }
    });
    if let Some(failure) = failure {
        return Err(failure);
    }
    let Some(encoder) = encoder else {
        return Err(RecordError::NothingRecorded { frames_run, every });
    };
    // The trailer, then whatever a buffered writer still holds: an error here
    // (a full disk) must not be dropped with the writer.
    let mut out = encoder.into_inner().map_err(RecordError::Finish)?;
    out.flush().map_err(RecordError::Finish)?;
    Ok(Recorded {
        frames_run,
        images,
        delay_centiseconds: delay,
    })
}

fn start<W: Write>(out: W, palette: &[u8]) -> Result<Encoder<W>, RecordError> {
    let mut encoder =
        Encoder::new(out, WIDTH as u16, HEIGHT as u16, palette).map_err(RecordError::Start)?;
    encoder
        .set_repeat(Repeat::Infinite)
        .map_err(RecordError::Start)?;
    Ok(encoder)
}

/// The DAC's 256 colours, 8 bits a component as the scan-out expands them.
fn dac_palette(machine: &Machine) -> Vec<u8> {
    (0..=255u8)
        .flat_map(|index| machine.vga().dac_entry(index).map(dac_6_to_8))
        .collect()
}

/// The image for `indices`: the whole picture first, then the smallest
/// rectangle holding every pixel that changed since `previous` (one pixel if
/// none did; a GIF image cannot be empty). The first image's palette is the
/// GIF's global one; a later image carries its own only if the DAC changed.
fn changed_image<'a>(
    indices: &'a [u8],
    palette: &[u8],
    previous: Option<&(Vec<u8>, Vec<u8>)>,
    delay: u16,
) -> Frame<'a> {
    let (left, top, right, bottom) = match previous {
        None => (0, 0, WIDTH, HEIGHT),
        Some((old, _)) => changed_rectangle(old, indices).unwrap_or((0, 0, 1, 1)),
    };
    let buffer: Vec<u8> = (top..bottom)
        .flat_map(|y| indices[y * WIDTH + left..y * WIDTH + right].iter().copied())
        .collect();
    let palette_changed = previous.is_some_and(|(_, old_palette)| old_palette != palette);
    Frame {
        left: left as u16,
        top: top as u16,
        width: (right - left) as u16,
        height: (bottom - top) as u16,
        buffer: Cow::Owned(buffer),
        delay,
        dispose: DisposalMethod::Keep,
        palette: palette_changed.then(|| palette.to_vec()),
        ..Frame::default()
    }
}

/// (left, top, right, bottom), exclusive at right and bottom, of the pixels
/// that differ; `None` if none do.
fn changed_rectangle(old: &[u8], new: &[u8]) -> Option<(usize, usize, usize, usize)> {
    let mut rectangle: Option<(usize, usize, usize, usize)> = None;
    for (pixel, _) in old.iter().zip(new).enumerate().filter(|(_, (a, b))| a != b) {
        let (x, y) = (pixel % WIDTH, pixel / WIDTH);
        rectangle = Some(match rectangle {
            None => (x, y, x + 1, y + 1),
            Some((l, t, r, b)) => (l.min(x), t.min(y), r.max(x + 1), b.max(y + 1)),
        });
    }
    rectangle
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_come_every_so_many_frames_from_the_first() {
        let script = Script {
            keys: crate::keys::parse_keys("r l m").unwrap(),
            key_every: 10,
        };
        let typed: Vec<u32> = (0..100)
            .filter(|&f| script.key_before(f).is_some())
            .collect();
        assert_eq!(typed, [0, 10, 20]);
    }

    #[test]
    fn the_changed_rectangle_holds_exactly_the_changes() {
        let old = vec![0u8; WIDTH * HEIGHT];
        let mut new = old.clone();
        assert_eq!(changed_rectangle(&old, &new), None);
        new[5 * WIDTH + 7] = 1;
        new[9 * WIDTH + 3] = 1;
        assert_eq!(changed_rectangle(&old, &new), Some((3, 5, 8, 10)));
    }

    #[test]
    fn esc_ends_the_run() {
        let script = Script {
            keys: crate::keys::parse_keys("r esc").unwrap(),
            key_every: 5,
        };
        assert_eq!(run_script(&script, 100, |_, _| {}), 5);
    }

    #[test]
    fn a_run_that_keeps_no_frame_is_an_error() {
        let script = Script {
            keys: crate::keys::parse_keys("esc").unwrap(),
            key_every: 1,
        };
        let error = record_gif(&script, 10, 2, Vec::new()).unwrap_err();
        assert!(
            matches!(
                error,
                RecordError::NothingRecorded {
                    frames_run: 0,
                    every: 2
                }
            ),
            "{error:?}"
        );
    }

    /// A writer that takes `room` bytes, then fails as a full disk does.
    struct Full {
        room: usize,
    }

    impl Write for Full {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            if self.room == 0 {
                return Err(std::io::Error::from(std::io::ErrorKind::StorageFull));
            }
            let taken = bytes.len().min(self.room);
            self.room -= taken;
            Ok(taken)
        }

        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn a_writer_that_fails_stops_the_recording_with_the_step_named() {
        let script = Script {
            keys: Vec::new(),
            key_every: 1,
        };
        let error = record_gif(&script, 4, 1, Full { room: 0 }).unwrap_err();
        assert!(matches!(error, RecordError::Start(_)), "{error:?}");
        // Room for the header and the global palette, not for the first image.
        let error = record_gif(&script, 4, 1, Full { room: 1024 }).unwrap_err();
        assert!(matches!(error, RecordError::Write(_)), "{error:?}");
        assert!(
            error.to_string().starts_with("writing the GIF: "),
            "{error}"
        );
    }

    #[test]
    fn a_disk_that_fills_while_the_last_buffer_is_flushed_is_an_error() {
        // Everything fits in the buffer, so only the final flush reaches the
        // full disk: the case `sim --record /dev/full` used to call a success.
        let script = Script {
            keys: Vec::new(),
            key_every: 1,
        };
        let out = std::io::BufWriter::with_capacity(1 << 20, Full { room: 0 });
        let error = record_gif(&script, 4, 1, out).unwrap_err();
        assert!(matches!(error, RecordError::Finish(_)), "{error:?}");
        assert!(
            error.to_string().starts_with("finishing the GIF: "),
            "{error}"
        );
    }
}
