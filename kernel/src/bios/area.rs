//! The trampoline's home: 16 KiB of free conventional memory, identity-mapped
//! (virtual address = physical address) into the kernel's page tables, since
//! the code that turns paging off and on must run where both views agree.

use super::trampoline::layout;
use bootloader_api::info::{MemoryRegionKind, MemoryRegions};
use x86_64::registers::control::Cr3;
use x86_64::structures::paging::mapper::MapToError;
use x86_64::structures::paging::{
    FrameAllocator, Mapper, OffsetPageTable, Page, PageTable, PageTableFlags, PhysFrame, Size4KiB,
};
use x86_64::{PhysAddr, VirtAddr};

/// Below this the interrupt table and the BIOS data area live.
const LOW_LIMIT: u64 = 0x1000;
/// Conventional memory ends here at the latest (the EBDA and the VGA window
/// follow); real mode can reach no further anyway.
const HIGH_LIMIT: u64 = 0x9_F000;
const PAGE: u64 = 4096;

/// Why no area could be set up.
#[derive(Clone, Copy, Debug)]
pub enum AreaError {
    /// No free 16 KiB below 640 KiB in the memory map.
    NoFreeLowMemory,
    /// The page tables hang above 4 GiB, where 32-bit code cannot load CR3.
    PageTablesAbove4GiB,
    /// Something else is mapped where the identity map must go.
    AlreadyMapped,
    /// No free frame for a page table.
    NoFrameForPageTable,
}

/// Picks the area: the first free, page-aligned 16 KiB between 4 KiB and
/// 636 KiB that the bootloader reports as usable.
pub fn find(regions: &MemoryRegions) -> Result<u64, AreaError> {
    let size = layout::AREA as u64;
    regions
        .iter()
        .filter(|region| region.kind == MemoryRegionKind::Usable)
        .find_map(|region| {
            let start = region.start.max(LOW_LIMIT).next_multiple_of(PAGE);
            (start + size <= region.end.min(HIGH_LIMIT)).then_some(start)
        })
        .ok_or(AreaError::NoFreeLowMemory)
}

/// Page-table frames come from usable memory above 1 MiB, which nothing
/// else in this kernel allocates from.
struct UsableFrames<'a> {
    regions: &'a MemoryRegions,
    next: u64,
}

// SAFETY: every frame handed out is usable RAM by the bootloader's map, above
// the first MiB, and handed out once (`next` only grows).
unsafe impl FrameAllocator<Size4KiB> for UsableFrames<'_> {
    fn allocate_frame(&mut self) -> Option<PhysFrame<Size4KiB>> {
        let region = self.regions.iter().find(|region| {
            region.kind == MemoryRegionKind::Usable
                && region.end >= self.next.max(region.start).next_multiple_of(PAGE) + PAGE
        })?;
        let frame = self.next.max(region.start).next_multiple_of(PAGE);
        self.next = frame + PAGE;
        Some(PhysFrame::containing_address(PhysAddr::new(frame)))
    }
}

/// Maps `[base, base + 16 KiB)` to itself, writable and executable.
pub fn identity_map(
    base: u64,
    regions: &MemoryRegions,
    physical_memory_offset: u64,
) -> Result<(), AreaError> {
    let (level_4, _) = Cr3::read();
    if level_4.start_address().as_u64() >= 1 << 32 {
        return Err(AreaError::PageTablesAbove4GiB);
    }
    let offset = VirtAddr::new(physical_memory_offset);
    let table = (offset + level_4.start_address().as_u64()).as_mut_ptr::<PageTable>();
    // SAFETY: CR3 holds the active level-4 table, and all physical memory is
    // mapped at `offset`; nothing else edits the page tables while this runs.
    let mut mapper = unsafe { OffsetPageTable::new(&mut *table, offset) };
    let mut frames = UsableFrames {
        regions,
        next: 0x10_0000,
    };
    let flags = PageTableFlags::PRESENT | PageTableFlags::WRITABLE;
    for address in (base..base + layout::AREA as u64).step_by(PAGE as usize) {
        let page = Page::<Size4KiB>::containing_address(VirtAddr::new(address));
        let frame = PhysFrame::containing_address(PhysAddr::new(address));
        // SAFETY: the frame is free conventional memory (by the memory map),
        // mapped at its own address; no Rust reference points into it.
        match unsafe { mapper.map_to(page, frame, flags, &mut frames) } {
            Ok(flush) => flush.flush(),
            Err(MapToError::PageAlreadyMapped(mapped)) if mapped == frame => {}
            Err(MapToError::FrameAllocationFailed) => return Err(AreaError::NoFrameForPageTable),
            Err(_) => return Err(AreaError::AlreadyMapped),
        }
    }
    Ok(())
}
