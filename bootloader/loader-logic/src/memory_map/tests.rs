use super::*;
use std::string::{String, ToString};
use std::vec::Vec;
use std::{format, vec};

/// The maps below are written as Linux's dmesg prints an E820 table
/// (`BIOS-e820: [mem 0xSTART-0xLAST] type`, the last byte inclusive). They
/// are made up for these tests in the shapes real PCs give, not copied.
fn parse(text: &str) -> Vec<Entry<u32>> {
    text.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .map(|line| {
            let rest = line.strip_prefix("BIOS-e820: [mem 0x").expect(line);
            let (range, kind) = rest.split_once("] ").expect(line);
            let (first, last) = range.split_once("-0x").expect(line);
            let start = u64::from_str_radix(first, 16).unwrap();
            let last = u64::from_str_radix(last, 16).unwrap();
            let kind = match kind.trim() {
                "usable" => 1,
                "reserved" => 2,
                "ACPI data" => 3,
                "ACPI NVS" => 4,
                "unusable" => 5,
                other => other
                    .strip_prefix("type ")
                    .and_then(|n| n.parse().ok())
                    .expect(line),
            };
            Entry {
                start,
                len: last - start + 1,
                kind,
            }
        })
        .collect()
}

fn print(map: &[Entry<u32>]) -> String {
    map.iter()
        .map(|entry| {
            let kind = match entry.kind {
                1 => "usable".to_string(),
                2 => "reserved".to_string(),
                3 => "ACPI data".to_string(),
                4 => "ACPI NVS".to_string(),
                5 => "unusable".to_string(),
                other => format!("type {other}"),
            };
            format!(
                "BIOS-e820: [mem {:#018x}-{:#018x}] {kind}\n",
                entry.start,
                entry.start + entry.len - 1
            )
        })
        .collect()
}

fn sanitised_with(given: &[Entry<u32>], capacity: usize) -> (Vec<Entry<u32>>, Report) {
    let mut out = vec![
        Entry {
            start: 0,
            len: 0,
            kind: 0
        };
        capacity
    ];
    let report = sanitise(given.iter().copied(), e820_strictness, &mut out);
    out.truncate(report.ranges);
    (out, report)
}

fn sanitised(given: &[Entry<u32>]) -> (Vec<Entry<u32>>, Report) {
    sanitised_with(given, 128)
}

fn unindent(text: &str) -> String {
    text.lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .map(|line| format!("{line}\n"))
        .collect()
}

/// QEMU 7.2's SeaBIOS with `-m 2048`, in the shape it gives.
const QEMU_2_GIB: &str = "
    BIOS-e820: [mem 0x0000000000000000-0x000000000009fbff] usable
    BIOS-e820: [mem 0x000000000009fc00-0x000000000009ffff] reserved
    BIOS-e820: [mem 0x00000000000f0000-0x00000000000fffff] reserved
    BIOS-e820: [mem 0x0000000000100000-0x000000007ffdffff] usable
    BIOS-e820: [mem 0x000000007ffe0000-0x000000007fffffff] reserved
    BIOS-e820: [mem 0x00000000feffc000-0x00000000feffffff] reserved
    BIOS-e820: [mem 0x00000000fffc0000-0x00000000ffffffff] reserved
";

/// A laptop's: holes below 1 MiB, ACPI NVS and ACPI data below the
/// graphics' stolen memory, the PCIe configuration window, the chipset's
/// and APICs' registers, the flash, and RAM remapped above 4 GiB.
const LAPTOP: &str = "
    BIOS-e820: [mem 0x0000000000000000-0x0000000000057fff] usable
    BIOS-e820: [mem 0x0000000000058000-0x0000000000058fff] reserved
    BIOS-e820: [mem 0x0000000000059000-0x000000000009efff] usable
    BIOS-e820: [mem 0x000000000009f000-0x00000000000fffff] reserved
    BIOS-e820: [mem 0x0000000000100000-0x000000008c9c7fff] usable
    BIOS-e820: [mem 0x000000008c9c8000-0x000000008d1c7fff] reserved
    BIOS-e820: [mem 0x000000008d1c8000-0x000000008d3c7fff] ACPI NVS
    BIOS-e820: [mem 0x000000008d3c8000-0x000000008d3fefff] ACPI data
    BIOS-e820: [mem 0x000000008d3ff000-0x000000008d3fffff] usable
    BIOS-e820: [mem 0x000000008d400000-0x000000008f7fffff] reserved
    BIOS-e820: [mem 0x00000000e0000000-0x00000000efffffff] reserved
    BIOS-e820: [mem 0x00000000fe000000-0x00000000fe010fff] reserved
    BIOS-e820: [mem 0x00000000fec00000-0x00000000fec00fff] reserved
    BIOS-e820: [mem 0x00000000fee00000-0x00000000fee00fff] reserved
    BIOS-e820: [mem 0x00000000ff000000-0x00000000ffffffff] reserved
    BIOS-e820: [mem 0x0000000100000000-0x000000026e7fffff] usable
";

#[test]
fn a_clean_laptop_map_is_kept_as_it_is() {
    let given = parse(LAPTOP);
    let (map, report) = sanitised(&given);
    assert_eq!(print(&map), unindent(LAPTOP));
    assert!(!report.anything_fixed() && !report.out_of_order);
    assert_eq!(report.to_string(), "16 entries; nothing to fix; 16 ranges");
}

#[test]
fn a_reserved_range_inside_the_top_of_ram_splits_it() {
    // Issue 66: [top-4 MiB, top-2 MiB) reserved inside the big usable entry.
    let mut given = parse(QEMU_2_GIB);
    given.extend(parse(
        "BIOS-e820: [mem 0x000000007fbe0000-0x000000007fddffff] reserved",
    ));
    let (map, report) = sanitised(&given);
    assert_eq!(
        print(&map),
        unindent(
            "
            BIOS-e820: [mem 0x0000000000000000-0x000000000009fbff] usable
            BIOS-e820: [mem 0x000000000009fc00-0x000000000009ffff] reserved
            BIOS-e820: [mem 0x00000000000f0000-0x00000000000fffff] reserved
            BIOS-e820: [mem 0x0000000000100000-0x000000007fbdffff] usable
            BIOS-e820: [mem 0x000000007fbe0000-0x000000007fddffff] reserved
            BIOS-e820: [mem 0x000000007fde0000-0x000000007ffdffff] usable
            BIOS-e820: [mem 0x000000007ffe0000-0x000000007fffffff] reserved
            BIOS-e820: [mem 0x00000000feffc000-0x00000000feffffff] reserved
            BIOS-e820: [mem 0x00000000fffc0000-0x00000000ffffffff] reserved
            "
        )
    );
    assert_eq!(
        report.to_string(),
        "8 entries; sorted, 1 overlap split; 9 ranges"
    );
}

#[test]
fn a_repeated_entry_is_merged() {
    // Issue 66: the big usable entry twice.
    let mut given = parse(QEMU_2_GIB);
    given.insert(4, given[3]);
    let (map, report) = sanitised(&given);
    assert_eq!(print(&map), unindent(QEMU_2_GIB));
    assert_eq!(report.duplicates_merged, 1);
    assert_eq!(report.overlaps_split, 0);
    assert_eq!(
        report.to_string(),
        "8 entries; 1 duplicate merged; 7 ranges"
    );
}

#[test]
fn a_reversed_list_is_sorted() {
    let mut given = parse(QEMU_2_GIB);
    given.reverse();
    let (map, report) = sanitised(&given);
    assert_eq!(print(&map), unindent(QEMU_2_GIB));
    assert!(report.out_of_order && !report.anything_fixed());
    assert_eq!(report.to_string(), "7 entries; sorted; 7 ranges");
}

/// A desktop whose BIOS lists stolen graphics memory and ACPI NVS inside
/// the usable entry below 4 GiB (after it, out of order) and the RAM above
/// 4 GiB twice.
#[test]
fn a_desktop_map_with_overlaps_and_a_repeat_is_made_whole() {
    let given = parse(
        "
        BIOS-e820: [mem 0x0000000000000000-0x000000000009ffff] usable
        BIOS-e820: [mem 0x00000000000e0000-0x00000000000fffff] reserved
        BIOS-e820: [mem 0x0000000000100000-0x00000000bfffffff] usable
        BIOS-e820: [mem 0x00000000bf800000-0x00000000bfffffff] reserved
        BIOS-e820: [mem 0x00000000bf700000-0x00000000bf7fffff] ACPI NVS
        BIOS-e820: [mem 0x00000000fed1c000-0x00000000fed1ffff] reserved
        BIOS-e820: [mem 0x0000000100000000-0x000000013fffffff] usable
        BIOS-e820: [mem 0x0000000100000000-0x000000013fffffff] usable
        ",
    );
    let (map, report) = sanitised(&given);
    assert_eq!(
        print(&map),
        unindent(
            "
            BIOS-e820: [mem 0x0000000000000000-0x000000000009ffff] usable
            BIOS-e820: [mem 0x00000000000e0000-0x00000000000fffff] reserved
            BIOS-e820: [mem 0x0000000000100000-0x00000000bf6fffff] usable
            BIOS-e820: [mem 0x00000000bf700000-0x00000000bf7fffff] ACPI NVS
            BIOS-e820: [mem 0x00000000bf800000-0x00000000bfffffff] reserved
            BIOS-e820: [mem 0x00000000fed1c000-0x00000000fed1ffff] reserved
            BIOS-e820: [mem 0x0000000100000000-0x000000013fffffff] usable
            "
        )
    );
    assert_eq!(
        report.to_string(),
        "8 entries; sorted, 2 overlaps split, 1 duplicate merged; 7 ranges"
    );
}

#[test]
fn the_stricter_kind_wins_where_entries_overlap() {
    // The kind that [0x2000, 0x4000) gets when entries of kinds `a` and `b`
    // both cover it, either listed first; each keeps the rest of its own.
    let winner = |a: u32, b: u32| {
        let given = [
            Entry {
                start: 0x1000,
                len: 0x3000,
                kind: a,
            },
            Entry {
                start: 0x2000,
                len: 0x3000,
                kind: b,
            },
        ];
        let (map, _) = sanitised(&given);
        let kind_at = |at: u64| {
            map.iter()
                .find(|e| e.start <= at && at < e.start + e.len)
                .map(|e| e.kind)
        };
        assert_eq!((kind_at(0x1000), kind_at(0x4000)), (Some(a), Some(b)));
        let (reversed, _) = sanitised(&[given[1], given[0]]);
        assert_eq!(reversed, map);
        kind_at(0x2000).unwrap()
    };
    // Usable loses to reserved, ACPI data, ACPI NVS, unusable, and to a
    // type no one defined (0 as well as 20).
    for stricter in [2, 3, 4, 5, 0, 20] {
        assert_eq!(winner(1, stricter), stricter, "type {stricter}");
        assert_eq!(winner(stricter, 1), stricter, "type {stricter}");
    }
    // ACPI data loses to reserved and NVS; reserved to NVS and unusable.
    assert_eq!(winner(3, 2), 2);
    assert_eq!(winner(2, 3), 2);
    assert_eq!(winner(2, 4), 4);
    assert_eq!(winner(4, 2), 4);
    assert_eq!(winner(2, 5), 5);
}

#[test]
fn a_partial_overlap_leaves_the_rest_of_each() {
    let given = parse(
        "
        BIOS-e820: [mem 0x0000000000100000-0x00000000001fffff] usable
        BIOS-e820: [mem 0x0000000000180000-0x000000000027ffff] reserved
        BIOS-e820: [mem 0x0000000000200000-0x00000000002fffff] usable
        ",
    );
    let (map, report) = sanitised(&given);
    assert_eq!(
        print(&map),
        unindent(
            "
            BIOS-e820: [mem 0x0000000000100000-0x000000000017ffff] usable
            BIOS-e820: [mem 0x0000000000180000-0x000000000027ffff] reserved
            BIOS-e820: [mem 0x0000000000280000-0x00000000002fffff] usable
            "
        )
    );
    assert_eq!(report.overlaps_split, 2);
}

#[test]
fn touching_and_nested_entries_of_one_kind_become_one_range() {
    let given = parse(
        "
        BIOS-e820: [mem 0x0000000000100000-0x00000000001fffff] usable
        BIOS-e820: [mem 0x0000000000200000-0x00000000002fffff] usable
        BIOS-e820: [mem 0x0000000000140000-0x000000000014ffff] usable
        ",
    );
    let (map, report) = sanitised(&given);
    assert_eq!(
        print(&map),
        "BIOS-e820: [mem 0x0000000000100000-0x00000000002fffff] usable\n"
    );
    assert_eq!((report.overlaps_split, report.duplicates_merged), (1, 0));
}

#[test]
fn empty_and_wrapping_entries_are_dropped() {
    let mut given = parse(QEMU_2_GIB);
    given.push(Entry {
        start: 0x4000_0000,
        len: 0,
        kind: 2,
    });
    // Would end past 2^64: a usable one must never reach the map.
    given.push(Entry {
        start: 0xffff_ffff_ffff_0000,
        len: 0x2_0000,
        kind: 1,
    });
    let (map, report) = sanitised(&given);
    assert_eq!(print(&map), unindent(QEMU_2_GIB));
    assert_eq!((report.empty_dropped, report.wrapping_dropped), (1, 1));
    assert_eq!(
        report.to_string(),
        "9 entries; 1 empty entry dropped, 1 entry wrapping past 2^64 dropped; 7 ranges"
    );
}

/// 150 entries, alternately 4 KiB usable and 4 KiB reserved, from 1 MiB,
/// in reverse order.
fn many() -> Vec<Entry<u32>> {
    (0..150u64)
        .rev()
        .map(|i| Entry {
            start: 0x10_0000 + i * 0x1000,
            len: 0x1000,
            kind: if i % 2 == 0 { 1 } else { 2 },
        })
        .collect()
}

#[test]
fn more_than_a_hundred_entries_are_all_kept_when_they_fit() {
    let (map, report) = sanitised_with(&many(), 256);
    assert_eq!(report.ranges, 150);
    assert!(map.windows(2).all(|w| w[0].start + w[0].len == w[1].start));
    assert_eq!(map[149].start, 0x10_0000 + 149 * 0x1000);
}

#[test]
fn ranges_past_the_table_are_dropped_from_the_top() {
    let (map, report) = sanitised_with(&many(), 128);
    assert_eq!((report.ranges, report.past_table_dropped), (128, 22));
    assert_eq!(map[127].start, 0x10_0000 + 127 * 0x1000);
    assert_eq!(
        report.to_string(),
        "150 entries; sorted, 22 ranges past the table of 128 dropped; 128 ranges"
    );
}

#[test]
fn nothing_given_is_an_empty_map() {
    let (map, report) = sanitised(&[]);
    assert!(map.is_empty());
    assert_eq!(report.to_string(), "0 entries; nothing to fix; 0 ranges");
    assert!(!usable_above(&map, e820_strictness, 0));
}

#[test]
fn usable_memory_above_1_mib_is_found_or_not() {
    let (map, _) = sanitised(&parse(QEMU_2_GIB));
    assert!(usable_above(&map, e820_strictness, 0x10_0000));
    let low_only = parse(
        "
        BIOS-e820: [mem 0x0000000000000000-0x000000000009fbff] usable
        BIOS-e820: [mem 0x0000000000100000-0x000000007ffdffff] reserved
        ",
    );
    let (map, _) = sanitised(&low_only);
    assert!(!usable_above(&map, e820_strictness, 0x10_0000));
}

#[test]
fn uefi_types_rank_conventional_memory_lowest() {
    // Conventional (7) inside loader data (2) inside reserved (0).
    let given = [
        Entry {
            start: 0,
            len: 0x10000,
            kind: 7u32,
        },
        Entry {
            start: 0x4000,
            len: 0x4000,
            kind: 2,
        },
        Entry {
            start: 0x5000,
            len: 0x1000,
            kind: 0,
        },
    ];
    let mut out = [Entry {
        start: 0,
        len: 0,
        kind: 0,
    }; 8];
    let report = sanitise(given.iter().copied(), uefi_strictness, &mut out);
    let kinds: Vec<_> = out[..report.ranges]
        .iter()
        .map(|entry| (entry.start, entry.kind))
        .collect();
    assert_eq!(
        kinds,
        [(0, 7), (0x4000, 2), (0x5000, 0), (0x6000, 2), (0x8000, 7)]
    );
}

/// Random maps (a fixed seed), checked against the definition address by
/// address at every boundary: sorted, no overlaps, no two touching ranges of
/// one kind, and each address covered exactly when a valid entry covers it,
/// by the strictest kind among them.
#[test]
fn random_maps_meet_the_definition() {
    let mut seed = 0x2545_f491_u64;
    let mut next = |bound: u64| {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 33) % bound
    };
    for _ in 0..500 {
        let count = next(12) as usize;
        let given: Vec<Entry<u32>> = (0..count)
            .map(|_| Entry {
                start: next(32) * 0x1000,
                len: next(10) * 0x1000,
                kind: [1, 1, 2, 3, 4, 5][next(6) as usize],
            })
            .collect();
        let (map, report) = sanitised(&given);
        assert_eq!(report.given, count);
        for pair in map.windows(2) {
            let end = pair[0].start + pair[0].len;
            assert!(end <= pair[1].start, "{given:x?} -> {map:x?}");
            assert!(
                end < pair[1].start || pair[0].kind != pair[1].kind,
                "{given:x?} -> {map:x?}"
            );
        }
        for page in 0..48u64 {
            let at = page * 0x1000;
            let expected = given
                .iter()
                .filter(|e| e.len != 0 && e.start <= at && at < e.start + e.len)
                .map(|e| e.kind)
                .max_by_key(|&kind| e820_strictness(kind));
            let found = map
                .iter()
                .find(|e| e.start <= at && at < e.start + e.len)
                .map(|e| e.kind);
            assert_eq!(found, expected, "at {at:#x}: {given:x?} -> {map:x?}");
        }
    }
}
