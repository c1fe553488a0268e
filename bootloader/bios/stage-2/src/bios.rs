//! Patched (see ../../../CHANGES.md, "The boot path on real firmware"): every
//! BIOS call of stage 2 goes through [`call`], after Linux's `intcall`
//! (`arch/x86/boot/bioscall.S`).
//!
//! A 16-bit BIOS owes its caller nothing above bit 15 of any register, and
//! some video BIOSes destroy BP; the compiler keeps values in 32-bit
//! registers and addresses the stack through ESP. So the call saves every
//! 32-bit general register, the flags and the segment registers, loads the
//! caller's [`Registers`], makes the call, hands back every register and the
//! flags the BIOS left, and restores the rest. A BIOS that switched to
//! protected mode and back (USB and AHCI disk emulation does) may also have
//! left DS with a 64 KiB limit, so [`call`] goes back into unreal mode
//! after each call.

use core::arch::global_asm;

/// The registers a BIOS call takes and gives back.
#[repr(C)]
#[derive(Clone, Copy, Default, Debug)]
pub struct Registers {
    pub eax: u32,
    pub ebx: u32,
    pub ecx: u32,
    pub edx: u32,
    pub esi: u32,
    pub edi: u32,
    pub ebp: u32,
    /// Given back only: the flags as the BIOS returned them.
    pub eflags: u32,
    pub ds: u16,
    pub es: u16,
}

impl Registers {
    /// The carry flag, which most BIOS calls set on failure.
    pub fn carry(&self) -> bool {
        self.eflags & 1 != 0
    }

    /// AH.
    pub fn ah(&self) -> u8 {
        (self.eax >> 8) as u8
    }
}

/// A real-mode far pointer to a linear address below 1 MiB: the segment is
/// the address / 16 and the offset the rest, so that a buffer the BIOS is
/// given is reached whatever 64 KiB it lies in.
pub fn far_pointer(linear: u32) -> (u16, u16) {
    // Opaque to the optimiser: folded into a static's address, the offset
    // would become a 16-bit relocation of the symbol, which the linker
    // refuses once the static lies above 64 KiB.
    let linear = core::hint::black_box(linear);
    ((linear >> 4) as u16, (linear & 0xf) as u16)
}

unsafe extern "C" {
    fn bios_call(interrupt: u32, registers: *mut Registers);
}

/// Calls BIOS interrupt `interrupt` with `registers` and returns what it gave
/// back. Every register not in [`Registers`] is as before; DS keeps its
/// 4 GiB limit.
pub fn call(interrupt: u8, registers: Registers) -> Registers {
    // On the stack, which lies below 0x7C00: `bios_call` reaches it with DS
    // = 0 whatever limit the BIOS left on DS.
    let mut frame = registers;
    // SAFETY: `bios_call` saves and restores every register but those it
    // hands back through `frame`, and writes nothing but `frame`; what the
    // BIOS writes is what the caller asked it to.
    unsafe { bios_call(u32::from(interrupt), &mut frame) };
    crate::protected_mode::enter_unreal_mode();
    frame
}

// The frame on the stack while the BIOS runs (ESP upwards): the registers'
// address, EFLAGS, GS, FS, ES, DS, the eight of `pushad`, the return address,
// then the two arguments. The interrupt number is written into the `int`
// instruction itself, as Linux does; the jump after the write makes the CPU
// fetch the changed byte.
global_asm!(
    r#"
    .section .text.bios_call, "ax"
    .global bios_call
bios_call:
    mov al, [esp + 4]
    cmp al, byte ptr [bios_call_int + 1]
    je 1f
    mov byte ptr [bios_call_int + 1], al
    jmp 1f
1:
    pushad
    push ds
    push es
    push fs
    push gs
    pushfd
    mov ebx, [esp + 52]
    push ebx

    mov ax, [ebx + 34]
    mov es, ax
    push word ptr [ebx + 32]
    mov eax, [ebx]
    mov ecx, [ebx + 8]
    mov edx, [ebx + 12]
    mov esi, [ebx + 16]
    mov edi, [ebx + 20]
    mov ebp, [ebx + 24]
    mov ebx, [ebx + 4]
    pop ds
bios_call_int:
    int 0

    movzx esp, sp
    pushfd
    push ds
    push es
    push ebx
    push eax
    xor ax, ax
    mov ds, ax
    mov ebx, [esp + 16]
    pop eax
    mov [ebx], eax
    pop eax
    mov [ebx + 4], eax
    mov [ebx + 8], ecx
    mov [ebx + 12], edx
    mov [ebx + 16], esi
    mov [ebx + 20], edi
    mov [ebx + 24], ebp
    pop ax
    mov [ebx + 34], ax
    pop ax
    mov [ebx + 32], ax
    pop eax
    mov [ebx + 28], eax

    pop ebx
    popfd
    pop gs
    pop fs
    pop es
    pop ds
    popad
    ret
"#
);
