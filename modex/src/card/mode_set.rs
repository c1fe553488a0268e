//! Setting Mode X on any card: the video BIOS's mode 13h first when it can be
//! called (only the card's BIOS knows how to leave its own extended modes),
//! then the register tweak into Mode X, then a read-back. If the BIOS cannot
//! be called, refuses, does not return in time, or leaves something the read-back catches, the
//! register-only mode set with the card's extension reset is the fallback.

use super::verify::Mismatch;
use crate::mode::MODE_X;
use crate::{ModeX, VgaBus};

/// BIOS video mode 13h: 320x200, 256 colours, chain-4. Mode X starts from it.
pub const BIOS_MODE_13H: u8 = 0x13;

/// Which way the mode was set.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// INT 10h mode 13h, then the tweak.
    VideoBios,
    /// The registers alone, after the card's extension reset.
    RegistersOnly,
}

/// How a call of the video BIOS's mode set went wrong.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BiosCallFailure {
    /// The BIOS reported a different mode (this one) after the call.
    ReportedMode(u8),
    /// The BIOS had not returned from INT 10h `function` (AH) within
    /// `within_millis`, so the call was abandoned.
    DidNotReturn {
        /// AH of the call.
        function: u8,
        /// How long it had run when it was abandoned, at least.
        within_millis: u32,
    },
}

/// Why the BIOS route was not taken or not kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fallback {
    /// There is no video BIOS to call (UEFI, no ROM, bad vector...).
    NoVideoBios,
    /// The BIOS reported a different mode (this one) after the call.
    BiosRefusedMode(u8),
    /// The BIOS did not return from the call in time; it was abandoned.
    BiosDidNotReturn {
        /// AH of the call.
        function: u8,
        /// How long it had run when it was abandoned, at least.
        within_millis: u32,
    },
    /// After the BIOS route the read-back failed.
    NotVerifiedAfterBios(Mismatch),
}

/// What happened, for the log: the route, why the BIOS route was left if it
/// was, and the final read-back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ModeSetReport {
    /// The route that produced the final state.
    pub route: Route,
    /// Why the BIOS route was not the one.
    pub fallback: Option<Fallback>,
    /// The read-back of the final state.
    pub verified: Result<(), Mismatch>,
}

impl<B: VgaBus> ModeX<B> {
    /// Sets Mode X by the best route: `bios_mode_13h`, if given, is called
    /// first and must set BIOS mode 13h (returning the mode the BIOS reports
    /// otherwise). Never reports a mode that did not read back.
    pub fn set_mode_x_on_any_card(
        &mut self,
        bios_mode_13h: Option<&mut dyn FnMut() -> Result<(), BiosCallFailure>>,
    ) -> ModeSetReport {
        let fallback = match bios_mode_13h {
            None => Fallback::NoVideoBios,
            Some(call) => match call() {
                Err(BiosCallFailure::ReportedMode(found)) => Fallback::BiosRefusedMode(found),
                // Whatever it did to the registers, the register-only mode
                // set below starts from any state.
                Err(BiosCallFailure::DidNotReturn {
                    function,
                    within_millis,
                }) => Fallback::BiosDidNotReturn {
                    function,
                    within_millis,
                },
                Ok(()) => {
                    // The BIOS wrote registers behind the driver's back.
                    self.invalidate_caches();
                    self.set_mode();
                    match self.verify(&MODE_X) {
                        Ok(()) => {
                            return ModeSetReport {
                                route: Route::VideoBios,
                                fallback: None,
                                verified: Ok(()),
                            }
                        }
                        Err(mismatch) => Fallback::NotVerifiedAfterBios(mismatch),
                    }
                }
            },
        };
        self.set_mode();
        ModeSetReport {
            route: Route::RegistersOnly,
            fallback: Some(fallback),
            verified: self.verify(&MODE_X),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::card::{Card, ExtensionProbe, Register};
    use crate::regs::{vbe, Port};
    use crate::soft::SoftVga;
    use std::boxed::Box;

    /// A software VGA left in a Bochs VBE linear mode, as the bootloader leaves it.
    fn in_vbe_mode() -> Box<SoftVga> {
        let mut soft = Box::new(SoftVga::new());
        soft.write_port16(Port::VBE_DISPI_INDEX, vbe::INDEX_ENABLE);
        soft.write_port16(Port::VBE_DISPI_DATA, vbe::ENABLED);
        soft
    }

    #[test]
    fn without_a_bios_the_registers_and_the_reset_do_it() {
        let mut soft = in_vbe_mode();
        let report = ModeX::for_card(&mut *soft, Card::BochsDispi).set_mode_x_on_any_card(None);
        assert_eq!(report.route, Route::RegistersOnly);
        assert_eq!(report.fallback, Some(Fallback::NoVideoBios));
        assert_eq!(report.verified, Ok(()));
    }

    #[test]
    fn a_working_bios_route_is_kept() {
        let mut soft = in_vbe_mode();
        let mut calls = 0;
        let mut bios = || {
            calls += 1;
            Ok(())
        };
        let report =
            ModeX::for_card(&mut *soft, Card::BochsDispi).set_mode_x_on_any_card(Some(&mut bios));
        assert_eq!(calls, 1);
        assert_eq!(report.route, Route::VideoBios);
        assert_eq!(report.verified, Ok(()));
    }

    #[test]
    fn a_bios_that_refuses_the_mode_falls_back() {
        let mut soft = in_vbe_mode();
        let mut bios = || Err(BiosCallFailure::ReportedMode(0x03));
        let report =
            ModeX::for_card(&mut *soft, Card::BochsDispi).set_mode_x_on_any_card(Some(&mut bios));
        assert_eq!(report.route, Route::RegistersOnly);
        assert_eq!(report.fallback, Some(Fallback::BiosRefusedMode(0x03)));
        assert_eq!(report.verified, Ok(()));
    }

    #[test]
    fn a_bios_abandoned_half_way_through_its_mode_set_falls_back_to_the_registers() {
        let mut soft = in_vbe_mode();
        // Half a mode set, as an abandoned BIOS leaves it: the sequencer
        // held in reset, the memory mode and the CRTC's overflow changed.
        for (index, value) in [(0x00, 0x01), (0x04, 0x06)] {
            soft.write_port8(Port::SEQUENCER_INDEX, index);
            soft.write_port8(Port::SEQUENCER_DATA, value);
        }
        soft.write_port8(Port::CRTC_INDEX, 0x07);
        soft.write_port8(Port::CRTC_DATA, 0xFF);
        let mut bios = || {
            Err(BiosCallFailure::DidNotReturn {
                function: 0x00,
                within_millis: 2032,
            })
        };
        let report =
            ModeX::for_card(&mut *soft, Card::BochsDispi).set_mode_x_on_any_card(Some(&mut bios));
        assert_eq!(report.route, Route::RegistersOnly);
        assert_eq!(
            report.fallback,
            Some(Fallback::BiosDidNotReturn {
                function: 0x00,
                within_millis: 2032
            })
        );
        assert_eq!(report.verified, Ok(()));
    }

    /// A card whose extensions we cannot reset and whose BIOS did not leave
    /// them: the read-back says so instead of claiming success.
    #[test]
    fn an_unknown_card_left_in_its_extended_mode_is_reported_not_hidden() {
        let mut soft = in_vbe_mode();
        // Known as Bochs VBE for the read-back, but the reset is skipped:
        // the standard card's mode set does not touch those ports.
        let mut vga = ModeX::new(&mut *soft);
        vga.set_mode();
        let mut vga = ModeX::for_card(vga.into_bus(), Card::BochsDispi);
        assert_eq!(
            vga.verify(&MODE_X).map_err(|m| m.register),
            Err(Register::Extension(ExtensionProbe::DispiEnable))
        );
    }
}
