//! Patched (issue 38, see ../CHANGES.md): the 32-bit UEFI loader,
//! `EFI/BOOT/BOOTIA32.EFI`, for PCs with a 64-bit CPU and a 32-bit UEFI (Bay
//! Trail tablets, Compute Sticks). As Linux's EFI mixed mode does with its
//! 32-bit stub, it does the firmware's part in 32-bit code and then runs the
//! 64-bit code the BIOS route already has: it reads BIOS stage 4 and the
//! kernel from the ESP it was started from, describes the GOP's framebuffer
//! and UEFI's memory map in stage 4's terms (`BiosInfo`, E820 entries), leaves
//! boot services, enters long mode and calls stage 4, which loads the kernel
//! as on a BIOS boot.
//!
//! Every failure is a line on the UEFI console and COM1, and then a wait; the
//! machine is never reset.

#![no_std]
#![no_main]
#![deny(unsafe_op_in_unsafe_fn)]

mod long_mode;
// The 64-bit loader's Secure Boot reading, the one copy (issue 48).
#[path = "../../uefi/src/secure_boot_state.rs"]
mod secure_boot_state;
// Whether the firmware copies its console to COM1 (issue 48), the same.
#[path = "../../uefi/src/firmware_console.rs"]
mod firmware_console;

// COM1 polled with a bound, and stage 4's span: the BIOS stages' own.
use bootloader_x86_64_bios_common::{
    BiosFramebufferInfo, BiosInfo, E820MemoryRegion, FIRMWARE_UEFI, PixelFormat, Region, serial,
    stack,
};
use core::fmt::{self, Write as _};
use core::ptr::{self, NonNull};
use core::time::Duration;
use loader_logic::cpu;
use loader_logic::file_hash::{self, HashSlot};
use loader_logic::uefi_map::{self, E820Entry, UefiRegion};
use uefi::boot::{self, AllocateType, MemoryType};
use uefi::proto::console::gop::{GraphicsOutput, PixelFormat as GopPixelFormat};
use uefi::proto::media::file::{File, FileAttribute, FileInfo, FileMode, RegularFile};
use uefi::table::cfg::ConfigTableEntry;
use uefi::{CStr16, Status, cstr16, entry};

/// Where stage 4 is linked (`bios/stage-4/stage-4-link.ld`).
const STAGE_4_ADDR: u64 = stack::STAGE_4_START as u64;
/// All the memory stage 4 uses from there: its file, then its `.bss` and its
/// own stack, which the flat binary does not hold.
const STAGE_4_SPAN: usize = (stack::STAGE_4_END - stack::STAGE_4_START) as usize;
/// The stack the switch to long mode and stage 4's entry run on, until
/// stage 4 moves to its own (`.stack` in its linker script).
const STACK_BYTES: usize = 16 * 1024;
/// Everything stage 4 reads must be below 4 GiB (it takes 32-bit addresses).
const BELOW_4_GIB: u64 = 0xFFFF_F000;
const PAGE: usize = 4096;

const STAGE_4_FILE: &CStr16 = cstr16!("boot-stage-4");
const KERNEL_FILE: &CStr16 = cstr16!("kernel-x86_64");
const CONFIG_FILE: &CStr16 = cstr16!("boot.json");

#[entry]
fn main() -> Status {
    serial::init();
    // The firmware's watchdog would reset the machine after 5 minutes,
    // also while a message waits to be read: off.
    if let Err(error) = boot::set_watchdog_timer(0, 0x10000, None) {
        say(format_args!(
            "loader: the watchdog could not be switched off ({:?}); going on\n",
            error.status()
        ));
    }
    say(format_args!("loader: loading kernel (UEFI IA32)\n"));
    check_cpu();

    let stage_4 = read_file(STAGE_4_FILE, Placement::Stage4).unwrap_or_else(|why| stop(why));
    let kernel = read_file(KERNEL_FILE, Placement::Below4Gib).unwrap_or_else(|why| stop(why));
    // Issue 48: both checked before anything of them runs.
    check_hash(file_hash::File::Stage4, stage_4);
    check_hash(file_hash::File::Kernel, kernel);
    let config = match read_file(CONFIG_FILE, Placement::Below4Gib) {
        Ok(region) => region,
        Err(Failure::NotFound(_)) => Region { start: 0, len: 0 },
        Err(why) => stop(why),
    };
    let framebuffer = framebuffer();
    let rsdp_addr = rsdp();
    // The Secure Boot record as the kernel's ramdisk, as the 64-bit loader
    // hands it over (issue 48); without a page the kernel says "unknown".
    let secure_boot = match secure_boot_state::record_as_ramdisk() {
        Some((record, page)) => {
            say(format_args!("loader: secure boot state {record:?}\n"));
            Region {
                start: page.as_ptr() as u64,
                len: page.len() as u64,
            }
        }
        None => {
            say(format_args!(
                "loader: no memory for the Secure Boot record; the kernel will say \"unknown\"\n"
            ));
            Region { start: 0, len: 0 }
        }
    };

    // Loader data for what stage 4 reads after boot services: its BiosInfo,
    // the handoff and GDT for the switch, the page tables, its stack.
    let info_page = allocate(PAGE, "the boot information").unwrap_or_else(|why| stop(why));
    let tables =
        allocate(long_mode::TABLE_PAGES * PAGE, "the page tables").unwrap_or_else(|why| stop(why));
    let stack = allocate(STACK_BYTES, "stage 4's stack").unwrap_or_else(|why| stop(why));
    // SAFETY: `tables` is TABLE_PAGES fresh pages of loader data, identity-
    // mapped, page-aligned, owned by nothing else.
    let pml4 = unsafe {
        let slice = core::slice::from_raw_parts_mut(
            tables.as_ptr().cast::<[u64; 512]>(),
            long_mode::TABLE_PAGES,
        );
        long_mode::build_tables(slice, tables.as_ptr() as u32)
    };

    // The memory map's buffer and the E820 table, sized from the map now
    // (with room for the descriptors these allocations and ExitBootServices
    // may add).
    let (map_bytes, descriptor_size) = memory_map_size().unwrap_or_else(|why| stop(why));
    let map_capacity = map_bytes + 16 * descriptor_size;
    let map_buffer =
        allocate(map_capacity + 2 * PAGE, "the memory map").unwrap_or_else(|why| stop(why));
    let map_buffer_len = (map_capacity + 2 * PAGE).next_multiple_of(PAGE);
    let table_entries = (map_buffer_len / descriptor_size).min(usize::from(u16::MAX));
    let table = allocate(
        table_entries * core::mem::size_of::<E820Entry>(),
        "the E820 table",
    )
    .unwrap_or_else(|why| stop(why));

    say(format_args!(
        "loader: stage 4 at {:#x}, kernel at {:#x} ({} bytes); leaving boot services\n",
        stage_4.start, kernel.start, kernel.len
    ));

    // SAFETY: the buffer is `map_buffer_len` bytes of our loader data.
    let map = unsafe { core::slice::from_raw_parts_mut(map_buffer.as_ptr(), map_buffer_len) };
    let (map_len, descriptor_size) = match exit_boot_services(map) {
        Ok(sizes) => sizes,
        // The console may be gone already: COM1 alone from here on.
        Err(why) => stop_after_exit(why),
    };

    // SAFETY: `table` holds `table_entries` entries of loader data; the
    // E820Entry's all-zero pattern is valid.
    let entries = unsafe {
        core::slice::from_raw_parts_mut(table.as_ptr().cast::<E820Entry>(), table_entries)
    };
    let regions = (0..map_len / descriptor_size).map(|index| {
        // SAFETY: inside the map the firmware wrote; descriptors are
        // `descriptor_size` apart, each at least a `MemoryDescriptor`.
        let descriptor = unsafe {
            ptr::read_unaligned(
                map.as_ptr()
                    .add(index * descriptor_size)
                    .cast::<uefi_raw::table::boot::MemoryDescriptor>(),
            )
        };
        UefiRegion {
            uefi_type: descriptor.ty.0,
            start: descriptor.phys_start,
            pages: descriptor.page_count,
        }
    });
    let count = match uefi_map::convert(regions, entries) {
        Ok(count) => count,
        Err(full) => stop_after_exit(Failure::TableFull(full.capacity)),
    };
    // Stage 4 reads `E820MemoryRegion`s: the same 24 bytes, written in place.
    let e820 = table.as_ptr().cast::<E820MemoryRegion>();
    // By index, each entry copied out before its slot is written: no
    // reference into the table is held across a write through `e820`.
    #[allow(clippy::needless_range_loop)]
    for index in 0..count {
        let entry = entries[index];
        // SAFETY: index < count <= table_entries; entry `index` was read
        // above, and E820MemoryRegion has E820Entry's size (checked in
        // bios/common and below).
        unsafe {
            e820.add(index).write(E820MemoryRegion {
                start_addr: entry.start,
                len: entry.len,
                region_type: entry.e820_type,
                acpi_extended_attributes: 1,
            })
        };
    }

    let info = info_page.as_ptr().cast::<BiosInfo>();
    let handoff_at = info_page.as_ptr() as usize + 256;
    let gdt_at = info_page.as_ptr() as usize + 512;
    // SAFETY: the info page is a fresh page of loader data: the BiosInfo at
    // its start (128 bytes), the handoff at 256, the GDT at 512.
    unsafe {
        info.write(BiosInfo {
            stage_4,
            kernel,
            ramdisk: secure_boot,
            config_file: config,
            // Stage 4's allocator starts after it; the rest of the loader's
            // data is kept from it by the map (reserved).
            last_used_addr: u64::from(stack::STAGE_4_END) - 1,
            framebuffer,
            memory_map_addr: e820 as u32,
            memory_map_len: count as u16,
            rsdp_addr,
            firmware: FIRMWARE_UEFI,
        });
        (gdt_at as *mut [u64; 3]).write(long_mode::GDT);
        (handoff_at as *mut long_mode::Handoff).write(long_mode::Handoff::new(
            gdt_at as u32,
            pml4,
            stack.as_ptr() as u32 + STACK_BYTES as u32,
            stage_4.start as u32,
            info as u32,
        ));
        long_mode::enter_stage_4(handoff_at as *const long_mode::Handoff)
    }
}

const _: () =
    assert!(core::mem::size_of::<E820Entry>() == core::mem::size_of::<E820MemoryRegion>());

/// Why the loader stopped.
enum Failure {
    Cpu(cpu::Refusal),
    NotFound(&'static CStr16),
    Unreadable(&'static CStr16, Status),
    NotAFile(&'static CStr16),
    BadSize(&'static CStr16),
    Stage4Busy(Status),
    NoMemory(&'static str, Status),
    MemoryMap(&'static str, Status),
    DescriptorTooSmall(usize),
    ExitBootServices(Status),
    TableFull(usize),
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        match self {
            Failure::Cpu(refusal) => write!(f, "{refusal}"),
            Failure::NotFound(name) => write!(
                f,
                "{name} is not on the stick's EFI partition; write the stick again"
            ),
            Failure::Unreadable(name, status) => write!(
                f,
                "{name} could not be read from the stick ({status:?}); see the lines above"
            ),
            Failure::NotAFile(name) => write!(f, "{name} on the stick is a directory, not a file"),
            Failure::BadSize(name) => write!(
                f,
                "{name} on the stick is empty or too large; write the stick again"
            ),
            Failure::Stage4Busy(status) => write!(
                f,
                "the memory stage 4 must occupy (from 0x130000) is not free ({status:?})"
            ),
            Failure::NoMemory(what, status) => write!(f, "no memory for {what} ({status:?})"),
            Failure::MemoryMap(when, status) => {
                write!(f, "GetMemoryMap {when} failed ({status:?})")
            }
            Failure::DescriptorTooSmall(size) => write!(
                f,
                "the firmware's memory descriptors are too small ({size} bytes)"
            ),
            Failure::ExitBootServices(status) => write!(
                f,
                "ExitBootServices failed ({status:?}), twice with a fresh map"
            ),
            Failure::TableFull(capacity) => write!(
                f,
                "the memory map has more entries than the {capacity} its table holds"
            ),
        }
    }
}

/// A line on the UEFI console (the screen) and on COM1, once: COM1 is
/// written here unless the line reached a console that the firmware copies
/// to COM1 itself (OVMF's; `firmware_console`, issue 48).
fn say(args: fmt::Arguments) {
    // The console wants CR LF.
    let on_console = console_available()
        && uefi::system::with_stdout(|stdout| ConsoleLines(stdout).write_fmt(args).is_ok());
    if loader_logic::console::com1_too(on_console, firmware_console::copies_to_com1) {
        let _ = serial::Com1.write_fmt(args);
    }
}

struct ConsoleLines<'a>(&'a mut uefi::proto::console::text::Output);

impl fmt::Write for ConsoleLines<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for (index, line) in s.split('\n').enumerate() {
            if index > 0 {
                self.0.write_str("\r\n")?;
            }
            self.0.write_str(line)?;
        }
        Ok(())
    }
}

fn console_available() -> bool {
    uefi::table::system_table_raw().is_some_and(|st| {
        // SAFETY: set by the entry macro before `main`; only read here.
        let st = unsafe { st.as_ref() };
        !st.boot_services.is_null() && !st.stdout.is_null()
    })
}

/// The SHA-256 of stage 4 and of the kernel file, written into this slot of
/// the PE file by the image build (`bootloader/src/lib.rs`,
/// `loader_logic::file_hash`), as for the 64-bit loader (issue 48).
static FILE_HASHES: HashSlot = HashSlot::EMPTY;

/// The file in `region`, as read, against [`FILE_HASHES`]: the firmware may
/// hand back wrong bytes as a good read. A mismatch is a stop.
fn check_hash(file: file_hash::File, region: Region) {
    // SAFETY: a read of a static of plain bytes. Volatile, so that the
    // compiler cannot fold in the zeros it was built with: the image build
    // writes the hashes into the file.
    let expected = unsafe { ptr::read_volatile(&raw const FILE_HASHES) };
    // SAFETY: `region` is the file as `read_file` read it into pages of our
    // loader data, below 4 GiB; read only.
    let bytes = unsafe {
        core::slice::from_raw_parts(region.start as usize as *const u8, region.len as usize)
    };
    if let Err(mismatch) = expected.check(file, file_hash::sha256(bytes)) {
        wait_forever(format_args!("{mismatch}\n"));
    }
}

/// Says why on the screen and COM1 and waits for good: the firmware's
/// stall, a second at a time (the watchdog is off); never a reset.
fn stop(why: Failure) -> ! {
    wait_forever(format_args!("loader: stopped: {why}\n"))
}

/// Says `line` on the screen and COM1 and waits for good (see [`stop`]).
fn wait_forever(line: fmt::Arguments) -> ! {
    say(line);
    loop {
        boot::stall(Duration::from_secs(1));
    }
}

/// After ExitBootServices (or a failed attempt) only COM1 is left.
fn stop_after_exit(why: Failure) -> ! {
    let _ = writeln!(serial::Com1, "loader: stopped: {why}");
    loop {
        // SAFETY: halting with interrupts off stops this CPU; nothing follows.
        unsafe { core::arch::asm!("cli", "hlt") };
    }
}

/// What the kernel needs of the CPU (`loader_logic::cpu`: long mode, PAE,
/// SSE2), or a stop that names the CPU. Every UEFI PC's CPU has CPUID.
fn check_cpu() {
    if let Err(refusal) = cpu::check(cpu::CpuidReadings::read()) {
        stop(Failure::Cpu(refusal));
    }
}

/// Where a file goes.
#[derive(Clone, Copy)]
enum Placement {
    /// At stage 4's link address, with zeroed room after it for its `.bss`.
    Stage4,
    /// Anywhere below 4 GiB.
    Below4Gib,
}

/// Reads a file of the ESP this loader was started from into loader data;
/// a failed read is tried once more.
fn read_file(name: &'static CStr16, placement: Placement) -> Result<Region, Failure> {
    let mut last = Status::SUCCESS;
    for attempt in 0..2 {
        match read_file_once(name, placement) {
            Ok(region) => return Ok(region),
            Err(ReadError::NotFound) => return Err(Failure::NotFound(name)),
            Err(ReadError::Firmware(step, status)) => {
                say(format_args!(
                    "loader: reading {name}: {step} failed ({status:?}){}\n",
                    if attempt == 0 { "; trying again" } else { "" }
                ));
                last = status;
            }
            Err(ReadError::Fatal(why)) => return Err(why),
        }
    }
    Err(Failure::Unreadable(name, last))
}

enum ReadError {
    NotFound,
    Firmware(&'static str, Status),
    Fatal(Failure),
}

fn read_file_once(name: &'static CStr16, placement: Placement) -> Result<Region, ReadError> {
    let firmware = |step| move |error: uefi::Error| ReadError::Firmware(step, error.status());
    let mut file_system = boot::get_image_file_system(boot::image_handle())
        .map_err(firmware("opening the loader's file system"))?;
    let mut root = file_system
        .open_volume()
        .map_err(firmware("opening the volume"))?;
    let handle = match root.open(name, FileMode::Read, FileAttribute::empty()) {
        Ok(handle) => handle,
        Err(error) if error.status() == Status::NOT_FOUND => return Err(ReadError::NotFound),
        Err(error) => return Err(ReadError::Firmware("opening the file", error.status())),
    };
    let Some(mut file): Option<RegularFile> = handle.into_regular_file() else {
        return Err(ReadError::Fatal(Failure::NotAFile(name)));
    };
    #[repr(C, align(8))]
    struct InfoBuffer([u8; 512]);
    let mut buffer = InfoBuffer([0; 512]);
    let size = file
        .get_info::<FileInfo>(&mut buffer.0)
        .map_err(|error| ReadError::Firmware("reading its size", error.status()))?
        .file_size();
    if size == 0 || size > u64::from(u32::MAX / 2) {
        return Err(ReadError::Fatal(Failure::BadSize(name)));
    }
    let size = size as usize;
    let (room, allocation) = match placement {
        Placement::Stage4 if size >= STAGE_4_SPAN => {
            return Err(ReadError::Fatal(Failure::BadSize(name)));
        }
        Placement::Stage4 => (STAGE_4_SPAN, AllocateType::Address(STAGE_4_ADDR)),
        Placement::Below4Gib => (size, AllocateType::MaxAddress(BELOW_4_GIB)),
    };
    let pages = room.div_ceil(PAGE);
    let memory =
        boot::allocate_pages(allocation, MemoryType::LOADER_DATA, pages).map_err(|error| {
            ReadError::Fatal(match placement {
                Placement::Stage4 => Failure::Stage4Busy(error.status()),
                Placement::Below4Gib => Failure::NoMemory("a file of the stick", error.status()),
            })
        })?;
    // SAFETY: `pages` fresh pages of loader data, identity-mapped.
    let bytes = unsafe {
        ptr::write_bytes(memory.as_ptr(), 0, pages * PAGE);
        core::slice::from_raw_parts_mut(memory.as_ptr(), size)
    };
    let mut done = 0;
    let mut result = Ok(());
    while done < size {
        match file.read(&mut bytes[done..]) {
            Ok(0) => {
                result = Err(ReadError::Firmware(
                    "reading (it ended early)",
                    Status::END_OF_FILE,
                ));
                break;
            }
            Ok(read) => done += read,
            Err(error) => {
                result = Err(ReadError::Firmware("reading", error.status()));
                break;
            }
        }
    }
    if let Err(error) = result {
        // SAFETY: the pages allocated above, no longer used.
        let _ = unsafe { boot::free_pages(memory, pages) };
        return Err(error);
    }
    Ok(Region {
        start: memory.as_ptr() as u64,
        len: size as u64,
    })
}

/// `bytes` of zeroed loader data below 4 GiB, page-aligned.
fn allocate(bytes: usize, what: &'static str) -> Result<NonNull<u8>, Failure> {
    let pages = bytes.div_ceil(PAGE);
    match boot::allocate_pages(
        AllocateType::MaxAddress(BELOW_4_GIB),
        MemoryType::LOADER_DATA,
        pages,
    ) {
        Ok(memory) => {
            // SAFETY: fresh pages of loader data.
            unsafe { ptr::write_bytes(memory.as_ptr(), 0, pages * PAGE) };
            Ok(memory)
        }
        Err(error) => Err(Failure::NoMemory(what, error.status())),
    }
}

/// The ACPI RSDP from UEFI's configuration table: ACPI 2.0's, else 1.0's;
/// 0 if neither (stage 4 then scans the BIOS areas).
fn rsdp() -> u64 {
    uefi::system::with_config_table(|entries| {
        let find = |guid| entries.iter().find(|entry| entry.guid == guid);
        find(ConfigTableEntry::ACPI2_GUID)
            .or_else(|| find(ConfigTableEntry::ACPI_GUID))
            .map_or(0, |entry| entry.address as usize as u64)
    })
}

fn boot_services() -> &'static uefi_raw::table::boot::BootServices {
    let st = uefi::table::system_table_raw().expect("the entry macro sets the system table");
    // SAFETY: the firmware's tables, valid while boot services run (every
    // caller runs before ExitBootServices or is the call itself).
    unsafe { &*st.as_ref().boot_services }
}

/// The memory map's size in bytes now, and the descriptor size.
fn memory_map_size() -> Result<(usize, usize), Failure> {
    let (mut size, mut key, mut descriptor_size, mut version) = (0usize, 0usize, 0usize, 0u32);
    // SAFETY: a size query: a zero-sized buffer is never written.
    let status = unsafe {
        (boot_services().get_memory_map)(
            &mut size,
            ptr::null_mut(),
            &mut key,
            &mut descriptor_size,
            &mut version,
        )
    };
    if status != Status::BUFFER_TOO_SMALL && status != Status::SUCCESS {
        return Err(Failure::MemoryMap("(its size)", status));
    }
    if descriptor_size < core::mem::size_of::<uefi_raw::table::boot::MemoryDescriptor>() {
        return Err(Failure::DescriptorTooSmall(descriptor_size));
    }
    Ok((size, descriptor_size))
}

/// Takes the memory map into `buffer` and leaves boot services; a stale map
/// key is tried once more with a fresh map, as the UEFI specification says.
/// Returns the map's size and the descriptor size.
fn exit_boot_services(buffer: &mut [u8]) -> Result<(usize, usize), Failure> {
    let bs = boot_services();
    let mut status = Status::SUCCESS;
    for _attempt in 0..2 {
        let (mut size, mut key, mut descriptor_size, mut version) =
            (buffer.len(), 0usize, 0usize, 0u32);
        // SAFETY: `buffer` is ours and `size` its length.
        status = unsafe {
            (bs.get_memory_map)(
                &mut size,
                buffer.as_mut_ptr().cast(),
                &mut key,
                &mut descriptor_size,
                &mut version,
            )
        };
        if status != Status::SUCCESS {
            return Err(Failure::MemoryMap("before leaving boot services", status));
        }
        // SAFETY: the key of the map just taken; after success nothing of
        // boot services is used again.
        status = unsafe { (bs.exit_boot_services)(boot::image_handle().as_ptr(), key) };
        if status == Status::SUCCESS {
            return Ok((size, descriptor_size));
        }
        if status != Status::INVALID_PARAMETER {
            break;
        }
    }
    Err(Failure::ExitBootServices(status))
}

/// The framebuffer of the GOP chosen as the 64-bit loader chooses
/// (`loader_logic::gop`: usable formats only, the console's first, else the
/// largest); none usable is a zero-length region, which stage 4 and the
/// kernel take as no framebuffer.
fn framebuffer() -> BiosFramebufferInfo {
    let none = BiosFramebufferInfo {
        region: Region { start: 0, len: 0 },
        width: 0,
        height: 0,
        bytes_per_pixel: 0,
        stride: 0,
        pixel_format: PixelFormat::Rgb,
    };
    choose_gop().unwrap_or(none)
}

fn choose_gop() -> Option<BiosFramebufferInfo> {
    use loader_logic::gop::{GopCandidate, GopFormat, UsableFormat, choose, judge, usable_layout};
    const MAX_GOPS: usize = 16;
    struct Found {
        candidate: GopCandidate,
        base: u64,
        size: usize,
        stride: usize,
    }
    let handles =
        boot::locate_handle_buffer(boot::SearchType::from_proto::<GraphicsOutput>()).ok()?;
    let console = uefi::table::system_table_raw().map(|st| {
        // SAFETY: set by the entry macro before `main`; boot services are up.
        unsafe { st.as_ref().stdout_handle }
    });
    let mut found: [Option<Found>; MAX_GOPS] = [const { None }; MAX_GOPS];
    let mut candidates = [GopCandidate {
        format: GopFormat::BltOnly,
        width: 0,
        height: 0,
        on_console: false,
    }; MAX_GOPS];
    let mut count = 0;
    for &handle in handles.iter().take(MAX_GOPS) {
        let params = boot::OpenProtocolParams {
            handle,
            agent: boot::image_handle(),
            controller: None,
        };
        // SAFETY: GetProtocol opens without taking the protocol from its
        // driver (the console keeps it); only the mode is read.
        let Ok(gop) = (unsafe {
            boot::open_protocol::<GraphicsOutput>(params, boot::OpenProtocolAttributes::GetProtocol)
        }) else {
            continue;
        };
        let info = gop.current_mode_info();
        let format = match info.pixel_format() {
            GopPixelFormat::Rgb => GopFormat::Rgb,
            GopPixelFormat::Bgr => GopFormat::Bgr,
            GopPixelFormat::Bitmask => match info.pixel_bitmask() {
                Some(mask) => GopFormat::Bitmask {
                    red: mask.red,
                    green: mask.green,
                    blue: mask.blue,
                    reserved: mask.reserved,
                },
                None => GopFormat::BltOnly,
            },
            GopPixelFormat::BltOnly => GopFormat::BltOnly,
        };
        let candidate = GopCandidate {
            format,
            width: info.resolution().0,
            height: info.resolution().1,
            on_console: console.is_some_and(|c| c == handle.as_ptr()),
        };
        // The framebuffer's base is a 64-bit physical address, which the
        // `uefi` crate hands out only as a (32-bit) pointer: read the mode.
        let raw = (&*gop as *const GraphicsOutput)
            .cast::<uefi_raw::protocol::console::GraphicsOutputProtocol>();
        // SAFETY: `GraphicsOutput` is a transparent wrapper of the raw
        // protocol; its mode is the firmware's, valid while boot services run.
        let (base, size) = unsafe {
            let mode = &*(*raw).mode;
            (mode.frame_buffer_base, mode.frame_buffer_size)
        };
        say(format_args!(
            "loader: GOP {}: {}x{} {:?}{}: {}\n",
            count,
            candidate.width,
            candidate.height,
            info.pixel_format(),
            if candidate.on_console {
                " (console)"
            } else {
                ""
            },
            loader_logic::gop::Verdict(judge(&candidate))
        ));
        found[count] = Some(Found {
            candidate,
            base,
            size,
            stride: info.stride(),
        });
        candidates[count] = candidate;
        count += 1;
    }
    let Some(index) = choose(&candidates[..count]) else {
        say(format_args!(
            "loader: no usable GOP of {count}: booting without a framebuffer\n"
        ));
        return None;
    };
    let chosen = found[index].as_ref()?;
    let fits = |value: usize| u16::try_from(value).ok();
    let (Some(width), Some(height), Some(stride)) = (
        fits(chosen.candidate.width),
        fits(chosen.candidate.height),
        fits(chosen.stride),
    ) else {
        say(format_args!(
            "loader: GOP {index} is too large to describe: booting without a framebuffer\n"
        ));
        return None;
    };
    // Issue 61: the pixel's size as its masks say (3 bytes for a 24-bit
    // mode), not always 4.
    let layout = usable_layout(chosen.candidate.format).ok()?;
    let pixel_format = match layout.format {
        UsableFormat::Rgb => PixelFormat::Rgb,
        UsableFormat::Bgr => PixelFormat::Bgr,
        UsableFormat::BitPositions { red, green, blue } => PixelFormat::Unknown {
            red_position: red,
            green_position: green,
            blue_position: blue,
        },
    };
    say(format_args!("loader: drawing on GOP {index}\n"));
    Some(BiosFramebufferInfo {
        region: Region {
            start: chosen.base,
            len: chosen.size as u64,
        },
        width,
        height,
        bytes_per_pixel: layout.bytes_per_pixel as u8, // 3 or 4
        stride,
        pixel_format,
    })
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    // Not expected (every firmware error is handled above), but never silent.
    // Patched (issue 66): on the screen too while the UEFI console is there
    // (before ExitBootServices); `say` writes COM1 unless it copies it.
    if console_available() {
        say(format_args!("loader: PANIC: {info}\n"));
    } else {
        let _ = writeln!(serial::Com1, "loader: PANIC: {info}");
    }
    loop {
        // SAFETY: halting with interrupts off stops this CPU; nothing follows.
        unsafe { core::arch::asm!("cli", "hlt") };
    }
}
