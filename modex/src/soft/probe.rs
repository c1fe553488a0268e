//! What tests measure on the bus: operation counts and a write guard that
//! records video memory writes outside an allowed range of CPU offsets.

use core::ops::Range;

/// Bus operations since power-on or the last reset of the counts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusCounts {
    /// OUTs; a 16-bit OUT counts once.
    pub port_writes: u64,
    /// INs.
    pub port_reads: u64,
    /// Bytes written to video memory; a fill of n bytes counts n.
    pub vram_writes: u64,
    /// Bytes read from video memory.
    pub vram_reads: u64,
}

/// Counts video memory writes outside `allowed`.
#[derive(Clone, Debug, Default)]
pub(super) struct WriteGuard {
    allowed: Option<Range<u16>>,
    violations: u64,
    first_violation: Option<u16>,
}

impl WriteGuard {
    /// Everything allowed, nothing seen.
    pub(super) const fn new() -> Self {
        WriteGuard {
            allowed: None,
            violations: 0,
            first_violation: None,
        }
    }

    /// Guards `allowed` (None: everything is allowed) and forgets past violations.
    pub(super) fn set(&mut self, allowed: Option<Range<u16>>) {
        *self = Self {
            allowed,
            ..Self::default()
        };
    }

    pub(super) fn check(&mut self, offset: u16) {
        if self
            .allowed
            .as_ref()
            .is_some_and(|allowed| !allowed.contains(&offset))
        {
            self.violations += 1;
            self.first_violation.get_or_insert(offset);
        }
    }

    pub(super) fn violations(&self) -> u64 {
        self.violations
    }

    pub(super) fn first_violation(&self) -> Option<u16> {
        self.first_violation
    }
}
