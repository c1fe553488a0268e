//! The on-screen display: a statistics line in the top 12 and one in the
//! bottom 12 pixel rows, and a help box listing every key. It is drawn with
//! `embedded-graphics` (its 6x10 mono font) into the RAM image of the frame,
//! after the scene, so it reaches video memory through the same
//! changed-pixels-only update as everything else: an unchanged figure costs no
//! bus traffic at all.

use core::fmt::Write;
use embedded_graphics::mono_font::{ascii::FONT_6X10, MonoTextStyle, MonoTextStyleBuilder};
use embedded_graphics::prelude::*;
use embedded_graphics::primitives::{PrimitiveStyleBuilder, Rectangle};
use embedded_graphics::text::{Baseline, Text};
use engine::FaceCounts;
use modex::{ImageCanvas, PageImage, PageSpans, PaletteIndex, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Rows the statistics lines may use at the top and at the bottom.
pub const BAR_ROWS: i32 = 12;
const TEXT_COLOUR: u8 = 15; // bright white
const BAR_BACKGROUND: u8 = 0; // black
const HELP_BACKGROUND: u8 = 1; // blue
const CHAR_WIDTH: i32 = 6;
const LINE_HEIGHT: i32 = 10;

/// Every key, as the help box lists it.
pub const HELP_LINES: [&str; 19] = [
    "Arrows       move left/right/up/down",
    "A  T         move away / toward",
    "4 6  8 2     turn about Y / about X",
    "F1 F2        turn about Z",
    "Space        spin on/off",
    "L            lighting on/off",
    "Home End     light left / right",
    "PgUp PgDn    light up / down",
    "N            next solid",
    "M            one object / three",
    "X            many objects on/off",
    "S            statistics on/off",
    "H            this help on/off",
    "I            report and QR code on/off",
    "R            back to the starting scene",
    "Esc          quit",
    "other keys   pause until next key",
    "",
    "Keypad digits turn with NumLock on.",
];

/// What the statistics lines show.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames drawn per second over the last whole second, in tenths; `None`
    /// until a second has been measured.
    pub frames_per_second_tenths: Option<u32>,
    /// CPU and bus time of the last frame, without the wait for retrace.
    pub frame_micros: u32,
    /// Faces drawn and culled in the last frame.
    pub faces: FaceCounts,
    /// The name of the solid the keys move.
    pub solid: &'static str,
    /// Objects in the scene.
    pub objects: usize,
    /// Whether the faces are shaded by the light.
    pub lighting: bool,
}

/// Which parts of the display are on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Overlay {
    /// The statistics lines, top and bottom.
    pub stats: bool,
    /// The help box.
    pub help: bool,
}

/// One line of the statistics: the machine's one line buffer, 64 bytes.
pub type Line = kernel_log::LogLine<64>;

impl Stats {
    /// "59.9 fps  0.43 ms/frame" ("--.- fps" until a second has passed).
    pub fn top_line(&self) -> Line {
        let mut line = Line::new();
        let _ = match self.frames_per_second_tenths {
            Some(tenths) => write!(line, "{}.{} fps", tenths / 10, tenths % 10),
            None => write!(line, "--.- fps"),
        };
        let _ = write!(
            line,
            "  {}.{:02} ms/frame",
            self.frame_micros / 1000,
            self.frame_micros % 1000 / 10,
        );
        line
    }

    /// "faces 3 drawn 3 culled  cube x1  flat".
    pub fn bottom_line(&self) -> Line {
        let mut line = Line::new();
        let _ = write!(
            line,
            "faces {} drawn {} culled  {} x{}  {}",
            self.faces.drawn,
            self.faces.culled,
            self.solid,
            self.objects,
            if self.lighting { "lit" } else { "flat" },
        );
        line
    }
}

fn text_style(background: u8) -> MonoTextStyle<'static, PaletteIndex> {
    MonoTextStyleBuilder::new()
        .font(&FONT_6X10)
        .text_color(PaletteIndex(TEXT_COLOUR))
        .background_color(PaletteIndex(background))
        .build()
}

/// Draws the parts of the display that are on over the frame in `image`,
/// marking every pixel drawn in `drawn`.
pub fn draw(image: &mut PageImage, drawn: &mut PageSpans, overlay: Overlay, stats: &Stats) {
    let mut canvas = ImageCanvas::marking(image, drawn);
    if overlay.stats {
        draw_stats(&mut canvas, stats);
    }
    if overlay.help {
        draw_help(&mut canvas);
    }
}

fn draw_stats(canvas: &mut ImageCanvas, stats: &Stats) {
    let style = text_style(BAR_BACKGROUND);
    // One row of margin above the top line and below the bottom one.
    let top = Point::new(2, 1);
    let bottom = Point::new(2, SCREEN_HEIGHT - 1 - LINE_HEIGHT);
    draw_text(canvas, &stats.top_line(), top, style);
    draw_text(canvas, &stats.bottom_line(), bottom, style);
}

/// One line of text, drawn through a clip to the whole canvas: the report
/// (`crate::report`) draws its text clipped, and one copy of the font
/// renderer for both keeps 7 KB out of the kernel file. The clip changes no
/// pixel: the canvas drops what falls outside it either way.
fn draw_text(
    canvas: &mut ImageCanvas,
    line: &str,
    at: Point,
    style: MonoTextStyle<'_, PaletteIndex>,
) {
    let area = canvas.bounding_box();
    let _ = Text::with_baseline(line, at, style, Baseline::Top).draw(&mut canvas.clipped(&area));
}

/// The help box's place: centred, wide enough for the longest line.
pub fn help_box() -> Rectangle {
    let columns = HELP_LINES.iter().map(|line| line.len()).max().unwrap_or(0) as i32;
    let size = Size::new(
        (columns * CHAR_WIDTH + 2 * 8) as u32,
        (HELP_LINES.len() as i32 * LINE_HEIGHT + 2 * 6) as u32,
    );
    let top_left = Point::new(
        (SCREEN_WIDTH - size.width as i32) / 2,
        (SCREEN_HEIGHT - size.height as i32) / 2,
    );
    Rectangle::new(top_left, size)
}

fn draw_help(canvas: &mut ImageCanvas) {
    let frame = help_box();
    let style = PrimitiveStyleBuilder::new()
        .fill_color(PaletteIndex(HELP_BACKGROUND))
        .stroke_color(PaletteIndex(TEXT_COLOUR))
        .stroke_width(1)
        .build();
    let _ = frame.into_styled(style).draw(canvas);
    let text = text_style(HELP_BACKGROUND);
    for (row, line) in HELP_LINES.iter().enumerate() {
        let at = frame.top_left + Point::new(8, 6 + row as i32 * LINE_HEIGHT);
        draw_text(canvas, line, at, text);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use modex::PAGE_PIXELS;

    fn stats() -> Stats {
        Stats {
            frames_per_second_tenths: Some(599),
            frame_micros: 431,
            faces: FaceCounts {
                drawn: 3,
                culled: 3,
            },
            solid: "cube",
            objects: 1,
            lighting: false,
        }
    }

    #[test]
    fn the_lines_say_what_the_figures_are() {
        assert_eq!(&*stats().top_line(), "59.9 fps  0.43 ms/frame");
        assert_eq!(
            &*stats().bottom_line(),
            "faces 3 drawn 3 culled  cube x1  flat"
        );
        let slow = Stats {
            frames_per_second_tenths: Some(5),
            frame_micros: 123_456,
            lighting: true,
            ..stats()
        };
        assert_eq!(&*slow.top_line(), "0.5 fps  123.45 ms/frame");
        let unmeasured = Stats {
            frames_per_second_tenths: None,
            ..stats()
        };
        assert_eq!(&*unmeasured.top_line(), "--.- fps  0.43 ms/frame");
        assert!(slow.bottom_line().ends_with("lit"));
    }

    #[test]
    fn every_line_fits_the_screen() {
        let widest = Stats {
            frames_per_second_tenths: Some(u32::MAX),
            frame_micros: u32::MAX,
            faces: FaceCounts {
                drawn: 60,
                culled: 60,
            },
            solid: "dodecahedron",
            objects: 3,
            lighting: false,
        };
        for line in [&*widest.top_line(), &*widest.bottom_line()] {
            assert!(line.len() as i32 * CHAR_WIDTH <= SCREEN_WIDTH - 4, "{line}");
        }
        let frame = help_box();
        assert!(frame.top_left.x >= 0 && frame.top_left.y >= 0);
        assert!(frame.bottom_right().unwrap().x < SCREEN_WIDTH);
        assert!(frame.bottom_right().unwrap().y < SCREEN_HEIGHT);
    }

    #[test]
    fn statistics_stay_in_the_top_and_bottom_twelve_rows() {
        let mut image = [7u8; PAGE_PIXELS];
        let overlay = Overlay {
            stats: true,
            help: false,
        };
        draw(&mut image, &mut PageSpans::none(), overlay, &stats());
        let width = SCREEN_WIDTH as usize;
        let changed_rows: std::vec::Vec<usize> = (0..SCREEN_HEIGHT as usize)
            .filter(|&y| image[y * width..(y + 1) * width].iter().any(|&c| c != 7))
            .collect();
        assert!(!changed_rows.is_empty());
        for y in changed_rows {
            assert!(
                y < BAR_ROWS as usize || y >= (SCREEN_HEIGHT - BAR_ROWS) as usize,
                "row {y}"
            );
        }
        let white = image.iter().filter(|&&c| c == TEXT_COLOUR).count();
        assert!(white > 200, "only {white} text pixels");
    }

    #[test]
    fn the_help_box_covers_its_rectangle_and_nothing_else() {
        let mut image = [7u8; PAGE_PIXELS];
        let overlay = Overlay {
            stats: false,
            help: true,
        };
        let mut drawn = PageSpans::none();
        draw(&mut image, &mut drawn, overlay, &stats());
        // Every pixel drawn is marked, for the page update.
        let mut unmarked = image;
        drawn.fill(&mut unmarked[..], 7);
        assert!(unmarked.iter().all(|&c| c == 7));
        let frame = help_box();
        let width = SCREEN_WIDTH as usize;
        for (pixel, &colour) in image.iter().enumerate() {
            let at = Point::new((pixel % width) as i32, (pixel / width) as i32);
            if frame.contains(at) {
                assert!(
                    [TEXT_COLOUR, HELP_BACKGROUND].contains(&colour),
                    "{at:?}: {colour}"
                );
            } else {
                assert_eq!(colour, 7, "{at:?}");
            }
        }
    }

    #[test]
    fn nothing_is_drawn_when_the_display_is_off() {
        let mut image = [7u8; PAGE_PIXELS];
        draw(
            &mut image,
            &mut PageSpans::none(),
            Overlay::default(),
            &stats(),
        );
        assert!(image.iter().all(|&c| c == 7));
    }

    #[test]
    fn the_help_lists_a_key_for_every_command_and_the_keys_do_what_it_says() {
        use crate::command::{Axis, Command::*, LightTurn, SceneCommand::*, Sense};
        use crate::keymap::command_for;
        use pc_keyboard::{DecodedKey::*, KeyCode};
        let listed = [
            ("Arrows", RawKey(KeyCode::ArrowLeft), Scene(MoveLeft)),
            ("Arrows", RawKey(KeyCode::ArrowRight), Scene(MoveRight)),
            ("Arrows", RawKey(KeyCode::ArrowUp), Scene(MoveUp)),
            ("Arrows", RawKey(KeyCode::ArrowDown), Scene(MoveDown)),
            ("A  T", Unicode('a'), Scene(Away)),
            ("A  T", Unicode('t'), Scene(Toward)),
            (
                "4 6  8 2",
                Unicode('4'),
                Scene(Rotate(Axis::Y, Sense::Negative)),
            ),
            (
                "4 6  8 2",
                Unicode('6'),
                Scene(Rotate(Axis::Y, Sense::Positive)),
            ),
            (
                "4 6  8 2",
                Unicode('8'),
                Scene(Rotate(Axis::X, Sense::Negative)),
            ),
            (
                "4 6  8 2",
                Unicode('2'),
                Scene(Rotate(Axis::X, Sense::Positive)),
            ),
            (
                "F1 F2",
                RawKey(KeyCode::F1),
                Scene(Rotate(Axis::Z, Sense::Positive)),
            ),
            (
                "F1 F2",
                RawKey(KeyCode::F2),
                Scene(Rotate(Axis::Z, Sense::Negative)),
            ),
            ("Space", Unicode(' '), Scene(ToggleSpin)),
            ("L ", Unicode('l'), Scene(ToggleLighting)),
            (
                "Home End",
                RawKey(KeyCode::Home),
                Scene(TurnLight(LightTurn::Left)),
            ),
            (
                "Home End",
                RawKey(KeyCode::End),
                Scene(TurnLight(LightTurn::Right)),
            ),
            (
                "PgUp PgDn",
                RawKey(KeyCode::PageUp),
                Scene(TurnLight(LightTurn::Up)),
            ),
            (
                "PgUp PgDn",
                RawKey(KeyCode::PageDown),
                Scene(TurnLight(LightTurn::Down)),
            ),
            ("N ", Unicode('n'), Scene(NextSolid)),
            ("M ", Unicode('m'), Scene(ToggleSeveral)),
            ("X ", Unicode('x'), Scene(ToggleCrowd)),
            ("S ", Unicode('s'), ToggleStats),
            ("H ", Unicode('h'), ToggleHelp),
            ("I ", Unicode('i'), ToggleReport),
            ("R ", Unicode('r'), Scene(Reset)),
            ("Esc", RawKey(KeyCode::Escape), Quit),
            ("other keys", Unicode('q'), Pause),
        ];
        for (label, key, command) in listed {
            assert!(
                HELP_LINES.iter().any(|line| line.starts_with(label)),
                "the help has no line for {label:?}"
            );
            assert_eq!(command_for(key), Some(command), "{label}: {key:?}");
        }
        // A command added to the enum stops this match compiling, as a
        // reminder to give it a key, a help line and a row above.
        for (_, _, command) in listed {
            match command {
                Scene(MoveLeft)
                | Scene(MoveRight)
                | Scene(MoveUp)
                | Scene(MoveDown)
                | Scene(Away)
                | Scene(Toward)
                | Scene(Rotate(..))
                | Scene(ToggleSpin)
                | Scene(ToggleLighting)
                | Scene(TurnLight(..))
                | Scene(NextSolid)
                | Scene(ToggleSeveral)
                | Scene(ToggleCrowd)
                | ToggleHelp
                | ToggleStats
                | ToggleReport
                | Scene(Reset)
                | Pause
                | Quit => {}
            }
        }
    }
}
