#![no_std]
#![no_main]
#![deny(unsafe_op_in_unsafe_fn)]

use crate::screen::Writer;
use bootloader_x86_64_bios_common::{BiosInfo, Region, hlt, serial::Com1};
use core::{arch::asm, fmt, fmt::Write as _, ptr};
use loader_logic::cpu;
use loader_logic::file_hash::{self, HashSlot};

mod gdt;
mod paging;
mod screen;

#[unsafe(no_mangle)]
#[unsafe(link_section = ".start")]
pub extern "C" fn _start(info: &mut BiosInfo) {
    // Patched (../../CHANGES.md): the page tables below are statics in .bss,
    // past the end of this file: zero them before anything else.
    // SAFETY: first thing, in flat protected mode; no static used yet.
    unsafe { bootloader_x86_64_bios_common::zero_bss() };
    screen::init(info.framebuffer);
    // Writer.clear_screen();
    writeln!(Writer, "Third Stage ({info:x?})").unwrap();
    // Patched (issue 61): before CR4.PAE and EFER.LME are set below, which
    // on a 32-bit CPU fault and reset the PC in a loop, say why not.
    check_cpu();
    // Patched (issue 48): nothing of stage 4 or the kernel runs unchecked.
    // The time it takes is said in TSC ticks: under QEMU's `-icount
    // shift=0` one tick is one instruction, so the figure repeats.
    let started = rdtsc();
    check_hash(file_hash::File::Stage4, info.stage_4);
    check_hash(file_hash::File::Kernel, info.kernel);
    let _ = writeln!(
        Com1,
        "loader: stage 4 and kernel SHA-256 match the loader's (BIOS stage 3, {} TSC ticks)",
        rdtsc().wrapping_sub(started)
    );

    // set up identity mapping, enable paging, and switch CPU into long
    // mode (32-bit compatibility mode)
    paging::init();

    gdt::LONG_MODE_GDT.load();
    enter_long_mode_and_jump_to_stage_4(info);

    loop {
        hlt();
    }
}

/// Patched (issue 48): the SHA-256 of stage 4 and of the kernel file,
/// written into this slot of stage 3's file by the image build
/// (`bootloader/src/lib.rs`, `loader_logic::file_hash`). Stage 2 read both
/// files through the BIOS, which may hand back wrong bytes as a good read,
/// from a stick that may rot.
static FILE_HASHES: HashSlot = HashSlot::EMPTY;

/// Patched (issue 48): `file`, where stage 2 put it, against
/// [`FILE_HASHES`]. Here, not in stage 2: SHA-256 in 16-bit code pushed
/// stage 2 past the 64 KiB real mode reaches (../../CHANGES.md).
fn check_hash(file: file_hash::File, region: Region) {
    // SAFETY: a read of a static of plain bytes. Volatile, so that the
    // compiler cannot fold in the zeros it was built with: the image build
    // writes the hashes into the file.
    let expected = unsafe { ptr::read_volatile(&raw const FILE_HASHES) };
    // SAFETY: stage 2 copied the file to `region` (below 4 GiB, flat
    // segments, paging off), and nothing writes there while it is read.
    let bytes = unsafe {
        core::slice::from_raw_parts(region.start as usize as *const u8, region.len as usize)
    };
    if let Err(mismatch) = expected.check(file, file_hash::sha256(bytes)) {
        stop(format_args!("{mismatch}"));
    }
}

/// Patched (issue 61): stops, naming the CPU, unless it has CPUID and what
/// the kernel needs of it (`loader_logic::cpu`: long mode, PAE, SSE2).
fn check_cpu() {
    if !has_cpuid() {
        stop(format_args!("loader: stopped: {}", cpu::NO_CPUID));
    }
    if let Err(refusal) = cpu::check(cpu::CpuidReadings::read()) {
        stop(format_args!("loader: stopped: {refusal}"));
    }
}

/// Patched (issue 61): whether CPUID exists, by the test the SDM gives: a
/// CPU that has it lets EFLAGS.ID (bit 21) be flipped. A 486 without it
/// would take CPUID for an invalid opcode.
fn has_cpuid() -> bool {
    const EFLAGS_ID: u32 = 1 << 21;
    let (before, after): (u32, u32);
    // SAFETY: only EFLAGS.ID is flipped and then put back as it was; the
    // stack is balanced (two pushes, two pops).
    unsafe {
        asm!(
            "pushfd",
            "pop {before:e}",
            "mov {after:e}, {before:e}",
            "xor {after:e}, {id}",
            "push {after:e}",
            "popfd",
            "pushfd",
            "pop {after:e}",
            "push {before:e}",
            "popfd",
            before = out(reg) before,
            after = out(reg) after,
            id = const EFLAGS_ID,
        );
    }
    (before ^ after) & EFLAGS_ID != 0
}

/// Patched (issue 48): the time-stamp counter, for the cost of the check.
fn rdtsc() -> u64 {
    let (low, high): (u32, u32);
    // SAFETY: reads the time-stamp counter; no memory is touched.
    unsafe { asm!("rdtsc", out("eax") low, out("edx") high, options(nomem, nostack)) };
    (u64::from(high) << 32) | u64::from(low)
}

/// Patched (issue 48): says `why` on the screen (the VESA framebuffer, or
/// the VGA text screen when stage 2 set no mode) and COM1, then halts for
/// good with interrupts off: no reset, nothing more runs.
fn stop(why: fmt::Arguments) -> ! {
    if screen::has_framebuffer() {
        let _ = writeln!(Writer, "{why}");
    } else {
        let _ = writeln!(screen::VgaText, "{why}");
    }
    let _ = writeln!(Com1, "{why}");
    loop {
        // SAFETY: halting with interrupts off stops this CPU; nothing follows.
        unsafe { asm!("cli", "hlt") };
    }
}

#[unsafe(no_mangle)]
pub fn enter_long_mode_and_jump_to_stage_4(info: &mut BiosInfo) {
    let _ = writeln!(Writer, "Paging init done, jumping to stage 4");
    unsafe {
        asm!(
            // align the stack
            "and esp, 0xffffff00",
            // push arguments (extended to 64 bit)
            "push 0",
            "push {info:e}",
            // push entry point address (extended to 64 bit)
            "push 0",
            "push {entry_point:e}",
            info = in(reg) info as *const _ as u32,
            entry_point = in(reg) info.stage_4.start as u32,
        );
        asm!("ljmp $0x8, $2f", "2:", options(att_syntax));
        asm!(
            ".code64",

            // reload segment registers
            "mov {0}, 0x10",
            "mov ds, {0}",
            "mov es, {0}",
            "mov ss, {0}",

            // jump to 4th stage
            "pop rax",
            "pop rdi",
            "call rax",

            // enter endless loop in case 4th stage returns
            "2:",
            "jmp 2b",
            out(reg) _,
            out("rax") _,
            out("rdi") _,
        );
    }
}

/// Patched (issue 66): on COM1 too (and on the VGA text screen without a
/// framebuffer), with the file and line, then halted for good.
#[panic_handler]
#[cfg(not(test))]
pub fn panic(info: &core::panic::PanicInfo) -> ! {
    stop(format_args!("loader: PANIC: {info}"))
}
