//! The Page Attribute Table arithmetic behind the kernel's write-combining
//! framebuffer (`kernel/src/pat.rs` does the MSR and page-table accesses):
//! which PAT entry a page-table entry selects, how to make it select another,
//! what an entry's memory type is, and one step of a page-table walk. Page
//! table bits are `x86_64`'s [`PageTableFlags`].
//!
//! # Example
//!
//! ```
//! use memory::pat::{pat_index, select_pat_entry, Level, MemoryType, WC_ENTRY};
//! use x86_64::structures::paging::PageTableFlags;
//!
//! // A 4 KiB page as the bootloader maps it: write-back, PAT entry 0.
//! let pte = (PageTableFlags::PRESENT | PageTableFlags::WRITABLE).bits() | 0x1234_5000;
//! assert_eq!(pat_index(pte, Level::Page), 0);
//! let wc = select_pat_entry(pte, Level::Page, WC_ENTRY);
//! assert_eq!(pat_index(wc, Level::Page), WC_ENTRY);
//! assert_eq!(wc & 0x000F_FFFF_FFFF_F000, 0x1234_5000, "the frame is kept");
//! assert_eq!(MemoryType::from_encoding(1), Some(MemoryType::WriteCombining));
//! ```

use x86_64::structures::paging::PageTableFlags;

/// The PAT's model-specific register.
pub const IA32_PAT: u32 = 0x277;
/// CPUID leaf 1, EDX bit 16: the PAT is there.
pub const CPUID_PAT: u32 = 1 << 16;
/// The PAT entry made write-combining: PAT bit set, PCD and PWT clear, which
/// the bootloader never uses, so no existing mapping changes type.
pub const WC_ENTRY: u8 = 4;
/// A page-table entry's physical address bits.
pub const ADDRESS: u64 = 0x000F_FFFF_FFFF_F000;
/// In a directory entry that maps a huge page, bit 12 is PAT (bit 7, where a
/// 4 KiB entry keeps PAT, says "huge page" there).
const PAT_HUGE: u64 = 1 << 12;

/// A memory type, as a PAT entry encodes it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MemoryType {
    /// UC.
    Uncacheable = 0x00,
    /// WC: stores gathered into bursts.
    WriteCombining = 0x01,
    /// WT.
    WriteThrough = 0x04,
    /// WP.
    WriteProtected = 0x05,
    /// WB: ordinary memory.
    WriteBack = 0x06,
    /// UC-: uncacheable unless the MTRRs say WC.
    UncacheableMinus = 0x07,
}

impl MemoryType {
    /// The type a PAT entry's low three bits encode, if any.
    pub fn from_encoding(encoding: u8) -> Option<MemoryType> {
        Some(match encoding {
            0x00 => MemoryType::Uncacheable,
            0x01 => MemoryType::WriteCombining,
            0x04 => MemoryType::WriteThrough,
            0x05 => MemoryType::WriteProtected,
            0x06 => MemoryType::WriteBack,
            0x07 => MemoryType::UncacheableMinus,
            _ => return None,
        })
    }

    /// The short name the SDM uses.
    pub fn name(self) -> &'static str {
        match self {
            MemoryType::Uncacheable => "UC",
            MemoryType::WriteCombining => "WC",
            MemoryType::WriteThrough => "WT",
            MemoryType::WriteProtected => "WP",
            MemoryType::WriteBack => "WB",
            MemoryType::UncacheableMinus => "UC-",
        }
    }
}

/// The name of the type PAT entry `index` of `pat` holds ("reserved" for an
/// encoding that is none).
pub fn entry_type_name(pat: u64, index: u8) -> &'static str {
    MemoryType::from_encoding(entry_encoding(pat, index)).map_or("reserved", MemoryType::name)
}

/// The low three bits of PAT entry `index` (0 to 7) of the MSR value `pat`.
pub fn entry_encoding(pat: u64, index: u8) -> u8 {
    ((pat >> (u32::from(index % 8) * 8)) & 0x07) as u8
}

/// `pat` with entry `index` set to `memory_type` and the others kept.
pub fn with_entry(pat: u64, index: u8, memory_type: MemoryType) -> u64 {
    let shift = u32::from(index % 8) * 8;
    (pat & !(0xFF << shift)) | ((memory_type as u64) << shift)
}

/// Where a page-table entry sits: a 4 KiB page's entry (level 1), or a
/// directory entry mapping a huge page (levels 2 and 3).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// A 4 KiB page-table entry.
    Page,
    /// A directory entry with the huge-page bit: a 2 MiB or 1 GiB page.
    Huge,
}

impl Level {
    /// The entry's PAT bit.
    pub fn pat_bit(self) -> u64 {
        match self {
            // In a 4 KiB entry bit 7 is PAT; x86_64 names it for directories.
            Level::Page => PageTableFlags::HUGE_PAGE.bits(),
            Level::Huge => PAT_HUGE,
        }
    }
}

/// The PAT entry (0 to 7) that `entry`'s PAT, PCD and PWT bits select.
pub fn pat_index(entry: u64, level: Level) -> u8 {
    let flags = PageTableFlags::from_bits_retain(entry);
    u8::from(entry & level.pat_bit() != 0) << 2
        | u8::from(flags.contains(PageTableFlags::NO_CACHE)) << 1
        | u8::from(flags.contains(PageTableFlags::WRITE_THROUGH))
}

/// `entry` made to select PAT entry `index` (0 to 7), nothing else changed.
pub fn select_pat_entry(entry: u64, level: Level, index: u8) -> u64 {
    let bits = [
        (PageTableFlags::WRITE_THROUGH.bits(), 1),
        (PageTableFlags::NO_CACHE.bits(), 2),
        (level.pat_bit(), 4),
    ];
    bits.iter().fold(entry, |entry, &(bit, selects)| {
        if index & selects != 0 {
            entry | bit
        } else {
            entry & !bit
        }
    })
}

/// Which of a table's 512 entries maps `virt` at `level` (4 = PML4 ... 1 = PT).
pub fn table_index(virt: u64, level: u32) -> u64 {
    (virt >> (12 + 9 * (level - 1))) & 0x1FF
}

/// What one entry of a page-table walk says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Walk {
    /// Nothing is mapped there.
    NotPresent,
    /// The entry maps the page: its size and where its PAT bit is.
    Leaf {
        /// The page's size in bytes.
        page_bytes: u64,
        /// A 4 KiB page's entry or a huge page's.
        level: Level,
    },
    /// The next table down, at this physical address.
    Table(u64),
}

/// One step of a walk: what `entry`, found at `level` (4 to 1), means.
pub fn walk_step(entry: u64, level: u32) -> Walk {
    let flags = PageTableFlags::from_bits_retain(entry);
    if !flags.contains(PageTableFlags::PRESENT) {
        Walk::NotPresent
    } else if level == 1 {
        Walk::Leaf {
            page_bytes: 4096,
            level: Level::Page,
        }
    } else if level <= 3 && flags.contains(PageTableFlags::HUGE_PAGE) {
        Walk::Leaf {
            page_bytes: 1 << (12 + 9 * (level - 1)),
            level: Level::Huge,
        }
    } else {
        Walk::Table(entry & ADDRESS)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PAT after reset: WB, WT, UC-, UC, then the same again.
    const POWER_ON_PAT: u64 = 0x0007_0406_0007_0406;

    #[test]
    fn the_power_on_pat_reads_as_the_sdm_says() {
        let names: [&str; 8] = core::array::from_fn(|i| entry_type_name(POWER_ON_PAT, i as u8));
        assert_eq!(names, ["WB", "WT", "UC-", "UC", "WB", "WT", "UC-", "UC"]);
        assert_eq!(entry_type_name(0x02, 0), "reserved");
    }

    #[test]
    fn making_entry_4_write_combining_changes_only_entry_4() {
        let pat = with_entry(POWER_ON_PAT, WC_ENTRY, MemoryType::WriteCombining);
        assert_eq!(pat, 0x0007_0401_0007_0406);
        for index in (0..8).filter(|&i| i != WC_ENTRY) {
            assert_eq!(
                entry_encoding(pat, index),
                entry_encoding(POWER_ON_PAT, index)
            );
        }
    }

    #[test]
    fn every_index_round_trips_at_both_levels() {
        let entry = 0x8000_0000_1234_5063; // NX, a frame, present, accessed...
        for level in [Level::Page, Level::Huge] {
            for index in 0..8 {
                let selected = select_pat_entry(entry, level, index);
                assert_eq!(pat_index(selected, level), index, "{level:?} {index}");
                let kept = !(level.pat_bit() | (1 << 3) | (1 << 4));
                assert_eq!(selected & kept, entry & kept);
            }
        }
        // A huge page's bit 7 is the huge-page bit, never touched.
        let huge = PageTableFlags::HUGE_PAGE.bits() | 1;
        assert_eq!(select_pat_entry(huge, Level::Huge, 0) & (1 << 7), 1 << 7);
        assert_eq!(pat_index(huge, Level::Huge), 0);
    }

    #[test]
    fn a_walk_stops_at_the_first_leaf_or_hole() {
        let present = PageTableFlags::PRESENT.bits();
        let huge = PageTableFlags::HUGE_PAGE.bits();
        assert_eq!(walk_step(0x1000, 4), Walk::NotPresent);
        assert_eq!(walk_step(0x8000_0000_0020_3003, 4), Walk::Table(0x20_3000));
        assert_eq!(
            walk_step(present | huge, 2),
            Walk::Leaf {
                page_bytes: 2 << 20,
                level: Level::Huge
            }
        );
        assert_eq!(
            walk_step(present | huge, 3),
            Walk::Leaf {
                page_bytes: 1 << 30,
                level: Level::Huge
            }
        );
        // Bit 7 of a PML4 entry is reserved, not a huge page.
        assert_eq!(walk_step(present | huge | 0x5000, 4), Walk::Table(0x5000));
        // Bit 7 of a 4 KiB entry is PAT.
        assert_eq!(
            walk_step(present | huge, 1),
            Walk::Leaf {
                page_bytes: 4096,
                level: Level::Page
            }
        );
    }

    #[test]
    fn table_indices_take_nine_bits_per_level() {
        let virt = 0xFFFF_8000_1234_5678u64;
        assert_eq!(table_index(virt, 1), (virt >> 12) & 0x1FF);
        assert_eq!(table_index(virt, 4), (virt >> 39) & 0x1FF);
    }
}
