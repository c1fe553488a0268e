//! The foundation, booted in QEMU: the banner, clean halts on faults, and the
//! isa-debug-exit codes. QEMU must be installed: these tests fail (never skip)
//! without it, and say how to install it.

mod common;

use boot::line::{FaultLine, FaultReport};
use boot::qemu::{EXIT_FAILURE, EXIT_SUCCESS};
use boot::{line, BootOption, Exit, Fault};
use common::{boot_bios as boot, BOOT_TIMEOUT};
use std::time::Duration;

#[test]
fn kernel_boots_and_prints_its_banner() {
    let mut qemu = boot(None);
    let console = qemu
        .wait_for_serial("kernel: initialised", BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains(&format!("modex-cube kernel v{}", env!("CARGO_PKG_VERSION"))),
        "{console}"
    );
}

/// Each fault is reported on serial and on screen (a white-on-red panel in
/// 80x25 text), then the kernel halts: QEMU (started with -no-reboot, so a
/// triple fault would end it) keeps running. The report must hold
/// `expected`, and say where the CPU was (the frame, or the panic's place).
fn assert_reported_and_halted(fault: Fault, expected: FaultLine) {
    let option = BootOption::Fault(fault);
    let mut qemu = boot(Some(option));
    let console = qemu.wait_for_serial(line::HALTED, BOOT_TIMEOUT).unwrap();
    let report = FaultReport::parse(&console)
        .unwrap_or_else(|| panic!("{option}: no fault report; console:\n{console}"));
    assert!(
        report.rows.contains(&Some(expected)),
        "expected {expected:?} for {option}, read {:?}; console:\n{console}",
        report.rows
    );
    assert!(
        matches!(
            report.rows[1],
            Some(FaultLine::Frame(_) | FaultLine::Location { .. })
        ),
        "{option}: no frame or location; console:\n{console}"
    );
    assert_eq!(
        qemu.wait_exit(Duration::from_secs(2)).unwrap(),
        None,
        "QEMU ended: the kernel rebooted or died"
    );
    assert!(qemu.is_running());

    let screen = qemu.screendump().unwrap();
    assert_eq!(
        (screen.width, screen.height),
        (640, 400),
        "{option}: the screen is not in 80x25 text with 8-dot cells"
    );
    // Its QR code says what the kernel encoded, the report first.
    let encoded: Vec<&str> = report.qr_lines().collect();
    assert_eq!(
        encoded.first().copied().and_then(FaultLine::parse),
        report.fault(),
        "{option}: the code's text does not start with the fault"
    );
    assert_eq!(
        common::decode_qr_codes(&screen),
        [encoded.join("\n")],
        "{option}: the panel's QR code"
    );
    let count = |is: fn([u8; 3]) -> bool| screen.pixels.iter().filter(|&&p| is(p)).count();
    let (red, white) = (count(is_red), count(is_white));
    assert!(
        red > 5000 && white > 500,
        "{option}: no report panel on screen ({red} red, {white} white pixels)"
    );
}

/// The panel's background, EGA red (0x2A, 0, 0 in the DAC).
fn is_red([r, g, b]: [u8; 3]) -> bool {
    r >= 128 && g < 64 && b < 64
}

/// The panel's text, EGA bright white.
fn is_white([r, g, b]: [u8; 3]) -> bool {
    r >= 200 && g >= 200 && b >= 200
}

#[test]
fn invalid_opcode_is_reported_and_the_kernel_halts() {
    assert_reported_and_halted(Fault::InvalidOpcode, FaultLine::Exception("invalid opcode"));
}

#[test]
fn page_fault_is_reported_with_its_address() {
    assert_reported_and_halted(Fault::Page, FaultLine::Address(0x7f00_dead_0000));
}

#[test]
fn general_protection_fault_is_reported() {
    assert_reported_and_halted(
        Fault::GeneralProtection,
        FaultLine::Exception("general protection fault"),
    );
}

#[test]
fn stack_overflow_becomes_a_reported_double_fault() {
    assert_reported_and_halted(
        Fault::StackOverflow,
        FaultLine::Exception("double fault (kernel stack overflow?)"),
    );
}

#[test]
fn panic_is_reported_and_the_kernel_halts() {
    assert_reported_and_halted(
        Fault::Panic,
        FaultLine::Panic("panic requested by the boot option"),
    );
}

#[test]
fn debug_exception_is_reported_by_name() {
    assert_reported_and_halted(
        Fault::Debug,
        FaultLine::Exception("debug exception (vector 1)"),
    );
}

#[test]
fn machine_check_is_reported_by_name() {
    assert_reported_and_halted(
        Fault::MachineCheck,
        FaultLine::Exception("machine check (vector 18)"),
    );
}

/// `int 0x80` reaches an IDT entry that is not there: the CPU raises a
/// segment-not-present fault whose error code names the vector (0x80 << 3,
/// with the IDT bit), and the report says which vector it was.
#[test]
fn a_vector_without_a_handler_is_reported_with_its_number() {
    assert_reported_and_halted(
        Fault::NoHandler,
        FaultLine::Exception("interrupt vector 128 has no handler (segment not present)"),
    );
}

/// Three NMIs while the cube spins, each told in the log; the cube still
/// answers a key, and Esc still powers the machine off.
#[test]
fn nmis_are_logged_and_the_kernel_carries_on() {
    let mut qemu = boot(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    qemu.send_key("spc").unwrap();
    qemu.wait_for_serial(&line::CommandDone(1).to_string(), BOOT_TIMEOUT)
        .unwrap();
    for n in 1..=3 {
        qemu.inject_nmi().unwrap();
        let told = format!("({n} since boot)");
        let console = qemu.wait_for_serial(&told, BOOT_TIMEOUT).unwrap();
        let nmi_lines: Vec<&str> = console
            .lines()
            .filter(|text| text.starts_with("NMI received: "))
            .collect();
        assert_eq!(nmi_lines.len(), n, "{console}");
        assert!(
            nmi_lines[n - 1].contains("reason unknown") && nmi_lines[n - 1].contains("port 0x61"),
            "{console}"
        );
    }
    qemu.send_key("right").unwrap();
    let console = qemu
        .wait_for_serial(&line::CommandDone(2).to_string(), BOOT_TIMEOUT)
        .unwrap();
    assert!(!console.contains(line::HALTED), "{console}");
    qemu.send_key("esc").unwrap();
    let status = qemu.wait_for_exit(BOOT_TIMEOUT).unwrap();
    assert_eq!(status.code(), Some(EXIT_SUCCESS), "{}", qemu.serial());
}

#[test]
fn breakpoint_is_reported_and_execution_resumes() {
    let mut qemu = boot(Some(BootOption::Fault(Fault::Breakpoint)));
    let console = qemu
        .wait_for_serial("breakpoint: resumed", BOOT_TIMEOUT)
        .unwrap();
    let reported = console.lines().any(|text| {
        matches!(FaultLine::parse(text), Some(FaultLine::Exception(kind))
            if kind.starts_with("breakpoint at 0x"))
    });
    assert!(reported, "{console}");
}

#[test]
fn the_host_sees_the_debug_exit_codes() {
    for (exit, code) in [(Exit::Success, EXIT_SUCCESS), (Exit::Failure, EXIT_FAILURE)] {
        let option = BootOption::Exit(exit);
        let mut qemu = boot(Some(option));
        let status = qemu
            .wait_for_exit(BOOT_TIMEOUT)
            .unwrap_or_else(|e| panic!("the kernel did not end QEMU: {e}"));
        assert_eq!(status.code(), Some(code), "{option}");
    }
}
