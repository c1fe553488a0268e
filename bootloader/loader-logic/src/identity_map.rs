//! What the UEFI loader identity-maps in page tables of its own (CHANGES.md,
//! issue 38): all physical memory up to the memory map's end, and the
//! framebuffer wherever the firmware put it, in 2 MiB pages.

/// The size of the pages the loader's own tables map with.
pub const PAGE: u64 = 0x20_0000;

/// A physical range `[start, end)`, both ends multiples of [`PAGE`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Range {
    /// The first byte.
    pub start: u64,
    /// One past the last byte.
    pub end: u64,
}

/// The ranges to identity-map, sorted and not overlapping: `[0, max_phys)`
/// and the framebuffer's bytes (`(address, length)`), each widened to whole
/// 2 MiB pages; one range when they touch or overlap.
pub fn identity_ranges(max_phys: u64, framebuffer: Option<(u64, u64)>) -> [Option<Range>; 2] {
    let memory = Range {
        start: 0,
        end: round_up(max_phys),
    };
    let Some((address, length)) = framebuffer.filter(|&(_, length)| length > 0) else {
        return [Some(memory), None];
    };
    let framebuffer = Range {
        start: address - address % PAGE,
        end: round_up(address.saturating_add(length)),
    };
    if framebuffer.start <= memory.end {
        let merged = Range {
            start: 0,
            end: memory.end.max(framebuffer.end),
        };
        [Some(merged), None]
    } else {
        [Some(memory), Some(framebuffer)]
    }
}

fn round_up(address: u64) -> u64 {
    address.div_ceil(PAGE).saturating_mul(PAGE)
}

#[cfg(test)]
mod tests {
    use super::*;

    const GIB: u64 = 1 << 30;

    fn range(start: u64, end: u64) -> Option<Range> {
        Some(Range { start, end })
    }

    #[test]
    fn memory_alone_is_one_range_rounded_up_to_a_page() {
        assert_eq!(identity_ranges(4 * GIB, None), [range(0, 4 * GIB), None]);
        assert_eq!(
            identity_ranges(4 * GIB + 1, None),
            [range(0, 4 * GIB + PAGE), None]
        );
    }

    #[test]
    fn a_framebuffer_inside_memory_adds_nothing() {
        let fb = Some((0x8000_0000, 4 << 20));
        assert_eq!(identity_ranges(4 * GIB, fb), [range(0, 4 * GIB), None]);
    }

    #[test]
    fn a_framebuffer_far_above_memory_is_a_range_of_its_own() {
        // Upstream issue 462: a framebuffer at 0xfc_1000_0000.
        let fb = Some((0xfc_1000_0000 + 0x1000, 8 << 20));
        assert_eq!(
            identity_ranges(4 * GIB, fb),
            [
                range(0, 4 * GIB),
                range(0xfc_1000_0000, 0xfc_1000_0000 + 5 * PAGE)
            ]
        );
    }

    #[test]
    fn a_framebuffer_across_the_end_of_memory_extends_it() {
        let fb = Some((4 * GIB - PAGE, 3 * PAGE));
        assert_eq!(
            identity_ranges(4 * GIB, fb),
            [range(0, 4 * GIB + 2 * PAGE), None]
        );
        let touching = Some((4 * GIB, PAGE));
        assert_eq!(
            identity_ranges(4 * GIB, touching),
            [range(0, 4 * GIB + PAGE), None]
        );
    }

    #[test]
    fn an_empty_framebuffer_adds_nothing() {
        assert_eq!(
            identity_ranges(4 * GIB, Some((64 * GIB, 0))),
            [range(0, 4 * GIB), None]
        );
    }
}
