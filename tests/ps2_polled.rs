//! PS/2 keys with IRQ 1 never delivered: the boot word `irq1=masked` masks
//! the keyboard's line at the PIC for the whole run, as firmware that leaves
//! IRQ 1 (or LINT0) undelivered does, and the cube keys must still give the
//! software VGA's pictures, read by the frame and idle loops' poll of the
//! 8042 alone. On SeaBIOS (true Mode X) and on OVMF (the framebuffer).

mod common;

use boot::{line, Board, BootRequest, Firmware, Graphics, Qemu, QemuOptions};
use common::{
    after_each_key_on, assert_pictures_equal, assert_same_picture, presented, BOOT_TIMEOUT,
    CUBE_KEYS,
};
use std::time::Duration;

/// OVMF boots in well under 20 s here, but emulation on a loaded machine is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
const MASKED: &str = "keyboard: IRQ 1 masked at the PIC for the whole run";

fn boot_masked(firmware: Firmware) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.firmware = firmware;
    if firmware == Firmware::Uefi {
        options.board = Board::Q35;
    }
    options.graphics = Graphics::StdVga;
    options.boot = BootRequest {
        irq1_masked: true,
        ..BootRequest::default()
    };
    let mut qemu = Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"));
    let console = qemu
        .wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(MASKED), "{console}");
    assert!(
        console.contains("keyboard: an 8042 answers at port 0x64"),
        "{console}"
    );
    qemu
}

/// Esc, then the goodbye's count of who took the keys: the poll all of
/// them, IRQ 1 none.
fn escape_and_check_nothing_came_by_irq(qemu: &mut Qemu, keys: usize) {
    qemu.send_key("esc").unwrap();
    let console = qemu.wait_for_serial(line::GOODBYE, BOOT_TIMEOUT).unwrap();
    let counts = console
        .lines()
        .find(|l| l.starts_with("ps2: "))
        .unwrap_or_else(|| panic!("no count of PS/2 bytes:\n{console}"));
    let by_poll: usize = counts
        .strip_prefix("ps2: 0 keyboard bytes taken by IRQ 1, ")
        .and_then(|rest| rest.strip_suffix(" by the poll"))
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("IRQ 1 took bytes, or the line is unreadable: {counts}"));
    // Each key a press and a release, one byte each or two with E0; and Esc.
    assert!(by_poll > 2 * keys, "{counts}");
}

#[test]
fn with_irq1_masked_the_cube_keys_work_on_seabios() {
    let mut qemu = boot_masked(Firmware::Bios);
    after_each_key_on(&mut qemu, &CUBE_KEYS, |screen, model, _, what| {
        assert_same_picture(screen, model, what)
    });
    escape_and_check_nothing_came_by_irq(&mut qemu, CUBE_KEYS.len());
}

#[test]
fn with_irq1_masked_the_cube_keys_work_on_ovmf() {
    let mut qemu = boot_masked(Firmware::Uefi);
    after_each_key_on(&mut qemu, &CUBE_KEYS, |screen, model, _, what| {
        let expected = presented(model, screen.width, screen.height);
        assert_pictures_equal(screen, &expected, what)
    });
    escape_and_check_nothing_came_by_irq(&mut qemu, CUBE_KEYS.len());
}
