//! The kernel's clock keeps the host's time, even on a busy host: it reads
//! the TSC, calibrated against PIT channel 2, instead of counting timer
//! interrupts, which an emulator may merge or drop when it falls behind.

mod common;

use boot::BootOption;
use common::{boot_bios, BOOT_TIMEOUT};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

/// The kernel prints its clock once a second for 10 s (boot option
/// `clock-check`); the host notes when each line arrives.
#[test]
fn kernel_time_agrees_with_the_host_clock_within_one_percent_under_load() {
    // Two threads that keep both of the host's cores busy throughout.
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

    let mut qemu = boot_bios(Some(BootOption::ClockCheck));
    let mut readings = Vec::new();
    for n in 1..=11 {
        let console = qemu
            .wait_for_serial_count("clock-check:", n, BOOT_TIMEOUT)
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

    let (first_micros, first_arrival) = readings[0];
    let (last_micros, last_arrival) = readings[readings.len() - 1];
    let kernel = Duration::from_micros(last_micros - first_micros);
    let host = last_arrival - first_arrival;
    let ratio = kernel.as_secs_f64() / host.as_secs_f64();
    println!("kernel {kernel:?} against host {host:?}: ratio {ratio:.5}");
    assert!(kernel >= Duration::from_secs(10), "{kernel:?}");
    assert!(
        (ratio - 1.0).abs() < 0.01,
        "the kernel's clock measured {kernel:?} while the host's measured {host:?}"
    );
}
