#![no_std]
#![no_main]

use crate::memory_descriptor::MemoryRegion;
use bootloader_api::info::{FrameBufferInfo, PixelFormat};
use bootloader_boot_config::{BootConfig, LevelFilter};
use bootloader_x86_64_bios_common::{
    BiosFramebufferInfo, BiosInfo, E820MemoryRegion, racy_cell::RacyCell,
};
use bootloader_x86_64_common::RawFrameBufferInfo;
use bootloader_x86_64_common::{
    Kernel, PageTables, SystemInfo, legacy_memory_region::LegacyFrameAllocator,
};
use core::{cmp, slice};
use loader_logic::memory_map::Entry; // Patched (issue 66)
use usize_conversions::usize_from;
use x86_64::structures::paging::{FrameAllocator, OffsetPageTable};
use x86_64::structures::paging::{
    Mapper, PageTable, PageTableFlags, PhysFrame, Size2MiB, Size4KiB,
};
use x86_64::{PhysAddr, VirtAddr};

const GIGABYTE: u64 = 4096 * 512 * 512;

mod memory_descriptor;

// Patched (see ../../CHANGES.md, "The boot path on real firmware"): stage 4
// used all 30 KiB of the boot sector's stack below 0x7C00 and more, so it
// gets a stack of its own, painted first (RDI, the `BiosInfo`, kept).
core::arch::global_asm!(
    r#"
    .section .start, "ax"
    .global _start
_start:
    cld
    mov rsi, rdi
    mov rdi, offset __stack_bottom
    mov rcx, offset __stack_top
    sub rcx, rdi
    shr rcx, 2
    mov eax, {paint}
    rep stosd
    mov rsp, offset __stack_top
    mov rdi, rsi
    call stage_4
1:
    cli
    hlt
    jmp 1b
"#,
    paint = const bootloader_x86_64_bios_common::stack::PAINT,
);

#[unsafe(no_mangle)]
pub extern "C" fn stage_4(info: &mut BiosInfo) -> ! {
    // Patched (../../CHANGES.md): .bss lies past the end of this file; zero
    // it before anything else.
    // SAFETY: first thing, in long mode with the first 10 GiB identity
    // mapped; no static used yet.
    unsafe { bootloader_x86_64_bios_common::zero_bss() };
    // Patched (issue 66): the screen for a panic before the logger is up.
    // SAFETY: nothing else runs; the panic handler only reads it later.
    unsafe { *PANIC_SCREEN.get_mut() = Some(info.framebuffer) };
    let memory_map: &[E820MemoryRegion] = unsafe {
        core::slice::from_raw_parts(
            info.memory_map_addr as *const _,
            usize::from(info.memory_map_len),
        )
    };

    // Patched (issue 66): one sanitised map, made here once, for the frame
    // allocator and the kernel's boot info (../../CHANGES.md): upstream only
    // sorted it, and a reserved range inside a usable one stayed usable.
    let memory_map = sanitised_memory_map(memory_map);

    let max_phys_addr = {
        let max = memory_map
            .iter()
            .map(|r| {
                log::info!("start: {:#x}, len: {:#x}", r.start, r.len);
                r.start + r.len // Patched (issue 66): a sanitised range
            })
            .max()
            .expect("no physical memory regions found");
        // Don't consider addresses > 4GiB when determining the maximum physical
        // address for the bootloader, as we are in protected mode and cannot
        // address more than 4 GiB of memory anyway.
        cmp::min(max, 4 * GIGABYTE)
    };

    let kernel_start = {
        assert!(info.kernel.start != 0, "kernel start address must be set");
        PhysAddr::new(info.kernel.start)
    };
    let kernel_size = info.kernel.len;
    let next_free_frame = PhysFrame::containing_address(PhysAddr::new(info.last_used_addr)) + 1;
    // Patched (issue 38): the regions say whether UEFI made the map.
    let uefi = info.firmware == bootloader_x86_64_bios_common::FIRMWARE_UEFI; // Patched
    let mut frame_allocator = LegacyFrameAllocator::new_starting_at(
        next_free_frame,
        // Patched (issue 66): the sanitised ranges as E820 entries.
        memory_map.iter().map(move |range| {
            let region = E820MemoryRegion {
                start_addr: range.start,
                len: range.len,
                region_type: range.kind,
                acpi_extended_attributes: 1,
            };
            MemoryRegion(region, uefi)
        }), // Patched
    );

    // We identity-mapped all memory, so the offset between physical and virtual addresses is 0
    let phys_offset = VirtAddr::new(0);

    let mut bootloader_page_table = {
        let frame = x86_64::registers::control::Cr3::read().0;
        let table: *mut PageTable = (phys_offset + frame.start_address().as_u64()).as_mut_ptr();
        unsafe { OffsetPageTable::new(&mut *table, phys_offset) }
    };
    // identity-map remaining physical memory (first 10 gigabytes are already identity-mapped)
    {
        let start_frame: PhysFrame<Size2MiB> =
            PhysFrame::containing_address(PhysAddr::new(GIGABYTE * 10));
        let end_frame = PhysFrame::containing_address(PhysAddr::new(max_phys_addr - 1));
        for frame in PhysFrame::range_inclusive(start_frame, end_frame) {
            let flusher = unsafe {
                bootloader_page_table
                    .identity_map(
                        frame,
                        PageTableFlags::PRESENT
                            | PageTableFlags::WRITABLE
                            | bootloader_x86_64_common::no_execute(), // Patched: none without NX
                        &mut frame_allocator,
                    )
                    .unwrap()
            };
            // skip flushing the entry from the TLB for now, as we will
            // flush the entire TLB at the end of the loop.
            flusher.ignore();
        }
    }

    // once all the physical memory is mapped, flush the TLB by reloading the
    // CR3 register.
    //
    // we perform a single flush here rather than flushing each individual entry as
    // it's mapped using `invlpg`, for efficiency.
    x86_64::instructions::tlb::flush_all();

    let page_tables = create_page_tables(&mut frame_allocator);

    let kernel_slice = {
        let ptr = kernel_start.as_u64() as *const u8;
        unsafe { slice::from_raw_parts(ptr, usize_from(kernel_size)) }
    };
    let kernel = Kernel::parse(kernel_slice);

    let mut config_file_slice: Option<&[u8]> = None;
    if info.config_file.len != 0 {
        config_file_slice = {
            let ptr = info.config_file.start as *mut u8;
            unsafe {
                Some(slice::from_raw_parts_mut(
                    ptr,
                    usize_from(info.config_file.len),
                ))
            }
        };
    }
    let mut error_loading_config: Option<serde_json_core::de::Error> = None;
    let mut config: BootConfig = match config_file_slice
        .map(serde_json_core::from_slice)
        .transpose()
    {
        Ok(data) => data.unwrap_or_default().0,
        Err(err) => {
            error_loading_config = Some(err);
            Default::default()
        }
    };

    #[allow(deprecated)]
    if config.frame_buffer.minimum_framebuffer_height.is_none() {
        config.frame_buffer.minimum_framebuffer_height =
            kernel.config.frame_buffer.minimum_framebuffer_height;
    }
    #[allow(deprecated)]
    if config.frame_buffer.minimum_framebuffer_width.is_none() {
        config.frame_buffer.minimum_framebuffer_width =
            kernel.config.frame_buffer.minimum_framebuffer_width;
    }
    let framebuffer_info = init_logger(
        info.framebuffer,
        config.log_level,
        config.frame_buffer_logging,
        config.serial_logging,
    );

    if let Some(err) = error_loading_config {
        log::warn!("Failed to deserialize the config file {:?}", err);
    }

    log::info!("4th Stage");
    log::info!("{info:x?}");
    log::info!(
        "{}",
        if uefi {
            "UEFI boot (32-bit UEFI loader)"
        } else {
            "BIOS boot"
        }
    ); // Patched

    let system_info = SystemInfo {
        // Patched: stage 2 hands on a zero-length region when it set no VESA
        // mode; the boot info then says there is no framebuffer.
        framebuffer: (info.framebuffer.region.len != 0).then(|| RawFrameBufferInfo {
            addr: PhysAddr::new(info.framebuffer.region.start),
            info: framebuffer_info,
        }),
        // Patched (issue 38): the loader's RSDP first (UEFI puts none where
        // `detect_rsdp` scans); a BIOS boot gives 0 and is scanned for.
        rsdp_addr: match info.rsdp_addr {
            0 => detect_rsdp(),
            addr => Some(PhysAddr::new(addr)),
        }, // Patched
        ramdisk_addr: match info.ramdisk.len {
            0 => None,
            _ => Some(info.ramdisk.start),
        },
        ramdisk_len: info.ramdisk.len,
    };

    // Patched: the three steps of `load_and_switch_to_kernel`, so that the
    // stack stages 2 to 4 used can be measured after the deepest of them.
    let mut page_tables = page_tables;
    let kernel_config = kernel.config;
    let mut mappings = bootloader_x86_64_common::set_up_mappings(
        kernel,
        &mut frame_allocator,
        &mut page_tables,
        system_info.framebuffer.as_ref(),
        &kernel_config,
        &system_info,
    );
    let boot_info = bootloader_x86_64_common::create_boot_info(
        &kernel_config,
        &config,
        frame_allocator,
        &mut page_tables,
        &mut mappings,
        system_info,
    );
    report_stack_use(uefi);
    bootloader_x86_64_common::switch_to_kernel(page_tables, mappings, boot_info);
}

/// Patched (issue 66): the sanitised map's room: two ranges for every entry
/// of stage 2's table (100), more than the 32-bit UEFI loader's merged map
/// has on any machine seen; ranges past it are dropped from the top and said.
const SANITISED_CAPACITY: usize = 512;

static SANITISED: RacyCell<[Entry<u32>; SANITISED_CAPACITY]> = RacyCell::new(
    [Entry {
        start: 0,
        len: 0,
        kind: 0,
    }; SANITISED_CAPACITY],
);

/// Patched (issue 66): the firmware's map (stage 2's E820 table, or the
/// 32-bit UEFI loader's from UEFI's descriptors) sanitised by
/// `loader_logic::memory_map`, said on COM1 (`loader: memory: ...`, then each
/// range as Linux prints E820 tables); a map without usable RAM above 1 MiB,
/// where stage 4 and the kernel's page tables must go, is a panic that says
/// so.
fn sanitised_memory_map(given: &[E820MemoryRegion]) -> &'static [Entry<u32>] {
    use core::fmt::Write as _;
    use loader_logic::memory_map::{e820_strictness, sanitise, usable_above};
    // SAFETY: called once, before anything else uses the table.
    let table = unsafe { SANITISED.get_mut() };
    let report = sanitise(
        given.iter().map(|region| Entry {
            start: region.start_addr,
            len: region.len,
            kind: region.region_type,
        }),
        e820_strictness,
        table,
    );
    let mut com1 = bootloader_x86_64_bios_common::serial::Com1;
    let _ = writeln!(com1, "loader: memory: {report}");
    for range in &table[..report.ranges] {
        let _ = writeln!(
            com1,
            "loader: memory: [mem {:#018x}-{:#018x}] {}",
            range.start,
            range.start + range.len - 1,
            E820Kind(range.kind)
        );
    }
    let table = &table[..report.ranges];
    if !usable_above(table, e820_strictness, 0x10_0000) {
        panic!("the memory map has no usable RAM above 1 MiB ({report})");
    }
    table
}

/// Patched (issue 66): an E820 type as Linux's dmesg names it.
struct E820Kind(u32);

impl core::fmt::Display for E820Kind {
    fn fmt(&self, f: &mut core::fmt::Formatter) -> core::fmt::Result {
        match self.0 {
            1 => write!(f, "usable"),
            2 => write!(f, "reserved"),
            3 => write!(f, "ACPI data"),
            4 => write!(f, "ACPI NVS"),
            5 => write!(f, "unusable"),
            other => write!(f, "type {other}"),
        }
    }
}

/// Patched: how deep stages 2 and 3 went on the boot sector's stack (on a
/// BIOS boot; the 32-bit UEFI loader paints none) and stage 4 on its own, on
/// COM1: `loader: stack: stages 2-3 used N of M bytes, stage 4 used N of M
/// bytes`, or `loader: stack: stage 4 used N of M bytes`.
fn report_stack_use(uefi: bool) {
    use bootloader_x86_64_bios_common::stack::{STACK_BOTTOM, STACK_TOP, used};
    use core::fmt::Write as _;
    unsafe extern "C" {
        static __stack_bottom: u8;
        static __stack_top: u8;
    }
    let words = |bottom: usize, top: usize| {
        (bottom..top).step_by(4).map(|address| {
            // SAFETY: a stack region of this loader (conventional memory, or
            // stage 4's `.stack`), identity-mapped; only read.
            unsafe { (address as *const u32).read_volatile() }
        })
    };
    let mut com1 = bootloader_x86_64_bios_common::serial::Com1;
    let _ = write!(com1, "loader: stack: ");
    if !uefi {
        let (bottom, top) = (STACK_BOTTOM as usize, STACK_TOP as usize);
        let used_below_7c00 = used(words(bottom, top), (top - bottom) as u32);
        let _ = write!(
            com1,
            "stages 2-3 used {used_below_7c00} of {} bytes, ",
            top - bottom
        );
    }
    let (bottom, top) = (
        &raw const __stack_bottom as usize,
        &raw const __stack_top as usize,
    );
    let own_stack = used(words(bottom, top), (top - bottom) as u32);
    let _ = writeln!(com1, "stage 4 used {own_stack} of {} bytes", top - bottom);
}

fn init_logger(
    info: BiosFramebufferInfo,
    log_level: LevelFilter,
    frame_buffer_logger_status: bool,
    serial_logger_status: bool,
) -> FrameBufferInfo {
    let framebuffer_info = FrameBufferInfo {
        byte_len: info.region.len.try_into().unwrap(),
        width: info.width.into(),
        height: info.height.into(),
        pixel_format: match info.pixel_format {
            bootloader_x86_64_bios_common::PixelFormat::Rgb => PixelFormat::Rgb,
            bootloader_x86_64_bios_common::PixelFormat::Bgr => PixelFormat::Bgr,
            bootloader_x86_64_bios_common::PixelFormat::Unknown {
                red_position,
                green_position,
                blue_position,
            } => PixelFormat::Unknown {
                red_position,
                green_position,
                blue_position,
            },
        },
        bytes_per_pixel: info.bytes_per_pixel.into(),
        stride: info.stride.into(),
    };

    // Patched: no framebuffer (a zero-length region from stage 2) means no
    // framebuffer logging, and no slice made from a null address.
    let has_framebuffer = info.region.len != 0;
    let framebuffer: &'static mut [u8] = if has_framebuffer {
        unsafe {
            core::slice::from_raw_parts_mut(
                info.region.start as *mut u8,
                info.region.len.try_into().unwrap(),
            )
        }
    } else {
        &mut []
    };

    bootloader_x86_64_common::init_logger(
        framebuffer,
        framebuffer_info,
        log_level,
        frame_buffer_logger_status && has_framebuffer,
        serial_logger_status,
    );

    framebuffer_info
}

/// Creates page table abstraction types for both the bootloader and kernel page tables.
fn create_page_tables(frame_allocator: &mut impl FrameAllocator<Size4KiB>) -> PageTables {
    // We identity-mapped all memory, so the offset between physical and virtual addresses is 0
    let phys_offset = VirtAddr::new(0);

    // copy the currently active level 4 page table, because it might be read-only
    let bootloader_page_table = {
        let frame = x86_64::registers::control::Cr3::read().0;
        let table: *mut PageTable = (phys_offset + frame.start_address().as_u64()).as_mut_ptr();
        unsafe { OffsetPageTable::new(&mut *table, phys_offset) }
    };

    // create a new page table hierarchy for the kernel
    let (kernel_page_table, kernel_level_4_frame) = {
        // get an unused frame for new level 4 page table
        let frame: PhysFrame = frame_allocator.allocate_frame().expect("no unused frames");
        log::info!("New page table at: {frame:#?}");
        // get the corresponding virtual address
        let addr = phys_offset + frame.start_address().as_u64();
        // initialize a new page table
        let ptr: *mut PageTable = addr.as_mut_ptr();
        unsafe { ptr.write(PageTable::new()) };
        let level_4_table = unsafe { &mut *ptr };
        (
            unsafe { OffsetPageTable::new(level_4_table, phys_offset) },
            frame,
        )
    };

    PageTables {
        bootloader: bootloader_page_table,
        kernel: kernel_page_table,
        kernel_level_4_frame,
    }
}

fn detect_rsdp() -> Option<PhysAddr> {
    use core::ptr::NonNull;
    use rsdp::{
        Rsdp,
        handler::{AcpiHandler, PhysicalMapping},
    };

    #[derive(Clone)]
    struct IdentityMapped;
    impl AcpiHandler for IdentityMapped {
        // TODO FIXME: This inline(never) annotation is required. Without it,
        // LLVM replaces the `search_for_on_bios` call below with a `ud2`
        // instruction. See https://github.com/rust-osdev/bootloader/issues/425
        #[inline(never)]
        unsafe fn map_physical_region<T>(
            &self,
            physical_address: usize,
            size: usize,
        ) -> PhysicalMapping<Self, T> {
            unsafe {
                PhysicalMapping::new(
                    physical_address,
                    NonNull::new(physical_address as *mut _).unwrap(),
                    size,
                    size,
                    Self,
                )
            }
        }

        fn unmap_physical_region<T>(_region: &PhysicalMapping<Self, T>) {}
    }

    unsafe {
        Rsdp::search_for_on_bios(IdentityMapped)
            .ok()
            .map(|mapping| PhysAddr::new(mapping.physical_start() as u64))
    }
}

/// Patched (issue 66): the framebuffer stage 2 or the 32-bit UEFI loader
/// handed on, for a panic before the logger draws on it.
static PANIC_SCREEN: RacyCell<Option<BiosFramebufferInfo>> = RacyCell::new(None);

/// Patched (issue 66): a panic is said on COM1 and on the screen, with its
/// file and line (`PanicInfo`'s text), however early: upstream only logged
/// it, and before the logger is set up that went nowhere.
#[cfg(target_os = "none")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    use core::fmt::Write as _;
    let _ = writeln!(
        bootloader_x86_64_bios_common::serial::Com1,
        "loader: PANIC: {info}"
    );
    match bootloader_x86_64_common::logger::LOGGER.get() {
        // SAFETY: this CPU stopped wherever it held the lock, and nothing
        // else runs; the logger is only written from here on.
        Some(logger) => unsafe { logger.force_unlock() },
        // SAFETY: only read; set once at entry.
        None => match unsafe { *PANIC_SCREEN.get_mut() } {
            Some(screen) if screen.region.len != 0 => {
                init_logger(screen, LevelFilter::Error, true, false);
            }
            _ => {
                let _ = writeln!(VgaText, "loader: PANIC: {info}");
            }
        },
    }
    log::error!("loader: PANIC: {info}");
    loop {
        // SAFETY: halting with interrupts off stops this CPU; nothing follows.
        unsafe { core::arch::asm!("cli; hlt") };
    }
}

/// Patched (issue 66): the VGA text screen (0xB8000, identity-mapped), when
/// stage 2 set no VESA mode: text from the top row, in white on red.
struct VgaText;

impl core::fmt::Write for VgaText {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        const CELLS: usize = 80 * 25;
        static AT: RacyCell<usize> = RacyCell::new(0);
        // SAFETY: only the panic handler writes, on this one CPU.
        let at = unsafe { AT.get_mut() };
        for byte in s.bytes() {
            if byte == b'\n' {
                *at = (*at / 80 + 1) * 80;
                continue;
            }
            if *at >= CELLS {
                break;
            }
            let shown = if byte.is_ascii_graphic() || byte == b' ' {
                byte
            } else {
                b'?'
            };
            // SAFETY: a cell of the VGA text buffer (`at` below 80x25).
            unsafe { ((0xb8000 as *mut u16).add(*at)).write_volatile(0x4f00 | u16::from(shown)) };
            *at += 1;
        }
        Ok(())
    }
}
