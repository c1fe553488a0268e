use bootloader_api::info::MemoryRegionKind;
use bootloader_x86_64_bios_common::E820MemoryRegion;
use bootloader_x86_64_common::legacy_memory_region::LegacyMemoryRegion;
use x86_64::PhysAddr;

impl LegacyMemoryRegion for MemoryRegion {
    fn start(&self) -> PhysAddr {
        PhysAddr::new(self.0.start_addr)
    }

    fn len(&self) -> u64 {
        self.0.len
    }

    fn kind(&self) -> MemoryRegionKind {
        match self.0.region_type {
            1 => MemoryRegionKind::Usable,
            // Patched (issue 38): a map the 32-bit UEFI loader made from
            // UEFI's descriptors names UEFI kinds, so that the kernel knows
            // UEFI booted it (it must never call a video BIOS then).
            other if self.1 => MemoryRegionKind::UnknownUefi(uefi_type(other)), // Patched
            other => MemoryRegionKind::UnknownBios(other),
        }
    }

    fn usable_after_bootloader_exit(&self) -> bool {
        matches!(self.kind(), MemoryRegionKind::Usable)
    }
}

/// A physical memory region returned by an `e820` BIOS call.
///
/// See http://wiki.osdev.org/Detecting_Memory_(x86)#Getting_an_E820_Memory_Map for more info.
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
///
/// Patched (issue 38): the flag says the entry came from UEFI's memory map
/// (the 32-bit UEFI loader), not from a BIOS's E820.
pub struct MemoryRegion(pub E820MemoryRegion, pub bool); // Patched

/// Patched (issue 38): the UEFI memory type for a non-usable E820 type of the
/// 32-bit UEFI loader's map: ACPI reclaimable (3) and NVS (4) as UEFI's ACPI
/// types (9, 10); everything else was UEFI-reserved, runtime services, MMIO
/// or the loader's own data, all reserved (0) for the kernel.
fn uefi_type(e820_type: u32) -> u32 {
    match e820_type {
        3 => 9,
        4 => 10,
        _ => 0,
    }
}
