//! Floating point in hardware, switched on before any Rust code runs.
//!
//! The kernel's target (`kernel/x86_64-modex-kernel.json`) is
//! `x86_64-unknown-none` with SSE2 instead of soft-float, so the pipeline's
//! `f32`/`f64` arithmetic is one instruction each rather than a library call.
//! Every x86-64 CPU has SSE2, but its instructions raise #UD until the system
//! says it saves their state (CR4.OSFXSR). UEFI firmware hands over with that
//! set; a BIOS boot through the bootloader's stages does not, and the compiler
//! may use SSE registers anywhere, even to copy a struct. So the ELF entry
//! point is `kernel_entry` below (the linker is told so in `build.rs`), not
//! bootloader_api's `_start`: it turns SSE on, gives x87 and MXCSR their reset
//! state (round to nearest, every exception masked: the same IEEE results as
//! the host's software VGA), and jumps to `_start` with the boot-info pointer
//! still in RDI.
//!
//! The interrupted code's registers: every handler is `extern
//! "x86-interrupt"`, for which the compiler saves and restores each register
//! the handler or anything it calls may change, XMM0-15 included (see the
//! `movaps` pairs in `objdump -d` of `keyboard_irq`). Nothing in the kernel
//! changes MXCSR or the x87 control word after this, and the fault handlers
//! never return. The video BIOS calls (`bios/`) declare the C ABI's registers
//! clobbered and keep MXCSR and the x87 control word across the call.

/// CR0.MP: WAIT/FWAIT honour TS (with EM clear, the setting for SSE).
const CR0_MONITOR_COPROCESSOR: u64 = 1 << 1;
/// CR0.EM: x87 emulation; set, every SSE instruction is #UD.
const CR0_EMULATION: u64 = 1 << 2;
/// CR0.TS: task switched; set, the first SSE instruction is #NM.
const CR0_TASK_SWITCHED: u64 = 1 << 3;
/// CR4.OSFXSR | CR4.OSXMMEXCPT: the system saves SSE state with FXSAVE and
/// handles SIMD exceptions (#XM rather than #UD, were one unmasked).
const CR4_SSE: u64 = (1 << 9) | (1 << 10);
/// MXCSR at reset: all six exceptions masked, round to nearest, no
/// flush-to-zero, so denormals behave as IEEE 754 says (as on the host).
#[no_mangle]
static KERNEL_MXCSR: u32 = 0x1F80;

// SAFETY (global_asm has no unsafe block, but the reasoning is the same): this
// runs first, on the bootloader's stack, with interrupts off; it changes only
// RAX, control-register bits that concern the FPU and SSE, and the FPU/SSE
// state that no code has used yet; RDI, the argument to `_start`, is kept.
core::arch::global_asm!(
    ".global kernel_entry",
    "kernel_entry:",
    "mov rax, cr0",
    "and rax, {clear_cr0}",
    "or rax, {set_cr0}",
    "mov cr0, rax",
    "mov rax, cr4",
    "or rax, {set_cr4}",
    "mov cr4, rax",
    "fninit",
    "ldmxcsr [rip + KERNEL_MXCSR]",
    "jmp _start",
    clear_cr0 = const !(CR0_EMULATION | CR0_TASK_SWITCHED) as i64,
    set_cr0 = const CR0_MONITOR_COPROCESSOR,
    set_cr4 = const CR4_SSE,
);
