//! The protocol read back as written.

use super::*;
use std::string::ToString;

#[test]
fn every_option_reads_back_as_written() {
    let mut count = 0;
    for option in BootOption::all() {
        assert_eq!(BootOption::parse(&option.to_string()), Ok(option));
        count += 1;
    }
    assert_eq!(count, 4 + 10 + 2);
}

#[test]
fn unknown_options_are_refused_with_the_list() {
    for text in [
        "",
        "fault=",
        "fault=nope",
        "exit=maybe",
        "bench ",
        "Test-Pattern",
    ] {
        assert_eq!(BootOption::parse(text), Err(UnknownOption), "{text:?}");
    }
    let message = UnknownOption.to_string();
    assert!(message.contains("fault=stack-overflow") && message.contains("clock-check"));
}

#[test]
fn requests_combine_true_mode_x_with_one_option() {
    for true_mode_x in [false, true] {
        for option in BootOption::all().map(Some).chain([None]) {
            let request = BootRequest {
                true_mode_x,
                irq1_masked: option.is_some(),
                echo_scancodes: !true_mode_x,
                clock: None,
                option,
            };
            assert_eq!(BootRequest::parse(&request.to_string()), Ok(request));
        }
    }
    assert_eq!(
        BootRequest::parse(" modex=true-mode-x  bench "),
        Ok(BootRequest {
            true_mode_x: true,
            clock: None,
            option: Some(BootOption::Bench),
            ..BootRequest::default()
        })
    );
    let keyed = BootRequest::parse("scancodes=echo irq1=masked").unwrap();
    assert!(keyed.irq1_masked && keyed.echo_scancodes && keyed.option.is_none());
    assert_eq!(keyed.to_string(), "irq1=masked scancodes=echo");
    assert_eq!(
        BootRequest::parse("irq1=masked irq1=masked"),
        Err(UnknownOption)
    );
    let clocked = BootRequest::parse("clock=hpet clock-check").unwrap();
    assert_eq!(clocked.clock, Some(ClockReference::Hpet));
    assert_eq!(clocked.option, Some(BootOption::ClockCheck));
    assert_eq!(clocked.to_string(), "clock=hpet clock-check");
    assert_eq!(
        BootRequest::parse("clock=hpet clock=pit"),
        Err(UnknownOption)
    );
    assert_eq!(BootRequest::parse("clock=sundial"), Err(UnknownOption));
    assert_eq!(BootRequest::parse("bench flip-rate"), Err(UnknownOption));
    assert_eq!(
        BootRequest::parse("modex=true-mode-x nope"),
        Err(UnknownOption)
    );
    assert!(BootRequest::parse("").unwrap().is_empty());
}

#[test]
fn scancode_lines_format_and_parse() {
    let taken = line::ScancodesTaken {
        bytes: &[0x1e, 0x9e, 0xe0, 0x4b],
        total: 1234,
    };
    let text = taken.to_string();
    assert_eq!(text, "scancodes: taken 1e 9e e0 4b, 1234 in all");
    let mut bytes = [0u8; 8];
    assert_eq!(
        line::ScancodesTaken::parse(&(text + "\r"), &mut bytes),
        Some((4, 1234))
    );
    assert_eq!(bytes[..4], [0x1e, 0x9e, 0xe0, 0x4b]);
    assert_eq!(
        line::ScancodesTaken::parse("scancodes: taken 1e 9e, 2 in all", &mut [0u8; 1]),
        None,
        "more bytes than room"
    );
    assert_eq!(
        line::ScancodesTaken::parse("scancodes: taken zz, 1 in all", &mut bytes),
        None
    );
    assert_eq!(
        line::ScancodesTaken::parse("demo: command 1 done", &mut bytes),
        None
    );
}

#[test]
fn command_lines_format_and_parse() {
    let line = line::CommandDone(12).to_string();
    assert_eq!(line, "demo: command 12 done");
    assert_eq!(
        line::CommandDone::parse(&(line + ", paused=false")),
        Some(12)
    );
    assert_eq!(line::CommandDone::parse("demo: goodbye"), None);
}

#[test]
fn report_lines_format_and_parse() {
    let shown = line::ReportShown {
        first: 3,
        last: 18,
        total: 40,
    };
    let text = shown.to_string();
    assert_eq!(text, "report: shown, log lines 3-18 of 40");
    assert_eq!(line::ReportShown::parse(&text), Some(shown));
    assert_eq!(line::ReportShown::parse("report: shown"), None);
    assert!(line::is_report_line(&text));
    assert!(line::is_report_line("report log: clock: TSC"));
    assert!(!line::is_report_line("clock: TSC"));
    assert!(line::is_report_line("facts: clock: TSC 2000.000 MHz"));
}

fn every_kind_of_fault_line() -> [line::FaultLine<'static>; 7] {
    use line::{FaultLine, InterruptFrame};
    [
        FaultLine::Exception("page fault"),
        FaultLine::Panic("panic requested by the boot option"),
        FaultLine::Frame(InterruptFrame {
            rip: 0x8000_0123_4567,
            cs: 0x8,
            rflags: 0x10006,
            rsp: 0x0100_0020_1f58,
            ss: 0,
        }),
        FaultLine::Frame(InterruptFrame {
            rip: u64::MAX,
            cs: 0xffff,
            rflags: u64::MAX,
            rsp: u64::MAX,
            ss: 0xffff,
        }),
        FaultLine::Location {
            file: "C:\\odd:path/kernel/src/main.rs",
            line: 120,
            column: 9,
        },
        FaultLine::ErrorCode(0x2),
        FaultLine::Address(0x7f00_dead_0000),
    ]
}

#[test]
fn fault_lines_read_back_as_written() {
    for fault in every_kind_of_fault_line() {
        let text = fault.to_string();
        assert_eq!(line::FaultLine::parse(&text), Some(fault), "{text:?}");
        let serial = text.clone() + "\r";
        assert_eq!(line::FaultLine::parse(&serial), Some(fault));
    }
    // The kernel's text, byte for byte.
    let [exception, _, frame, _, location, code, address] = every_kind_of_fault_line();
    assert_eq!(exception.to_string(), "EXCEPTION: page fault");
    assert_eq!(
        frame.to_string(),
        "  rip=0x800001234567 cs=0x8 rflags=0x10006 rsp=0x10000201f58 ss=0x0"
    );
    assert_eq!(
        location.to_string(),
        "  at C:\\odd:path/kernel/src/main.rs:120:9"
    );
    assert_eq!(code.to_string(), "  error code=0x2");
    assert_eq!(address.to_string(), "  address=0x7f00dead0000");
    let rows = every_kind_of_fault_line().map(|l| l.row());
    assert_eq!(rows, [0, 0, 1, 1, 1, 2, 3]);
    assert!(rows.iter().all(|&row| row < line::FAULT_ROWS));
}

#[test]
fn cut_fault_lines_are_never_read_as_another_line() {
    for fault in every_kind_of_fault_line() {
        let text = fault.to_string();
        for cut in 0..text.len() {
            let Some(read) = line::FaultLine::parse(&text[..cut]) else {
                continue;
            };
            // What a cut line reads as is its own kind, in its own row.
            assert_eq!(
                core::mem::discriminant(&read),
                core::mem::discriminant(&fault),
                "{:?}",
                &text[..cut]
            );
            assert_eq!(read.row(), fault.row());
        }
    }
    // A cut panic message is the cut text.
    assert_eq!(
        line::FaultLine::parse("PANIC: out of mem"),
        Some(line::FaultLine::Panic("out of mem"))
    );
    for other in [
        "HALTED",
        "",
        "  ",
        "  rip=0x1",
        "  at main.rs",
        "stack: 1 KiB",
    ] {
        assert_eq!(line::FaultLine::parse(other), None, "{other:?}");
    }
}

#[test]
fn a_fault_report_is_read_from_a_console() {
    let console = "modex-cube kernel v0.1.0\r\n\
        EXCEPTION: breakpoint at 0x1000\r\n\
        breakpoint: resumed\r\n\
        stack: 12 KiB used\r\n\
        EXCEPTION: page fault\r\n  \
        rip=0x10 cs=0x8 rflags=0x2 rsp=0x20 ss=0x0\r\n  \
        error code=0x2\r\n  \
        address=0xdead\r\n\
        fault qr: EXCEPTION: page fault\r\n\
        fault qr: firmware: BIOS\r\n\
        HALTED\r\n\
        fault qr: after the halt\r\n";
    let report = line::FaultReport::parse(console).unwrap();
    assert_eq!(
        report.fault(),
        Some(line::FaultLine::Exception("page fault"))
    );
    assert_eq!(report.rows[2], Some(line::FaultLine::ErrorCode(2)));
    assert!(console[..report.start].ends_with("used\r\n"));
    assert_eq!(report.rows[3], Some(line::FaultLine::Address(0xdead)));
    assert!(matches!(report.rows[1], Some(line::FaultLine::Frame(f)) if f.rip == 0x10));
    let qr: std::vec::Vec<&str> = report.qr_lines().collect();
    assert_eq!(qr, ["EXCEPTION: page fault", "firmware: BIOS"]);

    let panic = "PANIC: oops\n  at src/main.rs:1:2\nHALTED\n";
    let report = line::FaultReport::parse(panic).unwrap();
    assert_eq!(report.rows[0], Some(line::FaultLine::Panic("oops")));
    assert_eq!(report.rows[2], None);
    // No halt, no report.
    assert!(line::FaultReport::parse("PANIC: oops\n").is_none());
    assert!(line::FaultReport::parse("EXCEPTION: breakpoint at 0x1\nHALTED\n").is_none());
}

#[test]
fn usb_lines_read_back_as_written() {
    use std::string::ToString;
    let on = line::UsbKeyboardOn {
        kind: "uhci",
        function: "8086:2934 at 00:1d.0",
        location: "2.1",
    };
    let text = on.to_string();
    assert_eq!(text, "usb: keyboard on uhci 8086:2934 at 00:1d.0 2.1");
    assert_eq!(line::UsbKeyboardOn::parse(&text), Some(on));
    assert_eq!(
        line::UsbKeyboardOn::parse("usb: keyboard on vhci 1 2"),
        None
    );

    let halted = line::UsbHalted {
        kind: "ehci",
        function: "8086:293a at 00:1d.7",
        halted: true,
    };
    let text = halted.to_string();
    assert_eq!(text, "usb: ehci 8086:293a at 00:1d.7 halted");
    assert_eq!(line::UsbHalted::parse(&text), Some(halted));
    let xhci = "usb: xhci 1b36:000d at 00:02.0 halted and reset, ports switched off";
    assert!(line::UsbHalted::parse(xhci).is_some_and(|h| h.halted && h.kind == "xhci"));
    let not =
        line::UsbHalted::parse("usb: ohci 106b:003f at 00:03.0 not halted: still running").unwrap();
    assert!(!not.halted);
    assert_eq!(not.function, "106b:003f at 00:03.0");
    assert_eq!(
        line::UsbHalted::parse("usb: ohci 106b:003f at 00:03.0, 3 ports"),
        None
    );
    assert_eq!(
        line::UsbHalted::parse("usb: keyboard on uhci x at 1:2 halted"),
        None
    );

    let mut keyboards = line::UsbKeyboards::default();
    assert_eq!(keyboards.to_string(), "USB keyboards: none");
    keyboards.on[1] = 1;
    keyboards.on[3] = 12;
    let text = keyboards.to_string();
    assert_eq!(text, "USB keyboards: 1 ehci, 12 uhci");
    assert_eq!(line::UsbKeyboards::parse(&text), Some(keyboards));
    assert_eq!(
        line::UsbKeyboards::parse("USB keyboards: none"),
        Some(line::UsbKeyboards::default())
    );
    assert_eq!(
        line::UsbKeyboards::parse("USB keyboards: 1 ehci, 2 ehci"),
        None
    );
    assert_eq!(line::UsbKeyboards::parse("USB keyboards: 0 ehci"), None);
}
