//! COM1 serial console: the kernel's log, and the test harness's window into it.
//! Every line printed is also kept in memory (`crate::log`).
//!
//! The UART itself is driven by `uart_16550`. Its `try_send_byte` never waits,
//! so the one wait here is ours and bounded: if the transmitter never empties
//! (no UART fitted, a stuck bit), characters are dropped and counted instead of
//! hanging the kernel.

use core::fmt::{self, Write};
use core::sync::atomic::{AtomicU64, Ordering};
use spin::Mutex;
use uart_16550::backend::PioBackend;
use uart_16550::{BaudRate, Config, Uart16550};

const COM1: u16 = 0x3F8;
/// Line Status polls before a character is given up (a character takes ~87 µs
/// at 115200 baud; a port read takes ~1 µs on real hardware).
const TRANSMIT_WAIT_LIMIT: u32 = 100_000;

/// COM1, once `init` found it; `None` before that or if no UART answers.
struct Console(Option<Uart16550<PioBackend>>);

static DROPPED: AtomicU64 = AtomicU64::new(0);
static COM1_PORT: Mutex<Console> = Mutex::new(Console(None));

impl Console {
    fn send(&mut self, byte: u8) {
        let Some(uart) = self.0.as_mut() else {
            DROPPED.fetch_add(1, Ordering::Relaxed);
            return;
        };
        for _ in 0..TRANSMIT_WAIT_LIMIT {
            if uart.try_send_byte(byte).is_ok() {
                return;
            }
        }
        DROPPED.fetch_add(1, Ordering::Relaxed);
    }
}

impl Write for Console {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for byte in s.bytes() {
            if byte == b'\n' {
                self.send(b'\r');
            }
            self.send(byte);
        }
        Ok(())
    }
}

/// Finds and programs COM1 (115200 baud, 8N1, FIFO on, no interrupts). If no
/// UART answers, the log is dropped and counted rather than written nowhere.
pub fn init() {
    // SAFETY: 0x3F8..0x400 are COM1's registers; this module is their only user.
    let Ok(mut uart) = (unsafe { Uart16550::new_port(COM1) }) else {
        return;
    };
    let config = Config {
        baud_rate: BaudRate::Baud115200,
        ..Config::DEFAULT
    };
    if uart.init(config).is_ok() {
        COM1_PORT.lock().0 = Some(uart);
    }
}

/// Characters given up because the transmitter never became ready.
pub fn dropped() -> u64 {
    DROPPED.load(Ordering::Relaxed)
}

#[doc(hidden)]
pub fn _print(args: fmt::Arguments) {
    // Interrupt handlers print too: keep them out while the port is held, so a
    // handler can never spin on a lock its own CPU holds.
    x86_64::instructions::interrupts::without_interrupts(|| {
        crate::log::record(args);
        let _ = COM1_PORT.lock().write_fmt(args);
    });
}

/// Prints to COM1. A panic or fault handler that may have interrupted a print
/// uses [`force_unlock`] first.
#[macro_export]
macro_rules! serial_print {
    ($($arg:tt)*) => { $crate::serial::_print(format_args!($($arg)*)) };
}

#[macro_export]
macro_rules! serial_println {
    () => { $crate::serial_print!("\n") };
    ($($arg:tt)*) => { $crate::serial::_print(format_args!("{}\n", format_args!($($arg)*))) };
}

/// Frees the port's lock for a handler that interrupted a print on this CPU.
///
/// # Safety
///
/// The caller must never return to the code it interrupted (fault handlers,
/// the panic handler), so that the interrupted holder never writes again and
/// no two writers use the port at once.
pub unsafe fn force_unlock() {
    if COM1_PORT.is_locked() {
        // SAFETY: the caller guarantees the interrupted holder never resumes.
        unsafe { COM1_PORT.force_unlock() };
    }
}
