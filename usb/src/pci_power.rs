//! A controller the firmware (or an OS before a warm reboot) left in a
//! low-power state is brought to D0 before use, as Linux's
//! `pci_set_power_state` and memtest86+'s USB code do: the PCI Power
//! Management capability's PMCSR bits 1:0 written 0, then the wait the PCI
//! Power Management specification (1.2, table 18) asks before the function
//! is touched. In D3hot a controller ignores its memory and I/O BARs, so
//! its registers read as all ones and nothing else would work.
//!
//! The decisions are here, over a configuration space given as two
//! closures, so that the host tests run them; the kernel does the PCI
//! accesses and the wait.

/// The Status register's Capabilities List bit (config offset 0x06, bit 4).
const STATUS_CAPABILITIES: u32 = 1 << (16 + 4);
/// The capability pointer's offset.
const CAPABILITIES_POINTER: u8 = 0x34;
/// The Power Management capability's ID.
const POWER_MANAGEMENT: u8 = 0x01;
/// Capabilities walked at most: 48 fit in the 192 bytes past the header,
/// and a list that loops is cut there.
const MOST_CAPABILITIES: usize = 48;
/// PMCSR's PowerState field.
const POWER_STATE: u32 = 0b11;
/// PMCSR's PME_Status, write-1-to-clear: written 0, left alone.
const PME_STATUS: u32 = 1 << 15;
/// D3hot to D0: 10 ms before the function is accessed (PCI PM 1.2 5.6.1).
pub const D3HOT_TO_D0_MICROS: u64 = 10_000;
/// D2 to D0: 200 us (PCI PM 1.2 table 18).
pub const D2_TO_D0_MICROS: u64 = 200;

/// What waking a function takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wake {
    /// No Power Management capability: the function is always in D0.
    NoCapability,
    /// In D0 already: nothing written.
    AlreadyOn,
    /// PMCSR (config offset `pmcsr`) was written to go to D0 from state
    /// `from` (1 to 3); the caller waits `wait_micros`, then [`is_on`]
    /// checks that it took.
    Waking {
        /// PMCSR's configuration offset (4-aligned).
        pmcsr: u8,
        /// The state it was in: 1 (D1), 2 (D2) or 3 (D3hot).
        from: u8,
        /// How long to wait before the function is accessed.
        wait_micros: u64,
    },
}

/// The Power Management capability's offset, if the function has one: the
/// capability list walked, every pointer checked (inside the 256 bytes,
/// past the header, 4-aligned), at most `MOST_CAPABILITIES` of them.
pub fn power_management_capability(read: &mut impl FnMut(u8) -> u32) -> Option<u8> {
    if read(0x04) & STATUS_CAPABILITIES == 0 {
        return None;
    }
    let mut at = (read(CAPABILITIES_POINTER) & 0xFC) as u8;
    for _ in 0..MOST_CAPABILITIES {
        if at < 0x40 {
            return None;
        }
        let header = read(at);
        if header & 0xFF == u32::from(POWER_MANAGEMENT) {
            return Some(at);
        }
        at = ((header >> 8) & 0xFC) as u8;
    }
    None
}

/// Brings the function to D0: finds its PMCSR, and if it is not in D0
/// writes PowerState 0 (PME_Enable kept, PME_Status not cleared), saying
/// how long to wait.
pub fn wake(read: &mut impl FnMut(u8) -> u32, write: &mut impl FnMut(u8, u32)) -> Wake {
    let Some(capability) = power_management_capability(read) else {
        return Wake::NoCapability;
    };
    let pmcsr = capability + 4;
    let control = read(pmcsr);
    let from = (control & POWER_STATE) as u8;
    if from == 0 {
        return Wake::AlreadyOn;
    }
    write(pmcsr, control & 0xFFFF & !POWER_STATE & !PME_STATUS);
    let wait_micros = match from {
        3 => D3HOT_TO_D0_MICROS,
        2 => D2_TO_D0_MICROS,
        _ => 0,
    };
    Wake::Waking {
        pmcsr,
        from,
        wait_micros,
    }
}

/// Whether the function's PMCSR (at `pmcsr`) says D0, after the wait.
pub fn is_on(read: &mut impl FnMut(u8) -> u32, pmcsr: u8) -> bool {
    read(pmcsr) & POWER_STATE == 0
}

#[cfg(test)]
mod tests;
