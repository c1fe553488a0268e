//! Frame pacing under QEMU's timed retrace: the spinning cube flips in step
//! with vertical retrace for ten seconds, and the kernel's account of it adds
//! up. How many retraces a busy host makes QEMU miss is a figure for the soak
//! command in `docs/performance.md`, not something a test can promise.

mod common;

use clock::pacing::FRAME_MICROS;
use common::{boot_bios, BOOT_TIMEOUT};
use std::time::Duration;

#[test]
fn the_spinning_cube_flips_in_step_with_retrace_and_counts_what_it_misses() {
    let mut qemu = boot_bios(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    let console = qemu
        .wait_for_serial("pacing: 600 flips", Duration::from_secs(120))
        .unwrap();
    let line = console
        .lines()
        .find(|l| l.starts_with("pacing: 600 flips"))
        .unwrap();
    println!("{line}");
    // "pacing: F flips, M missed retraces, T wait timeouts, G gaps in U us"
    let numbers: Vec<u64> = line
        .split(|c: char| !c.is_ascii_digit())
        .filter_map(|word| word.parse().ok())
        .collect();
    let [flips, missed, timeouts, gaps, micros] = numbers[..] else {
        panic!("cannot read {line:?}");
    };
    assert_eq!(flips, 600, "{line}");
    assert_eq!(timeouts, 0, "a retrace wait hit its bound: {line}");
    // Every gap between flips is some whole number of refreshes: one for a
    // flip on time, more for each retrace missed.
    let refreshes = micros as f64 / FRAME_MICROS as f64;
    let counted = (gaps + missed) as f64;
    assert!(
        (counted / refreshes - 1.0).abs() < 0.01,
        "{counted} refreshes counted in {micros} us, which hold {refreshes:.1}: {line}"
    );
}
