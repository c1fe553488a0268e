//! The four drivers as one [`Driver`], as the kernel holds them: made by
//! kind, taken and started through the trait, driven by one device layer.

use super::*;
use crate::bus::Bus;
use crate::host::Speed;
use crate::model::devices::UsbDevice;
use crate::model::ehci::{self, EhciModel};
use crate::model::uhci::{self, UhciModel};

#[test]
fn an_ehci_is_taken_started_and_enumerated_as_a_driver() {
    let mut model = EhciModel::new(2).left_running();
    model.firmware_releases_after = Some(30_000);
    model.tree.plug(&[2], UsbDevice::Keyboard(Speed::High));
    let mut driver = Driver::new(
        ControllerKind::Ehci,
        model,
        ehci::BAR_BYTES,
        ehci::DMA_BASE,
        ehci::DMA_BYTES,
    )
    .unwrap();
    assert!(matches!(driver, Driver::Ehci(_)));
    assert!(matches!(
        driver.take_ownership(),
        Handoff::Released { micros: 30_000.. }
    ));
    driver.reset_and_start().unwrap();
    assert_eq!(driver.hardware().configflag(), 1, "the EHCI runs");
    let mut bus = Bus::new(driver);
    assert_eq!(bus.enumerate(), 1);
    assert!(bus.controller().hardware().errors.is_empty());
}

#[test]
fn a_uhci_the_firmware_keeps_is_refused_with_the_uhci_drivers_reason() {
    let mut model = UhciModel::new(2);
    model.bios_keeps_legsup = true;
    let mut driver = Driver::new(
        ControllerKind::Uhci,
        model,
        0,
        uhci::DMA_BASE,
        uhci::DMA_BYTES,
    )
    .unwrap();
    assert_eq!(driver.kind(), ControllerKind::Uhci);
    assert_eq!(driver.take_ownership(), Handoff::NeverReleased);
    let refused = driver.reset_and_start().unwrap_err();
    assert_eq!(refused, DriverError::Uhci(UhciError::FirmwareOwns));
    assert_eq!(
        std::format!("{refused}"),
        "the firmware keeps the controller"
    );
}

#[test]
fn a_driver_that_cannot_be_made_says_why() {
    let refused = Driver::new(
        ControllerKind::Ehci,
        EhciModel::new(2),
        ehci::BAR_BYTES,
        ehci::DMA_BASE,
        4096,
    )
    .unwrap_err();
    assert_eq!(refused, DriverError::Ehci(EhciError::DmaTooSmall));
}
