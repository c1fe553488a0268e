//! The boot request QEMU hands the kernel through fw_cfg
//! (`opt/modex/boot`): what it may ask for, written and read back.

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
    /// `int 1`: a debug exception, which no debugger here asked for.
    Debug,
    /// `int 18`: the machine-check vector, as a CPU's check would reach it.
    MachineCheck,
    /// `int 0x80`: a vector with no handler, which the CPU turns into a
    /// segment-not-present fault naming the vector.
    NoHandler,
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

const FAULTS: [(Fault, &str); 10] = [
    (Fault::InvalidOpcode, "invalid-opcode"),
    (Fault::Page, "page"),
    (Fault::GeneralProtection, "general-protection"),
    (Fault::StackOverflow, "stack-overflow"),
    (Fault::Divide, "divide"),
    (Fault::Panic, "panic"),
    (Fault::Breakpoint, "breakpoint"),
    (Fault::Debug, "debug"),
    (Fault::MachineCheck, "machine-check"),
    (Fault::NoHandler, "no-handler"),
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
/// takes ([`crate::line::ScancodesTaken`]), so that a test can pace its keys by
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
