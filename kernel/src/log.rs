//! The kernel's log kept in memory (`kernel_log`): `serial` feeds every
//! line it prints into this ring, so the report screen and the fault panel
//! can show the log on PCs without a serial port.
//!
//! Writers never wait for the ring: they take its lock with `try_lock`, and
//! if it is held (only possible if a fault or NMI interrupted a write on this
//! CPU, since writers run with interrupts off) their text is counted as lost
//! instead. Readers copy out what they need with interrupts off. The fault
//! path, which never returns to the code it interrupted, frees the lock with
//! `force_unlock` so the panel can still read the ring; the ring's reads are
//! bounded whatever state a cut-short write left.

use core::fmt::{self, Write};
use core::sync::atomic::{AtomicU64, Ordering};
use kernel_log::KernelLog;
use spin::{Mutex, MutexGuard};

static LOG: Mutex<KernelLog> = Mutex::new(KernelLog::new());
/// Writes not recorded because the ring was busy.
static LOST: AtomicU64 = AtomicU64::new(0);

/// Records text printed on serial; never waits.
pub fn record(args: fmt::Arguments) {
    match LOG.try_lock() {
        Some(mut ring) => {
            let _ = ring.write_fmt(args);
        }
        None => {
            LOST.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Writes lost because the ring was busy.
pub fn lost() -> u64 {
    LOST.load(Ordering::Relaxed)
}

/// Runs `read` on the ring with interrupts off (so no handler's print finds
/// it busy meanwhile); `None` if the ring is busy.
pub fn read<T>(read: impl FnOnce(&KernelLog) -> T) -> Option<T> {
    x86_64::instructions::interrupts::without_interrupts(|| LOG.try_lock().map(|ring| read(&ring)))
}

/// The ring for a fault handler: the lock is freed first if the interrupted
/// code held it.
///
/// # Safety
///
/// As `serial::force_unlock`: the caller never returns to the code it
/// interrupted, so that code never touches the ring again.
pub unsafe fn for_fault_handler() -> Option<MutexGuard<'static, KernelLog>> {
    if LOG.is_locked() {
        // SAFETY: the caller guarantees the interrupted holder never resumes.
        unsafe { LOG.force_unlock() };
    }
    LOG.try_lock()
}
