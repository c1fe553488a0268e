//! COM1 (0x3F8), polled: each byte waits for the transmitter a bounded
//! number of polls (as `bios/stage-2/src/serial.rs`), so a PC without a UART
//! loses the text, never the boot.

use core::{arch::asm, fmt};

const COM1: u16 = 0x3F8;
/// Polls of the line-status register per byte before giving up on it.
const POLLS_PER_BYTE: u32 = 100_000;

fn outb(port: u16, value: u8) {
    // SAFETY: COM1's registers; writing them has no effect on memory.
    unsafe { asm!("out dx, al", in("dx") port, in("al") value, options(nomem, nostack)) };
}

fn inb(port: u16) -> u8 {
    let value: u8;
    // SAFETY: reading COM1's line status has no effect on memory.
    unsafe { asm!("in al, dx", in("dx") port, out("al") value, options(nomem, nostack)) };
    value
}

/// 115200 baud, 8 data bits, no parity, one stop bit, FIFOs on, no
/// interrupts (as OVMF and the kernel set it).
pub fn init() {
    outb(COM1 + 1, 0x00);
    outb(COM1 + 3, 0x80);
    outb(COM1, 0x01);
    outb(COM1 + 1, 0x00);
    outb(COM1 + 3, 0x03);
    outb(COM1 + 2, 0xC7);
    outb(COM1 + 4, 0x03);
}

fn write_byte(byte: u8) {
    for _ in 0..POLLS_PER_BYTE {
        if inb(COM1 + 5) & 0x20 != 0 {
            break;
        }
    }
    outb(COM1, byte);
}

/// COM1 as a text sink (LF becomes CR LF).
pub struct Com1;

impl fmt::Write for Com1 {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for byte in s.bytes() {
            if byte == b'\n' {
                write_byte(b'\r');
            }
            write_byte(byte);
        }
        Ok(())
    }
}
