//! The end of the line: every CPU exception that cannot be resumed, and every
//! panic, is reported here on serial and on screen (80x25 text, white on red,
//! on the VGA or on the framebuffer, with the last lines of the kernel's log
//! before it), and the CPU halts for good. Halting, rather than returning or rebooting,
//! keeps the report readable and avoids a triple fault's reboot loop.

use core::fmt::Write;
use core::sync::atomic::{AtomicU64, Ordering};
use modex::card::Card;
use protocol::line::{FaultLine, InterruptFrame};
use spin::Once;
use x86_64::structures::idt::InterruptStackFrame;

/// Where physical memory is mapped, once the kernel knows that a legacy VGA is
/// there to show a report on; zero until then.
static SCREEN_PHYSICAL_OFFSET: AtomicU64 = AtomicU64::new(0);

/// The card, so the fault panel's mode set resets its extensions too. Set
/// once before the offset; read without a lock.
static SCREEN_CARD: Once<Card> = Once::new();

/// From now on, fault reports also go to the VGA screen (a `card`).
pub fn report_on_screen(physical_memory_offset: u64, card: Card) {
    SCREEN_CARD.call_once(|| card);
    SCREEN_PHYSICAL_OFFSET.store(physical_memory_offset, Ordering::Release);
}

const REPORT_LINES: usize = demo::screens::REPORT_LINES;
const PANEL_LOG_LINES: usize = demo::screens::PANEL_LOG_LINES;
const LINE_BYTES: usize = modex::TEXT_COLUMNS as usize;

/// A screen line built without a heap; text past the line's end is cut.
type Line = kernel_log::LogLine<LINE_BYTES>;
/// A fact for the QR code (a CPU brand string is up to 48 bytes).
type FactLine = kernel_log::LogLine<120>;

pub fn halt_with(
    kind: &str,
    frame: &InterruptStackFrame,
    error: Option<u64>,
    address: Option<u64>,
) -> ! {
    let frame = InterruptFrame {
        rip: frame.instruction_pointer.as_u64(),
        cs: frame.code_segment.0.into(),
        rflags: frame.cpu_flags.bits(),
        rsp: frame.stack_pointer.as_u64(),
        ss: frame.stack_segment.0.into(),
    };
    let fault_lines = [
        Some(FaultLine::<&str>::Exception(kind)),
        Some(FaultLine::Frame(frame)),
        error.map(FaultLine::ErrorCode),
        address.map(FaultLine::Address),
    ];
    report(&lines_of(fault_lines))
}

pub fn halt_with_panic(info: &core::panic::PanicInfo) -> ! {
    let location = info.location().map(|at| FaultLine::Location {
        file: at.file(),
        line: at.line(),
        column: at.column(),
    });
    report(&lines_of([
        Some(FaultLine::Panic(info.message())),
        location,
        None,
        None,
    ]))
}

/// The report's lines, each in its row.
fn lines_of<M: core::fmt::Display>(
    fault_lines: [Option<FaultLine<'_, M>>; REPORT_LINES],
) -> [Line; REPORT_LINES] {
    let mut lines = [const { Line::new() }; REPORT_LINES];
    for fault_line in fault_lines.into_iter().flatten() {
        let _ = write!(lines[fault_line.row()], "{}", fault_line);
    }
    lines
}

fn report(lines: &[Line]) -> ! {
    // SAFETY: this path ends in `halt_forever` and never returns to the
    // code the fault or panic interrupted.
    unsafe { crate::serial::force_unlock() };
    // The stack's high-water mark first: the report's own lines, from its
    // heading to the halt, are exactly the panel's.
    crate::stack::report();
    // The log as it was before the fault, for the panel. Held from here on,
    // so the fault's own lines go to serial only (counted as lost from the
    // ring), and the panel shows the lines that led up to it.
    // SAFETY: as above: the interrupted code never resumes.
    let ring = unsafe { crate::log::for_fault_handler() };
    for line in lines.iter().filter(|l| !l.is_empty()) {
        crate::serial_println!("{}", line.as_str());
    }
    let mut tail = [""; PANEL_LOG_LINES];
    let mut shown = 0;
    // The facts a report needs most, for the QR code: the build, the CPU,
    // NX, the firmware and the display (rows 0, 1, 2, 3 and 5 of
    // `MachineFacts::rows`). The record may be locked by the interrupted
    // code; then the QR code goes without them.
    let mut rows = [const { FactLine::new() }; demo::facts::FACT_COUNT];
    if let Some(facts) = crate::facts::try_get() {
        let mut next = rows.iter_mut();
        facts.rows(|row| {
            if let Some(line) = next.next() {
                let _ = write!(line, "{row}");
            }
        });
    }
    let facts = [0, 1, 2, 3, 5].map(|row| rows[row].as_str());
    if let Some(ring) = ring.as_deref() {
        shown = ring.len().min(PANEL_LOG_LINES);
        for (slot, back) in tail[..shown].iter_mut().zip((0..shown).rev()) {
            *slot = ring.newest(back).unwrap_or("");
        }
    }
    let mut text = [""; REPORT_LINES];
    for (text, line) in text.iter_mut().zip(lines) {
        *text = line.as_str();
    }
    let mut qr_text = [0u8; demo::screens::PANEL_QR_TEXT_BYTES];
    let qr_len = demo::screens::fault_qr_text(&text, &facts, &tail[..shown], &mut qr_text);
    let qr_text = &qr_text[..qr_len];
    // What the code says, on serial too (a test decodes the screen's code
    // and compares).
    for qr_line in qr_text.split(|&byte| byte == b'\n') {
        crate::serial_println!(
            "{}{}",
            protocol::line::FAULT_QR,
            core::str::from_utf8(qr_line).unwrap_or("?")
        );
    }
    show_on_screen(&text, &tail[..shown], qr_text);
    halt_forever()
}

/// Shows the report on screen: on the VGA in text mode if the kernel drives a
/// legacy VGA, else on the framebuffer through the software VGA's text mode
/// (`framebuffer::show_fault_panel`). Each is taken with an atomic swap, so
/// a fault while showing the panel goes to serial only. The interrupted code
/// may have been half-way through a register write; the mode set starts from
/// scratch, so that does not matter.
fn show_on_screen(text: &[&str; REPORT_LINES], log: &[&str], qr_text: &[u8]) {
    let offset = SCREEN_PHYSICAL_OFFSET.swap(0, Ordering::Acquire);
    if offset == 0 {
        crate::framebuffer::show_fault_panel(text, log, qr_text);
        return;
    }
    // SAFETY: the offset was recorded by the kernel after it found legacy VGA
    // through this mapping; nothing else runs after a fault, so the bus is ours.
    let bus = unsafe { crate::vga_bus::PortBus::new(offset) };
    let card = SCREEN_CARD.get().copied().unwrap_or(Card::Standard);
    demo::screens::fault_panel(&mut modex::ModeX::for_card(bus, card), text, log, qr_text);
}

/// Stops the demo with interrupts off. What is left is a loop that watches
/// the 8042 for Ctrl+Alt+Del and resets the machine on it: no interrupt is
/// trusted here, so the controller is polled. (A machine without an 8042
/// reads 0xFF there, which is no key; a USB keyboard is not polled here.)
pub fn halt_forever() -> ! {
    crate::serial_println!("{}", protocol::line::HALTED);
    x86_64::instructions::interrupts::disable();
    let mut reset_chord = keyboard::reset_keys::ResetChord::new();
    loop {
        if let Some(byte) = crate::input::ps2::poll_byte() {
            if reset_chord.feed(byte) {
                crate::platform::power::reset();
            }
        }
        core::hint::spin_loop();
    }
}
