//! The text screens on the framebuffer path. Under OVMF with `-vga none
//! -device bochs-display` each fault must end in the same white-on-red panel
//! as on a VGA, and Esc in the same goodbye line: the software VGA's text
//! scan-out, presented. QEMU's screendump is compared with the same screen
//! drawn by `demo::screens` on a host software VGA and presented the same way.
//!
//! The panel also shows the last lines of the kernel's log before the fault:
//! the test takes them from serial, where every line of that log went.
//!
//! The text scan-out itself is checked against QEMU's own VGA: on a BIOS
//! boot the panel is real VGA text mode, and QEMU's 720x400 picture of it
//! must equal the model's scan-out dot for dot.

use super::{boot, boot_with, presented, UEFI_BOOT_TIMEOUT, UEFI_FRAMEBUFFER};
use crate::common::{
    assert_pictures_equal, boot_bios, decode_qr_codes,
    escape_leaves_the_goodbye_on_the_framebuffer, soft_vga_in_mode_x, text_picture, BOOT_TIMEOUT,
};
use boot::line::FaultReport;
use boot::{line, BootOption, BootRequest, Fault, Firmware, Graphics, RgbImage};
use demo::screens::REPORT_LINES;
use modex::ModeX;
use std::time::Duration;

/// The fault report the kernel printed on serial.
fn fault_report(console: &str) -> FaultReport<'_> {
    FaultReport::parse(console).unwrap_or_else(|| panic!("no fault report on serial:\n{console}"))
}

/// The panel's lines as the kernel printed them on serial, each in its row
/// (serial leaves out empty lines).
fn report_lines(console: &str) -> [String; REPORT_LINES] {
    fault_report(console)
        .rows
        .map(|row| row.map(|line| line.to_string()).unwrap_or_default())
}

/// The kernel's log before the fault, as the panel shows it: its serial
/// lines from its first to the report's first, as the log ring keeps them
/// (cut at 120 bytes).
fn log_before_fault(console: &str) -> Vec<String> {
    let first = console
        .find(line::KERNEL_BANNER)
        .unwrap_or_else(|| panic!("no kernel on serial:\n{console}"));
    console[first..fault_report(console).start]
        .lines()
        .map(|line| line.chars().take(120).collect())
        .collect()
}

/// The text the kernel encoded in the panel's QR code, as it printed it.
fn qr_text(console: &str) -> String {
    let lines: Vec<&str> = fault_report(console).qr_lines().collect();
    assert!(!lines.is_empty(), "no QR text on serial:\n{console}");
    lines.join("\n")
}

/// The fault panel for the kernel's serial output, drawn on a software VGA
/// that was in Mode X. Its QR code must decode to the text the kernel
/// encoded, which starts with the report's lines.
fn panel_picture(console: &str) -> RgbImage {
    let lines = report_lines(console);
    let log = log_before_fault(console);
    assert!(log.len() >= 5, "{log:?}");
    let qr = qr_text(console);
    assert!(qr.starts_with(&lines[0]), "{qr}");
    let mut soft = soft_vga_in_mode_x();
    let text: [&str; REPORT_LINES] = std::array::from_fn(|i| lines[i].as_str());
    let log: Vec<&str> = log.iter().map(String::as_str).collect();
    demo::screens::fault_panel(&mut ModeX::new(&mut *soft), &text, &log, qr.as_bytes());
    text_picture(&soft)
}

/// The screen's one QR code decodes to the text the kernel encoded.
fn assert_code_decodes(screen: &RgbImage, console: &str, what: &str) {
    assert_eq!(decode_qr_codes(screen), [qr_text(console)], "{what}");
}

/// Boots `option` on OVMF + bochs-display, waits for the halt, and compares
/// the framebuffer with the panel presented.
fn assert_panel_on_the_framebuffer(fault: Fault) {
    let option = BootOption::Fault(fault);
    let mut qemu = boot(Firmware::Uefi, Graphics::BochsDisplay, Some(option));
    let console = qemu
        .wait_for_serial(line::HALTED, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(UEFI_FRAMEBUFFER), "{console}");
    assert_eq!(qemu.wait_exit(Duration::from_secs(1)).unwrap(), None);
    let screen = qemu.screendump().unwrap();
    let expected = presented(&panel_picture(&console), screen.width, screen.height);
    assert_pictures_equal(&screen, &expected, &format!("panel for {option}"));
    assert_code_decodes(&screen, &console, &format!("code for {option}"));
}

#[test]
fn a_page_fault_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::Page);
}

#[test]
fn an_invalid_opcode_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::InvalidOpcode);
}

#[test]
fn a_general_protection_fault_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::GeneralProtection);
}

#[test]
fn a_stack_overflow_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::StackOverflow);
}

#[test]
fn a_divide_error_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::Divide);
}

#[test]
fn a_panic_shows_the_panel_on_the_framebuffer() {
    assert_panel_on_the_framebuffer(Fault::Panic);
}

/// Esc: the goodbye line on the framebuffer. Without isa-debug-exit the
/// kernel says goodbye, then powers the machine off through ACPI; QEMU keeps
/// the last screen (`-no-shutdown`), so it can be looked at.
#[test]
fn escape_shows_the_goodbye_line_on_the_framebuffer() {
    let mut qemu = boot_with(
        Firmware::Uefi,
        Graphics::BochsDisplay,
        BootRequest::default(),
        false,
    );
    qemu.wait_for_serial(boot::READY_LINE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    escape_leaves_the_goodbye_on_the_framebuffer(&mut qemu, "goodbye on the framebuffer");
}

/// The oracle for the text scan-out: QEMU's VGA shows the BIOS boot's panel
/// exactly as the model scans it out.
#[test]
fn the_text_scan_out_matches_qemus_vga_dot_for_dot() {
    let mut qemu = boot_bios(Some(BootOption::Fault(Fault::Page)));
    let console = qemu.wait_for_serial(line::HALTED, BOOT_TIMEOUT).unwrap();
    let screen = qemu.screendump().unwrap();
    let expected = panel_picture(&console);
    assert_pictures_equal(&screen, &expected, "panel on the VGA");
    assert_code_decodes(&screen, &console, "code on the VGA");
}
