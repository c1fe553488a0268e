//! Which display the kernel drives: the VGA's own registers (true Mode X),
//! the framebuffer the firmware left (the same Mode X code on the software
//! VGA, presented), or nothing.
//!
//! The choice goes by how the machine booted, not by whether the VGA
//! registers answer: after a UEFI boot the card may scan out the firmware's
//! framebuffer whatever those registers say (Intel's integrated graphics
//! answer them with the VGA plane disabled), so true Mode X would be a black
//! screen. Only a BIOS (or CSM) boot, or the boot option that forces it under
//! QEMU, probes for a legacy VGA; the probe decides there.
//!
//! ```
//! use firmware::boot_firmware::Firmware;
//! use firmware::display::{choose, Display};
//!
//! // A UEFI boot with a framebuffer never probes the VGA.
//! let choice = choose(Firmware::Uefi, false, true, || unreachable!());
//! assert_eq!(choice.display, Display::Framebuffer);
//! ```

use crate::boot_firmware::Firmware;

/// What the kernel draws on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Display {
    /// The VGA's registers and memory: Mode X as Abrash wrote it.
    TrueModeX,
    /// The software VGA, each flip presented into the firmware's framebuffer.
    Framebuffer,
    /// No picture anywhere: the demo runs unseen; serial and keys work.
    Nothing,
}

/// The choice and how it was reached, for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Choice {
    /// What the kernel draws on.
    pub display: Display,
    /// The boot option asked for true Mode X.
    pub forced: bool,
    /// Whether the legacy VGA was probed, and what the probe said.
    pub probe: Probe,
}

/// The legacy VGA probe's part in a choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Probe {
    /// Not made: a UEFI boot, where the registers are never touched.
    NotMade,
    /// Made: a legacy VGA answered, or not.
    Answered(bool),
}

/// Chooses the display. `vga_answers` probes for a legacy VGA and is called
/// only on a BIOS boot (or an unknown one, or when `force_true_mode_x`);
/// `has_framebuffer` says whether the bootloader handed one over.
pub fn choose(
    booted_by: Firmware,
    force_true_mode_x: bool,
    has_framebuffer: bool,
    vga_answers: impl FnOnce() -> bool,
) -> Choice {
    let probe = if booted_by == Firmware::Uefi && !force_true_mode_x {
        Probe::NotMade
    } else {
        Probe::Answered(vga_answers())
    };
    let display = match (probe, has_framebuffer) {
        (Probe::Answered(true), _) => Display::TrueModeX,
        (_, true) => Display::Framebuffer,
        (_, false) => Display::Nothing,
    };
    Choice {
        display,
        forced: force_true_mode_x,
        probe,
    }
}

impl Choice {
    /// The lines the kernel logs for this choice, in order (`display: ...`).
    pub fn log_lines(&self) -> impl Iterator<Item = &'static str> {
        let uefi_framebuffer = self.probe == Probe::NotMade && self.display == Display::Framebuffer;
        [
            uefi_framebuffer.then_some(
                "display: UEFI boot: drawing through the firmware framebuffer \
                 (true Mode X needs a BIOS or CSM boot)",
            ),
            self.forced
                .then_some("display: true Mode X asked for by the boot option"),
            (self.display == Display::TrueModeX).then_some("display: legacy VGA found"),
            (self.probe == Probe::Answered(false))
                .then_some("display: no legacy VGA; Mode X runs on the software VGA"),
            (self.display == Display::Nothing).then_some(
                "display: none: no legacy VGA and no framebuffer from the bootloader \
                 (its log says why: no usable GOP, or no VESA linear mode); \
                 running without a picture",
            ),
        ]
        .into_iter()
        .flatten()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;
    use std::vec::Vec;

    /// Every case: each firmware, the boot option or not, a framebuffer or
    /// not, and a VGA that answers or not.
    #[test]
    fn every_case_of_the_decision_table() {
        use Display::*;
        // (firmware, forced, framebuffer, VGA answers) -> (display, probed)
        let table = [
            (Firmware::Bios, false, false, false, Nothing, true),
            (Firmware::Bios, false, false, true, TrueModeX, true),
            (Firmware::Bios, false, true, false, Framebuffer, true),
            (Firmware::Bios, false, true, true, TrueModeX, true),
            (Firmware::Bios, true, false, false, Nothing, true),
            (Firmware::Bios, true, false, true, TrueModeX, true),
            (Firmware::Bios, true, true, false, Framebuffer, true),
            (Firmware::Bios, true, true, true, TrueModeX, true),
            (Firmware::Uefi, false, false, false, Nothing, false),
            (Firmware::Uefi, false, false, true, Nothing, false),
            (Firmware::Uefi, false, true, false, Framebuffer, false),
            (Firmware::Uefi, false, true, true, Framebuffer, false),
            (Firmware::Uefi, true, false, false, Nothing, true),
            (Firmware::Uefi, true, false, true, TrueModeX, true),
            (Firmware::Uefi, true, true, false, Framebuffer, true),
            (Firmware::Uefi, true, true, true, TrueModeX, true),
            (Firmware::Unknown, false, false, false, Nothing, true),
            (Firmware::Unknown, false, false, true, TrueModeX, true),
            (Firmware::Unknown, false, true, false, Framebuffer, true),
            (Firmware::Unknown, false, true, true, TrueModeX, true),
            (Firmware::Unknown, true, false, false, Nothing, true),
            (Firmware::Unknown, true, false, true, TrueModeX, true),
            (Firmware::Unknown, true, true, false, Framebuffer, true),
            (Firmware::Unknown, true, true, true, TrueModeX, true),
        ];
        for (firmware, forced, framebuffer, answers, display, probed) in table {
            let calls = Cell::new(0);
            let choice = choose(firmware, forced, framebuffer, || {
                calls.set(calls.get() + 1);
                answers
            });
            let case = (firmware, forced, framebuffer, answers);
            assert_eq!(choice.display, display, "{case:?}");
            assert_eq!(calls.get(), usize::from(probed), "{case:?}");
            let probe = if probed {
                Probe::Answered(answers)
            } else {
                Probe::NotMade
            };
            assert_eq!(choice.probe, probe, "{case:?}");
            assert_eq!(choice.forced, forced, "{case:?}");
        }
    }

    fn lines(choice: Choice) -> Vec<&'static str> {
        choice.log_lines().collect()
    }

    #[test]
    fn the_log_says_why() {
        let uefi = choose(Firmware::Uefi, false, true, || true);
        assert_eq!(
            lines(uefi),
            [
                "display: UEFI boot: drawing through the firmware framebuffer \
              (true Mode X needs a BIOS or CSM boot)"
            ]
        );
        let forced = choose(Firmware::Uefi, true, true, || true);
        assert_eq!(
            lines(forced),
            [
                "display: true Mode X asked for by the boot option",
                "display: legacy VGA found"
            ]
        );
        let no_vga = choose(Firmware::Bios, false, true, || false);
        assert_eq!(
            lines(no_vga),
            ["display: no legacy VGA; Mode X runs on the software VGA"]
        );
        let uefi_blind = choose(Firmware::Uefi, false, false, || true);
        let blind = lines(uefi_blind);
        assert_eq!(blind.len(), 1, "{blind:?}");
        assert!(blind[0].starts_with("display: none: "), "{blind:?}");
        let bios_blind = lines(choose(Firmware::Bios, false, false, || false));
        assert_eq!(bios_blind.len(), 2, "{bios_blind:?}");
        assert!(
            bios_blind[1].starts_with("display: none: "),
            "{bios_blind:?}"
        );
    }
}
