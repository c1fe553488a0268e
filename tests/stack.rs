//! The kernel stack, measured in one boot: the bench (our renderer, the
//! per-pixel baseline and the crowd, each 120 frames), then in the demo the
//! crowd, every solid with several objects and lighting on, then Esc, where
//! the kernel reports the stack's high-water mark (painted at boot, see
//! `kernel/src/stack.rs`). The run must never have used more than half the
//! stack: the margin that a deeper path than any seen here still fits in.
//! (A fault report prints the same line; a fault ends the run, so it is not
//! part of this one boot.)

mod common;

use common::{boot_bios, BOOT_TIMEOUT};
use demo::solids::SHAPES;
use memory::stack::StackUse;
use protocol::{line, BootOption};
use std::time::Duration;

/// The bench draws 360 frames without waiting for retrace first.
const BENCH_TIMEOUT: Duration = Duration::from_secs(300);

#[test]
fn the_heaviest_scenes_use_at_most_half_the_stack() {
    let mut qemu = boot_bios(Some(BootOption::Bench));
    qemu.wait_for_serial(line::READY, BENCH_TIMEOUT).unwrap();
    assert!(qemu.serial().contains("bench: "), "{}", qemu.serial());

    // The crowd for a few frames, then every solid in the cube's place with
    // the satellites and the lighting on.
    let mut keys = vec!["x", "x", "m", "l"];
    keys.extend(std::iter::repeat_n("n", SHAPES.len()));
    for (n, key) in keys.iter().enumerate() {
        qemu.send_key(key).unwrap();
        let done = line::CommandDone(n as u64 + 1).to_string();
        qemu.wait_for_serial(&done, BOOT_TIMEOUT).unwrap();
    }

    qemu.send_key("esc").unwrap();
    let console = qemu
        .wait_for_serial(line::GOODBYE, BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e}:\n{}", qemu.serial()));
    let used = console
        .lines()
        .find_map(StackUse::parse)
        .unwrap_or_else(|| panic!("no stack line before the goodbye:\n{console}"));
    println!("{used}");
    assert_eq!(used.size, 1024 * 1024, "{used}");
    assert!(used.used > 0, "nothing measured: {used}");
    assert!(used.at_most_half(), "over half the stack used: {used}");
}
