//! The time-stamp counter, the kernel's one clock; every reference counter
//! is read beside it.

pub fn rdtsc() -> u64 {
    // SAFETY: RDTSC only reads the time-stamp counter.
    unsafe { core::arch::x86_64::_rdtsc() }
}
