//! TEMPORARY: stand-ins with the API of `usb::bus::Bus` and the EHCI, OHCI
//! and UHCI drivers (docs of issue 40's plan) until their branches are
//! merged; every `new` refuses, so no legacy controller is driven yet.
//! Deleted by the merge that brings the real ones.

#![allow(dead_code)]

use core::fmt;
use usb::host::{ControllerKind, Handoff};
use usb::PciHardware;

/// Why a stand-in refuses.
#[derive(Clone, Copy, Debug)]
pub struct NotMerged;

impl fmt::Display for NotMerged {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("driver not built in yet")
    }
}

/// Where a device hangs (stand-in).
#[derive(Clone, Copy, Debug)]
pub struct Location;

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("?")
    }
}

/// The controller side of the stand-in device layer.
pub trait Controller {
    fn kind(&self) -> ControllerKind;
    fn halt(&mut self) -> bool;
}

/// `usb::bus::Bus` (stand-in).
pub struct Bus<C> {
    controller: C,
}

impl<C: Controller> Bus<C> {
    pub fn new(controller: C) -> Bus<C> {
        Bus { controller }
    }
    pub fn enumerate(&mut self) -> usize {
        0
    }
    pub fn enumeration_idle(&self) -> bool {
        true
    }
    pub fn poll(&mut self, _out: &mut impl FnMut(u8)) {}
    pub fn keyboards(&self) -> impl Iterator<Item = Location> + '_ {
        core::iter::empty()
    }
    pub fn controller(&mut self) -> &mut C {
        &mut self.controller
    }
    pub fn shut_down(&mut self) -> bool {
        self.controller.halt()
    }
}

macro_rules! stand_in {
    ($name:ident, $kind:expr) => {
        /// A driver stand-in.
        pub struct $name<H> {
            hw: H,
        }

        impl<H: PciHardware> $name<H> {
            pub fn take_ownership(&mut self) -> Handoff {
                Handoff::NotOwned
            }
            pub fn reset_and_start(&mut self) -> Result<(), NotMerged> {
                Err(NotMerged)
            }
            pub fn hardware(&mut self) -> &mut H {
                &mut self.hw
            }
        }

        impl<H: PciHardware> Controller for $name<H> {
            fn kind(&self) -> ControllerKind {
                $kind
            }
            fn halt(&mut self) -> bool {
                false
            }
        }
    };
}

stand_in!(Uhci, ControllerKind::Uhci);
stand_in!(Ohci, ControllerKind::Ohci);
stand_in!(Ehci, ControllerKind::Ehci);

impl<H: PciHardware> Uhci<H> {
    pub fn new(_hw: H, _dma_base: u64, _dma_bytes: u64) -> Result<Self, NotMerged> {
        Err(NotMerged)
    }
}

impl<H: PciHardware> Ohci<H> {
    pub fn new(_hw: H, _mmio: u32, _dma_base: u64, _dma_bytes: u64) -> Result<Self, NotMerged> {
        Err(NotMerged)
    }
}

impl<H: PciHardware> Ehci<H> {
    pub fn new(_hw: H, _mmio: u32, _dma_base: u64, _dma_bytes: u64) -> Result<Self, NotMerged> {
        Err(NotMerged)
    }
}
