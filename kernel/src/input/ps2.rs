//! The PS/2 keyboard: IRQ 1 moves each scancode byte into a lock-free queue;
//! the render loop drains and decodes it. The render loop never touches the
//! controller, and the interrupt handler never waits for anything.
//!
//! Set-up follows Linux's `i8042_controller_init`: both ports are disabled
//! while the configuration byte is changed, the mouse port stays disabled
//! (and its bytes, flagged by status bit 5, are dropped), the byte written
//! is read back, and the firmware's translation setting is kept unless the
//! keyboard then speaks set 2 untranslated.

use crate::serial_println;
use keyboard::scancode_queue::ScancodeQueue;
use x86_64::instructions::port::Port;

const DATA_PORT: u16 = 0x60;
const STATUS_PORT: u16 = 0x64; // reads: status; writes: controller commands
const STATUS_OUTPUT_FULL: u8 = 0x01;
const STATUS_INPUT_FULL: u8 = 0x02;
/// The byte in the output buffer came from the second (mouse) port.
const STATUS_FROM_MOUSE: u8 = 0x20;
const COMMAND_READ_CONFIG: u8 = 0x20;
const COMMAND_WRITE_CONFIG: u8 = 0x60;
const COMMAND_DISABLE_MOUSE: u8 = 0xA7;
const COMMAND_DISABLE_KEYBOARD: u8 = 0xAD;
const COMMAND_ENABLE_KEYBOARD: u8 = 0xAE;
const CONFIG_PORT1_IRQ: u8 = 0x01;
const CONFIG_PORT2_IRQ: u8 = 0x02;
const CONFIG_PORT1_CLOCK_OFF: u8 = 0x10;
const CONFIG_PORT2_CLOCK_OFF: u8 = 0x20;
const CONFIG_TRANSLATE_TO_SET1: u8 = 0x40;
/// Keyboard command: get or set the scancode set; its answer.
const KEYBOARD_SCANCODE_SET: u8 = 0xF0;
const KEYBOARD_ACK: u8 = 0xFA;
/// Status reads before a controller wait gives up (~100 ms on real hardware).
const CONTROLLER_WAIT_LIMIT: u32 = 100_000;
/// Bytes a stale output buffer may hold before we stop draining it.
const FLUSH_LIMIT: u32 = 64;

pub static SCANCODES: ScancodeQueue = ScancodeQueue::new();

pub fn on_interrupt() {
    // An IRQ 1 can be stale: `init` polls the controller's answers with
    // interrupts off, but the PIC still latches the IRQ they raised. Only a
    // full output buffer holds a byte that nobody has taken yet.
    let status = status();
    if status & STATUS_OUTPUT_FULL == 0 {
        return;
    }
    // SAFETY: the output buffer is full; reading port 0x60 takes that byte and
    // touches nothing else.
    let byte = unsafe { Port::<u8>::new(DATA_PORT).read() };
    // A mouse's byte (the port is disabled, but firmware or a KVM switch may
    // have left one) is no scancode.
    if status & STATUS_FROM_MOUSE == 0 {
        SCANCODES.push(byte);
    }
}

/// Takes a keyboard byte if the controller holds one, with no interrupt: for
/// the fault handler's loop, where IRQs are off.
pub fn poll_byte() -> Option<u8> {
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

/// Leaves the controller with the keyboard port on and IRQ 1 enabled, the
/// mouse port off, and the keyboard's bytes arriving as set 1. Runs before
/// interrupts are enabled.
pub fn init() -> Result<(), &'static str> {
    // Nothing may arrive while the configuration changes.
    write(STATUS_PORT, COMMAND_DISABLE_KEYBOARD)?;
    write(STATUS_PORT, COMMAND_DISABLE_MOUSE)?;
    flush();
    write(STATUS_PORT, COMMAND_READ_CONFIG)?;
    let config = read_data()?;
    let wanted = (config | CONFIG_PORT1_IRQ | CONFIG_PORT2_CLOCK_OFF)
        & !(CONFIG_PORT1_CLOCK_OFF | CONFIG_PORT2_IRQ);
    write_config(wanted)?;
    write(STATUS_PORT, COMMAND_ENABLE_KEYBOARD)?;
    if config & CONFIG_TRANSLATE_TO_SET1 == 0 {
        // The firmware left translation off: the keyboard's own set decides.
        translate_if_set_2(wanted)?;
    }
    Ok(())
}

fn write_config(config: u8) -> Result<(), &'static str> {
    write(STATUS_PORT, COMMAND_WRITE_CONFIG)?;
    write(DATA_PORT, config)?;
    write(STATUS_PORT, COMMAND_READ_CONFIG)?;
    let read_back = read_data()?;
    if read_back != config {
        serial_println!(
            "keyboard: PS/2 configuration byte wrote {:#04x}, read back {:#04x}",
            config,
            read_back
        );
        return Err("PS/2 configuration byte did not stick");
    }
    Ok(())
}

/// Untranslated, set 1 (which some keyboards use) is what the demo wants as
/// it is; set 2, the usual, needs the controller's translation turned on. A
/// keyboard that does not say is taken to use set 2.
fn translate_if_set_2(config: u8) -> Result<(), &'static str> {
    let set = ask_keyboard(&[KEYBOARD_SCANCODE_SET, 0x00]);
    serial_println!(
        "keyboard: the firmware left translation off; the keyboard says scancode set {:?}",
        set
    );
    flush();
    if set == Some(1) {
        return Ok(());
    }
    write_config(config | CONFIG_TRANSLATE_TO_SET1)
}

/// Sends a command and its argument bytes to the keyboard, each answered by
/// an ACK; returns the byte that follows. Interrupts are still off.
fn ask_keyboard(bytes: &[u8]) -> Option<u8> {
    for &byte in bytes {
        write(DATA_PORT, byte).ok()?;
        if read_data().ok()? != KEYBOARD_ACK {
            return None;
        }
    }
    read_data().ok()
}

fn flush() {
    for _ in 0..FLUSH_LIMIT {
        if status() & STATUS_OUTPUT_FULL == 0 {
            break;
        }
        // SAFETY: as in `read_data`; the stale byte is discarded.
        let _ = unsafe { Port::<u8>::new(DATA_PORT).read() };
    }
}
