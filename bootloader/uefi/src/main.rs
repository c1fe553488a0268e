#![no_std]
#![no_main]
#![deny(unsafe_op_in_unsafe_fn)]

use bootloader_api::info::FrameBufferInfo;
use bootloader_boot_config::BootConfig;
use bootloader_x86_64_common::{
    Kernel, RawFrameBufferInfo, SystemInfo, legacy_memory_region::LegacyFrameAllocator,
};
use core::net::Ipv4Addr;
use core::{ptr, slice};
use loader_logic::file_hash::{self, HashSlot};
use uefi::mem::memory_map::{MemoryMap, MemoryMapMut};
use uefi::table::cfg::ConfigTableEntry;
use uefi::{
    CStr8, CStr16, boot,
    boot::{AllocateType, MemoryType},
    cstr8, cstr16,
    prelude::{Status, entry},
    proto::{
        ProtocolPointer,
        console::gop::{GraphicsOutput, PixelFormat},
        device_path::DevicePath,
        loaded_image::LoadedImage,
        media::file::{File, FileAttribute, FileInfo, FileMode},
        network::pxe::{BaseCode, DhcpV4Packet},
    },
};
use x86_64::{
    PhysAddr, VirtAddr,
    structures::paging::{FrameAllocator, OffsetPageTable, PageTable, PhysFrame, Size4KiB},
};

mod firmware_console; // Patched (issue 48)
mod memory_descriptor;
mod secure_boot_state; // Patched (issue 39)

struct BootFile {
    disk: &'static CStr16,
    tftp: &'static CStr8,
}

const KERNEL_FILE: BootFile = BootFile {
    disk: cstr16!("kernel-x86_64"),
    tftp: cstr8!("kernel-x86_64"),
};
const CONFIG_FILE: BootFile = BootFile {
    disk: cstr16!("boot.json"),
    tftp: cstr8!("boot.json"),
};
const RAMDISK_FILE: BootFile = BootFile {
    disk: cstr16!("ramdisk"),
    tftp: cstr8!("ramdisk"),
};

#[entry]
fn main() -> Status {
    let mut boot_mode = BootMode::Disk;

    // Patched: the loader's first line on COM1 (the logger is not set up
    // yet), so a slow load is no hang and tests can time a boot from it.
    say(format_args!("loader: loading kernel (UEFI)"));
    let mut kernel = load_kernel(boot_mode);
    if kernel.is_none() {
        // Try TFTP boot
        boot_mode = BootMode::Tftp;
        kernel = load_kernel(boot_mode);
    }
    // Patched (issue 38): said on the screen and COM1, not a panic.
    let Some(kernel) = kernel else {
        stop(format_args!(
            "loader: no kernel-x86_64 on the boot volume, nor from a network boot \
             server. Write the stick again. The loader stops here."
        ));
    };

    let config_file = load_config_file(boot_mode);
    let mut error_loading_config: Option<serde_json_core::de::Error> = None;
    let mut config: BootConfig = match config_file
        .as_deref()
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
    let framebuffer = init_logger(&config);

    log::info!("UEFI bootloader started");

    if let Some(framebuffer) = framebuffer {
        log::info!("Using framebuffer at {:#x}", framebuffer.addr);
    }

    if let Some(err) = error_loading_config {
        log::warn!("Failed to deserialize the config file {:?}", err);
    } else {
        log::info!("Reading configuration from disk was successful");
    }

    log::info!("Trying to load ramdisk via {:?}", boot_mode);
    // Ramdisk must load from same source, or not at all.
    // Patched (issue 39): with no ramdisk file, the Secure Boot state record.
    let ramdisk = load_ramdisk(boot_mode).or_else(|| {
        let (record, page) = secure_boot_state::record_as_ramdisk()?;
        say(format_args!("loader: secure boot state {record:?}"));
        Some(page)
    });

    log::info!(
        "{}",
        match ramdisk {
            Some(_) => "Loaded ramdisk",
            None => "Ramdisk not found.",
        }
    );

    log::trace!("exiting boot services");
    let mut memory_map = unsafe { boot::exit_boot_services(None) };

    memory_map.sort();

    // Patched (issue 66): one sanitised map for the allocator and the kernel.
    let mut frame_allocator =
        LegacyFrameAllocator::new(memory_descriptor::sanitised(memory_map.entries().copied()));

    let max_phys_addr = frame_allocator.max_phys_addr();
    let page_tables = create_page_tables(&mut frame_allocator, max_phys_addr, framebuffer.as_ref());
    let mut ramdisk_len = 0u64;
    let ramdisk_addr = if let Some(rd) = ramdisk {
        ramdisk_len = rd.len() as u64;
        Some(rd.as_ptr() as usize as u64)
    } else {
        None
    };
    let system_info = SystemInfo {
        framebuffer,
        rsdp_addr: {
            uefi::system::with_config_table(|config_entries| {
                // look for an ACPI2 RSDP first
                let acpi2_rsdp = config_entries
                    .iter()
                    .find(|entry| matches!(entry.guid, ConfigTableEntry::ACPI2_GUID));
                // if no ACPI2 RSDP is found, look for a ACPI1 RSDP
                let rsdp = acpi2_rsdp.or_else(|| {
                    config_entries
                        .iter()
                        .find(|entry| matches!(entry.guid, ConfigTableEntry::ACPI_GUID))
                });
                rsdp.map(|entry| PhysAddr::new(entry.address as u64))
            })
        },
        ramdisk_addr,
        ramdisk_len,
    };

    bootloader_x86_64_common::load_and_switch_to_kernel(
        kernel,
        config,
        frame_allocator,
        page_tables,
        system_info,
    );
}

#[derive(Clone, Copy, Debug)]
pub enum BootMode {
    Disk,
    Tftp,
}

fn load_ramdisk(boot_mode: BootMode) -> Option<&'static mut [u8]> {
    load_file_from_boot_method(&RAMDISK_FILE, boot_mode)
}

fn load_config_file(boot_mode: BootMode) -> Option<&'static mut [u8]> {
    load_file_from_boot_method(&CONFIG_FILE, boot_mode)
}

fn load_kernel(boot_mode: BootMode) -> Option<Kernel<'static>> {
    let kernel_slice = load_file_from_boot_method(&KERNEL_FILE, boot_mode)?;
    check_kernel_hash(kernel_slice); // Patched (issues 32, 48)
    Some(Kernel::parse(kernel_slice))
}

/// Patched (issues 32, 48): the SHA-256 of the kernel file this loader
/// starts, written into this slot of the PE file by the image build
/// (`bootloader/src/lib.rs`, `loader_logic::file_hash`), so every stick
/// carries it; on the signed stick the signature covers it.
static FILE_HASHES: HashSlot = HashSlot::EMPTY;

/// Patched (issues 32, 48): compares the kernel file with [`FILE_HASHES`]
/// before anything of it runs. The firmware may hand back wrong bytes as a
/// good read (OVMF's AHCI driver, for a sector that keeps failing); a
/// mismatch is said on the screen and COM1 and the loader stops, without a
/// reset (`stop`).
fn check_kernel_hash(kernel: &[u8]) {
    // SAFETY: a read of a static of plain bytes. Volatile, so that the
    // compiler cannot fold in the zeros it was built with: the build
    // changes them in the file.
    let expected = unsafe { ptr::read_volatile(&raw const FILE_HASHES) };
    match expected.check(file_hash::File::Kernel, file_hash::sha256(kernel)) {
        Ok(()) => say(format_args!("loader: kernel SHA-256 matches the loader's")),
        Err(mismatch) => stop(format_args!("{mismatch}")),
    }
}

fn load_file_from_boot_method(
    filename: &BootFile,
    boot_mode: BootMode,
) -> Option<&'static mut [u8]> {
    match boot_mode {
        BootMode::Disk => load_file_from_disk(filename.disk),
        BootMode::Tftp => load_file_from_tftp_boot_server(filename.tftp),
    }
}

/// Patched (issue 38): every firmware call checked; a failed open, info or
/// read (or a short read) is tried once more, and the log says so; a failure
/// that stays is shown on the screen and COM1 and the loader stops there
/// (`stop`). `None` only when the boot device has no file system (a network
/// boot) or the file is not there (the config file and ramdisk are optional).
fn load_file_from_disk(name: &CStr16) -> Option<&'static mut [u8]> {
    use loader_logic::file_read::{RecoveredLine, RetryLine, StopMessage, read_with_one_retry};
    let mut file_system = boot::get_image_file_system(boot::image_handle()).ok()?;
    let read = read_with_one_retry(
        || read_file_once(&mut file_system, name),
        |failure| {
            let line = RetryLine {
                file: name,
                failure,
            };
            say(format_args!("{line}"));
        },
    );
    match read {
        Ok(read) => {
            if read.retried_after.is_some() {
                let line = RecoveredLine { file: name };
                say(format_args!("{line}"));
            }
            read.value
        }
        Err(failure) => stop(format_args!(
            "{}",
            StopMessage {
                file: name,
                failure: &failure
            }
        )),
    }
}

type ReadFailure = loader_logic::file_read::Failure<Status>; // Patched (issue 38)

/// Patched (issue 38): one attempt at reading a whole file: `Ok(None)` when
/// it is not there. Pages taken for a read that then fails are given back.
fn read_file_once(
    file_system: &mut uefi::proto::media::fs::SimpleFileSystem,
    name: &CStr16,
) -> Result<Option<&'static mut [u8]>, ReadFailure> {
    use loader_logic::file_read::{Failure, Step};
    use uefi::proto::media::file::FileType;
    fn failed<D: core::fmt::Debug>(step: Step) -> impl Fn(uefi::Error<D>) -> ReadFailure {
        move |error| Failure::Status {
            step,
            status: error.status(),
        }
    }
    let mut root = file_system
        .open_volume()
        .map_err(failed(Step::OpenVolume))?;
    let handle = match root.open(name, FileMode::Read, FileAttribute::empty()) {
        Ok(handle) => handle,
        Err(error) if error.status() == Status::NOT_FOUND => return Ok(None),
        Err(error) => return Err(failed(Step::Open)(error)),
    };
    let mut file = match handle.into_type().map_err(failed(Step::GetInfo))? {
        FileType::Regular(file) => file,
        FileType::Dir(_) => return Err(Failure::Directory),
    };

    // `FileInfo` must be 8-byte aligned: a plain byte array need not be.
    #[repr(C, align(8))]
    struct InfoBuffer([u8; 512]);
    let mut buffer = InfoBuffer([0; 512]);
    let info: &mut FileInfo = file
        .get_info(&mut buffer.0)
        .map_err(failed(Step::GetInfo))?;
    let size = usize::try_from(info.file_size()).map_err(|_| Failure::Status {
        step: Step::GetInfo,
        status: Status::BAD_BUFFER_SIZE,
    })?;
    if size == 0 {
        return Ok(Some(&mut []));
    }

    let pages = size.div_ceil(4096);
    let start = boot::allocate_pages(AllocateType::AnyPages, MemoryType::LOADER_DATA, pages)
        .map_err(failed(Step::Allocate))?;
    // SAFETY: `pages` pages were just allocated at `start` for the loader
    // alone; `size` bytes fit in them.
    let slice = unsafe {
        ptr::write_bytes(start.as_ptr(), 0, size);
        slice::from_raw_parts_mut(start.as_ptr(), size)
    };
    let outcome = match file.read(slice) {
        Ok(read) if read == size => return Ok(Some(slice)),
        Ok(read) => Failure::Short { read, size },
        Err(error) => failed(Step::Read)(error),
    };
    // SAFETY: the pages allocated above, of which nothing is kept.
    if let Err(error) = unsafe { boot::free_pages(start, pages) } {
        // A leak, not a fault: said, and the read goes on failing as it was.
        say(format_args!(
            "loader: giving back {pages} pages for {name} failed ({:?})",
            error.status()
        ));
    }
    Err(outcome)
}

/// Patched (issue 38): shows `message` on the UEFI console (the screen) and
/// COM1, then waits for the user, forever, in bounded stalls: never a reset.
/// The firmware's watchdog (which resets the machine five minutes after it
/// started a boot option) is switched off first.
fn stop(message: core::fmt::Arguments) -> ! {
    say(message);
    if let Err(error) = boot::set_watchdog_timer(0, 0x10000, None) {
        let line = format_args!(
            "loader: the firmware's watchdog would not switch off ({:?}); it may reset \
             the machine",
            error.status()
        );
        say(line);
    }
    loop {
        boot::stall(core::time::Duration::from_secs(1));
    }
}

/// Try to load a kernel from a TFTP boot server.
fn load_file_from_tftp_boot_server(name: &CStr8) -> Option<&'static mut [u8]> {
    let mut base_code = open_pxe_base_code()?;

    // Find the TFTP boot server.
    let mode = base_code.mode();
    let dhcpv4: &DhcpV4Packet = mode.dhcp_ack().as_ref();
    let server_ip = Ipv4Addr::from_octets(dhcpv4.bootp_si_addr);

    // Determine the kernel file size.
    let file_size = base_code.tftp_get_file_size(&server_ip.into(), name).ok()?;
    let kernel_size = usize::try_from(file_size).expect("The file size should fit into usize");

    // Allocate some memory for the kernel file.
    let slice = allocate_loader_data(kernel_size);

    // Load the kernel file.
    base_code
        .tftp_read_file(&server_ip.into(), name, Some(slice))
        .expect("Failed to read kernel file from the TFTP boot server");

    Some(slice)
}

fn allocate_loader_data(size: usize) -> &'static mut [u8] {
    let ptr = boot::allocate_pages(
        // Patched: was `let mut` (a warning)
        AllocateType::AnyPages,
        MemoryType::LOADER_DATA,
        ((size - 1) / 4096) + 1,
    )
    .expect("Failed to allocate memory for the file");
    unsafe { ptr::write_bytes(ptr.as_ptr(), 0, size) };
    unsafe { slice::from_raw_parts_mut(ptr.as_ptr(), size) }
}

/// Opens PXE Base Code for the device path that loaded this image.
///
/// Firmware may expose multiple PXE handles. Resolving through the loaded
/// image's device path keeps TFTP reads tied to the booting network device.
fn open_pxe_base_code() -> Option<boot::ScopedProtocol<BaseCode>> {
    let base_code = locate_and_open_protocol_from_image_device_path::<BaseCode>()?;
    base_code.mode().dhcp_ack_received().then_some(base_code)
}

fn locate_and_open_protocol_from_image_device_path<P: ProtocolPointer + ?Sized>()
-> Option<boot::ScopedProtocol<P>> {
    let image_handle = boot::image_handle();
    let loaded_image = boot::open_protocol_exclusive::<LoadedImage>(image_handle).ok()?;
    let device_handle = loaded_image.device()?;
    let device_path = boot::open_protocol_exclusive::<DevicePath>(device_handle).ok()?;
    let handle = boot::locate_device_path::<P>(&mut &*device_path).ok()?;
    boot::open_protocol_exclusive::<P>(handle).ok()
}

/// Creates page table abstraction types for both the bootloader and kernel page tables.
fn create_page_tables(
    frame_allocator: &mut impl FrameAllocator<Size4KiB>,
    max_phys_addr: PhysAddr,
    frame_buffer: Option<&RawFrameBufferInfo>,
) -> bootloader_x86_64_common::PageTables {
    // UEFI identity-maps all memory, so the offset between physical and virtual addresses is 0
    let phys_offset = VirtAddr::new(0);

    // Patched (issue 38): the bootloader's tables are all its own. Upstream
    // copied the firmware's level-4 entries into a new table, so its later
    // mappings could land in the firmware's level-3..1 tables, which the
    // firmware may map read-only or share; now the firmware's tables are not
    // even read: physical memory up to the memory map's end and the
    // framebuffer are identity-mapped here, in 2 MiB pages (the first 2 MiB
    // in 4 KiB pages, which the fixed MTRRs split), writable and executable,
    // and cached as the MTRRs say, as the firmware's own identity map is.
    log::trace!("switching to new level 4 table");
    let bootloader_page_table = {
        let new_frame = frame_allocator
            .allocate_frame()
            .expect("Failed to allocate frame for new level 4 table");
        let new_table: &mut PageTable = {
            let ptr: *mut PageTable =
                (phys_offset + new_frame.start_address().as_u64()).as_mut_ptr();
            // create a new, empty page table
            unsafe {
                ptr.write(PageTable::new());
                &mut *ptr
            }
        };
        // SAFETY: the table is in a frame just allocated, reached through
        // the firmware's identity map (offset 0), which is still active.
        let mut table = unsafe { OffsetPageTable::new(new_table, phys_offset) }; // Patched
        identity_map(&mut table, frame_allocator, max_phys_addr, frame_buffer); // Patched

        // SAFETY: the new table maps the loader's code, data and stack, the
        // framebuffer and every frame it allocates at the same addresses as
        // the firmware's did (all are below the memory map's end).
        unsafe {
            x86_64::registers::control::Cr3::write(
                new_frame,
                x86_64::registers::control::Cr3Flags::empty(),
            );
        }
        table
    };

    // create a new page table hierarchy for the kernel
    let (kernel_page_table, kernel_level_4_frame) = {
        // get an unused frame for new level 4 page table
        let frame: PhysFrame = frame_allocator.allocate_frame().expect("no unused frames");
        log::info!("New page table at: {:#?}", &frame);
        // get the corresponding virtual address
        let addr = phys_offset + frame.start_address().as_u64();
        // initialize a new page table
        let ptr = addr.as_mut_ptr();
        unsafe { *ptr = PageTable::new() };
        let level_4_table = unsafe { &mut *ptr };
        (
            unsafe { OffsetPageTable::new(level_4_table, phys_offset) },
            frame,
        )
    };

    bootloader_x86_64_common::PageTables {
        bootloader: bootloader_page_table,
        kernel: kernel_page_table,
        kernel_level_4_frame,
    }
}

/// Patched (issue 38): identity-maps `loader_logic::identity_map`'s ranges
/// in the loader's own `table`: 2 MiB pages, and 4 KiB pages for the first
/// 2 MiB. Its tables come from `frame_allocator`, never from the firmware.
fn identity_map(
    table: &mut OffsetPageTable<'static>,
    frame_allocator: &mut impl FrameAllocator<Size4KiB>,
    max_phys_addr: PhysAddr,
    frame_buffer: Option<&RawFrameBufferInfo>,
) {
    use x86_64::structures::paging::{Mapper, Page, PageTableFlags as Flags, Size2MiB};
    let flags = Flags::PRESENT | Flags::WRITABLE;
    let frame_buffer = frame_buffer.map(|fb| (fb.addr.as_u64(), fb.info.byte_len as u64));
    let ranges = loader_logic::identity_map::identity_ranges(max_phys_addr.as_u64(), frame_buffer);
    for range in ranges.into_iter().flatten() {
        let mut address = range.start;
        while address < range.end {
            if address < loader_logic::identity_map::PAGE {
                let frame = PhysFrame::<Size4KiB>::containing_address(PhysAddr::new(address));
                let page = Page::<Size4KiB>::containing_address(VirtAddr::new(address));
                // SAFETY: an identity mapping in a table not yet active.
                match unsafe { table.map_to(page, frame, flags, frame_allocator) } {
                    Ok(flush) => flush.ignore(),
                    Err(error) => panic!("identity-mapping {address:#x} failed: {error:?}"),
                }
                address += 4096;
            } else {
                let frame = PhysFrame::<Size2MiB>::containing_address(PhysAddr::new(address));
                let page = Page::<Size2MiB>::containing_address(VirtAddr::new(address));
                // SAFETY: an identity mapping in a table not yet active.
                match unsafe { table.map_to(page, frame, flags, frame_allocator) } {
                    Ok(flush) => flush.ignore(),
                    Err(error) => panic!("identity-mapping {address:#x} failed: {error:?}"),
                }
                address += loader_logic::identity_map::PAGE;
            }
        }
    }
}

/// Patched: sets up the logger on the chosen GOP's framebuffer, or on serial
/// alone when no GOP can be drawn on (the boot info then has no framebuffer).
fn init_logger(config: &BootConfig) -> Option<RawFrameBufferInfo> {
    let chosen = choose_gop(); // Patched
    let Some((gop_handle, _)) = chosen else {
        // Patched: no usable GOP: log to serial only, boot without a
        // framebuffer, never panic.
        let info = FrameBufferInfo {
            byte_len: 0,
            width: 0,
            height: 0,
            pixel_format: bootloader_api::info::PixelFormat::Rgb,
            bytes_per_pixel: 4,
            stride: 0,
        };
        bootloader_x86_64_common::init_logger(
            &mut [],
            info,
            config.log_level,
            false,
            config.serial_logging,
        );
        log::warn!("No usable GOP (see the lines above): booting without a framebuffer");
        return None;
    };
    let mut gop = boot::open_protocol_exclusive::<GraphicsOutput>(gop_handle).ok()?;

    let mode = {
        // Patched: only modes whose format the kernel can take.
        let modes = gop
            .modes()
            .filter(|m| loader_logic::gop::usable_layout(gop_format(m.info())).is_ok());
        match (
            config
                .frame_buffer
                .minimum_framebuffer_height
                .map(|v| usize::try_from(v).unwrap()),
            config
                .frame_buffer
                .minimum_framebuffer_width
                .map(|v| usize::try_from(v).unwrap()),
        ) {
            (Some(height), Some(width)) => modes
                .filter(|m| {
                    let res = m.info().resolution();
                    res.1 >= height && res.0 >= width
                })
                .last(),
            (Some(height), None) => modes.filter(|m| m.info().resolution().1 >= height).last(),
            (None, Some(width)) => modes.filter(|m| m.info().resolution().0 >= width).last(),
            // Patched (issue 61): no size asked for: a 4-byte mode of the
            // current size if the current one is not.
            _ => mode_of_four_bytes(&gop),
        }
    };
    if let Some(mode) = mode {
        // Patched: a mode that will not set keeps the current one.
        let _ = gop.set_mode(&mode);
    }

    let mode_info = gop.current_mode_info();
    // Patched: the current mode is judged again (a set mode may differ), and
    // its pixel size handed on as its masks say (issue 61: 3 bytes for
    // OVMF's 24-bit modes, which upstream called 4).
    let layout = loader_logic::gop::usable_layout(gop_format(&mode_info)).ok()?;
    let mut framebuffer = gop.frame_buffer();
    let slice = unsafe { slice::from_raw_parts_mut(framebuffer.as_mut_ptr(), framebuffer.size()) };
    let info = FrameBufferInfo {
        byte_len: framebuffer.size(),
        width: mode_info.resolution().0,
        height: mode_info.resolution().1,
        pixel_format: bootloader_pixel_format(layout.format), // Patched
        bytes_per_pixel: layout.bytes_per_pixel,              // Patched
        stride: mode_info.stride(),
    };

    bootloader_x86_64_common::init_logger(
        slice,
        info,
        config.log_level,
        config.frame_buffer_logging,
        config.serial_logging,
    );

    Some(RawFrameBufferInfo {
        addr: PhysAddr::new(framebuffer.as_mut_ptr() as u64),
        info,
    })
}

/// Patched: a GOP mode's format in `loader_logic`'s terms.
fn gop_format(info: &uefi::proto::console::gop::ModeInfo) -> loader_logic::gop::GopFormat {
    use loader_logic::gop::GopFormat;
    match info.pixel_format() {
        PixelFormat::Rgb => GopFormat::Rgb,
        PixelFormat::Bgr => GopFormat::Bgr,
        PixelFormat::Bitmask => match info.pixel_bitmask() {
            Some(mask) => GopFormat::Bitmask {
                red: mask.red,
                green: mask.green,
                blue: mask.blue,
                reserved: mask.reserved,
            },
            None => GopFormat::BltOnly,
        },
        PixelFormat::BltOnly => GopFormat::BltOnly,
    }
}

/// Patched (issue 61): the mode `loader_logic::gop::choose_mode` picks over
/// the current one (a 4-byte mode of the same size when the current mode
/// is not 4 bytes a pixel), each mode asked of `QueryMode`; None keeps the
/// current mode. Says which and why on the UEFI console and COM1.
fn mode_of_four_bytes(gop: &GraphicsOutput) -> Option<uefi::proto::console::gop::Mode> {
    use loader_logic::gop::{GopMode, ModeChoice, choose_mode, usable_layout};
    let described = |info: &uefi::proto::console::gop::ModeInfo| GopMode {
        format: gop_format(info),
        width: info.resolution().0,
        height: info.resolution().1,
    };
    let current = described(&gop.current_mode_info());
    let bytes = |mode: &GopMode| usable_layout(mode.format).map_or(0, |l| l.bytes_per_pixel);
    match choose_mode(&current, gop.modes().map(|m| described(m.info()))) {
        ModeChoice::Keep(why) => {
            say(format_args!(
                "loader: keeping the current mode, {}x{} at {} bytes/pixel: {}",
                current.width,
                current.height,
                bytes(&current),
                why.as_str()
            ));
            None
        }
        ModeChoice::Set { position, mode } => {
            say(format_args!(
                "loader: setting a {}x{} mode at 4 bytes/pixel in place of the current one at {}: the same size, so the same timing",
                mode.width,
                mode.height,
                bytes(&current),
            ));
            gop.modes().nth(position)
        }
    }
}

/// Patched: the format handed to the kernel.
fn bootloader_pixel_format(
    format: loader_logic::gop::UsableFormat,
) -> bootloader_api::info::PixelFormat {
    use bootloader_api::info::PixelFormat as Format;
    use loader_logic::gop::UsableFormat;
    match format {
        UsableFormat::Rgb => Format::Rgb,
        UsableFormat::Bgr => Format::Bgr,
        UsableFormat::BitPositions { red, green, blue } => Format::Unknown {
            red_position: red,
            green_position: green,
            blue_position: blue,
        },
    }
}

/// Patched: every GOP handle judged by its current mode, the choice made by
/// `loader_logic::gop::choose` (host-tested): the usable one on the
/// console-output handle, else the largest usable. Written to the UEFI
/// console (which OVMF copies to serial), since the logger is not set up yet.
fn choose_gop() -> Option<(uefi::Handle, loader_logic::gop::GopCandidate)> {
    use loader_logic::gop::{GopCandidate, choose, judge};
    const MAX_GOPS: usize = 16;
    let handles =
        boot::locate_handle_buffer(boot::SearchType::from_proto::<GraphicsOutput>()).ok()?;
    let console = uefi::table::system_table_raw().map(|st| {
        // SAFETY: set by the entry macro before `main`; boot services are up.
        unsafe { st.as_ref().stdout_handle }
    });
    let mut found: [Option<(uefi::Handle, GopCandidate)>; MAX_GOPS] = [None; MAX_GOPS];
    let mut candidates = [GopCandidate {
        format: loader_logic::gop::GopFormat::BltOnly,
        width: 0,
        height: 0,
        on_console: false,
    }; MAX_GOPS];
    let mut count = 0;
    for &handle in handles.iter().take(MAX_GOPS) {
        // Non-exclusive: looking must not disconnect the console from it.
        let params = boot::OpenProtocolParams {
            handle,
            agent: boot::image_handle(),
            controller: None,
        };
        // SAFETY: GetProtocol opens without taking the protocol from its
        // driver; only the mode is read, while boot services still run.
        let Ok(gop) = (unsafe {
            boot::open_protocol::<GraphicsOutput>(params, boot::OpenProtocolAttributes::GetProtocol)
        }) else {
            continue;
        };
        let info = gop.current_mode_info();
        let candidate = GopCandidate {
            format: gop_format(&info),
            width: info.resolution().0,
            height: info.resolution().1,
            on_console: console.is_some_and(|c| c == handle.as_ptr()),
        };
        say(format_args!(
            "loader: GOP {}: {}x{} {:?}{}: {}",
            count,
            candidate.width,
            candidate.height,
            info.pixel_format(),
            if candidate.on_console {
                " (console)"
            } else {
                ""
            },
            loader_logic::gop::Verdict(judge(&candidate)) // Patched (issue 61)
        ));
        found[count] = Some((handle, candidate));
        candidates[count] = candidate;
        count += 1;
    }
    let chosen = choose(&candidates[..count]);
    match chosen {
        Some(index) => say(format_args!("loader: drawing on GOP {index}")),
        None => say(format_args!(
            "loader: no usable GOP of {count}: booting without a framebuffer"
        )),
    }
    found[chosen?]
}

/// Patched (issue 48): a loader line on the UEFI console (the screen) and
/// on COM1, once: COM1 is written here unless the line reached a console
/// that the firmware copies to COM1 itself (OVMF's; `firmware_console`).
fn say(line: core::fmt::Arguments) {
    let on_console = uefi_print(format_args!("{line}\r\n"));
    if loader_logic::console::com1_too(on_console, firmware_console::copies_to_com1) {
        write_com1(format_args!("{line}\n"));
    }
}

/// Patched: a line on COM1, through the common crate's serial port.
fn write_com1(args: core::fmt::Arguments) {
    use core::fmt::Write;
    // SAFETY: COM1's ports; the logger that later shares them is not set up.
    let mut port = unsafe { bootloader_x86_64_common::serial::SerialPort::init() };
    let _ = port.write_fmt(args);
}

/// Patched: a line on the UEFI console (screen and, under OVMF, serial);
/// whether the console took it.
fn uefi_print(args: core::fmt::Arguments) -> bool {
    use core::fmt::Write;
    uefi_stdout_available() && uefi::system::with_stdout(|stdout| stdout.write_fmt(args).is_ok())
}

#[cfg(target_os = "uefi")]
fn uefi_stdout_available() -> bool {
    uefi::table::system_table_raw()
        .map(|st| {
            // SAFETY: The UEFI entry macro sets this pointer before calling
            // `main`, and `system_table_raw` only returns a non-null pointer.
            let st = unsafe { st.as_ref() };
            !st.boot_services.is_null() && !st.stdout.is_null()
        })
        .unwrap_or(false)
}

#[cfg(target_os = "uefi")]
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    use core::arch::asm;
    use core::fmt::Write;

    if uefi_stdout_available() {
        uefi::system::with_stdout(|stdout| {
            let _ = stdout.clear();
            let _ = writeln!(stdout, "{}", info);
        });
    }
    // Patched: on COM1 too (firmware need not copy its console to serial),
    // so a stop such as no memory for the kernel is never silent there.
    write_com1(format_args!("loader: PANIC: {info}\n"));

    unsafe {
        bootloader_x86_64_common::logger::LOGGER
            .get()
            .map(|l| l.force_unlock())
    };
    log::error!("{}", info);

    loop {
        unsafe { asm!("cli; hlt") };
    }
}
