//! The report screen's facts, gathered on the machine: the build, the CPU
//! (CPUID), the display adapter (PCI), the counters, and whatever the
//! firmware, display, keyboard and clock code last said in the log (so the
//! report shows what those subsystems logged, and needs nothing from them).
//! Layout and drawing are `demo::report`'s. What is drawn is also printed on
//! serial (`protocol::line::REPORT_FACT` and friends), so the QEMU
//! tests can draw the same report on the software VGA and compare.

use crate::{input::ps2, pci, serial_println};
use clock::pacing::Pacing;
use core::fmt::Write;
use demo::app::App;
use demo::report::{LogPosition, Report, FACT_ROWS, LOG_ROWS};
use kernel_log::{text_of_field, LogLine};
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
    add_fact(&|fact| write_build_fact(fact));
    add_fact(&|fact| write_cpu_fact(fact));
    let adapter = pci::display_controller();
    add_fact(&|fact| {
        let _ = match adapter {
            Some((vendor, device)) => write!(
                fact,
                "adapter: PCI {:04x}:{:04x} {}",
                vendor,
                device,
                demo::report::pci_name(vendor, device)
            ),
            None => write!(fact, "adapter: no PCI display controller"),
        };
    });

    add_fact(&|fact| {
        let _ = write!(
            fact,
            "counters: {} missed retraces, {} dropped scancodes",
            pacing.missed,
            ps2::SCANCODES.dropped(),
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
        // What each subsystem said. The display code says first which path
        // it takes and then which adapter or framebuffer mode (its two
        // earliest lines); the VGA code last says how the mode was set and
        // whether it read back (its two latest).
        let earliest = |prefixes: &[&str], nth| ring.earliest_with_any_prefix(prefixes, nth);
        let latest = |prefixes: &[&str], nth| ring.latest_with_any_prefix(prefixes, nth);
        let keyboard = latest(&["keyboard:", "usb:"], 0);
        let said = [
            latest(&["firmware:"], 0),
            earliest(&["display:"], 0),
            earliest(&["display:"], 1),
            latest(&["vga:"], 1),
            latest(&["vga:"], 0),
            Some(keyboard.unwrap_or("keyboard: PS/2 (no problem logged)")),
            latest(&["clock:"], 0),
        ];
        for text in said.into_iter().flatten() {
            add_fact(&|fact| {
                let _ = fact.write_str(text);
            });
        }
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

/// "cpu: VENDOR, BRAND" (or "(no brand string)"), from CPUID.
pub fn write_cpu_fact(out: &mut impl Write) {
    let cpu = cpu_identity();
    let _ = match text_of_field(&cpu.brand) {
        "" => write!(out, "cpu: {} (no brand string)", text_of_field(&cpu.vendor)),
        brand => write!(out, "cpu: {}, {}", text_of_field(&cpu.vendor), brand),
    };
}

/// "modex-cube VERSION commit COMMIT".
pub fn write_build_fact(out: &mut impl Write) {
    let _ = write!(
        out,
        "modex-cube {} commit {}",
        env!("CARGO_PKG_VERSION"),
        env!("GIT_COMMIT")
    );
}

/// CPUID's vendor (12 bytes) and brand string (48 bytes), as the CPU gives
/// them: the brand may have no terminator, so `text_of_field` cuts it.
struct CpuIdentity {
    vendor: [u8; 12],
    brand: [u8; 48],
}

fn cpu_identity() -> CpuIdentity {
    use core::arch::x86_64::__cpuid;
    let mut identity = CpuIdentity {
        vendor: [0; 12],
        brand: [0; 48],
    };
    // CPUID is safe to call on x86-64: it only reads identification.
    let leaf0 = __cpuid(0);
    for (chunk, register) in identity
        .vendor
        .as_chunks_mut::<4>()
        .0
        .iter_mut()
        .zip([leaf0.ebx, leaf0.edx, leaf0.ecx])
    {
        chunk.copy_from_slice(&register.to_le_bytes());
    }
    // Leaf 0x8000_0000 reports the highest extended leaf.
    let highest = __cpuid(0x8000_0000).eax;
    if highest >= 0x8000_0004 {
        for (index, leaf) in (0x8000_0002u32..=0x8000_0004).enumerate() {
            let regs = __cpuid(leaf);
            for (word, register) in [regs.eax, regs.ebx, regs.ecx, regs.edx]
                .into_iter()
                .enumerate()
            {
                let at = index * 16 + word * 4;
                identity.brand[at..at + 4].copy_from_slice(&register.to_le_bytes());
            }
        }
    }
    identity
}
