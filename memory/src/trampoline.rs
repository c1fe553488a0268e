//! The data side of the kernel's trampoline to real mode (`kernel/src/bios/
//! trampoline.rs` holds the assembly): where things sit in the low-memory
//! area it runs from, its GDT's selectors, and the descriptors themselves.
//!
//! # Example
//!
//! ```
//! use memory::trampoline::{descriptors, layout, selector};
//!
//! let gdt = descriptors(0x8000);
//! assert_eq!(gdt.len(), layout::GDT_ENTRIES);
//! // The 16-bit segments are based at the area, so real mode finds its code.
//! let code_16 = gdt[usize::from(selector::CODE_16 / 8)];
//! assert_eq!((code_16 >> 16) & 0xFF_FFFF, 0x8000);
//! ```

use x86_64::structures::gdt::DescriptorFlags;

/// Offsets into the area. The data block comes first; the code after it.
pub mod layout {
    /// The trampoline's GDT: null, 64-bit code, 32-bit code, 32-bit data,
    /// 16-bit code and 16-bit data (the last two based at the area).
    pub const GDT: usize = 0x00;
    /// Descriptors in that GDT.
    pub const GDT_ENTRIES: usize = 6;
    /// Its pseudo-descriptor: 2-byte limit, 8-byte base.
    pub const GDTR: usize = 0x30;
    /// The kernel's GDTR, saved on the way out (10 bytes).
    pub const KERNEL_GDTR: usize = 0x40;
    /// The kernel's IDTR, saved on the way out (10 bytes).
    pub const KERNEL_IDTR: usize = 0x50;
    /// Real mode's IDTR: the interrupt vector table at 0, 256 vectors.
    pub const REAL_IDTR: usize = 0x60;
    /// CR0 as it was (8 bytes; CR3, CR4, EFER and RSP follow, 8 bytes each).
    pub const CR0: usize = 0x70;
    /// CR3 as it was.
    pub const CR3: usize = 0x78;
    /// CR4 as it was.
    pub const CR4: usize = 0x80;
    /// EFER as it was.
    pub const EFER: usize = 0x88;
    /// RSP as it was.
    pub const RSP: usize = 0x90;
    /// The kernel's CS, SS, DS, ES, FS and GS selectors (2 bytes each).
    pub const SELECTORS: usize = 0x98;
    /// The area's real-mode segment (its physical address / 16).
    pub const REAL_SEGMENT: usize = 0xA8;
    /// The registers in and out: EAX, EBX, ECX, EDX, ESI, EDI, EBP (4 bytes
    /// each), then DS, ES and FLAGS (2 bytes each).
    pub const REGISTERS: usize = 0xB0;
    /// DS in and out.
    pub const DS: usize = REGISTERS + 28;
    /// ES in and out.
    pub const ES: usize = DS + 2;
    /// FLAGS out.
    pub const FLAGS: usize = ES + 2;
    /// The BIOS's IRQ 0 vector (offset, segment), kept while the watchdog's
    /// handler stands in the real-mode table.
    pub const BIOS_TIMER_VECTOR: usize = 0xD4;
    /// IRQ 0 ticks left before the call is abandoned (2 bytes, counted down
    /// by the watchdog).
    pub const WATCHDOG_TICKS: usize = 0xD8;
    /// Nonzero out when the watchdog abandoned the call (2 bytes).
    pub const TIMED_OUT: usize = 0xDA;
    /// Where the code starts.
    pub const CODE: usize = 0x100;
    /// The real-mode stack grows down from here (the area is 16 KiB).
    pub const STACK_TOP: usize = 0x3FF0;
    /// The area's size.
    pub const AREA: usize = 0x4000;
}

/// Selectors in the trampoline's GDT: the descriptor's index times 8.
pub mod selector {
    /// 64-bit code, to come back to long mode.
    pub const CODE_64: u16 = 0x08;
    /// 32-bit code (compatibility mode, then protected mode).
    pub const CODE_32: u16 = 0x10;
    /// Flat 32-bit data.
    pub const DATA_32: u16 = 0x18;
    /// 16-bit code based at the area.
    pub const CODE_16: u16 = 0x20;
    /// 16-bit data based at the area.
    pub const DATA_16: u16 = 0x28;
}

/// The machine as a BIOS call expects it (issue 66): a video BIOS may wait
/// inside a mode set on the timer tick or on INT 15h AH=86h (the RTC's IRQ
/// 8), so the call runs with the PICs at the BIOS's vectors, its own masks,
/// PIT channel 0 at the BIOS's 18.2 Hz, and interrupts on; a watchdog on IRQ
/// 0 abandons a call that has not returned within `WATCHDOG_TICKS` ticks.
pub mod bios_world {
    /// Where the BIOS has the master PIC's IRQs: INT 08h-0Fh.
    pub const MASTER_VECTORS: u8 = 0x08;
    /// And the slave's: INT 70h-77h.
    pub const SLAVE_VECTORS: u8 = 0x70;
    /// PIT channel 0's divisor as the BIOS sets it: 65,536 (written as 0).
    pub const PIT_DIVISOR: u32 = 65_536;
    /// The PIT's input clock, Hz.
    pub const PIT_HZ: u32 = 1_193_182;
    /// Ticks the watchdog counts before it abandons the call. The first may
    /// come at once, so a call runs at least one tick less: 37 whole ticks,
    /// [`limit_millis`], a little over 2 s (a video BIOS's mode set takes
    /// milliseconds, and under emulation tens of them).
    pub const WATCHDOG_TICKS: u16 = 38;

    /// The least time a call runs before the watchdog abandons it, in ms.
    pub const fn limit_millis() -> u32 {
        ((WATCHDOG_TICKS as u64 - 1) * PIT_DIVISOR as u64 * 1000 / PIT_HZ as u64) as u32
    }

    /// The PIC masks for the call: the firmware's own (as it left them to
    /// the loader), with IRQ 0 open, for the watchdog rides on it, and the
    /// cascade (IRQ 2) open whenever a slave line is, or its IRQs could not
    /// arrive.
    pub const fn masks(firmware: [u8; 2]) -> [u8; 2] {
        const IRQ0: u8 = 1 << 0;
        const CASCADE: u8 = 1 << 2;
        let [master, slave] = firmware;
        let master = master & !IRQ0;
        if slave == 0xFF {
            [master, slave]
        } else {
            [master & !CASCADE, slave]
        }
    }
}

/// A descriptor as the CPU would mark it on first load, less that mark: the
/// trampoline's GDT is written fresh before every call.
const fn unaccessed(flags: DescriptorFlags) -> u64 {
    flags.bits() & !DescriptorFlags::ACCESSED.bits()
}

/// The trampoline's GDT for an area at `base` (below 1 MiB).
pub fn descriptors(base: u32) -> [u64; layout::GDT_ENTRIES] {
    // Flat 4 GiB segments: limit 0xFFFFF in pages.
    const CODE_64: u64 = unaccessed(DescriptorFlags::KERNEL_CODE64);
    const CODE_32: u64 = unaccessed(DescriptorFlags::KERNEL_CODE32);
    const DATA_32: u64 = unaccessed(DescriptorFlags::KERNEL_DATA);
    // 64 KiB segments at `base`, byte granular, 16-bit: what real mode expects
    // its segment registers' hidden limits to be.
    const SEGMENT_16: u64 = DescriptorFlags::PRESENT.bits()
        | DescriptorFlags::USER_SEGMENT.bits()
        | DescriptorFlags::WRITABLE.bits() // readable, for code
        | DescriptorFlags::LIMIT_0_15.bits();
    let base_bits = (u64::from(base & 0x00FF_FFFF) << 16) | (u64::from(base >> 24) << 56);
    let code_16 = SEGMENT_16 | DescriptorFlags::EXECUTABLE.bits() | base_bits;
    let data_16 = SEGMENT_16 | base_bits;
    [0, CODE_64, CODE_32, DATA_32, code_16, data_16]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_descriptors_are_the_ones_the_trampoline_was_written_for() {
        let gdt = descriptors(0x0009_1000);
        assert_eq!(gdt[0], 0);
        assert_eq!(gdt[1], 0x00AF_9A00_0000_FFFF); // 64-bit code, L=1
        assert_eq!(gdt[2], 0x00CF_9A00_0000_FFFF); // 32-bit code, D=1, G=1
        assert_eq!(gdt[3], 0x00CF_9200_0000_FFFF); // 32-bit data, B=1, G=1
        assert_eq!(gdt[4], 0x0000_9A09_1000_FFFF); // 16-bit code at the area
        assert_eq!(gdt[5], 0x0000_9209_1000_FFFF); // 16-bit data at the area
    }

    #[test]
    fn a_base_above_16_mib_lands_in_both_base_fields() {
        let gdt = descriptors(0x1234_5678);
        for descriptor in &gdt[4..] {
            assert_eq!((descriptor >> 16) & 0xFF_FFFF, 0x34_5678);
            assert_eq!(descriptor >> 56, 0x12);
            // Byte granular, 16-bit, 64 KiB.
            assert_eq!(descriptor & 0xFFFF, 0xFFFF);
            assert_eq!((descriptor >> 52) & 0xF, 0);
        }
    }

    #[test]
    fn the_watchdog_waits_at_least_2_s() {
        assert_eq!(bios_world::limit_millis(), 2032);
        assert!(bios_world::limit_millis() >= 2000);
    }

    #[test]
    fn the_bios_world_keeps_the_firmware_masks_but_opens_the_timer_and_cascade() {
        // SeaBIOS: timer, keyboard, cascade open; RTC and the disks on the slave.
        assert_eq!(bios_world::masks([0xB8, 0x8E]), [0xB8, 0x8E]);
        // A loader that masked everything: only the watchdog's IRQ 0.
        assert_eq!(bios_world::masks([0xFF, 0xFF]), [0xFE, 0xFF]);
        // The RTC open on the slave, the cascade masked: the cascade opens.
        assert_eq!(bios_world::masks([0xFF, 0xFE]), [0xFA, 0xFE]);
    }

    #[test]
    fn selectors_index_their_descriptors() {
        let gdt = descriptors(0x8000);
        let at = |selector: u16| gdt[usize::from(selector / 8)];
        let executable = |d: u64| d & DescriptorFlags::EXECUTABLE.bits() != 0;
        let long = |d: u64| d & DescriptorFlags::LONG_MODE.bits() != 0;
        let default_32 = |d: u64| d & DescriptorFlags::DEFAULT_SIZE.bits() != 0;
        assert!(executable(at(selector::CODE_64)) && long(at(selector::CODE_64)));
        assert!(executable(at(selector::CODE_32)) && default_32(at(selector::CODE_32)));
        assert!(!executable(at(selector::DATA_32)) && default_32(at(selector::DATA_32)));
        assert!(executable(at(selector::CODE_16)) && !default_32(at(selector::CODE_16)));
        assert!(!executable(at(selector::DATA_16)) && !default_32(at(selector::DATA_16)));
        assert!(usize::from(selector::DATA_16 / 8) < layout::GDT_ENTRIES);
    }

    #[test]
    fn the_data_block_fields_do_not_overlap_and_fit_before_the_code() {
        use layout::*;
        // (offset, size) in memory order.
        let fields = [
            (GDT, GDT_ENTRIES * 8),
            (GDTR, 10),
            (KERNEL_GDTR, 10),
            (KERNEL_IDTR, 10),
            (REAL_IDTR, 10),
            (CR0, 8),
            (CR3, 8),
            (CR4, 8),
            (EFER, 8),
            (RSP, 8),
            (SELECTORS, 12),
            (REAL_SEGMENT, 2),
            (REGISTERS, 28),
            (DS, 2),
            (ES, 2),
            (FLAGS, 2),
            (BIOS_TIMER_VECTOR, 4),
            (WATCHDOG_TICKS, 2),
            (TIMED_OUT, 2),
        ];
        for pair in fields.windows(2) {
            let ((offset, size), (next, _)) = (pair[0], pair[1]);
            assert!(
                offset + size <= next,
                "{offset:#x}+{size} runs into {next:#x}"
            );
        }
        let (last, size) = fields[fields.len() - 1];
        assert!(last + size <= CODE);
        const { assert!(CODE < STACK_TOP && STACK_TOP < AREA) };
    }
}
