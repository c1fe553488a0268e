use bootloader_api::info::MemoryRegionKind;
use bootloader_x86_64_common::legacy_memory_region::LegacyMemoryRegion;
use loader_logic::memory_map::{Entry, sanitise, uefi_strictness}; // Patched (issue 66)
use uefi::boot::{MemoryAttribute, MemoryDescriptor, MemoryType};
use x86_64::PhysAddr;

#[derive(Debug, Copy, Clone)]
pub struct UefiMemoryDescriptor(pub MemoryDescriptor);

const PAGE_SIZE: u64 = 4096;

impl LegacyMemoryRegion for UefiMemoryDescriptor {
    fn start(&self) -> PhysAddr {
        PhysAddr::new(self.0.phys_start)
    }

    fn len(&self) -> u64 {
        self.0.page_count * PAGE_SIZE
    }

    fn kind(&self) -> MemoryRegionKind {
        match self.0.ty {
            MemoryType::CONVENTIONAL => MemoryRegionKind::Usable,
            other => MemoryRegionKind::UnknownUefi(other.0),
        }
    }

    fn usable_after_bootloader_exit(&self) -> bool {
        match self.0.ty {
            MemoryType::CONVENTIONAL => true,
            MemoryType::LOADER_CODE
            | MemoryType::LOADER_DATA
            | MemoryType::BOOT_SERVICES_CODE
            | MemoryType::BOOT_SERVICES_DATA => {
                // we don't need this data anymore after the bootloader
                // passes control to the kernel
                true
            }
            MemoryType::RUNTIME_SERVICES_CODE | MemoryType::RUNTIME_SERVICES_DATA => {
                // the UEFI standard specifies that these should be presevered
                // by the bootloader and operating system
                false
            }
            _ => false,
        }
    }
}

/// Patched (issue 66): the sanitised map's room in ranges. UEFI maps of
/// real machines have a few hundred descriptors; ranges past it are dropped
/// from the top of the address space and said.
const SANITISED_CAPACITY: usize = 1024;

static mut SANITISED: [Entry<u32>; SANITISED_CAPACITY] = [Entry {
    start: 0,
    len: 0,
    kind: 0,
}; SANITISED_CAPACITY];

/// Patched (issue 66, see ../CHANGES.md): UEFI's memory map after
/// ExitBootServices, sanitised by `loader_logic::memory_map` as stage 4
/// sanitises E820 (sorted, overlaps split with the stricter type winning,
/// repeats merged, empty and wrapping descriptors dropped), for the frame
/// allocator and the kernel's boot info; what was fixed is said on COM1.
/// Called once.
pub fn sanitised(
    descriptors: impl Iterator<Item = MemoryDescriptor> + Clone,
) -> impl ExactSizeIterator<Item = UefiMemoryDescriptor> + Clone {
    // A page count whose bytes do not fit in 64 bits wraps too.
    let wrapping = descriptors
        .clone()
        .filter(|d| d.page_count.checked_mul(PAGE_SIZE).is_none())
        .count();
    let entries = descriptors.filter_map(|d| {
        Some(Entry {
            start: d.phys_start,
            len: d.page_count.checked_mul(PAGE_SIZE)?,
            kind: d.ty.0,
        })
    });
    // SAFETY: called once, before the frame allocator; nothing else holds a
    // reference to the table.
    let table = unsafe { &mut *(&raw mut SANITISED) };
    let mut report = sanitise(entries, uefi_strictness, table);
    report.given += wrapping;
    report.wrapping_dropped += wrapping;
    crate::write_com1(format_args!("loader: memory: {report}\n"));
    table[..report.ranges].iter().map(|range| {
        UefiMemoryDescriptor(MemoryDescriptor {
            ty: MemoryType(range.kind),
            phys_start: range.start,
            virt_start: 0,
            page_count: range.len / PAGE_SIZE,
            att: MemoryAttribute::empty(),
        })
    })
}
