//! A PC with a 64-bit CPU and a 32-bit UEFI (Bay Trail tablets, Compute
//! Sticks; issue 38): 32-bit OVMF (`ovmf-ia32`, on a Q35 with SMM) boots the
//! one image's `EFI/BOOT/BOOTIA32.EFI`, which hands over to BIOS stage 4 in
//! long mode (see `bootloader/CHANGES.md`). The loader's line comes before the
//! kernel's banner; the kernel knows UEFI booted it and found the ACPI tables
//! through the RSDP the loader passed on; the cube test's keys give the
//! software VGA's pictures on the GOP's framebuffer; Esc powers the machine
//! off through ACPI (no isa-debug-exit) and QEMU exits with 0. On a CPU
//! without long mode the loader says so and waits, the machine neither
//! resetting nor starting the kernel. The loader hands over the Secure Boot
//! record as the 64-bit one does (issue 48): the report says "setup mode"
//! with the empty variables, "off" with keys enrolled and Secure Boot
//! switched off. The host tests of the loader's memory map and of what each
//! variable read means are in `bootloader/loader-logic` (`uefi_map`,
//! `secure_boot`).

mod common;

use boot::qemu::WALL_CLOCK_CEILING;
use boot::{line, Firmware, Graphics, Qemu, QemuOptions};
use common::{assert_pictures_equal, presented, BOOT_TIMEOUT};
use std::path::Path;
use std::time::{Duration, Instant};

/// 32-bit OVMF boots in well under 30 s here; emulation on a loaded machine
/// is slow.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);
/// The 32-bit UEFI loader's first line (`bootloader/uefi-ia32`).
const IA32_LOADER_LINE: &str = "loader: loading kernel (UEFI IA32)";
/// The loader's stop on a CPU without long mode.
const NO_LONG_MODE: &str =
    "is a 32-bit CPU: it has no 64-bit mode; the cube needs an x86-64 processor";

fn start(cpu: Option<&str>) -> Qemu {
    start_with(cpu, None)
}

fn start_with(cpu: Option<&str>, vars: Option<&Path>) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    let mut options = QemuOptions::new(images.hybrid);
    options.firmware = Firmware::Uefi32;
    options.graphics = Graphics::StdVga;
    // A real PC's way out: Esc must power off through ACPI, which needs the
    // RSDP the loader found in UEFI's configuration table.
    options.debug_exit = false;
    options.cpu = cpu.map(str::to_owned);
    options.secure_boot_vars = vars.map(Path::to_owned);
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_32_bit_uefi_loader_boots_the_cube_and_esc_powers_off() {
    let mut qemu = start(None);
    let console = qemu
        .wait_for_serial(line::READY, UEFI_BOOT_TIMEOUT)
        .unwrap();
    let loader = console
        .find(IA32_LOADER_LINE)
        .unwrap_or_else(|| panic!("no IA32 loader line on serial:\n{console}"));
    assert!(
        IA32_LOADER_LINE.starts_with(line::LOADER_START),
        "the common start every loader's first line has"
    );
    let kernel = console
        .find(line::KERNEL_BANNER)
        .unwrap_or_else(|| panic!("no kernel banner on serial:\n{console}"));
    assert!(loader < kernel, "the loader's line comes first:\n{console}");
    common::assert_each_loader_line_once(&console);
    // Stage 4 handed over a map of UEFI kinds: no video BIOS calls.
    assert!(
        console.contains("facts: firmware: Uefi"),
        "the kernel knows UEFI booted it:\n{console}"
    );
    assert!(
        console.contains("display: UEFI boot: drawing through the firmware framebuffer"),
        "{console}"
    );
    // The RSDP from UEFI's configuration table (none where a BIOS has it).
    assert!(
        !console.contains("found no RSDP") && console.contains("acpi: FADT revision"),
        "the kernel found the ACPI tables:\n{console}"
    );
    assert!(
        !console.contains("PANIC") && !console.contains("panicked"),
        "{console}"
    );
    common::after_each_key_on(&mut qemu, &common::CUBE_KEYS, |screen, model, _, what| {
        assert_pictures_equal(screen, &presented(model, screen.width, screen.height), what)
    });
    qemu.send_key("esc").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("still running after Esc: {e}"));
    let console = qemu.serial();
    assert!(console.contains(line::GOODBYE), "{console}");
    assert!(
        console.contains("power: switching off (ACPI S5"),
        "{console}"
    );
    assert_eq!(status.code(), Some(0), "{status}\n{console}");
}

#[test]
fn on_a_cpu_without_long_mode_the_loader_says_so_and_waits() {
    // QEMU's 32-bit CPU: PAE, but no long mode.
    let mut qemu = start(Some("qemu32"));
    let console = qemu
        .wait_for_serial(NO_LONG_MODE, UEFI_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains(IA32_LOADER_LINE), "{console}");
    // It waits: five more seconds of the guest's progress (QEMU's CPU time;
    // the firmware's stall loop keeps the CPU busy) with QEMU still running
    // (`-no-reboot` would end it on a reset) and no kernel.
    let start = qemu.cpu_time().expect("QEMU is running");
    let began = Instant::now();
    loop {
        if let Some(status) = qemu.wait_exit(Duration::from_millis(200)).unwrap() {
            panic!(
                "QEMU ended ({status}) instead of waiting:\n{}",
                qemu.serial()
            );
        }
        let used = qemu.cpu_time().expect("QEMU is running") - start;
        if used >= Duration::from_secs(5) {
            break;
        }
        assert!(
            began.elapsed() < WALL_CLOCK_CEILING,
            "QEMU stopped using the CPU:\n{}",
            qemu.serial()
        );
    }
    let console = qemu.serial();
    assert!(!console.contains(line::KERNEL_BANNER), "{console}");
    assert_eq!(
        console.matches(IA32_LOADER_LINE).count(),
        console.matches(NO_LONG_MODE).count(),
        "started once, stopped once:\n{console}"
    );
}

/// The kernel's Secure Boot fact on COM1 at the ready line, booted with
/// `vars` (or the empty variables).
fn secure_boot_fact(vars: Option<&Path>) -> String {
    let mut qemu = start_with(None, vars);
    let console = qemu
        .wait_for_serial(line::READY, UEFI_BOOT_TIMEOUT)
        .unwrap();
    let prefix = format!("{}Secure Boot: ", line::MACHINE_FACT);
    let fact = console
        .lines()
        .find_map(|text| text.trim_end().strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no Secure Boot fact:\n{console}"));
    assert!(
        console.contains("loader: secure boot state Record"),
        "the loader says what it read:\n{console}"
    );
    fact.to_owned()
}

#[test]
fn with_the_empty_variables_the_report_says_setup_mode() {
    // No platform key: `SetupMode` 1, `SecureBoot` 0.
    assert_eq!(secure_boot_fact(None), "setup mode");
}

#[test]
fn with_keys_enrolled_and_secure_boot_switched_off_the_report_says_off() {
    // A PC whose setup screen switched Secure Boot off: Microsoft's keys
    // (a platform key, so not setup mode) and `SecureBootEnable` 0, written
    // into the empty variables by virt-fw-vars (boot/setup.sh installs it).
    let scratch = tempfile::tempdir().unwrap();
    let vars = common::vars_from(
        boot::qemu::OVMF32_VARS,
        &scratch.path().join("OVMF32_VARS_4M.fd"),
        &[
            "--enroll-microsoft".as_ref(),
            "--set-false".as_ref(),
            "SecureBootEnable".as_ref(),
        ],
    );
    assert_eq!(secure_boot_fact(Some(&vars)), "off");
}
