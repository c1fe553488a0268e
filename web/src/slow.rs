//! Slow motion: one frame's bus operations stepped one at a time on a copy
//! of the software VGA, each described with the `modex` function that
//! issued it, and a panel that shows what it did: the planes a Map Mask
//! write opens, where in the four planes a video-memory write lands, and a
//! start-address write waiting for the retrace that latches it.

use std::convert::Infallible;

use embedded_graphics::mono_font::{ascii::FONT_6X10, MonoTextStyle};
use embedded_graphics::pixelcolor::Rgb888;
use embedded_graphics::prelude::*;
use embedded_graphics::text::{Baseline, Text};
use modex::regs::{Crtc, Graphics, Port, Sequencer};
use modex::soft::{dac_6_to_8, SoftVga, PLANE_BYTES};
use modex::{Page, BYTES_PER_LINE, PAGE_BYTES, SCREEN_HEIGHT};
use sim::oplog::{BusOp, LoggedOp};

/// The slow-motion panel's size.
pub const PANEL_WIDTH: usize = 400;
/// The slow-motion panel's height.
pub const PANEL_HEIGHT: usize = 360;

const PLANES: usize = 4;
/// A byte not written this frame.
const UNTOUCHED: u8 = 0;
/// A byte an earlier operation of this frame wrote.
const WRITTEN: u8 = 1;
/// A byte the operation just shown wrote.
const JUST_WRITTEN: u8 = 2;

/// A frame being stepped through.
pub struct SlowMotion {
    vga: Box<SoftVga>,
    log: Vec<LoggedOp>,
    next: usize,
    frame: u64,
    /// Per plane and byte of the CPU window: [`UNTOUCHED`], [`WRITTEN`] or
    /// [`JUST_WRITTEN`].
    marks: Vec<u8>,
    /// The (plane, offset, count) runs the last operation marked.
    just: Vec<(usize, usize, usize)>,
    /// The page the last video-memory write went to.
    page: Page,
    last: Option<String>,
}

impl SlowMotion {
    /// Steps through `log`, the operations of frame `frame`, which ran on a
    /// VGA that was `before` when the frame began.
    pub fn new(before: Box<SoftVga>, log: Vec<LoggedOp>, frame: u64) -> Self {
        let shown = Page::ALL
            .into_iter()
            .find(|page| page.base() == before.displayed_start())
            .unwrap_or(Page::Zero);
        SlowMotion {
            vga: before,
            log,
            next: 0,
            frame,
            marks: vec![UNTOUCHED; PLANES * PLANE_BYTES],
            just: Vec::new(),
            page: shown.other(),
            last: None,
        }
    }

    /// The VGA as the operations so far left it.
    pub fn vga(&self) -> &SoftVga {
        &self.vga
    }

    /// Whether every operation of the frame has been done.
    pub fn finished(&self) -> bool {
        self.next >= self.log.len()
    }

    /// Does the next operation; returns its description, or `None` when
    /// the frame has none left.
    pub fn step(&mut self) -> Option<&str> {
        let entry = *self.log.get(self.next)?;
        let text = format!(
            "frame {}, operation {} of {}: {}",
            self.frame,
            self.next + 1,
            self.log.len(),
            describe(&entry, &self.vga)
        );
        self.mark(&entry.op);
        entry.replay(&mut self.vga);
        self.next += 1;
        self.last = Some(text);
        self.last.as_deref()
    }

    /// The description of the operation last done.
    pub fn last(&self) -> Option<&str> {
        self.last.as_deref()
    }

    /// Marks where a video-memory write lands: the planes the Map Mask
    /// opens (as the VGA holds it before the write), at its offsets.
    fn mark(&mut self, op: &BusOp) {
        for (plane, offset, count) in self.just.drain(..) {
            self.marks[plane * PLANE_BYTES + offset..][..count].fill(WRITTEN);
        }
        let (offset, count) = match *op {
            BusOp::WriteVram8 { offset, .. } => (usize::from(offset), 1),
            BusOp::FillVram { offset, count, .. } => (
                usize::from(offset),
                usize::from(count).min(PLANE_BYTES - usize::from(offset)),
            ),
            _ => return,
        };
        let mask = self.vga.sequencer(Sequencer::MapMask);
        for plane in (0..PLANES).filter(|plane| mask & (1 << plane) != 0) {
            self.marks[plane * PLANE_BYTES + offset..][..count].fill(JUST_WRITTEN);
            self.just.push((plane, offset, count));
        }
        if let Some(page) = page_of(offset as u16) {
            self.page = page;
        }
    }

    /// The panel: the operation, the Map Mask's planes, the start address
    /// written and latched, and the four planes of the page being drawn with
    /// this frame's writes marked. RGBA, [`PANEL_WIDTH`] x [`PANEL_HEIGHT`].
    pub fn draw_panel(&self) -> Vec<u8> {
        let mut panel = Canvas::new();
        let heading = format!(
            "Slow motion: frame {}, {} of {} operations done",
            self.frame,
            self.next,
            self.log.len()
        );
        panel.text(&heading, 8, 2, TEXT);
        let mut y = 16;
        let description = self.last.as_deref().unwrap_or("no operation yet: step one");
        for line in wrap(description, (PANEL_WIDTH - 16) / 6)
            .into_iter()
            .take(4)
        {
            panel.text(&line, 8, y, HIGHLIGHT);
            y += 11;
        }
        let y = 64;
        panel.text("Map Mask:", 8, y + 1, TEXT);
        let mask = self.vga.sequencer(Sequencer::MapMask);
        for plane in 0..PLANES {
            let left = 70 + plane as i32 * 34;
            let open = mask & (1 << plane) != 0;
            panel.fill(left, y, 28, 11, if open { OPEN } else { CLOSED });
            panel.text(&format!("p{plane}"), left + 8, y + 1, TEXT);
        }
        panel.text(
            if mask == 0 { "(none open)" } else { "open" },
            212,
            y + 1,
            TEXT,
        );
        let written = u16::from_be_bytes([
            self.vga.crtc(Crtc::StartAddressHigh),
            self.vga.crtc(Crtc::StartAddressLow),
        ]);
        let latched = self.vga.displayed_start();
        let flip = if written == latched {
            format!(
                "CRTC start 0x{written:04X} ({}): on screen",
                page_name(written)
            )
        } else {
            format!(
                "CRTC start 0x{written:04X} ({}) shows at the next retrace; 0x{latched:04X} now",
                page_name(written)
            )
        };
        panel.text(
            &flip,
            8,
            y + 15,
            if written == latched { TEXT } else { PENDING },
        );
        let planes_top = 120;
        panel.text(
            &format!(
                "{}, planes 0-3: this frame's writes blue, this one's yellow",
                page_name(self.page.base())
            ),
            8,
            planes_top - 14,
            TEXT,
        );
        self.draw_planes(&mut panel, planes_top);
        panel.rgba
    }

    fn draw_planes(&self, panel: &mut Canvas, top: i32) {
        let palette: Vec<[u8; 3]> = (0..=255u8)
            .map(|index| self.vga.dac_entry(index).map(dac_6_to_8))
            .collect();
        let width = usize::from(BYTES_PER_LINE);
        let base = usize::from(self.page.base());
        for plane in 0..PLANES {
            let left = 8 + plane * (width + 16);
            let bytes = self.vga.plane(plane);
            let marks = &self.marks[plane * PLANE_BYTES..][..PLANE_BYTES];
            for offset in 0..usize::from(PAGE_BYTES) {
                let address = base + offset;
                let colour = match marks[address] {
                    JUST_WRITTEN => [255, 230, 0],
                    WRITTEN => {
                        let [r, g, b] = palette[usize::from(bytes[address])];
                        [r / 2, g / 2, b / 2 + 127]
                    }
                    _ => palette[usize::from(bytes[address])],
                };
                let (x, y) = (left + offset % width, top as usize + offset / width);
                panel.put(x, y, colour);
            }
        }
    }
}

fn page_of(offset: u16) -> Option<Page> {
    Page::ALL
        .into_iter()
        .find(|page| (page.base()..page.base() + PAGE_BYTES).contains(&offset))
}

fn page_name(offset: u16) -> String {
    match Page::ALL.into_iter().find(|page| page.base() == offset) {
        Some(page) => format!("page {}", page.index()),
        None => match page_of(offset) {
            Some(page) => format!("inside page {}", page.index()),
            None => "past the pages".to_string(),
        },
    }
}

/// "Map Mask" from `MapMask`: the register's name as the book writes it.
fn spaced(debug_name: String) -> String {
    let mut words = String::new();
    for (index, character) in debug_name.chars().enumerate() {
        if index > 0 && character.is_ascii_uppercase() {
            words.push(' ');
        }
        words.push(character);
    }
    words
}

fn planes_text(mask: u8) -> String {
    let open: Vec<String> = (0..PLANES)
        .filter(|plane| mask & (1 << plane) != 0)
        .map(|plane| plane.to_string())
        .collect();
    if open.is_empty() {
        "no plane".to_string()
    } else {
        format!(
            "plane{} {}",
            if open.len() > 1 { "s" } else { "" },
            open.join(" ")
        )
    }
}

/// Where video-memory bytes `offset..offset + count` are on screen.
fn place(offset: u16, count: u16) -> String {
    let Some(page) = page_of(offset) else {
        return format!("0x{offset:04X}, past the pages");
    };
    let within = offset - page.base();
    let (line, byte) = (within / BYTES_PER_LINE, within % BYTES_PER_LINE);
    let last_x = (byte + count.max(1) - 1).min(BYTES_PER_LINE - 1) * 4 + 3;
    let lines = if byte + count > BYTES_PER_LINE {
        format!("from line {line}")
    } else {
        format!("line {line}")
    };
    format!(
        "0x{offset:04X}: page {} {lines}, x {}-{last_x}",
        page.index(),
        byte * 4
    )
}

/// What an indexed register write means.
fn indexed_write(port: Port, index: u8, value: u8, vga: &SoftVga) -> String {
    match port {
        Port::SEQUENCER_INDEX => {
            let name = Sequencer::from_index(index).map(|r| spaced(format!("{r:?}")));
            let name = name.unwrap_or_else(|| format!("index 0x{index:02X}"));
            let mut text = format!("Sequencer {name} = 0x{value:02X}");
            if index == Sequencer::MapMask.index() {
                text.push_str(&format!(": {} open to CPU writes", planes_text(value)));
            }
            text
        }
        Port::GRAPHICS_INDEX => {
            let name = Graphics::from_index(index).map(|r| spaced(format!("{r:?}")));
            let name = name.unwrap_or_else(|| format!("index 0x{index:02X}"));
            format!("Graphics Controller {name} = 0x{value:02X}")
        }
        Port::CRTC_INDEX => {
            let register = Crtc::from_index(index);
            let name = register.map(|r| spaced(format!("{r:?}")));
            let name = name.unwrap_or_else(|| format!("index 0x{index:02X}"));
            let mut text = format!("CRTC {name} = 0x{value:02X}");
            let start = match register {
                Some(Crtc::StartAddressHigh) => {
                    Some(u16::from_be_bytes([value, vga.crtc(Crtc::StartAddressLow)]))
                }
                Some(Crtc::StartAddressLow) => Some(u16::from_be_bytes([
                    vga.crtc(Crtc::StartAddressHigh),
                    value,
                ])),
                _ => None,
            };
            if let Some(start) = start {
                text.push_str(&format!(
                    ": start address 0x{start:04X} ({}), latched at the next vertical retrace",
                    page_name(start)
                ));
            }
            text
        }
        _ => format!("index 0x{index:02X} = 0x{value:02X}"),
    }
}

fn port_name(port: Port) -> &'static str {
    match port {
        Port::ATTRIBUTE_INDEX => "Attribute Controller index/data",
        Port::ATTRIBUTE_DATA_READ => "Attribute Controller data",
        Port::MISC_OUTPUT_WRITE => "Miscellaneous Output",
        Port::SEQUENCER_INDEX => "Sequencer index",
        Port::SEQUENCER_DATA => "Sequencer data",
        Port::DAC_PIXEL_MASK => "DAC Pixel Mask",
        Port::DAC_READ_INDEX => "DAC Read Index",
        Port::DAC_WRITE_INDEX => "DAC Write Index",
        Port::DAC_DATA => "DAC Data (one colour component)",
        Port::MISC_OUTPUT_READ => "Miscellaneous Output (read)",
        Port::GRAPHICS_INDEX => "Graphics Controller index",
        Port::GRAPHICS_DATA => "Graphics Controller data",
        Port::CRTC_INDEX => "CRTC index",
        Port::CRTC_DATA => "CRTC data",
        Port::INPUT_STATUS_1 => "Input Status 1",
        Port::VBE_DISPI_INDEX => "Bochs VBE index",
        Port::VBE_DISPI_DATA => "Bochs VBE data",
        _ => "a VGA port",
    }
}

/// One line for an entry of the log, given the VGA just before it: the
/// operation, what it means, and the `modex` functions that issued it.
pub fn describe(entry: &LoggedOp, vga: &SoftVga) -> String {
    let times = if entry.repeat > 1 {
        format!(" (x{})", entry.repeat)
    } else {
        String::new()
    };
    let what = match entry.op {
        BusOp::WritePort16 { port, value } if port.data().is_some() => {
            let [index, data] = value.to_le_bytes();
            format!(
                "OUT 0x{:03X}, 0x{value:04X}{times}: {}",
                port.number(),
                indexed_write(port, index, data, vga)
            )
        }
        BusOp::WritePort16 { port, value } => format!(
            "OUT 0x{:03X}, 0x{value:04X}{times}: {}",
            port.number(),
            port_name(port)
        ),
        BusOp::WritePort8 { port, value } => format!(
            "OUT 0x{:03X}, 0x{value:02X}{times}: {} = 0x{value:02X}",
            port.number(),
            port_name(port)
        ),
        BusOp::ReadPort8 { port, value } if port == Port::INPUT_STATUS_1 => {
            let retrace = if value & modex::regs::status::VERTICAL_RETRACE != 0 {
                "in vertical retrace"
            } else {
                "not in vertical retrace"
            };
            format!("IN 0x3DA -> 0x{value:02X}{times}: Input Status 1, {retrace}")
        }
        BusOp::ReadPort8 { port, value } => format!(
            "IN 0x{:03X} -> 0x{value:02X}{times}: {}",
            port.number(),
            port_name(port)
        ),
        BusOp::ReadPort16 { port, value } => format!(
            "IN 0x{:03X} -> 0x{value:04X}{times}: {}",
            port.number(),
            port_name(port)
        ),
        BusOp::WriteVram8 { offset, value } => format!(
            "write colour {value}{times} at {} through {}",
            place(offset, 1),
            planes_text(vga.sequencer(Sequencer::MapMask))
        ),
        BusOp::ReadVram8 { offset, value } => {
            format!("read 0x{offset:04X} -> {value}{times}, latches loaded")
        }
        BusOp::FillVram {
            offset,
            count,
            value,
        } => format!(
            "fill {count} bytes of colour {value}{times} from {} through {}",
            place(offset, count),
            planes_text(vga.sequencer(Sequencer::MapMask))
        ),
        BusOp::Flush => format!("flush{times}: the model lets a frame pass"),
    };
    let from = match entry.callers.names() {
        [] => "outside the driver".to_string(),
        names => names.join(" > "),
    };
    format!("{what}; from {from}")
}

/// `text` cut into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split(' ') {
        if !line.is_empty() && line.len() + 1 + word.len() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

const BACKGROUND: [u8; 3] = [24, 24, 32];
const TEXT: Rgb888 = Rgb888::new(230, 230, 230);
const HIGHLIGHT: Rgb888 = Rgb888::new(255, 230, 0);
const PENDING: Rgb888 = Rgb888::new(255, 150, 60);
const OPEN: [u8; 3] = [40, 150, 60];
const CLOSED: [u8; 3] = [70, 70, 70];

/// The panel's RGBA pixels, drawn on with embedded-graphics.
struct Canvas {
    rgba: Vec<u8>,
}

impl Canvas {
    fn new() -> Self {
        let [r, g, b] = BACKGROUND;
        Canvas {
            rgba: [r, g, b, 255].repeat(PANEL_WIDTH * PANEL_HEIGHT),
        }
    }

    fn put(&mut self, x: usize, y: usize, [r, g, b]: [u8; 3]) {
        if x < PANEL_WIDTH && y < PANEL_HEIGHT {
            self.rgba[(y * PANEL_WIDTH + x) * 4..][..4].copy_from_slice(&[r, g, b, 255]);
        }
    }

    fn fill(&mut self, left: i32, top: i32, width: i32, height: i32, colour: [u8; 3]) {
        for y in top.max(0)..top + height {
            for x in left.max(0)..left + width {
                self.put(x as usize, y as usize, colour);
            }
        }
    }

    fn text(&mut self, text: &str, x: i32, y: i32, colour: Rgb888) {
        let style = MonoTextStyle::new(&FONT_6X10, colour);
        // Drawing into a Vec cannot fail.
        let _ = Text::with_baseline(text, Point::new(x, y), style, Baseline::Top).draw(self);
    }
}

impl OriginDimensions for Canvas {
    fn size(&self) -> Size {
        Size::new(PANEL_WIDTH as u32, PANEL_HEIGHT as u32)
    }
}

impl DrawTarget for Canvas {
    type Color = Rgb888;
    type Error = Infallible;

    fn draw_iter<I: IntoIterator<Item = Pixel<Rgb888>>>(
        &mut self,
        pixels: I,
    ) -> Result<(), Infallible> {
        for Pixel(point, colour) in pixels {
            if point.x >= 0 && point.y >= 0 {
                self.put(
                    point.x as usize,
                    point.y as usize,
                    [colour.r(), colour.g(), colour.b()],
                );
            }
        }
        Ok(())
    }
}

const _: () = assert!(120 + SCREEN_HEIGHT as usize <= PANEL_HEIGHT);

#[cfg(test)]
mod tests {
    use super::*;
    use sim::machine::Machine;

    fn slow_frame(machine: &mut Machine) -> SlowMotion {
        let before = Box::new(machine.vga().clone());
        let (_, log) = machine.frame_logged();
        SlowMotion::new(before, log, machine.frames())
    }

    #[test]
    fn a_map_mask_write_names_its_planes_and_the_function() {
        crate::with_big_stack(|| {
            let mut machine = Machine::new();
            let mut slow = slow_frame(&mut machine);
            let text = loop {
                let text = slow
                    .step()
                    .expect("a frame writes the Map Mask")
                    .to_string();
                if text.contains("Map Mask") {
                    break text;
                }
            };
            let mask = slow.vga().sequencer(Sequencer::MapMask);
            assert!(text.contains(&planes_text(mask)), "{text}");
            assert!(text.contains("OUT 0x3C4"), "{text}");
            assert!(text.ends_with("from ModeX::update_page"), "{text}");
            assert_eq!(slow.last(), Some(text.as_str()));
        });
    }

    #[test]
    fn a_video_memory_write_lights_up_where_it_lands() {
        crate::with_big_stack(|| {
            let mut machine = Machine::new();
            let mut slow = slow_frame(&mut machine);
            let (offset, mask) = loop {
                let entry = slow.log[slow.next];
                let mask = slow.vga().sequencer(Sequencer::MapMask);
                slow.step().expect("a frame writes video memory");
                if let BusOp::WriteVram8 { offset, .. } | BusOp::FillVram { offset, .. } = entry.op
                {
                    break (usize::from(offset), mask);
                }
            };
            for plane in 0..PLANES {
                let lit = slow.marks[plane * PLANE_BYTES + offset] == JUST_WRITTEN;
                assert_eq!(
                    lit,
                    mask & (1 << plane) != 0,
                    "plane {plane}, mask {mask:#x}"
                );
            }
            // Drawn on the panel in yellow, at its place in its plane's image.
            let panel = slow.draw_panel();
            let within = offset - usize::from(slow.page.base());
            let plane = (0..PLANES).find(|p| mask & (1 << p) != 0).unwrap();
            let (x, y) = (8 + plane * 96 + within % 80, 120 + within / 80);
            assert_eq!(&panel[(y * PANEL_WIDTH + x) * 4..][..3], &[255, 230, 0]);
            // The next write turns it blue: written earlier this frame.
            loop {
                let entry = slow.log[slow.next];
                slow.step().unwrap();
                if matches!(entry.op, BusOp::WriteVram8 { .. } | BusOp::FillVram { .. }) {
                    break;
                }
            }
            let mark = slow.marks[plane * PLANE_BYTES + offset];
            assert!(mark == WRITTEN || mark == JUST_WRITTEN);
        });
    }

    #[test]
    fn the_start_address_write_waits_for_the_retrace() {
        crate::with_big_stack(|| {
            let mut machine = Machine::new();
            let mut slow = slow_frame(&mut machine);
            let shown_before = slow.vga().displayed_start();
            while let Some(text) = slow.step() {
                if text.contains("Start Address Low") {
                    break;
                }
            }
            let text = slow.last().unwrap().to_string();
            assert!(
                text.contains("latched at the next vertical retrace"),
                "{text}"
            );
            assert!(text.contains("from ModeX::show_page"), "{text}");
            // Written, not yet shown.
            assert_eq!(slow.vga().displayed_start(), shown_before);
            while slow.step().is_some() {}
            assert!(slow.finished());
            assert_ne!(slow.vga().displayed_start(), shown_before);
            assert_eq!(
                slow.vga().displayed_start(),
                machine.vga().displayed_start()
            );
        });
    }

    #[test]
    fn descriptions_say_where_bytes_land() {
        assert_eq!(place(19200 + 81, 1), "0x4B51: page 1 line 1, x 4-7");
        assert_eq!(place(0, 80), "0x0000: page 0 line 0, x 0-319");
        assert_eq!(place(79, 2), "0x004F: page 0 from line 0, x 316-319");
        assert_eq!(planes_text(0x05), "planes 0 2");
        assert_eq!(planes_text(0x08), "plane 3");
        assert_eq!(spaced("StartAddressHigh".into()), "Start Address High");
        assert_eq!(wrap("aa bb cc", 5), ["aa bb", "cc"]);
    }
}
