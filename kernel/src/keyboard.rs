//! The PS/2 keyboard: IRQ 1 moves each scancode byte into a lock-free queue;
//! the render loop drains and decodes it. The render loop never touches the
//! controller, and the interrupt handler never waits for anything.

use demo::queue::ScancodeQueue;
use x86_64::instructions::port::Port;

const DATA_PORT: u16 = 0x60;
const STATUS_PORT: u16 = 0x64; // reads: status; writes: controller commands
const STATUS_OUTPUT_FULL: u8 = 0x01;
const STATUS_INPUT_FULL: u8 = 0x02;
const COMMAND_READ_CONFIG: u8 = 0x20;
const COMMAND_WRITE_CONFIG: u8 = 0x60;
const CONFIG_PORT1_IRQ: u8 = 0x01;
const CONFIG_PORT1_CLOCK_OFF: u8 = 0x10;
const CONFIG_TRANSLATE_TO_SET1: u8 = 0x40;
/// Status reads before a controller wait gives up (~100 ms on real hardware).
const CONTROLLER_WAIT_LIMIT: u32 = 100_000;
/// Bytes a stale output buffer may hold before we stop draining it.
const FLUSH_LIMIT: u32 = 64;

pub static SCANCODES: ScancodeQueue = ScancodeQueue::new();

pub fn on_interrupt() {
    // An IRQ 1 can be stale: `init` polls the controller's answers with
    // interrupts off, but the PIC still latches the IRQ they raised. Only a
    // full output buffer holds a byte that nobody has taken yet.
    if status() & STATUS_OUTPUT_FULL == 0 {
        return;
    }
    // SAFETY: the output buffer is full; reading port 0x60 takes that byte and
    // touches nothing else.
    let byte = unsafe { Port::<u8>::new(DATA_PORT).read() };
    SCANCODES.push(byte);
}

/// Takes a keyboard byte if the controller holds one, with no interrupt: for
/// the fault handler's loop, where IRQs are off.
pub fn poll_byte() -> Option<u8> {
    const STATUS_FROM_MOUSE: u8 = 0x20;
    let status = status();
    if status & STATUS_OUTPUT_FULL == 0 || status == 0xFF {
        return None;
    }
    // SAFETY: the output buffer is full; reading port 0x60 takes that byte.
    let byte = unsafe { Port::<u8>::new(DATA_PORT).read() };
    (status & STATUS_FROM_MOUSE == 0).then_some(byte)
}

fn status() -> u8 {
    // SAFETY: reading the 8042 status register has no side effects.
    unsafe { Port::<u8>::new(STATUS_PORT).read() }
}

fn wait_until(ready: impl Fn(u8) -> bool) -> Result<(), &'static str> {
    for _ in 0..CONTROLLER_WAIT_LIMIT {
        if ready(status()) {
            return Ok(());
        }
    }
    Err("PS/2 controller did not answer")
}

fn write(port: u16, byte: u8) -> Result<(), &'static str> {
    wait_until(|s| s & STATUS_INPUT_FULL == 0)?;
    // SAFETY: the controller is ready for a byte on its command or data port.
    unsafe { Port::<u8>::new(port).write(byte) };
    Ok(())
}

fn read_data() -> Result<u8, &'static str> {
    wait_until(|s| s & STATUS_OUTPUT_FULL != 0)?;
    // SAFETY: the output buffer is full, so the read takes exactly that byte.
    Ok(unsafe { Port::<u8>::new(DATA_PORT).read() })
}

/// Leaves the controller translating to scancode set 1 with IRQ 1 on, whatever
/// the firmware left. Runs before interrupts are enabled.
pub fn init() -> Result<(), &'static str> {
    for _ in 0..FLUSH_LIMIT {
        if status() & STATUS_OUTPUT_FULL == 0 {
            break;
        }
        // SAFETY: as in `read_data`; the stale byte is discarded.
        let _ = unsafe { Port::<u8>::new(DATA_PORT).read() };
    }
    write(STATUS_PORT, COMMAND_READ_CONFIG)?;
    let config = read_data()?;
    let wanted = (config | CONFIG_PORT1_IRQ | CONFIG_TRANSLATE_TO_SET1) & !CONFIG_PORT1_CLOCK_OFF;
    if wanted != config {
        write(STATUS_PORT, COMMAND_WRITE_CONFIG)?;
        write(DATA_PORT, wanted)?;
    }
    Ok(())
}
