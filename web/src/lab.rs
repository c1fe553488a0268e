//! The register lab, after TWEAK (1993): every register the VGA has, edited
//! in place while the demo runs. An edit is the port writes a program would
//! make ([`port_accesses`]), made on the demo's machine
//! (`sim::machine::Machine::access_ports`); the demo's own writes then
//! leave the edited registers of the index/data pairs and Misc Output as
//! edited (`Machine::hold`), so a Map Mask or start address edit stays
//! while it draws and flips. A timing that a VGA monitor would not sync to
//! is named ([`monitor_problem`]), "Back to Mode X" writes back what each
//! edited register held before, and the edits export as a table and
//! travel in the URL (`lab=crtc.13:50,seq.02:01`).

use modex::regs::{crtc, seq, Attribute, Crtc, Graphics, IndexedPair, Port, Sequencer};
use modex::soft::{CrtTiming, SoftVga};
use sim::machine::{HeldRegister, PortAccess};

/// The horizontal frequencies, in Hz, a VGA monitor syncs to: 31.469 kHz
/// nominal (640 dots of 800 at 25.175 MHz), give or take 1.5 kHz.
pub const HORIZONTAL_HZ: core::ops::RangeInclusive<u64> = 30_000..=33_000;
/// The vertical frequencies, in Hz, a VGA monitor syncs to.
pub const VERTICAL_HZ: core::ops::RangeInclusive<u64> = 50..=75;
/// The Attribute Controller index's Palette Address Source bit: left set,
/// the screen stays on while a register is written.
const PALETTE_ADDRESS_SOURCE: u8 = 0x20;

/// A register of the VGA, as the inspector and the lab name it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Register {
    /// Miscellaneous Output.
    MiscOutput,
    /// A Sequencer register.
    Sequencer(Sequencer),
    /// A CRT Controller register.
    Crtc(Crtc),
    /// A Graphics Controller register.
    Graphics(Graphics),
    /// An Attribute Controller register.
    Attribute(Attribute),
    /// The DAC's pixel mask.
    DacPixelMask,
    /// A DAC entry: its value is 0xRRGGBB, 6 bits a component.
    DacEntry(u8),
}

impl Register {
    /// Every register, in the lab's order: Misc Output, the Sequencer,
    /// CRTC, Graphics and Attribute Controllers, the DAC.
    pub fn all() -> impl Iterator<Item = Register> {
        core::iter::once(Register::MiscOutput)
            .chain(Sequencer::ALL.into_iter().map(Register::Sequencer))
            .chain(Crtc::ALL.into_iter().map(Register::Crtc))
            .chain(Graphics::ALL.into_iter().map(Register::Graphics))
            .chain(Attribute::ALL.into_iter().map(Register::Attribute))
            .chain(core::iter::once(Register::DacPixelMask))
            .chain((0..=255).map(Register::DacEntry))
    }

    /// The group's short name, as the URL and the page's keys spell it.
    fn group(self) -> &'static str {
        match self {
            Register::MiscOutput => "misc",
            Register::Sequencer(_) => "seq",
            Register::Crtc(_) => "crtc",
            Register::Graphics(_) => "gc",
            Register::Attribute(_) => "ac",
            Register::DacPixelMask => "dacmask",
            Register::DacEntry(_) => "dac",
        }
    }

    /// The group's name in the table.
    pub fn group_name(self) -> &'static str {
        match self {
            Register::MiscOutput => "Misc Output",
            Register::Sequencer(_) => "Sequencer",
            Register::Crtc(_) => "CRTC",
            Register::Graphics(_) => "Graphics Controller",
            Register::Attribute(_) => "Attribute Controller",
            Register::DacPixelMask | Register::DacEntry(_) => "DAC",
        }
    }

    /// The index written to the group's index port (0 for Misc Output and
    /// the pixel mask, which have none).
    pub fn index(self) -> u8 {
        match self {
            Register::MiscOutput | Register::DacPixelMask => 0,
            Register::Sequencer(register) => register.index(),
            Register::Crtc(register) => register.index(),
            Register::Graphics(register) => register.index(),
            Register::Attribute(register) => register.index(),
            Register::DacEntry(entry) => entry,
        }
    }

    /// The register's own name ("Map Mask", "DAC entry 0x05").
    pub fn name(self) -> String {
        let spaced = |debug: String| {
            let mut out = String::new();
            for (i, c) in debug.chars().enumerate() {
                if i > 0 && c.is_ascii_uppercase() {
                    out.push(' ');
                }
                out.push(c);
            }
            out
        };
        match self {
            Register::MiscOutput => "Miscellaneous Output".into(),
            Register::Sequencer(register) => spaced(format!("{register:?}")),
            Register::Crtc(register) => spaced(format!("{register:?}")),
            Register::Graphics(register) => spaced(format!("{register:?}")),
            Register::Attribute(register) => spaced(format!("{register:?}")),
            Register::DacPixelMask => "Pixel Mask".into(),
            Register::DacEntry(entry) => format!("Entry 0x{entry:02X} (RRGGBB)"),
        }
    }

    /// The page's key for it: `crtc.13`, `misc.00`, `dac.05`.
    pub fn key(self) -> String {
        format!("{}.{:02x}", self.group(), self.index())
    }

    /// The register a key names (`crtc.13`); `None` if none.
    pub fn from_key(key: &str) -> Option<Register> {
        let (group, index) = key.split_once('.')?;
        if index.len() != 2 {
            return None;
        }
        let index = u8::from_str_radix(index, 16).ok()?;
        Some(match group.to_ascii_lowercase().as_str() {
            "misc" if index == 0 => Register::MiscOutput,
            "dacmask" if index == 0 => Register::DacPixelMask,
            "seq" => Register::Sequencer(Sequencer::from_index(index)?),
            "crtc" => Register::Crtc(Crtc::from_index(index)?),
            "gc" => Register::Graphics(Graphics::from_index(index)?),
            "ac" => Register::Attribute(Attribute::from_index(index)?),
            "dac" => Register::DacEntry(index),
            _ => return None,
        })
    }

    /// The largest value it takes: 0xFF, or 0x3F3F3F for a DAC entry.
    pub fn max_value(self) -> u32 {
        match self {
            Register::DacEntry(_) => 0x3F3F3F,
            _ => 0xFF,
        }
    }

    /// Hex digits its value is shown in.
    fn digits(self) -> usize {
        match self {
            Register::DacEntry(_) => 6,
            _ => 2,
        }
    }

    /// Its value in `vga`, as the hardware holds it.
    pub fn value(self, vga: &SoftVga) -> u32 {
        u32::from(match self {
            Register::MiscOutput => vga.misc_output(),
            Register::Sequencer(register) => vga.sequencer(register),
            Register::Crtc(register) => vga.crtc(register),
            Register::Graphics(register) => vga.graphics(register),
            Register::Attribute(register) => vga.attribute(register),
            Register::DacPixelMask => vga.dac_pixel_mask(),
            Register::DacEntry(entry) => {
                let [r, g, b] = vga.dac_entry(entry);
                return u32::from_be_bytes([0, r, g, b]);
            }
        })
    }

    /// Its value written as the lab shows it (`3F`, `2A1510`).
    pub fn format(self, value: u32) -> String {
        format!("{value:0width$X}", width = self.digits())
    }

    /// The value typed for it (hex, `0x` or not); a clear line if it is
    /// not one.
    pub fn parse(self, text: &str) -> Result<u32, String> {
        let trimmed = text.trim();
        let digits = trimmed
            .strip_prefix("0x")
            .or_else(|| trimmed.strip_prefix("0X"))
            .unwrap_or(trimmed);
        let value = (!digits.is_empty() && digits.len() <= 8)
            .then(|| u32::from_str_radix(digits, 16).ok())
            .flatten();
        let bad = || {
            format!(
                "{} {}: {text:?} is not a hex value from 0 to {}",
                self.group_name(),
                self.name(),
                self.format(self.max_value())
            )
        };
        let value = value.ok_or_else(bad)?;
        let components_fit = match self {
            Register::DacEntry(_) => value.to_be_bytes().iter().all(|&c| c <= 0x3F),
            _ => true,
        };
        if value > self.max_value() || !components_fit {
            return Err(bad());
        }
        Ok(value)
    }

    /// What the demo's writes must leave as the lab set it; `None` for the
    /// Attribute Controller and the DAC, which the demo writes only when it
    /// sets the mode or loads colours.
    pub fn held(self) -> Option<HeldRegister> {
        match self {
            Register::MiscOutput => Some(HeldRegister::MiscOutput),
            Register::Sequencer(r) => Some(HeldRegister::Pair(IndexedPair::Sequencer, r.index())),
            Register::Crtc(r) => Some(HeldRegister::Pair(IndexedPair::Crtc, r.index())),
            Register::Graphics(r) => Some(HeldRegister::Pair(IndexedPair::Graphics, r.index())),
            _ => None,
        }
    }

    /// Whether the frequencies the monitor gets depend on it.
    fn sets_sync(self) -> bool {
        matches!(
            self,
            Register::MiscOutput
                | Register::Sequencer(Sequencer::ClockingMode)
                | Register::Crtc(Crtc::HorizontalTotal | Crtc::VerticalTotal | Crtc::Overflow)
        )
    }
}

/// The port accesses that write `value` to `register` on `vga`, as a
/// program does it: the dot clock and the character clock under the
/// Sequencer's synchronous reset; CRTC 0-7 with their write protection
/// (Vertical Retrace End bit 7) lifted and put back; the Attribute
/// Controller's flip-flop reset by a read of Input Status 1 first; a DAC
/// entry as its index and three components.
pub fn port_accesses(vga: &SoftVga, register: Register, value: u32) -> Vec<PortAccess> {
    use PortAccess::{Read, Write};
    let byte = value as u8;
    let colour = vga.misc_output() & modex::regs::misc::COLOR_IO_ADDRESSING != 0;
    let (crtc_index, crtc_data, status) = if colour {
        (Port::CRTC_INDEX, Port::CRTC_DATA, Port::INPUT_STATUS_1)
    } else {
        (
            Port::CRTC_INDEX_MONO,
            Port::CRTC_DATA_MONO,
            Port::INPUT_STATUS_1_MONO,
        )
    };
    let reset = vga.sequencer(Sequencer::Reset);
    let under_reset = |writes: &[PortAccess]| {
        let mut all = vec![
            Write(Port::SEQUENCER_INDEX, Sequencer::Reset.index()),
            Write(Port::SEQUENCER_DATA, seq::RESET_SYNCHRONOUS),
        ];
        all.extend_from_slice(writes);
        all.extend([
            Write(Port::SEQUENCER_INDEX, Sequencer::Reset.index()),
            Write(Port::SEQUENCER_DATA, reset),
        ]);
        all
    };
    match register {
        Register::MiscOutput => under_reset(&[Write(Port::MISC_OUTPUT_WRITE, byte)]),
        Register::Sequencer(Sequencer::ClockingMode) => under_reset(&[
            Write(Port::SEQUENCER_INDEX, Sequencer::ClockingMode.index()),
            Write(Port::SEQUENCER_DATA, byte),
        ]),
        Register::Sequencer(r) => vec![
            Write(Port::SEQUENCER_INDEX, r.index()),
            Write(Port::SEQUENCER_DATA, byte),
        ],
        Register::Crtc(r) => {
            let retrace_end = vga.crtc(Crtc::VerticalRetraceEnd);
            let protected = retrace_end & crtc::PROTECT_0_7 != 0;
            let write = [Write(crtc_index, r.index()), Write(crtc_data, byte)];
            if protected && r.index() <= Crtc::Overflow.index() {
                let mut all = vec![
                    Write(crtc_index, Crtc::VerticalRetraceEnd.index()),
                    Write(crtc_data, retrace_end & !crtc::PROTECT_0_7),
                ];
                all.extend(write);
                all.extend([
                    Write(crtc_index, Crtc::VerticalRetraceEnd.index()),
                    Write(crtc_data, retrace_end),
                ]);
                all
            } else {
                write.to_vec()
            }
        }
        Register::Graphics(r) => vec![
            Write(Port::GRAPHICS_INDEX, r.index()),
            Write(Port::GRAPHICS_DATA, byte),
        ],
        Register::Attribute(r) => vec![
            Read(status),
            Write(Port::ATTRIBUTE_INDEX, r.index() | PALETTE_ADDRESS_SOURCE),
            Write(Port::ATTRIBUTE_INDEX, byte),
        ],
        Register::DacPixelMask => vec![Write(Port::DAC_PIXEL_MASK, byte)],
        Register::DacEntry(entry) => {
            let [_, r, g, b] = value.to_be_bytes();
            vec![
                Write(Port::DAC_WRITE_INDEX, entry),
                Write(Port::DAC_DATA, r),
                Write(Port::DAC_DATA, g),
                Write(Port::DAC_DATA, b),
            ]
        }
    }
}

/// The line and frame rates `timing` sends a monitor, in Hz.
pub fn sync_rates(timing: &CrtTiming) -> (f64, f64) {
    let dots_per_line = (timing.characters_per_line * timing.dots_per_character).max(1);
    let horizontal = timing.dot_clock_hz as f64 / dots_per_line as f64;
    (
        horizontal,
        horizontal / timing.lines_per_frame.max(1) as f64,
    )
}

/// Why `timing` would harm a VGA monitor (which syncs only near 31.5 kHz
/// and from 50 to 75 Hz, and may not survive long outside), or `None`.
pub fn monitor_problem(timing: &CrtTiming) -> Option<String> {
    let (horizontal, vertical) = sync_rates(timing);
    let mut problems = Vec::new();
    if !(*HORIZONTAL_HZ.start() as f64..=*HORIZONTAL_HZ.end() as f64).contains(&horizontal) {
        problems.push(format!(
            "horizontal {:.2} kHz, outside the {:.1}-{:.1} kHz a VGA monitor syncs to",
            horizontal / 1000.0,
            *HORIZONTAL_HZ.start() as f64 / 1000.0,
            *HORIZONTAL_HZ.end() as f64 / 1000.0
        ));
    }
    if !(*VERTICAL_HZ.start() as f64..=*VERTICAL_HZ.end() as f64).contains(&vertical) {
        problems.push(format!(
            "vertical {vertical:.1} Hz, outside {}-{} Hz",
            VERTICAL_HZ.start(),
            VERTICAL_HZ.end()
        ));
    }
    (!problems.is_empty()).then(|| {
        format!(
            "would harm a real monitor: {} ({} dots a line at {:.3} MHz, {} lines)",
            problems.join("; "),
            timing.characters_per_line * timing.dots_per_character,
            timing.dot_clock_hz as f64 / 1e6,
            timing.lines_per_frame
        )
    })
}

/// The lab's edits: each register edited, with what it held before the
/// first edit and what the lab set, in the order first edited.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Lab {
    edits: Vec<Edit>,
}

/// One register's edit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Edit {
    register: Register,
    before: u32,
    value: u32,
}

impl Lab {
    /// Notes that `register` now holds `value`, after `before`.
    pub fn note(&mut self, register: Register, before: u32, value: u32) {
        match self.edits.iter_mut().find(|e| e.register == register) {
            Some(edit) => edit.value = value,
            None => self.edits.push(Edit {
                register,
                before,
                value,
            }),
        }
    }

    /// Whether nothing has been edited.
    pub fn is_empty(&self) -> bool {
        self.edits.is_empty()
    }

    /// What "Back to Mode X" writes: each edited register's value before
    /// the lab, the last edited first; the lab is emptied.
    pub fn take_restore(&mut self) -> Vec<(Register, u32)> {
        let edits = std::mem::take(&mut self.edits);
        edits.iter().rev().map(|e| (e.register, e.before)).collect()
    }

    /// The registers the demo's writes must leave alone.
    pub fn held(&self) -> Vec<HeldRegister> {
        self.edits
            .iter()
            .filter_map(|e| e.register.held())
            .collect()
    }

    /// Whether `register` has been edited.
    pub fn edited(&self, register: Register) -> bool {
        self.edits.iter().any(|e| e.register == register)
    }

    /// The edits as the URL's `lab` value: `crtc.13:50,seq.02:01`.
    pub fn url_value(&self) -> String {
        let tokens: Vec<String> = self
            .edits
            .iter()
            .map(|e| format!("{}:{}", e.register.key(), e.register.format(e.value)))
            .collect();
        tokens.join(",")
    }
}

/// The edits in a URL's `lab` value (`crtc.13:50,seq.02:01`), in order,
/// and the first bad token, named in one line.
pub fn parse_url_value(text: &str) -> (Vec<(Register, u32)>, Option<String>) {
    let mut edits = Vec::new();
    let mut problem = None;
    for token in text.split(',').filter(|t| !t.is_empty()) {
        let parsed = token
            .split_once(':')
            .ok_or_else(|| format!("{token:?} in the URL's lab is not register:value"))
            .and_then(|(key, value)| {
                let register = Register::from_key(key).ok_or_else(|| {
                    format!("unknown register {key:?} in the URL's lab (crtc.13, seq.02, ...)")
                })?;
                Ok((register, register.parse(value)?))
            });
        match parsed {
            Ok(edit) => edits.push(edit),
            Err(line) => {
                problem.get_or_insert(line);
            }
        }
    }
    (edits, problem)
}

/// The lab's table for the page, one register a line, tab-separated: its
/// key, group, index, name, value, and the reason it is marked (empty if
/// not). The DAC's 256 entries come last.
pub fn table(vga: &SoftVga, lab: &Lab) -> String {
    use std::fmt::Write;
    let problem = monitor_problem(&vga.timing());
    let mut out = String::new();
    for register in Register::all() {
        let mark = match &problem {
            Some(reason) if register.sets_sync() && lab.edited(register) => reason.as_str(),
            _ => "",
        };
        // Writing into a String cannot fail.
        let _ = writeln!(
            out,
            "{}\t{}\t{:02X}\t{}\t{}\t{}",
            register.key(),
            register.group_name(),
            register.index(),
            register.name(),
            register.format(register.value(vga)),
            mark
        );
    }
    out
}

/// The lab's fields as HTML, one table per group (the DAC's inside a
/// `<details>`): a row per register in [`table`]'s order, with its index,
/// name, an input for its value and a cell for the reason it is marked.
/// The page fills the values in from [`table`].
pub fn html() -> String {
    use std::fmt::Write;
    let mut out = String::from("<div class=\"lab-groups\">");
    let mut group = "";
    for register in Register::all() {
        let name = register.group_name();
        if name != group {
            if !group.is_empty() {
                out.push_str("</table>");
            }
            if name == "DAC" {
                out.push_str("<details><summary>DAC: pixel mask and 256 entries</summary>");
            }
            let _ = write!(out, "<table><caption>{name}</caption>");
            group = name;
        }
        let _ = write!(
            out,
            "<tr><td>{:02X}</td><td>{}</td><td><input data-key=\"{}\" spellcheck=\"false\" \
             aria-label=\"{name} {}\"></td><td class=\"reason\"></td></tr>",
            register.index(),
            register.name(),
            register.key(),
            register.name()
        );
    }
    out.push_str("</table></details></div>");
    out
}

/// The mode the VGA holds, as a table (CSV: register, index, value): every
/// register of the five groups and the DAC pixel mask, and the DAC entries
/// the lab changed.
pub fn export(vga: &SoftVga, lab: &Lab) -> String {
    use std::fmt::Write;
    let mut out = String::from("register,index,value\n");
    for register in Register::all() {
        if matches!(register, Register::DacEntry(_)) && !lab.edited(register) {
            continue;
        }
        let _ = writeln!(
            out,
            "{} {},0x{:02X},0x{}",
            register.group_name(),
            register.name(),
            register.index(),
            register.format(register.value(vga))
        );
    }
    out
}

#[cfg(test)]
mod tests;
