//! Non-maskable interrupts: counted in the handler, told by the frame loop.
//!
//! The handler may have interrupted anything, the serial port's or the
//! log's lock holder included, so it only reads System Control Port B,
//! clears a latched check there, and stores the count and the port's byte
//! in atomics. The frame loop calls [`log_news`], and `firmware::nmi`
//! decides what the log says and bounds a storm.

use core::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use firmware::nmi::{NmiLog, NmiReason, SYSTEM_CONTROL_PORT_B};
use spin::Mutex;
use x86_64::instructions::port::Port;

/// NMIs since boot.
static COUNT: AtomicU64 = AtomicU64::new(0);
/// Port B as the last NMI found it.
static LAST_PORT_B: AtomicU8 = AtomicU8::new(0);
/// The frame loop's record of what it has told.
static TOLD: Mutex<NmiLog> = Mutex::new(NmiLog::new());

/// The NMI handler's work: read port B, clear a latched parity, SERR# or
/// I/O channel check (else it would fire again at once), count.
pub fn on_nmi() {
    let mut port_b: Port<u8> = Port::new(SYSTEM_CONTROL_PORT_B);
    // SAFETY: reading System Control Port B has no side effect.
    let reason = NmiReason(unsafe { port_b.read() });
    if let Some(acknowledge) = reason.acknowledge() {
        // SAFETY: the bits written back are the ones read (speaker, PIT
        // gate, the two check enables), plus the disable bit that clears
        // the latch; the checks are turned on again at once.
        unsafe {
            port_b.write(acknowledge);
            port_b.write(reason.reenable());
        }
    }
    LAST_PORT_B.store(reason.0, Ordering::Relaxed);
    COUNT.fetch_add(1, Ordering::Release);
}

/// NMIs since boot, for the report screen.
pub fn count() -> u64 {
    COUNT.load(Ordering::Acquire)
}

/// Tells the log of NMIs it has not heard of, within the storm bound.
pub fn log_news() {
    let total = count();
    if total == 0 {
        return;
    }
    let Some(mut told) = TOLD.try_lock() else {
        return;
    };
    let reason = NmiReason(LAST_PORT_B.load(Ordering::Relaxed));
    if let Some(news) = told.news(total, reason, crate::time::micros()) {
        drop(told);
        crate::serial_println!("{news}");
    }
}
