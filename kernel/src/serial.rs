//! COM1 serial console: the kernel's log, and the test harness's window into it.
//!
//! A small 16550 driver of our own rather than `uart_16550`, because that crate's
//! transmit waits on the Line Status register without a bound, and no wait on a
//! hardware status bit may hang this kernel. If the transmitter never empties (no
//! UART fitted, a stuck bit), characters are dropped and counted instead.

use core::fmt::{self, Write};
use core::sync::atomic::{AtomicU64, Ordering};
use spin::Mutex;
use x86_64::instructions::port::Port;

const COM1: u16 = 0x3F8;
// Register offsets from the base port.
const DATA: u16 = 0; // also Divisor Latch Low while DLAB is set
const INTERRUPT_ENABLE: u16 = 1; // also Divisor Latch High while DLAB is set
const FIFO_CONTROL: u16 = 2;
const LINE_CONTROL: u16 = 3;
const MODEM_CONTROL: u16 = 4;
const LINE_STATUS: u16 = 5;

const LINE_CONTROL_DLAB: u8 = 0x80;
const LINE_CONTROL_8N1: u8 = 0x03;
const FIFO_ENABLE_AND_CLEAR: u8 = 0xC7;
const MODEM_DTR_RTS_OUT2: u8 = 0x0B;
const LINE_STATUS_THR_EMPTY: u8 = 0x20;
/// 115200 baud: the divisor of the UART's 1.8432 MHz / 16 clock.
const DIVISOR_115200: u8 = 1;
/// Reads of Line Status before a character is given up (a character takes ~87 µs
/// at 115200 baud; a port read takes ~1 µs on real hardware).
const TRANSMIT_WAIT_LIMIT: u32 = 100_000;

pub struct Serial {
    base: u16,
}

static DROPPED: AtomicU64 = AtomicU64::new(0);
pub static COM1_PORT: Mutex<Serial> = Mutex::new(Serial { base: COM1 });

impl Serial {
    fn port(&self, offset: u16) -> Port<u8> {
        Port::new(self.base + offset)
    }

    fn init(&mut self) {
        // SAFETY: COM1's registers are I/O ports owned by this driver; programming
        // them has no effect on memory.
        unsafe {
            self.port(INTERRUPT_ENABLE).write(0);
            self.port(LINE_CONTROL).write(LINE_CONTROL_DLAB);
            self.port(DATA).write(DIVISOR_115200);
            self.port(INTERRUPT_ENABLE).write(0);
            self.port(LINE_CONTROL).write(LINE_CONTROL_8N1);
            self.port(FIFO_CONTROL).write(FIFO_ENABLE_AND_CLEAR);
            self.port(MODEM_CONTROL).write(MODEM_DTR_RTS_OUT2);
        }
    }

    fn send(&mut self, byte: u8) {
        for _ in 0..TRANSMIT_WAIT_LIMIT {
            // SAFETY: reading Line Status and writing the transmit register of
            // COM1 touch only the UART.
            unsafe {
                if self.port(LINE_STATUS).read() & LINE_STATUS_THR_EMPTY != 0 {
                    self.port(DATA).write(byte);
                    return;
                }
            }
        }
        DROPPED.fetch_add(1, Ordering::Relaxed);
    }
}

impl Write for Serial {
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

pub fn init() {
    COM1_PORT.lock().init();
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

/// Frees the port's lock for a handler that interrupted a print on this CPU and
/// will never return to it (fault handlers, the panic handler).
pub fn force_unlock() {
    if COM1_PORT.is_locked() {
        // SAFETY: called only on paths that never return to the interrupted
        // holder, so no two writers use the port at once afterwards.
        unsafe { COM1_PORT.force_unlock() };
    }
}
