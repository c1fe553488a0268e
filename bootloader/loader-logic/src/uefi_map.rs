//! The 32-bit UEFI loader's memory map for stage 4 (`uefi-ia32/`): UEFI's
//! memory descriptors as E820 entries, the form a BIOS boot hands stage 4.
//!
//! Conventional memory and boot services' code and data are usable (E820
//! type 1: boot services are gone when stage 4 runs); ACPI reclaimable memory
//! is type 3 and ACPI NVS type 4; everything else is reserved (2), and so is
//! the loader's own code and data: stage 4, the kernel file, this map, the
//! `BiosInfo`, the page tables and stage 4's stack are all loader data, and
//! stage 4's frame allocator must never hand them out.

/// One UEFI memory descriptor, as far as the map needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UefiRegion {
    /// The UEFI memory type (`EFI_MEMORY_TYPE`).
    pub uefi_type: u32,
    /// Physical start address.
    pub start: u64,
    /// Length in 4 KiB pages.
    pub pages: u64,
}

/// One E820 entry (start, length in bytes, type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct E820Entry {
    pub start: u64,
    pub len: u64,
    pub e820_type: u32,
}

/// E820's usable RAM.
pub const USABLE: u32 = 1;
/// E820's reserved.
pub const RESERVED: u32 = 2;
/// E820's ACPI reclaimable memory.
pub const ACPI_RECLAIMABLE: u32 = 3;
/// E820's ACPI NVS memory.
pub const ACPI_NVS: u32 = 4;

/// UEFI memory types by their numbers in the UEFI specification.
pub mod uefi_type {
    pub const RESERVED: u32 = 0;
    pub const LOADER_CODE: u32 = 1;
    pub const LOADER_DATA: u32 = 2;
    pub const BOOT_SERVICES_CODE: u32 = 3;
    pub const BOOT_SERVICES_DATA: u32 = 4;
    pub const RUNTIME_SERVICES_CODE: u32 = 5;
    pub const RUNTIME_SERVICES_DATA: u32 = 6;
    pub const CONVENTIONAL: u32 = 7;
    pub const UNUSABLE: u32 = 8;
    pub const ACPI_RECLAIM: u32 = 9;
    pub const ACPI_NVS: u32 = 10;
    pub const MMIO: u32 = 11;
}

/// The E820 type of a UEFI memory type, after boot services are left and
/// while the loader's data is still needed.
pub fn e820_type(uefi: u32) -> u32 {
    match uefi {
        uefi_type::CONVENTIONAL | uefi_type::BOOT_SERVICES_CODE | uefi_type::BOOT_SERVICES_DATA => {
            USABLE
        }
        uefi_type::ACPI_RECLAIM => ACPI_RECLAIMABLE,
        uefi_type::ACPI_NVS => ACPI_NVS,
        // Loader code and data included: see the module's comment.
        _ => RESERVED,
    }
}

/// More entries than the table holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TableFull {
    /// The table's size in entries.
    pub capacity: usize,
}

/// Converts `regions` into `table`: each as its E820 type, empty ones
/// dropped, sorted by start, and neighbours of one type that touch merged
/// into one entry. Returns how many entries of `table` it filled.
pub fn convert(
    regions: impl IntoIterator<Item = UefiRegion>,
    table: &mut [E820Entry],
) -> Result<usize, TableFull> {
    let capacity = table.len();
    let mut count = 0;
    for region in regions {
        if region.pages == 0 {
            continue;
        }
        let slot = table.get_mut(count).ok_or(TableFull { capacity })?;
        *slot = E820Entry {
            start: region.start,
            len: region.pages.saturating_mul(4096),
            e820_type: e820_type(region.uefi_type),
        };
        count += 1;
    }
    let filled = &mut table[..count];
    filled.sort_unstable_by_key(|entry| entry.start);
    let mut merged = 0;
    for index in 0..count {
        let entry = table[index];
        if merged > 0 {
            let last = &mut table[merged - 1];
            if last.e820_type == entry.e820_type
                && last.start.saturating_add(last.len) == entry.start
            {
                last.len += entry.len;
                continue;
            }
        }
        table[merged] = entry;
        merged += 1;
    }
    Ok(merged)
}

#[cfg(test)]
mod tests {
    use super::*;
    use uefi_type::{
        BOOT_SERVICES_CODE, BOOT_SERVICES_DATA, CONVENTIONAL, LOADER_CODE, LOADER_DATA, MMIO,
        RUNTIME_SERVICES_CODE, RUNTIME_SERVICES_DATA, UNUSABLE,
    };

    fn region(uefi_type: u32, start: u64, pages: u64) -> UefiRegion {
        UefiRegion {
            uefi_type,
            start,
            pages,
        }
    }

    fn entry(start: u64, len: u64, e820_type: u32) -> E820Entry {
        E820Entry {
            start,
            len,
            e820_type,
        }
    }

    const EMPTY: E820Entry = E820Entry {
        start: 0,
        len: 0,
        e820_type: 0,
    };

    #[test]
    fn each_uefi_type_has_its_e820_type() {
        assert_eq!(e820_type(CONVENTIONAL), USABLE);
        assert_eq!(e820_type(BOOT_SERVICES_CODE), USABLE);
        assert_eq!(e820_type(BOOT_SERVICES_DATA), USABLE);
        assert_eq!(e820_type(uefi_type::ACPI_RECLAIM), ACPI_RECLAIMABLE);
        assert_eq!(e820_type(uefi_type::ACPI_NVS), ACPI_NVS);
        for reserved in [
            uefi_type::RESERVED,
            LOADER_CODE,
            LOADER_DATA,
            RUNTIME_SERVICES_CODE,
            RUNTIME_SERVICES_DATA,
            UNUSABLE,
            MMIO,
            12,
            13,
            14,
            15,
            0x7000_0000,
            0x8000_0001,
        ] {
            assert_eq!(e820_type(reserved), RESERVED, "UEFI type {reserved:#x}");
        }
    }

    #[test]
    fn touching_regions_of_one_kind_merge_and_others_do_not() {
        let mut table = [EMPTY; 8];
        let regions = [
            region(BOOT_SERVICES_CODE, 0x0, 0x9f),
            // touches and is usable too: merged
            region(CONVENTIONAL, 0x9f000, 0x1),
            // a gap before it: not merged
            region(CONVENTIONAL, 0x10_0000, 0x10),
            region(BOOT_SERVICES_DATA, 0x11_0000, 0x20),
            // touches, but reserved: its own entry
            region(RUNTIME_SERVICES_DATA, 0x13_0000, 0x2),
            region(uefi_type::ACPI_NVS, 0x13_2000, 0x1),
            region(MMIO, 0xffc0_0000, 0x400),
        ];
        let count = convert(regions, &mut table).unwrap();
        assert_eq!(
            &table[..count],
            &[
                entry(0x0, 0xa0000, USABLE),
                entry(0x10_0000, 0x30000, USABLE),
                entry(0x13_0000, 0x2000, RESERVED),
                entry(0x13_2000, 0x1000, ACPI_NVS),
                entry(0xffc0_0000, 0x40_0000, RESERVED),
            ]
        );
    }

    #[test]
    fn loader_data_stays_reserved_between_usable_memory() {
        // Stage 4 at 0x130000 and the kernel file, as the loader allocates
        // them: neither may become usable, nor be swallowed by a merge.
        let mut table = [EMPTY; 8];
        let regions = [
            region(CONVENTIONAL, 0x10_0000, 0x30),
            region(LOADER_DATA, 0x13_0000, 0x40),
            region(CONVENTIONAL, 0x17_0000, 0x100),
            region(LOADER_DATA, 0x27_0000, 0x80),
            region(LOADER_CODE, 0x2f_0000, 0x10),
            region(BOOT_SERVICES_DATA, 0x30_0000, 0x10),
        ];
        let count = convert(regions, &mut table).unwrap();
        assert_eq!(
            &table[..count],
            &[
                entry(0x10_0000, 0x30000, USABLE),
                entry(0x13_0000, 0x40000, RESERVED),
                entry(0x17_0000, 0x100000, USABLE),
                // loader data and code touch: one reserved entry
                entry(0x27_0000, 0x90000, RESERVED),
                entry(0x30_0000, 0x10000, USABLE),
            ]
        );
    }

    #[test]
    fn the_map_is_sorted_and_empty_regions_dropped() {
        let mut table = [EMPTY; 4];
        let regions = [
            region(CONVENTIONAL, 0x20_0000, 0x10),
            region(uefi_type::RESERVED, 0x5000, 0),
            region(CONVENTIONAL, 0x1000, 0x4),
            region(uefi_type::ACPI_RECLAIM, 0x1f_0000, 0x10),
        ];
        let count = convert(regions, &mut table).unwrap();
        assert_eq!(
            &table[..count],
            &[
                entry(0x1000, 0x4000, USABLE),
                entry(0x1f_0000, 0x10000, ACPI_RECLAIMABLE),
                entry(0x20_0000, 0x10000, USABLE),
            ]
        );
    }

    #[test]
    fn a_full_table_is_an_error_not_a_truncated_map() {
        let mut table = [EMPTY; 2];
        let regions = [
            region(CONVENTIONAL, 0x0, 1),
            region(uefi_type::RESERVED, 0x1000, 1),
            region(CONVENTIONAL, 0x2000, 1),
        ];
        assert_eq!(convert(regions, &mut table), Err(TableFull { capacity: 2 }));
        // Regions that merge still need a slot each before merging: the
        // loader sizes its table by the descriptor count.
        let mut table = [EMPTY; 3];
        assert_eq!(convert(regions, &mut table), Ok(3));
    }
}
