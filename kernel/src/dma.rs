//! Memory a device reads and writes by itself (DMA): whole pages of usable
//! RAM from the bootloader's memory map, below 4 GiB, handed out once by a
//! bump allocator (the kernel has no heap). Taken from the top of the highest
//! usable region below 4 GiB, because the BIOS trampoline's page tables come
//! from the bottom of usable memory above 1 MiB.
//!
//! Also maps device registers (an xHCI's BAR0) uncached at a virtual address
//! of their own, with page tables from the same pages: a 64-bit BAR may lie
//! beyond the bootloader's map of physical memory, and that map is cached.

use bootloader_api::info::{MemoryRegionKind, MemoryRegions};
use x86_64::registers::control::Cr3;
use x86_64::structures::paging::{
    FrameAllocator, Mapper, OffsetPageTable, Page, PageTable, PageTableFlags, PhysFrame, Size4KiB,
};
use x86_64::{PhysAddr, VirtAddr};

pub const PAGE: u64 = 4096;
const FOUR_GIB: u64 = 1 << 32;
/// DMA below 16 MiB is left to anything that needs ISA-reachable memory.
const LOW_LIMIT: u64 = 16 << 20;

/// A run of physical pages, handed out from its start.
#[derive(Clone, Copy, Debug)]
pub struct Pages {
    pub next: u64,
    pub end: u64,
}

/// Takes `bytes` (a multiple of a page) from the top of the highest usable
/// region below 4 GiB that has room.
pub fn take(regions: &MemoryRegions, bytes: u64) -> Option<Pages> {
    regions
        .iter()
        .filter(|region| region.kind == MemoryRegionKind::Usable)
        .filter_map(|region| {
            let end = region.end.min(FOUR_GIB) & !(PAGE - 1);
            let start = end.checked_sub(bytes)?;
            (start >= region.start.max(LOW_LIMIT)).then_some(Pages { next: start, end })
        })
        .max_by_key(|pages| pages.end)
}

impl Pages {
    /// Splits off the first `bytes`.
    pub fn split(&mut self, bytes: u64) -> Option<Pages> {
        let end = self.next.checked_add(bytes)?;
        if end > self.end {
            return None;
        }
        let taken = Pages {
            next: self.next,
            end,
        };
        self.next = end;
        Some(taken)
    }
}

// SAFETY: every frame is usable RAM by the bootloader's map, from a range
// `take` gave out once, and each is handed out once (`next` only grows).
unsafe impl FrameAllocator<Size4KiB> for Pages {
    fn allocate_frame(&mut self) -> Option<PhysFrame<Size4KiB>> {
        let frame = self.split(PAGE)?.next;
        Some(PhysFrame::containing_address(PhysAddr::new(frame)))
    }
}

/// Maps `bytes` of device registers at physical `base` uncached (PCD and
/// PWT: UC whatever the PAT), into a level-4 slot nothing uses yet; page
/// tables come from `frames`, which must be mapped at `physical_memory_offset`
/// (usable RAM is). Returns the registers' virtual address.
pub fn map_uncached(
    base: u64,
    bytes: u64,
    frames: &mut Pages,
    physical_memory_offset: u64,
) -> Result<u64, &'static str> {
    let offset = VirtAddr::new(physical_memory_offset);
    let (level_4, _) = Cr3::read();
    let table = (offset + level_4.start_address().as_u64()).as_mut_ptr::<PageTable>();
    // SAFETY: CR3 holds the active level-4 table, all physical memory is
    // mapped at `offset`, and nothing else edits the page tables meanwhile
    // (this runs once, at boot, with one core).
    let mut mapper = unsafe { OffsetPageTable::new(&mut *table, offset) };
    // A free slot in the lower half (canonical without sign extension).
    let slot = (1..256usize)
        .find(|&index| mapper.level_4_table()[index].is_unused())
        .ok_or("no free level-4 slot for the registers")?;
    let first = base & !(PAGE - 1);
    let last = (base + bytes.max(1) - 1) & !(PAGE - 1);
    let virtual_base = (slot as u64) << 39;
    let flags = PageTableFlags::PRESENT
        | PageTableFlags::WRITABLE
        | PageTableFlags::NO_CACHE
        | PageTableFlags::WRITE_THROUGH;
    for frame in (first..=last).step_by(PAGE as usize) {
        let page =
            Page::<Size4KiB>::containing_address(VirtAddr::new(virtual_base + (frame - first)));
        // SAFETY: the frame is the device's register window (from its BAR),
        // mapped at a virtual address that nothing else uses (its level-4
        // slot was empty); the page tables come from our own DMA pages.
        let flush = unsafe {
            mapper.map_to(
                page,
                PhysFrame::containing_address(PhysAddr::new(frame)),
                flags,
                frames,
            )
        }
        .map_err(|_| "no page-table frame for the registers")?;
        flush.flush();
    }
    Ok(virtual_base + (base - first))
}
