//! What the property tests share, here and in the runner's tests
//! (`tests/common/mod.rs` includes this file): proptest's settings and a
//! software VGA in Mode X.

#![allow(dead_code)] // each test binary uses its own part of this

use modex::soft::SoftVga;
use modex::ModeX;

/// Proptest's settings: `default_cases` cases, or as many as the
/// `PROPTEST_CASES` environment variable asks for, from a fixed seed so that
/// every run tries the same cases (a longer hunt with more cases still finds
/// new ones, and reproduces them).
pub fn proptest_config(default_cases: u32) -> proptest::prelude::ProptestConfig {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default_cases);
    proptest::prelude::ProptestConfig {
        cases,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5EED_CA5E),
        ..proptest::prelude::ProptestConfig::default()
    }
}

/// A software VGA with Mode X set, on the heap (it is large).
pub fn soft_vga_in_mode_x() -> Box<SoftVga> {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    soft
}
