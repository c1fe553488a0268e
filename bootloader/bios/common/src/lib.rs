#![no_std]

pub mod racy_cell;
pub mod serial; // Patched

/// Patched (see ../../CHANGES.md, "The boot path on real firmware"): the
/// stacks the BIOS stages run on, and how their use is measured. Stages 2
/// and 3 run on the stack the boot sector set up below 0000:7000, which
/// stage 2 paints from [`STACK_BOTTOM`] up to just below where it runs; stage
/// 4, which goes far deeper, has a stack of its own (`.stack` in its linker
/// script) that it paints at entry. Before it jumps to the kernel, stage 4
/// finds in each the lowest word no longer painted.
pub mod stack {
    /// The lowest address of the boot sector's stack: conventional memory
    /// starts here.
    pub const STACK_BOTTOM: u32 = 0x500;
    /// The boot sector's initial SS:ESP, 0000:7000: the 4 KiB page boundary
    /// below the boot sector (0x7C00) and stage 2 (0x7E00), so that no stack
    /// write lands in a page of their code. Under QEMU's TCG each such write
    /// takes the slow self-modifying-code check; at 0x7C00 that made the
    /// BIOS boot twice as slow (../../CHANGES.md). `_stack_end` in
    /// `boot_sector/boot-sector-link.ld` must match.
    pub const STACK_TOP: u32 = 0x7000;
    /// The paint, one 32-bit word at a time.
    pub const PAINT: u32 = 0x5ca1_ab1e;
    /// Where stage 4 is linked (`bios/stage-4/stage-4-link.ld`).
    pub const STAGE_4_START: u32 = 0x13_0000;
    /// The end of all the memory stage 4 uses from [`STAGE_4_START`]: its
    /// file, its `.bss` and its own stack, none past this (the linker script
    /// asserts it). A loader that places stage 4 keeps this span free.
    pub const STAGE_4_END: u32 = 0x20_0000;

    /// The bytes used of a stack of `size` bytes, given its 32-bit words from
    /// the bottom up: everything above the lowest word that is no longer the
    /// paint.
    pub fn used(words: impl IntoIterator<Item = u32>, size: u32) -> u32 {
        let painted = words.into_iter().take_while(|&word| word == PAINT).count() as u32;
        size.saturating_sub(painted * 4)
    }
}

#[cfg_attr(feature = "debug", derive(Debug))]
#[repr(C)]
pub struct BiosInfo {
    pub stage_4: Region,
    pub kernel: Region,
    pub ramdisk: Region,
    pub config_file: Region,
    pub last_used_addr: u64,
    pub framebuffer: BiosFramebufferInfo,
    pub memory_map_addr: u32,
    pub memory_map_len: u16,
    /// Patched (issue 38): the ACPI RSDP's address when the loader knows it
    /// (the 32-bit UEFI loader, from UEFI's configuration table), else 0:
    /// stage 4 then scans the BIOS areas for it.
    pub rsdp_addr: u64, // Patched
    /// Patched (issue 38): [`FIRMWARE_UEFI`] when UEFI booted the machine
    /// (the 32-bit UEFI loader), [`FIRMWARE_BIOS`] from stage 2.
    pub firmware: u64, // Patched
}

/// Patched (issue 38): `BiosInfo::firmware` on a BIOS boot.
pub const FIRMWARE_BIOS: u64 = 0;
/// Patched (issue 38): `BiosInfo::firmware` when a UEFI loader started stage 4.
pub const FIRMWARE_UEFI: u64 = 1;

// Patched (issue 38): 16-, 32- and 64-bit code share this struct, and 32-bit
// targets may align a u64 at 4 bytes or at 8: the offsets are pinned so that
// every stage reads the fields where the others wrote them.
const _: () = {
    assert!(core::mem::offset_of!(BiosInfo, last_used_addr) == 64);
    assert!(core::mem::offset_of!(BiosInfo, framebuffer) == 72);
    assert!(core::mem::offset_of!(BiosInfo, memory_map_addr) == 104);
    assert!(core::mem::offset_of!(BiosInfo, memory_map_len) == 108);
    assert!(core::mem::offset_of!(BiosInfo, rsdp_addr) == 112);
    assert!(core::mem::offset_of!(BiosInfo, firmware) == 120);
    assert!(core::mem::size_of::<BiosInfo>() == 128);
    assert!(core::mem::size_of::<E820MemoryRegion>() == 24);
};

#[cfg_attr(feature = "debug", derive(Debug))]
#[derive(Clone, Copy)]
#[repr(C)]
pub struct BiosFramebufferInfo {
    pub region: Region,
    pub width: u16,
    pub height: u16,
    pub bytes_per_pixel: u8,
    pub stride: u16,
    pub pixel_format: PixelFormat,
}

#[cfg_attr(feature = "debug", derive(Debug))]
#[derive(Clone, Copy)]
#[repr(C)]
pub struct Region {
    pub start: u64,
    pub len: u64,
}

#[cfg_attr(feature = "debug", derive(Debug))]
#[derive(Clone, Copy)]
#[repr(C)]
pub enum PixelFormat {
    Rgb,
    Bgr,
    Unknown {
        red_position: u8,
        green_position: u8,
        blue_position: u8,
    },
}

impl PixelFormat {
    pub fn is_unknown(&self) -> bool {
        match self {
            PixelFormat::Rgb | PixelFormat::Bgr => false,
            PixelFormat::Unknown { .. } => true,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(C)]
pub struct E820MemoryRegion {
    pub start_addr: u64,
    pub len: u64,
    pub region_type: u32,
    pub acpi_extended_attributes: u32,
}

/// Patched (see ../../CHANGES.md): zeroes the calling stage's `.bss`, between
/// the linker script's `__bss_start` and `__bss_end`. A stage's `.bss` lies
/// past the end of its file, and RAM is not zero at power-on; each stage
/// calls this first, before anything uses a static.
///
/// # Safety
/// Only at a stage's entry, before any static in `.bss` is used, and in a
/// mode that reaches the whole of it (flat protected or long mode, or unreal
/// mode).
///
/// `#[inline]`: compiled only into the stages that call it, since the
/// symbols exist only in their linker scripts (the 32-bit UEFI loader links
/// this crate too).
#[inline]
pub unsafe fn zero_bss() {
    unsafe extern "C" {
        static mut __bss_start: u8;
        static mut __bss_end: u8;
    }
    let end = &raw mut __bss_end;
    let mut at = &raw mut __bss_start;
    while at < end {
        // SAFETY: between the two symbols is this stage's .bss, unused yet
        // (the caller's promise).
        unsafe { at.write_volatile(0) };
        at = at.wrapping_add(1);
    }
}

pub fn hlt() {
    unsafe { core::arch::asm!("hlt") };
}
