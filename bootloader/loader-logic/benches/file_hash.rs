//! What the loaders' SHA-256 check costs on a real CPU: this machine's.
//!
//! `cargo bench -p loader-logic --bench file_hash` hashes as many bytes as
//! BIOS stage 3 checks (stage 4 and the kernel file of the test-profile
//! image, 881,472 bytes when issue 48 measured it; pass another count as the
//! first argument) with `file_hash::sha256`, the same portable `sha2` code
//! the loaders run, built for x86-64. It prints the best of 50 runs, which a
//! busy machine stretches least.
//!
//! Under QEMU's TCG the same check is dominated by emulation: stage 3 logs
//! its guest instruction count (`docs/performance.md`), and TCG spends tens
//! of host nanoseconds on each. This figure is the one a PC sees, less the
//! 32-bit code's register pressure.

use loader_logic::file_hash::sha256;
use std::hint::black_box;
use std::time::Instant;

const ISSUE_48_BYTES: usize = 881_472;

fn main() {
    let bytes = std::env::args()
        .skip(1)
        .find_map(|arg| arg.parse().ok())
        .unwrap_or(ISSUE_48_BYTES);
    // Bytes that are not all alike, so no run is special.
    let data: Vec<u8> = (0..bytes as u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 24) as u8)
        .collect();
    let mut best = f64::MAX;
    for _ in 0..50 {
        let start = Instant::now();
        black_box(sha256(black_box(&data)));
        best = best.min(start.elapsed().as_secs_f64());
    }
    println!(
        "SHA-256 of {bytes} bytes, best of 50: {:.2} ms ({:.1} MB/s)",
        best * 1e3,
        bytes as f64 / best / 1e6
    );
}
