//! Write-combining for the framebuffer. Firmware framebuffers sit in PCI
//! memory that the MTRRs usually make uncacheable: every 4-byte pixel store
//! is then its own bus transaction. Write-combining lets the CPU gather
//! stores into whole-line bursts, which is how graphics drivers map
//! framebuffers. The memory type of a page comes from the Page Attribute
//! Table entry its PTE's PAT, PCD and PWT bits select, so: program a PAT
//! entry that nothing uses (entry 4: PAT bit set, PCD and PWT clear; the
//! bootloader never sets the PAT bit) to write-combining, point the
//! framebuffer's PTEs at it, and flush the TLB.
//!
//! The bootloader's own mapping is reported first, so a user's serial log
//! says what we started from.

use crate::serial_println;
use memory::pat::{
    entry_encoding, entry_type_name, pat_index, select_pat_entry, table_index, walk_step,
    with_entry, Level, MemoryType, Walk, CPUID_PAT, IA32_PAT, WC_ENTRY,
};
use x86_64::registers::control::Cr3;
use x86_64::registers::model_specific::Msr;

/// The page-table entry mapping `virt` and the size of its page.
struct Leaf {
    entry: *mut u64,
    page_bytes: u64,
    level: Level,
}

impl Leaf {
    fn read(&self) -> u64 {
        // SAFETY: `entry` points into a live page table, reached through the
        // physical-memory mapping (see `leaf`).
        unsafe { self.entry.read_volatile() }
    }

    fn pat_index(&self) -> u8 {
        pat_index(self.read(), self.level)
    }
}

/// Walks the page tables the CPU is using (CR3) through the mapping of all
/// physical memory at `offset`, down to the entry that maps `virt`.
fn leaf(virt: u64, offset: u64) -> Option<Leaf> {
    let mut table = Cr3::read().0.start_address().as_u64() + offset;
    for level in (1..=4u32).rev() {
        let entry = (table + table_index(virt, level) * 8) as *mut u64;
        // SAFETY: `table` is a page table's physical address (from CR3 or a
        // present entry above) plus the offset at which the bootloader maps
        // all physical memory; an entry is 8 bytes and the index < 512.
        let value = unsafe { entry.read_volatile() };
        match walk_step(value, level) {
            Walk::NotPresent => return None,
            Walk::Leaf { page_bytes, level } => {
                return Some(Leaf {
                    entry,
                    page_bytes,
                    level,
                })
            }
            Walk::Table(physical) => table = physical + offset,
        }
    }
    None
}

/// Maps `buffer` write-combining if the CPU has a PAT, logging the mapping
/// the bootloader made and what was done. True if write-combining read back
/// in effect.
pub fn map_write_combining(buffer: &mut [u8], physical_memory_offset: u64) -> bool {
    let start = buffer.as_ptr() as u64;
    let end = start + buffer.len() as u64;
    let has_pat = core::arch::x86_64::__cpuid(1).edx & CPUID_PAT != 0;
    let Some(first) = leaf(start, physical_memory_offset) else {
        serial_println!("display: framebuffer at {:#x} is not mapped?", start);
        return false;
    };
    if !has_pat {
        serial_println!(
            "display: no PAT (CPUID), framebuffer mapping left as the bootloader made it"
        );
        return false;
    }
    // SAFETY: the CPU has the PAT (CPUID above), so the MSR exists.
    let pat = unsafe { Msr::new(IA32_PAT).read() };
    let before = first.pat_index();
    serial_println!(
        "display: framebuffer mapped by the bootloader with {} KiB pages, PAT entry {} = {}",
        first.page_bytes / 1024,
        before,
        entry_type_name(pat, before)
    );

    let wc_pat = with_entry(pat, WC_ENTRY, MemoryType::WriteCombining);
    x86_64::instructions::interrupts::without_interrupts(|| {
        // SAFETY: entry 4 is selected only by PTEs with the PAT bit set,
        // which the bootloader does not use, so no existing mapping changes
        // type; caches are written back before and after, as the SDM asks
        // when memory types change.
        unsafe {
            core::arch::asm!("wbinvd", options(nostack));
            Msr::new(IA32_PAT).write(wc_pat);
            core::arch::asm!("wbinvd", options(nostack));
        }
        let mut pages = 0u64;
        let mut virt = start;
        while virt < end {
            let Some(page) = leaf(virt, physical_memory_offset) else {
                break;
            };
            // SAFETY: the entry maps the framebuffer (it was reached from its
            // address); only its memory-type bits change, to entry 4 (WC).
            unsafe {
                let value = page.entry.read_volatile();
                page.entry
                    .write_volatile(select_pat_entry(value, page.level, WC_ENTRY));
            }
            pages += 1;
            virt = (virt & !(page.page_bytes - 1)) + page.page_bytes;
        }
        // Every core's TLB may hold the old types; there is only this core.
        x86_64::instructions::tlb::flush_all();
        // Read back both halves before saying so: the PAT entry, and the
        // first page's choice of it.
        // SAFETY: as the read above.
        let pat_now = unsafe { Msr::new(IA32_PAT).read() };
        let entry_now = leaf(start, physical_memory_offset).map(|page| page.pat_index());
        let wc = MemoryType::WriteCombining as u8;
        let in_effect = entry_encoding(pat_now, WC_ENTRY) == wc && entry_now == Some(WC_ENTRY);
        if in_effect {
            serial_println!(
                "display: framebuffer now write-combining (PAT entry {} = WC, {} pages, read back)",
                WC_ENTRY,
                pages
            );
        } else {
            serial_println!(
                "display: write-combining NOT in effect (PAT {:#018x}, first page uses entry {:?})",
                pat_now,
                entry_now
            );
        }
        in_effect
    })
}
