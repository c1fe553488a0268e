//! What the kernel, the runner and the tests say to each other, defined once:
//! the boot options QEMU hands the kernel through fw_cfg (`opt/modex/boot`),
//! and the serial lines the harness waits for. A renamed option or line is a
//! compile error on every side, not a test that silently waits forever.

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
/// first that works: `machine::clock`).
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

/// Everything one fw_cfg string asks for: true Mode X on UEFI or not, a
/// clock reference or not, and at most one boot option, separated by spaces
/// ("modex=true-mode-x clock=hpet bench").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BootRequest {
    /// Drive the real VGA registers even on a UEFI boot.
    pub true_mode_x: bool,
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
    /// The start of the goodbye line after Esc.
    pub const GOODBYE: &str = "demo: goodbye";
    /// The last line before a fault or panic halts the CPU.
    pub const HALTED: &str = "HALTED";

    /// Before each fact the report screen shows, when it is drawn.
    pub const REPORT_FACT: &str = "report fact: ";
    /// Before each log line the report screen shows, when it is drawn.
    pub const REPORT_LOG: &str = "report log: ";

    /// A line the kernel printed about its report screen (which the
    /// report's own log window leaves out).
    pub fn is_report_line(line: &str) -> bool {
        line.starts_with(REPORT_FACT)
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
                option: Some(BootOption::Bench)
            })
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
    }
}
