//! The trampoline: a few hundred bytes of code that leave long mode, make one
//! real-mode `int 0x10`, and come back, with everything the kernel relies on
//! restored (GDT, IDT, CR0/CR3/CR4, EFER, segment registers, stack).
//!
//! It is assembled into the kernel image but only ever runs from a copy in
//! low memory (`LowArea`), identity-mapped, because the moment paging goes off
//! the CPU fetches by physical address, and real mode reaches only the first
//! MiB. The copy's first `CODE` bytes are its data block, which the Rust side
//! fills in before the call (the GDT, the real-mode segment, the registers)
//! and reads back after.
//!
//! The way out and back:
//! 1. 64-bit: save the kernel's state; load the trampoline's GDT; far return
//!    into a 32-bit code segment (compatibility mode).
//! 2. 32-bit: paging off (long mode ends), EFER.LME off; far jump into a 16-bit
//!    protected-mode segment whose base is the area.
//! 3. 16-bit protected mode: 64 KiB data segments, a stack in the area;
//!    protection off; far return into real mode at the area's segment.
//! 4. Real mode: the real-mode interrupt table (0..0x3FF), with the
//!    watchdog's handler in IRQ 0's vector (08h); the caller's registers;
//!    interrupts on, as a BIOS caller has them (the Rust side has put the
//!    PICs and the PIT as the BIOS expects them: `bios_world`); `int 0x10`;
//!    the results saved; the BIOS's IRQ 0 vector put back.
//!    The watchdog chains each tick to the BIOS's own handler and counts it;
//!    when the ticks run out it abandons the call: the trampoline's own
//!    stack again, `TIMED_OUT` set, and on from the return of `int 0x10`.
//! 5. Back: protection on, 32-bit code; CR4, CR3, EFER, CR0 as saved (paging
//!    on: compatibility mode); 64-bit code; the kernel's GDT, IDT, stack and
//!    selectors; return to the caller.

use core::arch::global_asm;

// The data block's layout, the GDT's selectors and its descriptors are
// pure, so they live in `memory::trampoline` and are tested on the host.
pub use memory::trampoline::{descriptors, layout, selector};

extern "C" {
    static bios_trampoline_start: u8;
    static bios_trampoline_entry: u8;
    static bios_trampoline_end: u8;
}

/// The trampoline as assembled: copy it to the area's start.
pub fn image() -> &'static [u8] {
    let start = &raw const bios_trampoline_start;
    let end = &raw const bios_trampoline_end;
    // SAFETY: both symbols are labels in the one `global_asm!` block below,
    // start before end, and the bytes between are read-only data of the image.
    unsafe { core::slice::from_raw_parts(start, end.offset_from(start) as usize) }
}

/// Where the 64-bit entry point is, from the area's start.
pub fn entry_offset() -> usize {
    let start = &raw const bios_trampoline_start;
    let entry = &raw const bios_trampoline_entry;
    // SAFETY: both are labels in the same assembled block.
    unsafe { entry.offset_from(start) as usize }
}

global_asm!(
    r#"
    .pushsection .rodata.bios_trampoline, "a"
    .balign 16
    .global bios_trampoline_start
bios_trampoline_start:
    .skip {code}

    .code64
    .global bios_trampoline_entry
bios_trampoline_entry:
    // rdi: the area's address, identity-mapped. Interrupts are off.
    push %rbx
    push %rbp
    push %r12
    push %r13
    push %r14
    push %r15
    mov %rdi, %rbx
    sgdt {kernel_gdtr}(%rbx)
    sidt {kernel_idtr}(%rbx)
    mov %cr0, %rax
    mov %rax, {cr0}(%rbx)
    mov %cr3, %rax
    mov %rax, {cr3}(%rbx)
    mov %cr4, %rax
    mov %rax, {cr4}(%rbx)
    mov $0xC0000080, %ecx
    rdmsr
    mov %eax, {efer}(%rbx)
    mov %edx, {efer}+4(%rbx)
    mov %rsp, {rsp}(%rbx)
    movw %cs, {selectors}+0(%rbx)
    movw %ss, {selectors}+2(%rbx)
    movw %ds, {selectors}+4(%rbx)
    movw %es, {selectors}+6(%rbx)
    movw %fs, {selectors}+8(%rbx)
    movw %gs, {selectors}+10(%rbx)
    lgdt {gdtr}(%rbx)
    pushq ${code_32}
    lea (2f - bios_trampoline_start)(%rbx), %rax
    push %rax
    lretq

    .code32
2:  // Compatibility mode. No stack until step 3 sets one in the area.
    mov ${data_32}, %ax
    mov %ax, %ds
    mov %ax, %es
    mov %ax, %ss
    mov %cr0, %eax
    and $0x7FFFFFFF, %eax
    mov %eax, %cr0
    // Paging is off: plain 32-bit protected mode. Long mode off too.
    mov $0xC0000080, %ecx
    rdmsr
    and $0xFFFFFEFF, %eax
    wrmsr
    ljmp ${code_16}, $(3f - bios_trampoline_start)

    .code16
3:  mov ${data_16}, %ax
    mov %ax, %ds
    mov %ax, %es
    mov %ax, %fs
    mov %ax, %gs
    mov %ax, %ss
    mov ${stack_top}, %esp
    mov %cr0, %eax
    and $0xFFFFFFFE, %eax
    mov %eax, %cr0
    // Real mode: reload CS with the area's segment.
    pushw {real_segment}
    pushw $(4f - bios_trampoline_start)
    lretw

4:  mov %cs, %ax
    mov %ax, %ds
    mov %ax, %ss
    mov ${stack_top}, %esp
    xor %ax, %ax
    mov %ax, %fs
    mov %ax, %gs
    lidt {real_idtr}
    // IRQ 0 reaches the watchdog first while the BIOS runs.
    movl %fs:0x20, %eax              // vector 08h: 8 * 4
    movl %eax, {bios_timer}
    movw $(9f - bios_trampoline_start), %fs:0x20
    movw %cs, %fs:0x22
    movw $0, {timed_out}
    mov {es}, %ax
    mov %ax, %es
    movl {registers}+0, %eax
    movl {registers}+4, %ebx
    movl {registers}+8, %ecx
    movl {registers}+12, %edx
    movl {registers}+16, %esi
    movl {registers}+20, %edi
    movl {registers}+24, %ebp
    pushw {ds}
    popw %ds
    sti
    int $0x10
8:  cli
    pushfw
    pushw %ds
    pushl %eax
    mov %cs, %ax
    mov %ax, %ds
    popl %eax
    movl %eax, {registers}+0
    movl %ebx, {registers}+4
    movl %ecx, {registers}+8
    movl %edx, {registers}+12
    movl %esi, {registers}+16
    movl %edi, {registers}+20
    movl %ebp, {registers}+24
    popw {ds}
    popw {flags}
    mov %es, %ax
    mov %ax, {es}
    cld
    xor %ax, %ax
    mov %ax, %fs
    movl {bios_timer}, %eax
    movl %eax, %fs:0x20

    // Back to protected mode, then long mode.
    xor %ebx, %ebx
    mov %cs, %bx
    shl $4, %ebx
    lgdtl {gdtr}
    mov %cr0, %eax
    or $1, %eax
    mov %eax, %cr0
    pushl ${code_32}
    leal (5f - bios_trampoline_start)(%ebx), %eax
    pushl %eax
    lretl

9:  // The watchdog, on IRQ 0 in real mode: the BIOS's handler first, as
    // the interrupt would have called it (it counts the BIOS tick and
    // acknowledges the PIC), then one tick less.
    pushfw
    lcallw *%cs:{bios_timer}
    decw %cs:{watchdog_ticks}
    jz 10f
    iretw
10: // Out of ticks: abandon the call where it is, on our own stack.
    cli
    mov %cs, %ax
    mov %ax, %ss
    mov ${stack_top}, %esp
    movw $1, %cs:{timed_out}
    jmp 8b

    .code32
5:  mov ${data_32}, %ax
    mov %ax, %ds
    mov %ax, %es
    mov %ax, %ss
    leal {stack_top}(%ebx), %esp
    mov {cr4}(%ebx), %eax
    mov %eax, %cr4
    mov {cr3}(%ebx), %eax
    mov %eax, %cr3
    mov $0xC0000080, %ecx
    mov {efer}(%ebx), %eax
    and $0xFFFFFBFF, %eax
    mov {efer}+4(%ebx), %edx
    wrmsr
    mov {cr0}(%ebx), %eax
    mov %eax, %cr0
    // Paging on with EFER.LME: compatibility mode. Into 64-bit code.
    pushl ${code_64}
    leal (6f - bios_trampoline_start)(%ebx), %eax
    pushl %eax
    lretl

    .code64
6:  mov %ebx, %ebx
    lgdt {kernel_gdtr}(%rbx)
    lidt {kernel_idtr}(%rbx)
    mov {rsp}(%rbx), %rsp
    movw {selectors}+2(%rbx), %ss
    movw {selectors}+4(%rbx), %ds
    movw {selectors}+6(%rbx), %es
    movw {selectors}+8(%rbx), %fs
    movw {selectors}+10(%rbx), %gs
    movzwq {selectors}+0(%rbx), %rax
    push %rax
    lea 7f(%rip), %rax
    push %rax
    lretq
7:  pop %r15
    pop %r14
    pop %r13
    pop %r12
    pop %rbp
    pop %rbx
    ret

    .global bios_trampoline_end
bios_trampoline_end:
    .popsection
"#,
    code = const layout::CODE,
    kernel_gdtr = const layout::KERNEL_GDTR,
    kernel_idtr = const layout::KERNEL_IDTR,
    gdtr = const layout::GDTR,
    real_idtr = const layout::REAL_IDTR,
    cr0 = const layout::CR0,
    cr3 = const layout::CR3,
    cr4 = const layout::CR4,
    efer = const layout::EFER,
    rsp = const layout::RSP,
    selectors = const layout::SELECTORS,
    real_segment = const layout::REAL_SEGMENT,
    registers = const layout::REGISTERS,
    ds = const layout::DS,
    es = const layout::ES,
    flags = const layout::FLAGS,
    bios_timer = const layout::BIOS_TIMER_VECTOR,
    watchdog_ticks = const layout::WATCHDOG_TICKS,
    timed_out = const layout::TIMED_OUT,
    stack_top = const layout::STACK_TOP,
    code_64 = const selector::CODE_64,
    code_32 = const selector::CODE_32,
    data_32 = const selector::DATA_32,
    code_16 = const selector::CODE_16,
    data_16 = const selector::DATA_16,
    options(att_syntax)
);
