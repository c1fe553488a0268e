//! One sanitised memory map, made once in the loader before anything
//! allocates from it, as Linux's `e820__update_table` makes its own: the
//! firmware's list (BIOS E820 entries, or UEFI memory descriptors) may be
//! out of order, repeat an entry, or lay a reserved range (SMRAM, stolen
//! graphics memory, ACPI NVS) inside a usable one. The result is sorted,
//! its ranges never overlap, and where entries overlap the stricter kind
//! wins; touching ranges of one kind are one range. Empty entries and
//! entries that wrap past 2^64 are dropped.
//!
//! No allocation: the caller hands in the output table, and ranges that do
//! not fit are dropped from the top of the address space and counted.
//! Dropping a range leaves it out of the map, which the loader and kernel
//! then never use: never does a reserved range become usable.
//!
//! The sweep visits every boundary and, at each, looks at every entry: time
//! grows with the square of the entries, a few million steps for a thousand
//! UEFI descriptors, and no scratch memory.

use core::fmt;

/// One entry: `len` bytes from `start`, of a firmware kind (an E820 type,
/// or a UEFI memory type).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Entry<K> {
    pub start: u64,
    pub len: u64,
    pub kind: K,
}

impl<K> Entry<K> {
    /// The end (exclusive), or None for an entry that wraps past 2^64.
    fn end(&self) -> Option<u64> {
        self.start.checked_add(self.len)
    }

    fn is_valid(&self) -> bool {
        self.len != 0 && self.end().is_some()
    }
}

/// E820 usable RAM.
pub const E820_USABLE: u32 = 1;
/// E820 ACPI reclaimable memory (the tables; free once they are read).
pub const E820_ACPI_RECLAIMABLE: u32 = 3;

/// How strictly an E820 type keeps its range from use: where entries
/// overlap, the higher wins. Usable loses to everything, ACPI reclaimable
/// to everything else; of the rest (reserved 2, ACPI NVS 4, unusable 5,
/// persistent 7, and types no one defined, 0 included), the larger type
/// wins, as in Linux.
pub fn e820_strictness(e820_type: u32) -> u64 {
    match e820_type {
        E820_USABLE => 0,
        E820_ACPI_RECLAIMABLE => 1,
        other => u64::from(other) + 2,
    }
}

/// How strictly a UEFI memory type keeps its range from use (see
/// [`e820_strictness`]): conventional memory loses to everything, then
/// boot services' code and data, then the loader's own (the kernel file is
/// in it), then ACPI reclaimable; of the rest (reserved, runtime services,
/// ACPI NVS, MMIO, ...), the larger type wins.
pub fn uefi_strictness(uefi_type: u32) -> u64 {
    match uefi_type {
        7 => 0,
        3 | 4 => 1,
        1 | 2 => 2,
        9 => 3,
        other => u64::from(other) + 4,
    }
}

/// What was given and what was fixed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Report {
    /// Entries given.
    pub given: usize,
    /// Whether a valid entry started below the one before it.
    pub out_of_order: bool,
    /// Entries that overlapped an earlier one (not an exact copy of it):
    /// split, the stricter kind winning.
    pub overlaps_split: usize,
    /// Entries that were exact copies of an earlier one.
    pub duplicates_merged: usize,
    /// Entries of zero length, dropped.
    pub empty_dropped: usize,
    /// Entries whose end wraps past 2^64, dropped.
    pub wrapping_dropped: usize,
    /// Ranges past the end of the output table, dropped (the highest ones).
    pub past_table_dropped: usize,
    /// The output table's size in entries.
    pub capacity: usize,
    /// Ranges in the sanitised map.
    pub ranges: usize,
}

impl Report {
    /// Whether the map needed anything but sorting.
    pub fn anything_fixed(&self) -> bool {
        self.overlaps_split
            + self.duplicates_merged
            + self.empty_dropped
            + self.wrapping_dropped
            + self.past_table_dropped
            != 0
    }
}

/// `12 entries; 1 overlap split, 1 duplicate merged; 13 ranges`, or
/// `7 entries; nothing to fix; 7 ranges`.
impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "{} entries; ", self.given)?;
        let plural = |n: usize, one: &'static str, many: &'static str| {
            if n == 1 {
                one
            } else {
                many
            }
        };
        let mut first = true;
        let mut item = |f: &mut fmt::Formatter, args: fmt::Arguments| {
            let separator = if first { "" } else { ", " };
            first = false;
            write!(f, "{separator}{args}")
        };
        if self.out_of_order {
            item(f, format_args!("sorted"))?;
        }
        let n = self.overlaps_split;
        if n > 0 {
            item(
                f,
                format_args!("{n} {} split", plural(n, "overlap", "overlaps")),
            )?;
        }
        let n = self.duplicates_merged;
        if n > 0 {
            let word = plural(n, "duplicate", "duplicates");
            item(f, format_args!("{n} {word} merged"))?;
        }
        let n = self.empty_dropped;
        if n > 0 {
            let word = plural(n, "empty entry", "empty entries");
            item(f, format_args!("{n} {word} dropped"))?;
        }
        let n = self.wrapping_dropped;
        if n > 0 {
            let word = plural(n, "entry", "entries");
            item(f, format_args!("{n} {word} wrapping past 2^64 dropped"))?;
        }
        let n = self.past_table_dropped;
        if n > 0 {
            let word = plural(n, "range", "ranges");
            let capacity = self.capacity;
            item(
                f,
                format_args!("{n} {word} past the table of {capacity} dropped"),
            )?;
        }
        if first {
            write!(f, "nothing to fix")?;
        }
        write!(f, "; {} ranges", self.ranges)
    }
}

/// Sanitises `given` into `out` (see the module's comment); `strictness`
/// ranks the kinds (two kinds must not rank the same). Returns the report;
/// `out[..report.ranges]` is the map.
pub fn sanitise<K, I>(given: I, strictness: impl Fn(K) -> u64, out: &mut [Entry<K>]) -> Report
where
    K: Copy + Eq,
    I: Iterator<Item = Entry<K>> + Clone,
{
    let mut report = Report {
        capacity: out.len(),
        ..Report::default()
    };
    let valid = given.clone().filter(Entry::is_valid);
    let mut previous_start = None;
    for (index, entry) in given.clone().enumerate() {
        report.given += 1;
        if entry.len == 0 {
            report.empty_dropped += 1;
            continue;
        }
        let Some(end) = entry.end() else {
            report.wrapping_dropped += 1;
            continue;
        };
        if previous_start.is_some_and(|previous| previous > entry.start) {
            report.out_of_order = true;
        }
        previous_start = Some(entry.start);
        let mut earlier = given.clone().take(index).filter(Entry::is_valid);
        if earlier.clone().any(|other| other == entry) {
            report.duplicates_merged += 1;
        } else if earlier.any(|other| other.start < end && entry.start < other.start + other.len) {
            report.overlaps_split += 1;
        }
    }

    // The sweep: from the lowest start, boundary to boundary; between two,
    // the strictest kind of the entries that cover it (none: a hole).
    let Some(mut at) = valid.clone().map(|entry| entry.start).min() else {
        return report;
    };
    let mut filled: usize = 0;
    loop {
        let mut next: Option<u64> = None;
        let mut kind: Option<K> = None;
        for entry in valid.clone() {
            let end = entry.start + entry.len;
            for boundary in [entry.start, end] {
                if boundary > at && next.is_none_or(|next| boundary < next) {
                    next = Some(boundary);
                }
            }
            if entry.start <= at
                && at < end
                && kind.is_none_or(|kind| strictness(entry.kind) > strictness(kind))
            {
                kind = Some(entry.kind);
            }
        }
        let Some(next) = next else {
            break;
        };
        if let Some(kind) = kind {
            match filled.checked_sub(1).map(|last| &mut out[last]) {
                Some(last) if last.kind == kind && last.start + last.len == at => {
                    last.len = next - last.start;
                }
                _ => match out.get_mut(filled) {
                    Some(slot) => {
                        *slot = Entry {
                            start: at,
                            len: next - at,
                            kind,
                        };
                        filled += 1;
                    }
                    None => report.past_table_dropped += 1,
                },
            }
        }
        at = next;
    }
    report.ranges = filled;
    report
}

/// Whether `map` has usable memory (strictness 0) that ends above `address`.
pub fn usable_above<K: Copy>(
    map: &[Entry<K>],
    strictness: impl Fn(K) -> u64,
    address: u64,
) -> bool {
    map.iter()
        .any(|entry| strictness(entry.kind) == 0 && entry.start.saturating_add(entry.len) > address)
}

#[cfg(test)]
mod tests;
