//! Mode X on every VGA card QEMU can emulate, each with its own VGA BIOS: the
//! kernel asks the card's BIOS for mode 13h, tweaks it into Mode X and reads
//! the registers back. On each card QEMU's picture must equal the software
//! VGA's after every key, the serial log must name the route, and Esc must
//! end in the BIOS's own text mode. All boot the one image (GPT with a hybrid
//! MBR) under SeaBIOS.
//!
//! Two cards fail with the unpatched bootloader 0.11.17 (see
//! `bootloader/CHANGES.md`): the ATI's video BIOS loads a GDT of its own, on
//! which stage 2's far jump into protected mode triple-faulted, and the ISA
//! Cirrus has no VBE linear mode, on which stage 2 panicked.

mod common;

use boot::{Board, Graphics, Qemu};
use common::{after_each_key_on, assert_same_picture, boot_bios_on_board, BOOT_TIMEOUT};
use demo::command::{Axis, Command, SceneCommand, Sense};

/// A reset (the spin stops), moves, turns and lighting: every kind of frame.
const KEYS: [(&str, Command); 5] = [
    ("r", Command::Scene(SceneCommand::Reset)),
    ("4", common::turn(Axis::Y, Sense::Negative)),
    ("up", Command::Scene(SceneCommand::MoveUp)),
    ("f1", common::turn(Axis::Z, Sense::Positive)),
    ("l", Command::Scene(SceneCommand::ToggleLighting)),
];

fn boots_to_mode_x_through_its_video_bios(graphics: Graphics) {
    boots_to_mode_x_on(Board::PC, graphics);
}

fn boots_to_mode_x_on(board: Board, graphics: Graphics) {
    let mut qemu = boot_bios_on_board(board, graphics, None);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("vga: mode 13h set by the video BIOS, then tweaked"),
        "{graphics:?} did not take the video BIOS route:\n{console}"
    );
    assert!(
        console.contains("vga: Mode X 320x240 set, registers read back as written"),
        "{graphics:?}: the mode set did not read back:\n{console}"
    );
    after_each_key_on(&mut qemu, &KEYS, |qemu_picture, model, _, what| {
        assert_same_picture(qemu_picture, model, &format!("{graphics:?}, {what}"))
    });
    leaves_through_bios_text_mode(&mut qemu, graphics);
}

fn leaves_through_bios_text_mode(qemu: &mut Qemu, graphics: Graphics) {
    qemu.send_key("esc").unwrap();
    let console = qemu
        .wait_for_serial(boot::line::GOODBYE, BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("demo: text mode 3 set by the video BIOS"),
        "{graphics:?}: goodbye did not use the BIOS's text mode:\n{console}"
    );
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("QEMU powers off after the goodbye: {e}"));
    assert_eq!(status.code(), Some(33), "{graphics:?}: {status}");
}

#[test]
fn std_vga() {
    boots_to_mode_x_through_its_video_bios(Graphics::StdVga);
}

#[test]
fn cirrus() {
    boots_to_mode_x_through_its_video_bios(Graphics::Cirrus);
}

#[test]
fn vmware_svga() {
    boots_to_mode_x_through_its_video_bios(Graphics::Vmware);
}

#[test]
fn qxl() {
    boots_to_mode_x_through_its_video_bios(Graphics::Qxl);
}

#[test]
fn virtio_vga() {
    boots_to_mode_x_through_its_video_bios(Graphics::Virtio);
}

/// Its video BIOS returns from the VESA calls with GDTR on a table of its own.
#[test]
fn ati() {
    boots_to_mode_x_through_its_video_bios(Graphics::Ati);
}

/// `-M isapc -cpu qemu64`: no PCI, and no VBE linear mode, so the bootloader
/// hands over no framebuffer; Mode X needs none.
#[test]
fn isa_cirrus() {
    boots_to_mode_x_through_its_video_bios(Graphics::IsaCirrus);
}

/// SeaBIOS on a Q35 (AHCI disk, PCI Express), as a PC of today with CSM.
#[test]
fn std_vga_on_q35() {
    boots_to_mode_x_on(Board::Q35, Graphics::StdVga);
}
