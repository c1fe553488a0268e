//! The end of the line: every CPU exception that cannot be resumed, and every
//! panic, is reported here on serial and the CPU halts for good. Halting (rather
//! than returning or rebooting) keeps the report readable and avoids a triple
//! fault's reboot loop.

use x86_64::structures::idt::InterruptStackFrame;

pub fn halt_with(kind: &str, frame: &InterruptStackFrame, error: Option<u64>, address: Option<u64>) -> ! {
    crate::serial::force_unlock();
    crate::serial_println!("EXCEPTION: {}", kind);
    crate::serial_println!(
        "  rip={:#x} cs={:#x} rflags={:#x} rsp={:#x} ss={:#x}",
        frame.instruction_pointer.as_u64(),
        frame.code_segment.0,
        frame.cpu_flags.bits(),
        frame.stack_pointer.as_u64(),
        frame.stack_segment.0
    );
    if let Some(error) = error {
        crate::serial_println!("  error code={:#x}", error);
    }
    if let Some(address) = address {
        crate::serial_println!("  address={:#x}", address);
    }
    halt_forever()
}

/// Stops the CPU with interrupts off; only a reset or power-off leaves.
pub fn halt_forever() -> ! {
    crate::serial_println!("HALTED");
    x86_64::instructions::interrupts::disable();
    loop {
        x86_64::instructions::hlt();
    }
}
