//! Time and power on the machines users have: with and without the 8254 PIT
//! and the HPET, under SeaBIOS and under OVMF. On each, the kernel's clock
//! keeps the host's time even on a busy host (it reads the TSC, whose rate it
//! takes from whatever reference the machine has, instead of counting timer
//! interrupts, which an emulator may merge or drop), and it leaves as a real
//! PC would: Esc powers the machine off through ACPI, Ctrl+Alt+Del resets it.
//!
//! The four machines boot one after another, so that each clock check has
//! the host's two busy cores to itself; each boot then goes on to a check of
//! its own, so that no boot is spent on one thing only.

mod common;

use boot::{
    line, Board, BootOption, BootRequest, ClockReference, Firmware, Graphics, Qemu, QemuOptions,
};
use common::{
    after_each_key_on, assert_pictures_equal, escape_leaves_the_goodbye_on_the_framebuffer,
    presented, BOOT_TIMEOUT, CUBE_KEYS,
};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

/// OVMF takes several seconds to boot under emulation, more on a loaded host.
const UEFI_BOOT_TIMEOUT: Duration = Duration::from_secs(120);

/// What each machine does after its clock check.
#[derive(Clone, Copy, Debug)]
enum Then {
    /// Esc: the goodbye line, then ACPI S5, and QEMU exits by itself.
    EscapePowersOff,
    /// Ctrl+Alt+Del: a reset, which `-no-reboot` turns into QEMU's exit.
    CtrlAltDelResets,
    /// The cube spins, the cube test's keys give the software VGA's pictures,
    /// and Esc shows the goodbye line before the machine powers off.
    SpinKeysAndGoodbye,
}

struct Machine {
    name: &'static str,
    firmware: Firmware,
    board: Board,
    /// A reference the kernel must use (otherwise its own choice).
    clock: Option<ClockReference>,
    /// The clock source the boot log must name.
    source: &'static str,
    then: Then,
}

const NO_PIT: Board = Board {
    pit: false,
    ..Board::Q35
};

const MACHINES: [Machine; 4] = [
    Machine {
        name: "SeaBIOS -M pc, measured against PIT channel 2",
        firmware: Firmware::Bios,
        board: Board::PC,
        clock: Some(ClockReference::Pit),
        source: "from PIT channel 2",
        then: Then::EscapePowersOff,
    },
    Machine {
        name: "OVMF -M q35, measured against the HPET",
        firmware: Firmware::Uefi,
        board: Board::Q35,
        clock: Some(ClockReference::Hpet),
        source: "from the HPET",
        then: Then::CtrlAltDelResets,
    },
    Machine {
        name: "OVMF -M q35,pit=off,hpet=off",
        firmware: Firmware::Uefi,
        board: Board {
            hpet: false,
            ..NO_PIT
        },
        clock: None,
        source: "from the ACPI PM timer",
        then: Then::EscapePowersOff,
    },
    Machine {
        name: "OVMF -M q35,pit=off",
        firmware: Firmware::Uefi,
        board: NO_PIT,
        clock: None,
        source: "from the ACPI PM timer",
        then: Then::SpinKeysAndGoodbye,
    },
];

#[test]
fn on_every_machine_the_clock_keeps_time_and_the_machine_powers_off_or_resets() {
    for machine in &MACHINES {
        println!("{}:", machine.name);
        let mut qemu = boot(machine);
        check_the_clock(&mut qemu, machine);
        let timeout = match machine.firmware {
            Firmware::Bios => BOOT_TIMEOUT,
            Firmware::Uefi | Firmware::Uefi32 => UEFI_BOOT_TIMEOUT,
        };
        qemu.wait_for_serial(line::READY, timeout).unwrap();
        match machine.then {
            Then::EscapePowersOff => escape_powers_off(&mut qemu, machine),
            Then::CtrlAltDelResets => ctrl_alt_del_resets(&mut qemu, machine),
            Then::SpinKeysAndGoodbye => spin_keys_and_goodbye(&mut qemu),
        }
    }
}

/// Boots with the clock check and no isa-debug-exit: the kernel leaves by
/// ACPI, as on a real PC.
fn boot(machine: &Machine) -> Qemu {
    let images = boot::images::publish().expect("the build script made the images");
    // The one image, which boots under SeaBIOS and OVMF alike.
    let mut options = QemuOptions::new(images.hybrid);
    options.firmware = machine.firmware;
    options.board = machine.board;
    options.graphics = Graphics::StdVga;
    options.debug_exit = false;
    options.keep_after_power_off = matches!(machine.then, Then::SpinKeysAndGoodbye);
    options.boot = BootRequest {
        clock: machine.clock,
        option: Some(BootOption::ClockCheck),
        ..BootRequest::default()
    };
    Qemu::start(&options).unwrap_or_else(|e| panic!("{}: {e}", machine.name))
}

/// The kernel prints its clock once a second for 10 s (boot option
/// `clock-check`) while two threads keep both host cores busy; the host notes
/// when each line arrives. Between the promptest line of the first three and
/// of the last three (7 s or more apart) the two must agree within 1 %.
fn check_the_clock(qemu: &mut Qemu, machine: &Machine) {
    let stop = Arc::new(AtomicBool::new(false));
    let load: Vec<_> = (0..2)
        .map(|_| {
            let stop = Arc::clone(&stop);
            thread::spawn(move || {
                let mut x = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                }
            })
        })
        .collect();

    let mut readings = Vec::new();
    for n in 1..=11 {
        let console = qemu
            .wait_for_serial_count("clock-check:", n, UEFI_BOOT_TIMEOUT)
            .unwrap();
        let arrived = Instant::now();
        let line = console
            .lines()
            .filter(|l| l.starts_with("clock-check:"))
            .nth(n - 1)
            .expect("the line just waited for");
        let micros: u64 = line
            .split_whitespace()
            .nth(1)
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("cannot read {line:?}"));
        readings.push((micros, arrived));
    }
    stop.store(true, Ordering::Relaxed);
    load.into_iter().for_each(|t| t.join().unwrap());

    let console = qemu.serial();
    let source = console
        .lines()
        .find(|l| l.starts_with("clock: TSC"))
        .unwrap_or_else(|| panic!("{}: no clock line:\n{console}", machine.name));
    println!("  {source}");
    assert!(
        source.contains(machine.source),
        "{}: {source}",
        machine.name
    );

    let whole = Duration::from_micros(readings[readings.len() - 1].0 - readings[0].0);
    assert!(whole >= Duration::from_secs(10), "{whole:?}");
    // A line reaches the host some time after the kernel printed it, never
    // before, and on a busy host that delay varies (up to 0.1 s seen beside
    // four busy loops). So the two clocks are compared between the promptest
    // of the first three lines and the promptest of the last three: the
    // line whose arrival, less its kernel time, is least.
    let promptest = |lines: &[(u64, Instant)]| {
        *lines
            .iter()
            .min_by_key(|&&(micros, arrived)| arrived - Duration::from_micros(micros))
            .expect("three lines")
    };
    let (first_micros, first_arrival) = promptest(&readings[..3]);
    let (last_micros, last_arrival) = promptest(&readings[readings.len() - 3..]);
    let kernel = Duration::from_micros(last_micros - first_micros);
    let host = last_arrival - first_arrival;
    let ratio = kernel.as_secs_f64() / host.as_secs_f64();
    println!("  kernel {kernel:?} against host {host:?}: ratio {ratio:.5}");
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "{}: the kernel's clock measured {kernel:?} while the host's measured {host:?}",
        machine.name
    );
}

/// Esc: goodbye, then ACPI S5; QEMU, with no debug-exit device and no
/// `-no-shutdown`, exits by itself with status 0.
fn escape_powers_off(qemu: &mut Qemu, machine: &Machine) {
    qemu.send_key("esc").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{}: still running after Esc: {e}", machine.name));
    let console = qemu.serial();
    assert!(console.contains(line::GOODBYE), "{console}");
    assert!(
        console.contains("power: switching off (ACPI S5"),
        "{console}"
    );
    assert_eq!(
        status.code(),
        Some(0),
        "{}: {status}\n{console}",
        machine.name
    );
    println!("  Esc: powered off");
}

/// Ctrl+Alt+Del resets the machine; QEMU runs with `-no-reboot`, so the
/// reset ends it.
fn ctrl_alt_del_resets(qemu: &mut Qemu, machine: &Machine) {
    qemu.send_key("ctrl-alt-delete").unwrap();
    let status = qemu
        .wait_for_exit(BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{}: still running after Ctrl+Alt+Del: {e}", machine.name));
    let console = qemu.serial();
    assert!(
        console.contains("power: Ctrl+Alt+Del: resetting"),
        "{console}"
    );
    assert!(!console.contains(line::GOODBYE), "{console}");
    assert_eq!(status.code(), Some(0), "{}: {status}", machine.name);
    println!("  Ctrl+Alt+Del: reset");
}

/// Without a PIT nothing wakes the CPU from `hlt`, so the kernel must not
/// sleep on it: the cube spins, keys act, and Esc leaves.
fn spin_keys_and_goodbye(qemu: &mut Qemu) {
    // Looks a second apart until the picture changes (at once, if it spins);
    // a cube frozen on its first frame never passes.
    // Bounded by QEMU's CPU time, the guest's progress, not the host's speed.
    let first = qemu.screendump().unwrap();
    let started = Instant::now();
    let cpu_at_first = qemu.cpu_time().unwrap_or_default();
    loop {
        thread::sleep(Duration::from_secs(1));
        if qemu.screendump().unwrap() != first {
            break;
        }
        let cpu = qemu.cpu_time().unwrap_or_default() - cpu_at_first;
        assert!(
            cpu < BOOT_TIMEOUT,
            "pit=off: the picture has not changed while QEMU ran {cpu:?} of CPU time: \
             the cube does not spin",
        );
    }
    println!(
        "  the cube spins: the picture changed within {:?}",
        started.elapsed()
    );

    after_each_key_on(qemu, &CUBE_KEYS, |screen, model, _, what| {
        let expected = presented(model, screen.width, screen.height);
        assert_pictures_equal(screen, &expected, &format!("pit=off, {what}"));
    });
    println!("  {} keys: the software VGA's pictures", CUBE_KEYS.len());

    escape_leaves_the_goodbye_on_the_framebuffer(qemu, "pit=off, the goodbye line");
    println!("  Esc: the goodbye line, then powered off");
}
