//! What the kernel reads from ACPI beyond what the `acpi` crate parses: the
//! sleep type for soft-off (`\_S5`) from the AML of the DSDT or an SSDT, the
//! PM1 control value that enters it, what the FADT's boot flags say about
//! legacy devices, and the order in which the machine is reset.
//!
//! `\_S5` is AML, and a full AML interpreter needs a heap the kernel does not
//! have. Almost every firmware declares it as a plain named package,
//! `Name (_S5, Package () { SLP_TYPa, SLP_TYPb, ... })`, so a minimal reader
//! finds the `NameOp` (0x08) of `_S5_` followed by a `PackageOp` (0x12) and
//! decodes its first two elements (the OSDev wiki's "Shutdown" page describes
//! the same). A `\_S5` computed by a method is not understood, and is reported
//! as missing rather than guessed.

use core::fmt;

/// The sleep type values for S5, for PM1a and PM1b control.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SleepTypes {
    /// SLP_TYPa, written to PM1a control.
    pub a: u8,
    /// SLP_TYPb, written to PM1b control (if the machine has one).
    pub b: u8,
}

/// Why `\_S5` could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum S5Error {
    /// No `Name (_S5, Package ...)` in the table.
    Missing,
    /// The package is cut short or holds something other than integers.
    Malformed,
}

impl fmt::Display for S5Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            S5Error::Missing => "no \\_S5 package in the AML",
            S5Error::Malformed => "the \\_S5 package is not two integers",
        })
    }
}

const NAME_OP: u8 = 0x08;
const ROOT_PREFIX: u8 = b'\\';
const PACKAGE_OP: u8 = 0x12;
const ZERO_OP: u8 = 0x00;
const ONE_OP: u8 = 0x01;
const BYTE_PREFIX: u8 = 0x0A;
const WORD_PREFIX: u8 = 0x0B;
const DWORD_PREFIX: u8 = 0x0C;
const QWORD_PREFIX: u8 = 0x0E;
const ONES_OP: u8 = 0xFF;
/// SLP_TYP is a 3-bit field.
const SLEEP_TYPE_MASK: u64 = 0b111;

/// Finds `\_S5`'s sleep types in an AML byte stream (a DSDT's or SSDT's body,
/// after the 36-byte header, or the whole table: the header cannot hold the
/// pattern). Every read is bounds-checked: any byte string is safe input.
pub fn s5_sleep_types(aml: &[u8]) -> Result<SleepTypes, S5Error> {
    let mut found_malformed = false;
    for start in 0..aml.len() {
        let Some(package) = s5_package_at(aml, start) else {
            continue;
        };
        match read_package(package) {
            Ok(types) => return Ok(types),
            Err(_) => found_malformed = true,
        }
    }
    Err(if found_malformed {
        S5Error::Malformed
    } else {
        S5Error::Missing
    })
}

/// The bytes after `PackageOp` if a `Name (_S5, Package ...)` starts at `start`.
fn s5_package_at(aml: &[u8], start: usize) -> Option<&[u8]> {
    let rest = aml.get(start..)?;
    let rest = rest.strip_prefix(&[NAME_OP])?;
    let rest = rest.strip_prefix(&[ROOT_PREFIX]).unwrap_or(rest);
    let rest = rest.strip_prefix(b"_S5_")?;
    rest.strip_prefix(&[PACKAGE_OP])
}

/// Decodes `PkgLength NumElements element element ...`, taking the first two.
fn read_package(bytes: &[u8]) -> Result<SleepTypes, S5Error> {
    let lead = *bytes.first().ok_or(S5Error::Malformed)?;
    // PkgLength: bits 7-6 of the lead byte say how many bytes follow (0-3).
    let length_bytes = 1 + usize::from(lead >> 6);
    let mut rest = bytes.get(length_bytes..).ok_or(S5Error::Malformed)?;
    let count = *rest.first().ok_or(S5Error::Malformed)?;
    if count < 2 {
        return Err(S5Error::Malformed);
    }
    rest = &rest[1..];
    let (a, rest) = read_integer(rest)?;
    let (b, _) = read_integer(rest)?;
    Ok(SleepTypes {
        a: (a & SLEEP_TYPE_MASK) as u8,
        b: (b & SLEEP_TYPE_MASK) as u8,
    })
}

/// One AML integer data object and what follows it.
fn read_integer(bytes: &[u8]) -> Result<(u64, &[u8]), S5Error> {
    let (&op, rest) = bytes.split_first().ok_or(S5Error::Malformed)?;
    let width = match op {
        ZERO_OP => return Ok((0, rest)),
        ONE_OP => return Ok((1, rest)),
        ONES_OP => return Ok((u64::MAX, rest)),
        BYTE_PREFIX => 1,
        WORD_PREFIX => 2,
        DWORD_PREFIX => 4,
        QWORD_PREFIX => 8,
        _ => return Err(S5Error::Malformed),
    };
    let value = rest.get(..width).ok_or(S5Error::Malformed)?;
    let mut little_endian = [0u8; 8];
    little_endian[..width].copy_from_slice(value);
    Ok((u64::from_le_bytes(little_endian), &rest[width..]))
}

/// PM1 control's SLP_TYP field (bits 10-12) and SLP_EN (bit 13).
const SLP_TYP_SHIFT: u16 = 10;
const SLP_TYP_BITS: u16 = 0b111 << SLP_TYP_SHIFT;
/// Setting it enters the sleep state SLP_TYP names.
pub const SLP_EN: u16 = 1 << 13;
/// PM1 control's SCI_EN (bit 0): the chipset is in ACPI mode.
pub const SCI_EN: u16 = 1;

/// The PM1 control value that selects sleep type `sleep_type`, keeping the
/// other bits of `current`, without SLP_EN yet: the ACPI specification
/// (4.8.3.2.1) has SLP_TYP written first and SLP_EN set by a second write.
pub fn pm1_control_with_sleep_type(current: u16, sleep_type: u8) -> u16 {
    (current & !(SLP_TYP_BITS | SLP_EN)) | ((u16::from(sleep_type) & 0b111) << SLP_TYP_SHIFT)
}

/// Whether a legacy device is there, as the FADT's IA-PC boot flags say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Presence {
    /// The flags say it is there (or, for VGA, do not say it is absent).
    Present,
    /// The flags say it is not.
    Absent,
    /// The FADT is too old to have the flags (revision 1), or there is no
    /// FADT: probe as before.
    Unknown,
}

/// What the FADT says about the legacy devices the kernel would probe.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LegacyDevices {
    /// The 8042 keyboard controller.
    pub i8042: Presence,
    /// The VGA.
    pub vga: Presence,
}

/// IAPC_BOOT_ARCH bit 1: the motherboard has an 8042.
const BOOT_ARCH_8042: u16 = 1 << 1;
/// IAPC_BOOT_ARCH bit 2: VGA is not present.
const BOOT_ARCH_VGA_NOT_PRESENT: u16 = 1 << 2;

impl LegacyDevices {
    /// Nothing known: probe everything.
    pub const UNKNOWN: LegacyDevices = LegacyDevices {
        i8042: Presence::Unknown,
        vga: Presence::Unknown,
    };

    /// From the FADT's revision and IAPC_BOOT_ARCH. The field was reserved in
    /// revision 1 (ACPI 1.0), so its zeros say nothing there; Linux ignores
    /// it before revision 2 too.
    pub fn from_fadt(revision: u8, iapc_boot_arch: u16) -> LegacyDevices {
        if revision < 2 {
            return LegacyDevices::UNKNOWN;
        }
        LegacyDevices {
            i8042: if iapc_boot_arch & BOOT_ARCH_8042 != 0 {
                Presence::Present
            } else {
                Presence::Absent
            },
            vga: if iapc_boot_arch & BOOT_ARCH_VGA_NOT_PRESENT != 0 {
                Presence::Absent
            } else {
                Presence::Present
            },
        }
    }
}

/// Ways to reset the machine, in the order they are tried: each is tried
/// only if the one before did not reset it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ResetStep {
    /// The FADT's reset register, where its RESET_REG_SUP flag says it works.
    FadtRegister,
    /// The chipset's Reset Control Register at port 0xCF9 (a full reset).
    ResetControlPort,
    /// The 8042's output port pulse of the reset line (command 0xFE).
    KeyboardControllerPulse,
    /// A triple fault: no IDT, then an exception.
    TripleFault,
}

impl ResetStep {
    /// The order, with the FADT register first where the FADT offers one,
    /// the 8042 only where it may be there.
    pub fn order(fadt_register: bool, i8042: Presence) -> impl Iterator<Item = ResetStep> {
        [
            fadt_register.then_some(ResetStep::FadtRegister),
            Some(ResetStep::ResetControlPort),
            (i8042 != Presence::Absent).then_some(ResetStep::KeyboardControllerPulse),
            Some(ResetStep::TripleFault),
        ]
        .into_iter()
        .flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    /// A DSDT as QEMU 7.2 builds it for `-M pc` and `-M q35`: a 36-byte
    /// header, then (among much else) `Name (_S5, Package (0x04) { Zero,
    /// Zero, Zero, Zero })` at the root, after `_S3`/`_S4` packages that must
    /// not be taken for it.
    fn qemu_like_dsdt() -> Vec<u8> {
        let mut table = b"DSDT".to_vec();
        table.extend_from_slice(&[0; 32]);
        // Scope (\_SB) { ... } with a device using a name that contains "S5".
        table.extend_from_slice(&[
            0x10, 0x0B, b'\\', b'_', b'S', b'B', b'_', 0x08, b'S', b'5', b'X', b'_', 0x00,
        ]);
        // Name (_S3, Package (0x04) { One, One, Zero, Zero })
        table.extend_from_slice(&[
            0x08, b'_', b'S', b'3', b'_', 0x12, 0x06, 0x04, 0x01, 0x01, 0x00, 0x00,
        ]);
        // Name (_S4, Package (0x04) { 0x02, 0x02, Zero, Zero })
        table.extend_from_slice(&[
            0x08, b'_', b'S', b'4', b'_', 0x12, 0x08, 0x04, 0x0A, 0x02, 0x0A, 0x02, 0x00, 0x00,
        ]);
        // Name (_S5, Package (0x04) { Zero, Zero, Zero, Zero })
        table.extend_from_slice(&[
            0x08, b'_', b'S', b'5', b'_', 0x12, 0x06, 0x04, 0x00, 0x00, 0x00, 0x00,
        ]);
        table
    }

    /// A typical desktop board's: `Name (\_S5, Package () { 0x07, 0x07, Zero,
    /// Zero })` with the root prefix and byte constants.
    fn desktop_dsdt() -> Vec<u8> {
        let mut table = b"DSDT".to_vec();
        table.extend_from_slice(&[0; 32]);
        table.extend_from_slice(&[
            0x08, b'\\', b'_', b'S', b'5', b'_', 0x12, 0x0A, 0x04, 0x0A, 0x07, 0x0A, 0x07, 0x00,
            0x00,
        ]);
        table
    }

    #[test]
    fn the_s5_value_is_read_from_a_dsdt() {
        assert_eq!(
            s5_sleep_types(&qemu_like_dsdt()),
            Ok(SleepTypes { a: 0, b: 0 })
        );
        assert_eq!(
            s5_sleep_types(&desktop_dsdt()),
            Ok(SleepTypes { a: 7, b: 7 })
        );
    }

    #[test]
    fn word_and_dword_constants_and_long_package_lengths_are_read() {
        // PkgLength in two bytes (lead 0x4x), DWord and Word constants.
        let aml = [
            0x08, b'_', b'S', b'5', b'_', 0x12, 0x40, 0x01, 0x02, 0x0C, 0x05, 0, 0, 0, 0x0B, 0x06,
            0x00,
        ];
        assert_eq!(s5_sleep_types(&aml), Ok(SleepTypes { a: 5, b: 6 }));
    }

    #[test]
    fn a_missing_or_cut_s5_is_an_error_never_a_panic() {
        let mut no_s5 = qemu_like_dsdt();
        let at = no_s5.windows(4).position(|w| w == b"_S5_").unwrap();
        no_s5[at + 2] = b'6';
        assert_eq!(s5_sleep_types(&no_s5), Err(S5Error::Missing));
        assert_eq!(s5_sleep_types(&[]), Err(S5Error::Missing));

        let whole = desktop_dsdt();
        let name = whole.windows(4).position(|w| w == b"_S5_").unwrap();
        for cut in name..whole.len() - 2 {
            assert_eq!(s5_sleep_types(&whole[..cut]).ok(), None, "cut at {cut}");
        }
        // A package of one element, or of a string, is not understood.
        let one = [0x08, b'_', b'S', b'5', b'_', 0x12, 0x03, 0x01, 0x00];
        assert_eq!(s5_sleep_types(&one), Err(S5Error::Malformed));
        let string = [
            0x08, b'_', b'S', b'5', b'_', 0x12, 0x05, 0x02, 0x0D, b'x', 0x00,
        ];
        assert_eq!(s5_sleep_types(&string), Err(S5Error::Malformed));
    }

    #[test]
    fn any_bytes_are_safe_input() {
        // Every prefix of a pseudo-random stream seeded with the pattern.
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut bytes: Vec<u8> = (0..4096)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                state as u8
            })
            .collect();
        for at in (0..4000).step_by(97) {
            bytes[at..at + 6].copy_from_slice(&[0x08, b'_', b'S', b'5', b'_', 0x12]);
        }
        for end in (0..bytes.len()).step_by(61) {
            let _ = s5_sleep_types(&bytes[..end]);
        }
    }

    #[test]
    fn the_sleep_type_goes_into_bits_10_to_12_and_keeps_the_rest() {
        assert_eq!(pm1_control_with_sleep_type(0x0001, 5), 0x1401);
        // An old SLP_TYP and a stray SLP_EN are cleared.
        assert_eq!(pm1_control_with_sleep_type(0x3C01, 0), 0x0001);
        assert_eq!(pm1_control_with_sleep_type(0x0000, 7) | SLP_EN, 0x3C00);
    }

    #[test]
    fn the_boot_flags_say_which_legacy_devices_are_there() {
        // QEMU q35 with i8042=off: flags 0.
        assert_eq!(
            LegacyDevices::from_fadt(3, 0),
            LegacyDevices {
                i8042: Presence::Absent,
                vga: Presence::Present
            }
        );
        assert_eq!(LegacyDevices::from_fadt(3, 0b0010).i8042, Presence::Present);
        assert_eq!(LegacyDevices::from_fadt(5, 0b0110).vga, Presence::Absent);
        // ACPI 1.0's FADT has no flags: nothing is known.
        assert_eq!(LegacyDevices::from_fadt(1, 0), LegacyDevices::UNKNOWN);
    }

    #[test]
    fn the_reset_steps_go_from_the_fadt_to_a_triple_fault() {
        let all: Vec<_> = ResetStep::order(true, Presence::Present).collect();
        assert_eq!(
            all,
            [
                ResetStep::FadtRegister,
                ResetStep::ResetControlPort,
                ResetStep::KeyboardControllerPulse,
                ResetStep::TripleFault
            ]
        );
        let no_8042: Vec<_> = ResetStep::order(false, Presence::Absent).collect();
        assert_eq!(
            no_8042,
            [ResetStep::ResetControlPort, ResetStep::TripleFault]
        );
    }
}
