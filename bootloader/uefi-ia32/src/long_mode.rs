//! The switch from the firmware's 32-bit protected mode to long mode, and the
//! jump to stage 4, as BIOS stage 3 does it (`bios/stage-3/src/paging.rs`,
//! `main.rs`): the first 10 GiB identity-mapped with 2 MiB pages, PAE,
//! EFER.LME, paging, a far jump to a 64-bit code segment, then stage 4's entry
//! called with the `BiosInfo` in RDI. Everything the switch reads lives in
//! pages this loader allocated as loader data (kept out of stage 4's frame
//! allocator by the memory map, see `loader_logic::uefi_map`).

use core::arch::asm;

/// Identity-mapped by the tables built here, as stage 3 maps it.
const MAPPED_GIB: usize = 10;
/// Pages the tables take: one level 4, one level 3, a level 2 per GiB.
pub const TABLE_PAGES: usize = 2 + MAPPED_GIB;

const PRESENT_WRITABLE: u64 = 0b11;
const HUGE: u64 = 1 << 7;

/// Fills `tables` (the [`TABLE_PAGES`] pages at physical address `base`,
/// identity-mapped while boot services run) and returns the level 4 table's
/// address, for CR3.
pub fn build_tables(tables: &mut [[u64; 512]], base: u32) -> u32 {
    assert_eq!(tables.len(), TABLE_PAGES);
    let address = |index: usize| u64::from(base) + 4096 * index as u64;
    for table in tables.iter_mut() {
        *table = [0; 512];
    }
    tables[0][0] = address(1) | PRESENT_WRITABLE;
    for gib in 0..MAPPED_GIB {
        tables[1][gib] = address(2 + gib) | PRESENT_WRITABLE;
        for (entry, slot) in tables[2 + gib].iter_mut().enumerate() {
            let start = (gib as u64) << 30 | (entry as u64) << 21;
            *slot = start | PRESENT_WRITABLE | HUGE;
        }
    }
    base
}

/// A long-mode GDT: null, 64-bit code at 0x08, data at 0x10 (stage 3's).
pub const GDT: [u64; 3] = {
    let common = (1 << 44) | (1 << 47) | (1 << 41) | (1 << 40);
    [0, common | (1 << 43) | (1 << 53), common]
};

/// What the switch reads, at fixed offsets (the assembly below names them).
#[repr(C)]
pub struct Handoff {
    _pad: u16,
    /// The GDTR's limit, then its base (offset 2, so the base is aligned).
    pub gdt_limit: u16,
    pub gdt_base: u32,
    /// CR3: the level 4 table (offset 8).
    pub pml4: u32,
    /// The stack for stage 4, 16-byte aligned (offset 12).
    pub stack_top: u32,
    /// Stage 4's entry point (offset 16).
    pub entry: u32,
    /// The `BiosInfo` handed to stage 4 in RDI (offset 20).
    pub info: u32,
}

impl Handoff {
    pub fn new(gdt_base: u32, pml4: u32, stack_top: u32, entry: u32, info: u32) -> Self {
        Self {
            _pad: 0,
            gdt_limit: (GDT.len() * 8 - 1) as u16,
            gdt_base,
            pml4,
            stack_top: stack_top & !0xF,
            entry,
            info,
        }
    }
}

const _: () = {
    assert!(core::mem::offset_of!(Handoff, gdt_limit) == 2);
    assert!(core::mem::offset_of!(Handoff, pml4) == 8);
    assert!(core::mem::offset_of!(Handoff, stack_top) == 12);
    assert!(core::mem::offset_of!(Handoff, entry) == 16);
    assert!(core::mem::offset_of!(Handoff, info) == 20);
};

/// Interrupts off, paging off (if the firmware had it on), PAE, the tables,
/// EFER.LME, paging on: compatibility mode; the far jump to selector 0x08
/// enters 64-bit mode, where the data selectors are reloaded, RSP set and
/// stage 4 called with the `BiosInfo` in RDI. Stage 4 never returns; if it
/// did, the CPU halts with interrupts off.
///
/// # Safety
///
/// Boot services must have been left; `handoff` and everything it points at
/// must be valid, identity-mapped below 4 GiB and out of stage 4's allocator.
pub unsafe fn enter_stage_4(handoff: *const Handoff) -> ! {
    // SAFETY: the caller's contract. The code runs identity-mapped (UEFI
    // runs with physical = virtual, and the new tables map the same), so
    // turning paging off and on keeps the next instruction where it is. The
    // upper halves of the registers are undefined after the mode switch:
    // each 64-bit value is made by a 32-bit move, which zero-extends.
    unsafe {
        asm!(
            "cli",
            "lgdt [ebx + 2]",
            "mov eax, cr0",
            "and eax, 0x7fffffff",
            "mov cr0, eax",
            "mov eax, cr4",
            "or eax, 0x20",
            "mov cr4, eax",
            "mov eax, [ebx + 8]",
            "mov cr3, eax",
            "mov ecx, 0xC0000080",
            "rdmsr",
            "or eax, 0x100",
            "wrmsr",
            "mov eax, cr0",
            "or eax, 0x80000000",
            "mov cr0, eax",
            // jmp far 0x08:2f (ptr16:32), as bytes.
            ".byte 0xea",
            ".long 2f",
            ".word 0x08",
            "2:",
            ".code64",
            "mov eax, 0x10",
            "mov ds, eax",
            "mov es, eax",
            "mov ss, eax",
            "mov fs, eax",
            "mov gs, eax",
            "mov ebx, ebx",
            "mov esp, [rbx + 12]",
            "mov edi, [rbx + 20]",
            "mov eax, [rbx + 16]",
            "call rax",
            "3:",
            "cli",
            "hlt",
            "jmp 3b",
            ".code32",
            in("ebx") handoff,
            options(noreturn)
        )
    }
}
