//! Deliberate failures, asked for by a QEMU test through the boot option
//! (`fault=...`, `exit=...`). They prove that each kind of fault is reported and
//! ends in a clean halt. A real PC has no fw_cfg, so it can never take this path.

use crate::platform::qemu;
use protocol::{Exit, Fault};

/// Raises `fault`; only a breakpoint returns.
pub fn raise(fault: Fault) {
    match fault {
        Fault::InvalidOpcode => invalid_opcode(),
        Fault::Page => page_fault(),
        Fault::GeneralProtection => general_protection(),
        Fault::StackOverflow => {
            stack_overflow(0);
        }
        Fault::Divide => divide_error(),
        Fault::Panic => panic!("panic requested by the boot option"),
        Fault::Debug => debug_exception(),
        Fault::MachineCheck => machine_check(),
        Fault::NoHandler => vector_without_handler(),
        Fault::Breakpoint => {
            x86_64::instructions::interrupts::int3();
            crate::serial_println!("breakpoint: resumed");
        }
    }
}

/// Ends QEMU with the status `exit` asks for.
pub fn exit(exit: Exit) {
    qemu::exit(exit);
}

fn invalid_opcode() {
    // SAFETY: `ud2` raises #UD, whose handler reports it and never returns.
    unsafe { core::arch::asm!("ud2") };
}

fn page_fault() {
    // Canonical, but far from anything the bootloader maps.
    let unmapped = 0x0000_7f00_dead_0000 as *const u64;
    // SAFETY: the read faults, and the page-fault handler never returns.
    let _ = unsafe { unmapped.read_volatile() };
}

fn general_protection() {
    // A non-canonical address raises #GP rather than #PF.
    let non_canonical = 0x8000_0000_0000_0000u64 as *const u64;
    // SAFETY: the read faults, and the #GP handler never returns.
    let _ = unsafe { non_canonical.read_volatile() };
}

fn divide_error() {
    // SAFETY: `div` by zero raises #DE, whose handler never returns; the
    // registers it clobbers are declared.
    unsafe {
        core::arch::asm!("xor edx, edx", "xor ecx, ecx", "div ecx", out("eax") _, out("edx") _, out("ecx") _);
    }
}

/// Recurses until it runs into the guard page below the kernel stack; the page
/// fault then cannot be delivered on that stack, which makes it a double fault
/// handled on its own IST stack.
#[allow(unconditional_recursion)]
fn stack_overflow(depth: u64) -> u64 {
    let frame = core::hint::black_box([depth; 64]);
    stack_overflow(depth + 1) + frame[0]
}

fn debug_exception() {
    // `int 1`, not ICEBP (0xF1): QEMU's TCG takes ICEBP for an invalid opcode.
    // SAFETY: enters the debug handler, which reports it and never returns.
    unsafe { core::arch::asm!("int 1") };
}

fn machine_check() {
    // SAFETY: `int 18` enters the machine-check handler (which takes no
    // error code, so the frame is the one it expects); it never returns.
    unsafe { core::arch::asm!("int 18") };
}

fn vector_without_handler() {
    // SAFETY: vector 0x80 has no IDT entry, so the CPU raises #NP with the
    // vector in its error code; that handler never returns.
    unsafe { core::arch::asm!("int 0x80") };
}
