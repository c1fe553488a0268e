//! Serial lines the harness waits for: the kernel's and the loaders' lines,
//! each a constant (or a type that writes and reads it) every side uses.

use core::fmt;

/// The start of the kernel's first line, before its version: where its
/// log begins.
pub const KERNEL_BANNER: &str = "modex-cube kernel v";
/// The first picture is on screen and keys are read.
pub const READY: &str = "screen: ready";
/// There is no display at all (no legacy VGA, no framebuffer): the demo
/// runs unseen and keys are read.
pub const READY_NO_DISPLAY: &str = "screen: none, ready (no display)";
/// Printed on COM1 by the bootloader (BIOS stage 2, the UEFI loader) for
/// every disk read that failed and was tried again; the rest of the line
/// names the LBA or the file, and the status. Stage 2 also prints it for a
/// read the boot sector had to try again.
pub const LOADER_READ_RETRIED: &str = "loader: read retried";
/// A read that failed for good, on the screen and on COM1, before the
/// loader waits: `loader: cannot read the disk at LBA 0x00000800 (BIOS
/// status 0x01) ...` (BIOS) or `loader: cannot read kernel-x86_64
/// (DEVICE_ERROR) ...` (UEFI).
pub const LOADER_CANNOT_READ: &str = "loader: cannot read";
/// The bootloader's first line on serial (BIOS stage 2 and the UEFI
/// loader), written before it loads the kernel.
pub const LOADER_START: &str = "loader: loading kernel";
/// The BIOS loader's stack use, written by stage 4 before it jumps to the
/// kernel: `loader: stack: stages 2-3 used N of M bytes, stage 4 used N
/// of M bytes`.
pub const LOADER_STACK: &str = "loader: stack: ";
/// The memory map stage 4 (BIOS and 32-bit UEFI) or the UEFI loader made,
/// sanitised (issue 66): `loader: memory: 12 entries; 1 overlap split, 1
/// duplicate merged; 13 ranges`; stage 4 then names each range as Linux
/// prints E820 tables: `loader: memory: [mem 0x...-0x...] usable`.
pub const LOADER_MEMORY: &str = "loader: memory: ";
/// A loader stage's panic, on COM1 and the screen, with its file and line:
/// `loader: PANIC: panicked at src/main.rs:80:9:` and the message on the
/// next line.
pub const LOADER_PANIC: &str = "loader: PANIC: ";
/// The start of the goodbye line after Esc.
pub const GOODBYE: &str = "demo: goodbye";
/// The last line before a fault or panic halts the CPU.
pub const HALTED: &str = "HALTED";

/// Before each of the machine's facts, logged once when boot has found
/// them all (`demo::facts::MachineFacts::rows`).
pub const MACHINE_FACT: &str = "facts: ";

/// Before each fact the report screen shows, when it is drawn.
pub const REPORT_FACT: &str = "report fact: ";
/// Before each log line the report screen shows, when it is drawn.
pub const REPORT_LOG: &str = "report log: ";

/// A line the kernel printed about its report screen, or one of the
/// machine's facts the report shows above its log (which the report's
/// own log window leaves out).
pub fn is_report_line(line: &str) -> bool {
    line.starts_with(MACHINE_FACT)
        || line.starts_with(REPORT_FACT)
        || line.starts_with(REPORT_LOG)
        || line.starts_with(ReportShown::PREFIX)
}

/// "report: shown, log lines F-L of T": the report screen is drawn, its
/// log window showing lines F to L of the T in the log (after the facts
/// and log lines above, each on its own line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReportShown {
    /// The first log line shown, from 1 (0: none).
    pub first: usize,
    /// The last log line shown.
    pub last: usize,
    /// Log lines in all.
    pub total: usize,
}

impl ReportShown {
    const PREFIX: &'static str = "report: shown, log lines ";

    /// The figures of a line that is this message.
    pub fn parse(line: &str) -> Option<ReportShown> {
        let rest = line.strip_prefix(Self::PREFIX)?;
        let (range, total) = rest.split_once(" of ")?;
        let (first, last) = range.split_once('-')?;
        Some(ReportShown {
            first: first.parse().ok()?,
            last: last.parse().ok()?,
            total: total.trim().parse().ok()?,
        })
    }
}

impl fmt::Display for ReportShown {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}{}-{} of {}",
            Self::PREFIX,
            self.first,
            self.last,
            self.total
        )
    }
}

/// Rows of a fault report: the fault itself, then where it happened, the
/// error code and the faulting address (a row a kind of line; rows a
/// fault has nothing for stay empty).
pub const FAULT_ROWS: usize = 4;

/// Before each line of the text the fault panel's QR code encodes, printed
/// after the fault's own lines (so a test can decode the code and compare).
pub const FAULT_QR: &str = "fault qr: ";

/// The CPU's interrupt stack frame, as a fault report prints it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct InterruptFrame {
    /// The instruction pointer.
    pub rip: u64,
    /// The code segment selector.
    pub cs: u64,
    /// The flags register.
    pub rflags: u64,
    /// The stack pointer.
    pub rsp: u64,
    /// The stack segment selector.
    pub ss: u64,
}

/// One line of the report a fault or a panic prints on serial before the
/// halt, and the fault panel shows in its row ([`FaultLine::row`]).
/// `Display` writes it; [`FaultLine::parse`] reads it back. A panic's
/// message is any `Display` (`M`) when written, text when read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultLine<'a, M = &'a str> {
    /// "EXCEPTION: KIND", the CPU exception's name.
    Exception(&'a str),
    /// "PANIC: MESSAGE".
    Panic(M),
    /// "  rip=0x.. cs=0x.. rflags=0x.. rsp=0x.. ss=0x..".
    Frame(InterruptFrame),
    /// "  at FILE:LINE:COLUMN", where a panic was raised.
    Location {
        /// The source file.
        file: &'a str,
        /// Its line.
        line: u32,
        /// Its column.
        column: u32,
    },
    /// "  error code=0x..", the exception's error code.
    ErrorCode(u64),
    /// "  address=0x..", the address a page fault was for (CR2).
    Address(u64),
}

impl<M> FaultLine<'_, M> {
    const EXCEPTION: &'static str = "EXCEPTION: ";
    const PANIC: &'static str = "PANIC: ";
    const AT: &'static str = "  at ";
    const ERROR_CODE: &'static str = "  error code=";
    const ADDRESS: &'static str = "  address=";
    const FRAME_FIELDS: [&'static str; 5] = ["rip=", "cs=", "rflags=", "rsp=", "ss="];

    /// The report's row for this line, below [`FAULT_ROWS`].
    pub const fn row(&self) -> usize {
        match self {
            FaultLine::Exception(_) | FaultLine::Panic(_) => 0,
            FaultLine::Frame(_) | FaultLine::Location { .. } => 1,
            FaultLine::ErrorCode(_) => 2,
            FaultLine::Address(_) => 3,
        }
    }
}

/// "0x1f" as a number.
fn hex(text: &str) -> Option<u64> {
    u64::from_str_radix(text.strip_prefix("0x")?, 16).ok()
}

impl<'a> FaultLine<'a> {
    /// The line `text` is, if it is one (a trailing `\r` is ignored). A
    /// line cut short reads as its own kind (a cut panic message as the
    /// cut text, a cut number as its first digits) or as `None`, never
    /// as another kind of line.
    pub fn parse(text: &'a str) -> Option<FaultLine<'a>> {
        let text = text.trim_end_matches('\r');
        if let Some(kind) = text.strip_prefix(Self::EXCEPTION) {
            return Some(FaultLine::Exception(kind));
        }
        if let Some(message) = text.strip_prefix(Self::PANIC) {
            return Some(FaultLine::Panic(message));
        }
        if let Some(code) = text.strip_prefix(Self::ERROR_CODE) {
            return hex(code).map(FaultLine::ErrorCode);
        }
        if let Some(address) = text.strip_prefix(Self::ADDRESS) {
            return hex(address).map(FaultLine::Address);
        }
        if let Some(location) = text.strip_prefix(Self::AT) {
            let mut parts = location.rsplitn(3, ':');
            let column = parts.next()?.parse().ok()?;
            let line = parts.next()?.parse().ok()?;
            let file = parts.next()?;
            return Some(FaultLine::Location { file, line, column });
        }
        let mut fields = text.strip_prefix("  ")?.split(' ');
        let mut values = [0; 5];
        for (value, name) in values.iter_mut().zip(Self::FRAME_FIELDS) {
            *value = hex(fields.next()?.strip_prefix(name)?)?;
        }
        if fields.next().is_some() {
            return None;
        }
        let [rip, cs, rflags, rsp, ss] = values;
        Some(FaultLine::Frame(InterruptFrame {
            rip,
            cs,
            rflags,
            rsp,
            ss,
        }))
    }
}

impl<M: fmt::Display> fmt::Display for FaultLine<'_, M> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FaultLine::Exception(kind) => write!(f, "{}{}", Self::EXCEPTION, kind),
            FaultLine::Panic(message) => write!(f, "{}{}", Self::PANIC, message),
            FaultLine::Frame(frame) => write!(
                f,
                "  rip={:#x} cs={:#x} rflags={:#x} rsp={:#x} ss={:#x}",
                frame.rip, frame.cs, frame.rflags, frame.rsp, frame.ss
            ),
            FaultLine::Location { file, line, column } => {
                write!(f, "{}{}:{}:{}", Self::AT, file, line, column)
            }
            FaultLine::ErrorCode(code) => write!(f, "{}{:#x}", Self::ERROR_CODE, code),
            FaultLine::Address(address) => write!(f, "{}{:#x}", Self::ADDRESS, address),
        }
    }
}

/// The fault report in a serial console: the lines from the first
/// "EXCEPTION: " or "PANIC: " line up to [`HALTED`], each in its row,
/// and the text the fault panel's QR code encodes ([`FAULT_QR`] lines).
#[derive(Clone, Copy, Debug)]
pub struct FaultReport<'a> {
    /// The report's lines by row; `None` where the fault has nothing.
    pub rows: [Option<FaultLine<'a>>; FAULT_ROWS],
    /// Where the report's first line starts in the console: what comes
    /// before it is the log from before the fault.
    pub start: usize,
    /// The console from the report's first line to the halt.
    text: &'a str,
}

impl<'a> FaultReport<'a> {
    /// The report in `console`, if it has one that reached the halt.
    pub fn parse(console: &'a str) -> Option<FaultReport<'a>> {
        let start = console
            .match_indices('\n')
            .map(|(at, _)| at + 1)
            .chain([0])
            .filter(|&at| {
                let rest = &console[at..];
                rest.starts_with(FaultLine::<&str>::EXCEPTION)
                    && !rest.starts_with("EXCEPTION: breakpoint")
                    || rest.starts_with(FaultLine::<&str>::PANIC)
            })
            .min()?;
        let text = &console[start..];
        let end = text.lines().position(|l| l.trim_end() == HALTED)?;
        let mut rows = [None; FAULT_ROWS];
        for line in text.lines().take(end) {
            if let Some(fault) = FaultLine::parse(line) {
                rows[fault.row()].get_or_insert(fault);
            }
        }
        Some(FaultReport { rows, start, text })
    }

    /// The first line: the exception or the panic.
    pub fn fault(&self) -> Option<FaultLine<'a>> {
        self.rows[0]
    }

    /// The lines of the QR code's text, in order.
    pub fn qr_lines(&self) -> impl Iterator<Item = &'a str> {
        self.text
            .lines()
            .take_while(|l| l.trim_end() != HALTED)
            .filter_map(|l| l.strip_prefix(FAULT_QR))
            .map(|l| l.trim_end_matches('\r'))
    }
}

/// "scancodes: taken 1e 9e e0 4b, 1234 in all": the scancode bytes the
/// frame loop took from the queue since its last such line, and how
/// many it has taken since boot (with the boot word `scancodes=echo`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScancodesTaken<'a> {
    /// The bytes, in order.
    pub bytes: &'a [u8],
    /// Bytes taken since boot, these included.
    pub total: u64,
}

impl ScancodesTaken<'_> {
    const PREFIX: &'static str = "scancodes: taken";
    const SUFFIX: &'static str = " in all";

    /// The bytes and the total of such a line, if it is one.
    pub fn parse(line: &str, bytes: &mut [u8]) -> Option<(usize, u64)> {
        let rest = line.trim_end().strip_prefix(Self::PREFIX)?;
        let (list, total) = rest.rsplit_once(", ")?;
        let total = total.strip_suffix(Self::SUFFIX)?.parse().ok()?;
        let mut count = 0;
        for word in list.split_whitespace() {
            *bytes.get_mut(count)? = u8::from_str_radix(word, 16).ok()?;
            count += 1;
        }
        Some((count, total))
    }
}

impl fmt::Display for ScancodesTaken<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(Self::PREFIX)?;
        for byte in self.bytes {
            write!(f, " {byte:02x}")?;
        }
        write!(f, ", {}{}", self.total, Self::SUFFIX)
    }
}

/// "demo: command N done": the kernel has drawn the Nth command's frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CommandDone(pub u64);

impl CommandDone {
    const PREFIX: &'static str = "demo: command ";
    const SUFFIX: &'static str = " done";

    /// The count in a line that starts with this message, if it does.
    pub fn parse(line: &str) -> Option<u64> {
        line.strip_prefix(Self::PREFIX)?
            .split(Self::SUFFIX)
            .next()?
            .parse()
            .ok()
    }
}

impl fmt::Display for CommandDone {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{}{}", Self::PREFIX, self.0, Self::SUFFIX)
    }
}

/// The USB host controller kinds, by the names lines and facts give them
/// (`usb::host::ControllerKind::name`), in the facts row's order.
pub const USB_HOST_KINDS: [&str; 4] = ["xhci", "ehci", "ohci", "uhci"];

/// The index of `kind` in [`USB_HOST_KINDS`].
pub fn usb_host_index(kind: &str) -> Option<usize> {
    USB_HOST_KINDS.iter().position(|&known| known == kind)
}

/// "usb: keyboard on KIND FUNCTION LOCATION": the kernel has a USB keyboard
/// on a controller of kind KIND (one of [`USB_HOST_KINDS`]) at PCI FUNCTION
/// (`8086:2934 at 00:1d.0`), at LOCATION (the root port, then the hub port
/// of each tier: `2.1`). Said once a keyboard is set up, at boot or later.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsbKeyboardOn<'a, F = &'a str, L = &'a str> {
    /// The controller's kind.
    pub kind: &'a str,
    /// The controller's PCI function.
    pub function: F,
    /// Where the keyboard hangs.
    pub location: L,
}

impl<F, L> UsbKeyboardOn<'_, F, L> {
    const PREFIX: &'static str = "usb: keyboard on ";
}

impl UsbKeyboardOn<'_> {
    /// The parts of a line that is this message.
    pub fn parse(line: &str) -> Option<UsbKeyboardOn<'_>> {
        let rest = line.trim_end().strip_prefix(Self::PREFIX)?;
        let (kind, rest) = rest.split_once(' ')?;
        let (function, location) = rest.rsplit_once(' ')?;
        let kind = USB_HOST_KINDS[usb_host_index(kind)?];
        Some(UsbKeyboardOn {
            kind,
            function,
            location,
        })
    }
}

impl<F: fmt::Display, L: fmt::Display> fmt::Display for UsbKeyboardOn<'_, F, L> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}{} {} {}",
            Self::PREFIX,
            self.kind,
            self.function,
            self.location
        )
    }
}

/// Before power-off or reset, for each USB controller the kernel drove:
/// "usb: KIND FUNCTION halted" (an xHCI adds ", and reset, ports switched
/// off"), or "usb: KIND FUNCTION not halted: WHY".
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UsbHalted<'a, F = &'a str> {
    /// The controller's kind (one of [`USB_HOST_KINDS`]).
    pub kind: &'a str,
    /// The controller's PCI function.
    pub function: F,
    /// Whether it halted.
    pub halted: bool,
}

impl<F> UsbHalted<'_, F> {
    const PREFIX: &'static str = "usb: ";
    const HALTED: &'static str = " halted";
    const NOT_HALTED: &'static str = " not halted: ";
}

impl UsbHalted<'_> {
    /// The parts of a line that is this message.
    pub fn parse(line: &str) -> Option<UsbHalted<'_>> {
        let rest = line.strip_prefix(Self::PREFIX)?;
        let (kind, rest) = rest.split_once(' ')?;
        let kind = USB_HOST_KINDS[usb_host_index(kind)?];
        // The function is three words: `VVVV:DDDD at BB:DD.F`.
        let mut words = rest.split(' ');
        let (id, at, address) = (words.next()?, words.next()?, words.next()?);
        if at != "at" || !id.contains(':') || !address.contains(':') {
            return None;
        }
        let (function, after) = rest.split_at(id.len() + at.len() + address.len() + 2);
        let halted = if after.starts_with(Self::NOT_HALTED) {
            false
        } else if after.starts_with(Self::HALTED) {
            true
        } else {
            return None;
        };
        Some(UsbHalted {
            kind,
            function,
            halted,
        })
    }
}

impl<F: fmt::Display> fmt::Display for UsbHalted<'_, F> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}{} {}", Self::PREFIX, self.kind, self.function)?;
        f.write_str(if self.halted {
            Self::HALTED
        } else {
            Self::NOT_HALTED
        })
    }
}

/// The machine's facts row of USB keyboards, by the kind of controller
/// each is on: "USB keyboards: 1 ehci, 2 uhci", or "USB keyboards: none".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UsbKeyboards {
    /// Keyboards on each kind, in [`USB_HOST_KINDS`]' order.
    pub on: [u8; USB_HOST_KINDS.len()],
}

impl UsbKeyboards {
    const PREFIX: &'static str = "USB keyboards: ";
    const NONE: &'static str = "none";

    /// The counts of a row that is this fact.
    pub fn parse(row: &str) -> Option<UsbKeyboards> {
        let rest = row.trim_end().strip_prefix(Self::PREFIX)?;
        let mut keyboards = UsbKeyboards::default();
        if rest == Self::NONE {
            return Some(keyboards);
        }
        for part in rest.split(", ") {
            let (count, kind) = part.split_once(' ')?;
            let count: u8 = count.parse().ok()?;
            let slot = &mut keyboards.on[usb_host_index(kind)?];
            if *slot != 0 || count == 0 {
                return None;
            }
            *slot = count;
        }
        Some(keyboards)
    }

    /// Keyboards in all.
    pub fn total(&self) -> u32 {
        self.on.iter().map(|&n| u32::from(n)).sum()
    }
}

impl fmt::Display for UsbKeyboards {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(Self::PREFIX)?;
        if self.total() == 0 {
            return f.write_str(Self::NONE);
        }
        let mut first = true;
        for (count, kind) in self.on.iter().zip(USB_HOST_KINDS) {
            if *count != 0 {
                if !first {
                    f.write_str(", ")?;
                }
                first = false;
                write!(f, "{count} {kind}")?;
            }
        }
        Ok(())
    }
}
