//! What the kernel, the runner and the tests say to each other, defined once:
//! the boot options QEMU hands the kernel through fw_cfg (`opt/modex/boot`),
//! and the serial lines the harness waits for. A renamed option or line is a
//! compile error on every side, not a test that silently waits forever.

#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![warn(missing_debug_implementations)]

#[cfg(test)]
extern crate std;

use core::fmt;

/// The fw_cfg file QEMU passes the boot option in.
pub const BOOT_OPTION_FILE: &str = "opt/modex/boot";

/// A fault raised on purpose, to prove it is reported and ends in a halt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// `ud2`.
    InvalidOpcode,
    /// A read of an unmapped page.
    Page,
    /// A read of a non-canonical address.
    GeneralProtection,
    /// Unbounded recursion into the guard page: a double fault.
    StackOverflow,
    /// Division by zero.
    Divide,
    /// `panic!`.
    Panic,
    /// `int3`, which is reported and resumed.
    Breakpoint,
}

/// How to end QEMU through isa-debug-exit: the kernel's goodbye (success),
/// or a boot option's request (either).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Exit {
    /// Status 33.
    Success,
    /// Status 35.
    Failure,
}

impl Exit {
    /// The value the kernel writes to isa-debug-exit.
    pub const fn code(self) -> u32 {
        match self {
            Exit::Success => 0x10,
            Exit::Failure => 0x11,
        }
    }

    /// QEMU's exit status for it: `(code << 1) | 1`.
    pub const fn qemu_status(self) -> i32 {
        ((self.code() << 1) | 1) as i32
    }
}

/// A boot option: what the kernel shows or does instead of (or before) the demo.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BootOption {
    /// The Mode X test pattern on pages 0 and 1; any key flips.
    TestPattern,
    /// Three seconds of page flips, the rate reported.
    FlipRate,
    /// The clock printed once a second for 12 s.
    ClockCheck,
    /// The renderer timed against per-pixel drawing.
    Bench,
    /// A deliberate fault.
    Fault(Fault),
    /// End QEMU at once.
    Exit(Exit),
}

const FAULTS: [(Fault, &str); 7] = [
    (Fault::InvalidOpcode, "invalid-opcode"),
    (Fault::Page, "page"),
    (Fault::GeneralProtection, "general-protection"),
    (Fault::StackOverflow, "stack-overflow"),
    (Fault::Divide, "divide"),
    (Fault::Panic, "panic"),
    (Fault::Breakpoint, "breakpoint"),
];

const EXITS: [(Exit, &str); 2] = [(Exit::Success, "success"), (Exit::Failure, "failure")];

/// The value of `name` in a (value, name) table.
fn named<T: Copy>(table: &[(T, &str)], name: &str) -> Option<T> {
    table
        .iter()
        .find(|(_, known)| *known == name)
        .map(|&(value, _)| value)
}

/// The name of `value` in a (value, name) table.
fn name<T: PartialEq>(table: &[(T, &'static str)], value: T) -> &'static str {
    table
        .iter()
        .find(|(known, _)| *known == value)
        .map_or("?", |(_, name)| name)
}

/// An option no one knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UnknownOption;

impl fmt::Display for UnknownOption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("unknown boot option; known: test-pattern, flip-rate, clock-check, bench, ")?;
        for (_, name) in FAULTS {
            write!(f, "fault={name}, ")?;
        }
        f.write_str("exit=success, exit=failure")
    }
}

impl BootOption {
    /// Every option, for help texts and tests.
    pub fn all() -> impl Iterator<Item = BootOption> {
        [
            BootOption::TestPattern,
            BootOption::FlipRate,
            BootOption::ClockCheck,
            BootOption::Bench,
        ]
        .into_iter()
        .chain(FAULTS.iter().map(|&(fault, _)| BootOption::Fault(fault)))
        .chain(EXITS.iter().map(|&(exit, _)| BootOption::Exit(exit)))
    }

    /// The option named `text` (as `Display` writes it).
    pub fn parse(text: &str) -> Result<BootOption, UnknownOption> {
        match text {
            "test-pattern" => Ok(BootOption::TestPattern),
            "flip-rate" => Ok(BootOption::FlipRate),
            "clock-check" => Ok(BootOption::ClockCheck),
            "bench" => Ok(BootOption::Bench),
            _ => {
                if let Some(fault) = text.strip_prefix("fault=").and_then(|n| named(&FAULTS, n)) {
                    Ok(BootOption::Fault(fault))
                } else if let Some(exit) = text.strip_prefix("exit=").and_then(|n| named(&EXITS, n))
                {
                    Ok(BootOption::Exit(exit))
                } else {
                    Err(UnknownOption)
                }
            }
        }
    }
}

impl fmt::Display for BootOption {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            BootOption::TestPattern => f.write_str("test-pattern"),
            BootOption::FlipRate => f.write_str("flip-rate"),
            BootOption::ClockCheck => f.write_str("clock-check"),
            BootOption::Bench => f.write_str("bench"),
            BootOption::Fault(fault) => write!(f, "fault={}", name(&FAULTS, fault)),
            BootOption::Exit(exit) => write!(f, "exit={}", name(&EXITS, exit)),
        }
    }
}

/// A clock reference a boot option can insist on, so that the tests drive
/// each one on a machine that has them all (the kernel otherwise takes the
/// first that works: `clock::tsc_rate`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ClockReference {
    /// The ACPI PM timer.
    PmTimer,
    /// The HPET.
    Hpet,
    /// PIT channel 2.
    Pit,
}

const CLOCK_REFERENCES: [(ClockReference, &str); 3] = [
    (ClockReference::PmTimer, "pm-timer"),
    (ClockReference::Hpet, "hpet"),
    (ClockReference::Pit, "pit"),
];

/// The prefix of the word that names a clock reference: `clock=hpet`.
const CLOCK_PREFIX: &str = "clock=";

/// The word that forces true Mode X on a UEFI boot (QEMU only), so OVMF with
/// QEMU's standard VGA still tests the real registers.
pub const TRUE_MODE_X: &str = "modex=true-mode-x";

/// The word that masks IRQ 1 at the PIC for the whole run, so that PS/2
/// keys arrive only through the frame and idle loops' poll of the 8042, as
/// on a machine whose firmware left the interrupt undelivered.
pub const IRQ1_MASKED: &str = "irq1=masked";

/// The word that makes the kernel say on serial every scancode byte it
/// takes ([`line::ScancodesTaken`]), so that a test can pace its keys by
/// what the kernel has received.
pub const ECHO_SCANCODES: &str = "scancodes=echo";

/// Everything one fw_cfg string asks for: true Mode X on UEFI or not, a
/// clock reference or not, IRQ 1 masked or not, scancodes echoed or not, and
/// at most one boot option, separated by spaces ("modex=true-mode-x
/// clock=hpet irq1=masked bench").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BootRequest {
    /// Drive the real VGA registers even on a UEFI boot.
    pub true_mode_x: bool,
    /// Mask IRQ 1 for the whole run ([`IRQ1_MASKED`]).
    pub irq1_masked: bool,
    /// Echo every scancode byte taken ([`ECHO_SCANCODES`]).
    pub echo_scancodes: bool,
    /// Measure the TSC against this reference only.
    pub clock: Option<ClockReference>,
    /// The boot option, if any.
    pub option: Option<BootOption>,
}

impl BootRequest {
    /// The request in `text`; an unknown word, or two options, is refused.
    pub fn parse(text: &str) -> Result<BootRequest, UnknownOption> {
        let mut request = BootRequest::default();
        for word in text.split_whitespace() {
            let clock = word
                .strip_prefix(CLOCK_PREFIX)
                .map(|name| named(&CLOCK_REFERENCES, name));
            if word == TRUE_MODE_X && !request.true_mode_x {
                request.true_mode_x = true;
            } else if word == IRQ1_MASKED && !request.irq1_masked {
                request.irq1_masked = true;
            } else if word == ECHO_SCANCODES && !request.echo_scancodes {
                request.echo_scancodes = true;
            } else if let Some(clock) = clock {
                match (clock, request.clock) {
                    (Some(reference), None) => request.clock = Some(reference),
                    _ => return Err(UnknownOption),
                }
            } else if request.option.is_none() {
                request.option = Some(BootOption::parse(word)?);
            } else {
                return Err(UnknownOption);
            }
        }
        Ok(request)
    }

    /// Nothing asked for.
    pub fn is_empty(&self) -> bool {
        *self == BootRequest::default()
    }
}

impl fmt::Display for BootRequest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut separator = "";
        if self.true_mode_x {
            f.write_str(TRUE_MODE_X)?;
            separator = " ";
        }
        for (asked, word) in [
            (self.irq1_masked, IRQ1_MASKED),
            (self.echo_scancodes, ECHO_SCANCODES),
        ] {
            if asked {
                write!(f, "{separator}{word}")?;
                separator = " ";
            }
        }
        if let Some(reference) = self.clock {
            write!(
                f,
                "{separator}{CLOCK_PREFIX}{}",
                name(&CLOCK_REFERENCES, reference)
            )?;
            separator = " ";
        }
        if let Some(option) = self.option {
            write!(f, "{separator}{option}")?;
        }
        Ok(())
    }
}

/// Serial lines the harness waits for.
pub mod line {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    #[test]
    fn every_option_reads_back_as_written() {
        let mut count = 0;
        for option in BootOption::all() {
            assert_eq!(BootOption::parse(&option.to_string()), Ok(option));
            count += 1;
        }
        assert_eq!(count, 4 + 7 + 2);
    }

    #[test]
    fn unknown_options_are_refused_with_the_list() {
        for text in [
            "",
            "fault=",
            "fault=nope",
            "exit=maybe",
            "bench ",
            "Test-Pattern",
        ] {
            assert_eq!(BootOption::parse(text), Err(UnknownOption), "{text:?}");
        }
        let message = UnknownOption.to_string();
        assert!(message.contains("fault=stack-overflow") && message.contains("clock-check"));
    }

    #[test]
    fn requests_combine_true_mode_x_with_one_option() {
        for true_mode_x in [false, true] {
            for option in BootOption::all().map(Some).chain([None]) {
                let request = BootRequest {
                    true_mode_x,
                    irq1_masked: option.is_some(),
                    echo_scancodes: !true_mode_x,
                    clock: None,
                    option,
                };
                assert_eq!(BootRequest::parse(&request.to_string()), Ok(request));
            }
        }
        assert_eq!(
            BootRequest::parse(" modex=true-mode-x  bench "),
            Ok(BootRequest {
                true_mode_x: true,
                clock: None,
                option: Some(BootOption::Bench),
                ..BootRequest::default()
            })
        );
        let keyed = BootRequest::parse("scancodes=echo irq1=masked").unwrap();
        assert!(keyed.irq1_masked && keyed.echo_scancodes && keyed.option.is_none());
        assert_eq!(keyed.to_string(), "irq1=masked scancodes=echo");
        assert_eq!(
            BootRequest::parse("irq1=masked irq1=masked"),
            Err(UnknownOption)
        );
        let clocked = BootRequest::parse("clock=hpet clock-check").unwrap();
        assert_eq!(clocked.clock, Some(ClockReference::Hpet));
        assert_eq!(clocked.option, Some(BootOption::ClockCheck));
        assert_eq!(clocked.to_string(), "clock=hpet clock-check");
        assert_eq!(
            BootRequest::parse("clock=hpet clock=pit"),
            Err(UnknownOption)
        );
        assert_eq!(BootRequest::parse("clock=sundial"), Err(UnknownOption));
        assert_eq!(BootRequest::parse("bench flip-rate"), Err(UnknownOption));
        assert_eq!(
            BootRequest::parse("modex=true-mode-x nope"),
            Err(UnknownOption)
        );
        assert!(BootRequest::parse("").unwrap().is_empty());
    }

    #[test]
    fn scancode_lines_format_and_parse() {
        let taken = line::ScancodesTaken {
            bytes: &[0x1e, 0x9e, 0xe0, 0x4b],
            total: 1234,
        };
        let text = taken.to_string();
        assert_eq!(text, "scancodes: taken 1e 9e e0 4b, 1234 in all");
        let mut bytes = [0u8; 8];
        assert_eq!(
            line::ScancodesTaken::parse(&(text + "\r"), &mut bytes),
            Some((4, 1234))
        );
        assert_eq!(bytes[..4], [0x1e, 0x9e, 0xe0, 0x4b]);
        assert_eq!(
            line::ScancodesTaken::parse("scancodes: taken 1e 9e, 2 in all", &mut [0u8; 1]),
            None,
            "more bytes than room"
        );
        assert_eq!(
            line::ScancodesTaken::parse("scancodes: taken zz, 1 in all", &mut bytes),
            None
        );
        assert_eq!(
            line::ScancodesTaken::parse("demo: command 1 done", &mut bytes),
            None
        );
    }

    #[test]
    fn command_lines_format_and_parse() {
        let line = line::CommandDone(12).to_string();
        assert_eq!(line, "demo: command 12 done");
        assert_eq!(
            line::CommandDone::parse(&(line + ", paused=false")),
            Some(12)
        );
        assert_eq!(line::CommandDone::parse("demo: goodbye"), None);
    }

    #[test]
    fn report_lines_format_and_parse() {
        let shown = line::ReportShown {
            first: 3,
            last: 18,
            total: 40,
        };
        let text = shown.to_string();
        assert_eq!(text, "report: shown, log lines 3-18 of 40");
        assert_eq!(line::ReportShown::parse(&text), Some(shown));
        assert_eq!(line::ReportShown::parse("report: shown"), None);
        assert!(line::is_report_line(&text));
        assert!(line::is_report_line("report log: clock: TSC"));
        assert!(!line::is_report_line("clock: TSC"));
        assert!(line::is_report_line("facts: clock: TSC 2000.000 MHz"));
    }

    fn every_kind_of_fault_line() -> [line::FaultLine<'static>; 7] {
        use line::{FaultLine, InterruptFrame};
        [
            FaultLine::Exception("page fault"),
            FaultLine::Panic("panic requested by the boot option"),
            FaultLine::Frame(InterruptFrame {
                rip: 0x8000_0123_4567,
                cs: 0x8,
                rflags: 0x10006,
                rsp: 0x0100_0020_1f58,
                ss: 0,
            }),
            FaultLine::Frame(InterruptFrame {
                rip: u64::MAX,
                cs: 0xffff,
                rflags: u64::MAX,
                rsp: u64::MAX,
                ss: 0xffff,
            }),
            FaultLine::Location {
                file: "C:\\odd:path/kernel/src/main.rs",
                line: 120,
                column: 9,
            },
            FaultLine::ErrorCode(0x2),
            FaultLine::Address(0x7f00_dead_0000),
        ]
    }

    #[test]
    fn fault_lines_read_back_as_written() {
        for fault in every_kind_of_fault_line() {
            let text = fault.to_string();
            assert_eq!(line::FaultLine::parse(&text), Some(fault), "{text:?}");
            let serial = text.clone() + "\r";
            assert_eq!(line::FaultLine::parse(&serial), Some(fault));
        }
        // The kernel's text, byte for byte.
        let [exception, _, frame, _, location, code, address] = every_kind_of_fault_line();
        assert_eq!(exception.to_string(), "EXCEPTION: page fault");
        assert_eq!(
            frame.to_string(),
            "  rip=0x800001234567 cs=0x8 rflags=0x10006 rsp=0x10000201f58 ss=0x0"
        );
        assert_eq!(
            location.to_string(),
            "  at C:\\odd:path/kernel/src/main.rs:120:9"
        );
        assert_eq!(code.to_string(), "  error code=0x2");
        assert_eq!(address.to_string(), "  address=0x7f00dead0000");
        let rows = every_kind_of_fault_line().map(|l| l.row());
        assert_eq!(rows, [0, 0, 1, 1, 1, 2, 3]);
        assert!(rows.iter().all(|&row| row < line::FAULT_ROWS));
    }

    #[test]
    fn cut_fault_lines_are_never_read_as_another_line() {
        for fault in every_kind_of_fault_line() {
            let text = fault.to_string();
            for cut in 0..text.len() {
                let Some(read) = line::FaultLine::parse(&text[..cut]) else {
                    continue;
                };
                // What a cut line reads as is its own kind, in its own row.
                assert_eq!(
                    core::mem::discriminant(&read),
                    core::mem::discriminant(&fault),
                    "{:?}",
                    &text[..cut]
                );
                assert_eq!(read.row(), fault.row());
            }
        }
        // A cut panic message is the cut text.
        assert_eq!(
            line::FaultLine::parse("PANIC: out of mem"),
            Some(line::FaultLine::Panic("out of mem"))
        );
        for other in [
            "HALTED",
            "",
            "  ",
            "  rip=0x1",
            "  at main.rs",
            "stack: 1 KiB",
        ] {
            assert_eq!(line::FaultLine::parse(other), None, "{other:?}");
        }
    }

    #[test]
    fn a_fault_report_is_read_from_a_console() {
        let console = "modex-cube kernel v0.1.0\r\n\
            EXCEPTION: breakpoint at 0x1000\r\n\
            breakpoint: resumed\r\n\
            stack: 12 KiB used\r\n\
            EXCEPTION: page fault\r\n  \
            rip=0x10 cs=0x8 rflags=0x2 rsp=0x20 ss=0x0\r\n  \
            error code=0x2\r\n  \
            address=0xdead\r\n\
            fault qr: EXCEPTION: page fault\r\n\
            fault qr: firmware: BIOS\r\n\
            HALTED\r\n\
            fault qr: after the halt\r\n";
        let report = line::FaultReport::parse(console).unwrap();
        assert_eq!(
            report.fault(),
            Some(line::FaultLine::Exception("page fault"))
        );
        assert_eq!(report.rows[2], Some(line::FaultLine::ErrorCode(2)));
        assert!(console[..report.start].ends_with("used\r\n"));
        assert_eq!(report.rows[3], Some(line::FaultLine::Address(0xdead)));
        assert!(matches!(report.rows[1], Some(line::FaultLine::Frame(f)) if f.rip == 0x10));
        let qr: std::vec::Vec<&str> = report.qr_lines().collect();
        assert_eq!(qr, ["EXCEPTION: page fault", "firmware: BIOS"]);

        let panic = "PANIC: oops\n  at src/main.rs:1:2\nHALTED\n";
        let report = line::FaultReport::parse(panic).unwrap();
        assert_eq!(report.rows[0], Some(line::FaultLine::Panic("oops")));
        assert_eq!(report.rows[2], None);
        // No halt, no report.
        assert!(line::FaultReport::parse("PANIC: oops\n").is_none());
        assert!(line::FaultReport::parse("EXCEPTION: breakpoint at 0x1\nHALTED\n").is_none());
    }
}
