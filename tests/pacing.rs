//! Frame pacing under QEMU's timed retrace: the spinning cube flips once per
//! vertical retrace for 30 seconds without missing one.

mod common;

use common::{boot_bios, BOOT_TIMEOUT};
use std::time::Duration;

#[test]
fn the_spinning_cube_flips_on_every_retrace_for_thirty_seconds() {
    let mut qemu = boot_bios(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    // 1800 flips at 60 Hz: three reports, ten seconds apart.
    let console = qemu
        .wait_for_serial("pacing: 1800 flips", Duration::from_secs(90))
        .unwrap();
    let line = console
        .lines()
        .find(|l| l.starts_with("pacing: 1800 flips"))
        .unwrap();
    println!("{line}");
    assert_eq!(
        line,
        "pacing: 1800 flips, 0 missed retraces, 0 wait timeouts"
    );
}
