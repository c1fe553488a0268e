//! The report screen on the machine: the machine's facts as boot recorded
//! them (`crate::facts`), the counters, and a window on the log. Layout and
//! drawing are `demo::report`'s. What is drawn is also printed on
//! serial (`protocol::line::REPORT_FACT` and friends), so the QEMU
//! tests can draw the same report on the software VGA and compare.

use crate::{input::ps2, serial_println};
use clock::pacing::Pacing;
use core::fmt::Write;
use demo::app::App;
use demo::report::{LogPosition, Report, FACT_ROWS, LOG_ROWS};
use kernel_log::LogLine;
use modex::{ModeX, PageImage, VgaBus, PAGE_PIXELS};
use protocol::line;
use spin::Mutex;

/// A fact or a copied log line: printable ASCII, cut at 120 bytes.
type Text = LogLine<120>;

/// The report's picture before it is written to its page (75 KiB: .bss, not
/// the stack).
static IMAGE: Mutex<PageImage> = Mutex::new([0; PAGE_PIXELS]);

/// Draws the report if the app asks for it (the report key, or a scroll).
pub fn show_if_asked<B: VgaBus, R: core::borrow::BorrowMut<demo::frame::Renderer>>(
    vga: &mut ModeX<B>,
    app: &mut App<R>,
    pacing: &Pacing,
) {
    let Some(scroll) = app.report_to_draw() else {
        return;
    };
    let mut facts = [const { Text::new() }; FACT_ROWS];
    let mut window = [const { Text::new() }; LOG_ROWS];
    let mut fact_count = 0;
    let mut add_fact = |write: &dyn Fn(&mut Text)| {
        if let Some(fact) = facts.get_mut(fact_count) {
            write(fact);
            fact_count += 1;
        }
    };
    crate::facts::get().rows(|row| {
        add_fact(&|fact| {
            let _ = write!(fact, "{row}");
        })
    });
    add_fact(&|fact| {
        let _ = write!(
            fact,
            "counters: {} missed retraces, {} dropped scancodes, {} NMIs",
            pacing.missed,
            ps2::SCANCODES.dropped(),
            crate::nmi::count(),
        );
    });
    let frames = app.frames_drawn();
    let mut window_lines = 0;
    let position = crate::log::read(|ring| {
        let dropped = ring.dropped() + crate::log::lost();
        add_fact(&|fact| {
            let _ = write!(
                fact,
                "counters: {frames} frames drawn, {dropped} log lines dropped"
            );
        });
        ring.window(line::is_report_line, scroll, LOG_ROWS, |text| {
            if let Some(copy) = window.get_mut(window_lines) {
                let _ = copy.write_str(text);
                window_lines += 1;
            }
        })
    });
    let Some(position) = position else {
        // Not asked again until the next key: no line on every loop.
        app.report_drawn(scroll);
        serial_println!("report: the log is busy; not shown");
        return;
    };

    let mut fact_texts = [""; FACT_ROWS];
    for (text, fact) in fact_texts.iter_mut().zip(&facts[..fact_count]) {
        *text = fact.as_str();
    }
    let mut log_texts = [""; LOG_ROWS];
    for (text, copy) in log_texts.iter_mut().zip(&window[..window_lines]) {
        *text = copy.as_str();
    }
    let report = Report {
        facts: &fact_texts[..fact_count],
        log: &log_texts[..window_lines],
        position: LogPosition {
            first: position.first,
            last: position.last,
            total: position.total,
        },
    };
    let Some(mut image) = IMAGE.try_lock() else {
        app.report_drawn(scroll);
        serial_println!("report: the picture buffer is busy; not shown");
        return;
    };
    demo::report::show(vga, &mut image, &report);
    app.report_drawn(position.scroll);
    for fact in report.facts {
        serial_println!("{}{}", line::REPORT_FACT, fact);
    }
    for text in report.log {
        serial_println!("{}{}", line::REPORT_LOG, text);
    }
    serial_println!(
        "{}",
        line::ReportShown {
            first: position.first,
            last: position.last,
            total: position.total,
        }
    );
}
