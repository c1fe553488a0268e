//! Which firmware booted the machine, from the bootloader's memory map (the
//! decision itself is `firmware::boot_firmware`, tested on the host).

use bootloader_api::info::{MemoryRegionKind, MemoryRegions};
use firmware::boot_firmware::{firmware_from_regions, Firmware, RegionOrigin};

pub fn firmware(regions: &MemoryRegions) -> Firmware {
    firmware_from_regions(regions.iter().map(|region| match region.kind {
        MemoryRegionKind::UnknownBios(_) => RegionOrigin::Bios,
        MemoryRegionKind::UnknownUefi(_) => RegionOrigin::Uefi,
        _ => RegionOrigin::Neutral,
    }))
}
