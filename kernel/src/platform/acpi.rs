//! The ACPI tables, read once at boot with rust-osdev's `acpi` crate (without
//! its heap-using parts): where the PM timer and the HPET are, how to power
//! off (PM1 control and `\_S5`) and reset (the FADT's reset register), and
//! what the FADT's boot flags say about the 8042 and the VGA. The decisions
//! on those values are `firmware::acpi`'s, tested on the host.
//!
//! Tables are reached through the bootloader's map of physical memory. A
//! table that fails its checksum, or a pointer outside that map, costs only
//! what it would have told: each fact is optional, and each gap is logged.

use crate::serial_println;
use acpi::address::{AddressSpace, GenericAddress};
use acpi::fadt::Fadt;
use acpi::hpet::{HpetInfo, HpetTable};
use acpi::{AcpiHandler, AcpiTable, AcpiTables, PhysicalMapping};
use core::ptr::NonNull;
use firmware::acpi::{s5_sleep_types, LegacyDevices, SleepTypes};
use spin::Once;

/// The PM timer's I/O port and width.
#[derive(Clone, Copy, Debug)]
pub struct PmTimer {
    pub port: u16,
    pub is_32_bit: bool,
}

/// Where a register is, as the FADT's generic address says, for the kinds the
/// kernel can write.
#[derive(Clone, Copy, Debug)]
pub enum Register {
    Io(u16),
    /// A virtual address, inside the map of physical memory.
    Memory(u64),
    /// Bus 0's configuration space: device, function, offset.
    PciConfig {
        device: u8,
        function: u8,
        offset: u8,
    },
}

/// What soft-off (S5) needs.
#[derive(Clone, Copy, Debug)]
pub struct SoftOff {
    pub pm1a_control: u16,
    pub pm1b_control: Option<u16>,
    pub sleep_types: SleepTypes,
    /// Where to ask the firmware to hand the chipset to ACPI, and the value.
    pub smi_command: Option<(u16, u8)>,
}

/// Everything the kernel takes from the tables.
#[derive(Clone, Copy, Debug)]
pub struct Facts {
    pub pm_timer: Option<PmTimer>,
    /// The HPET's registers' physical address.
    pub hpet: Option<u64>,
    pub soft_off: Option<SoftOff>,
    /// The reset register and the value to write, where the FADT says it works.
    pub reset: Option<(Register, u8)>,
    pub legacy: LegacyDevices,
}

impl Facts {
    const NONE: Facts = Facts {
        pm_timer: None,
        hpet: None,
        soft_off: None,
        reset: None,
        legacy: LegacyDevices::UNKNOWN,
    };
}

static FACTS: Once<Facts> = Once::new();

/// What the tables said (nothing, before `init` or without tables).
pub fn facts() -> &'static Facts {
    FACTS.get().unwrap_or(&Facts::NONE)
}

/// Physical memory as the bootloader mapped it: `[0, limit)` at `offset`.
#[derive(Clone, Copy, Debug)]
struct PhysicalMemory {
    offset: u64,
    limit: u64,
}

/// A page of zeros standing in for any table a corrupt pointer puts outside
/// the mapped memory: its signature matches nothing and its length is zero.
static OUTSIDE_THE_MAP: [u8; 4096] = [0; 4096];

impl PhysicalMemory {
    /// The virtual address of `[physical, physical + length)`, if all of it is
    /// mapped.
    fn virtual_address(&self, physical: u64, length: u64) -> Option<u64> {
        let end = physical.checked_add(length)?;
        (end <= self.limit).then(|| self.offset + physical)
    }
}

impl AcpiHandler for PhysicalMemory {
    unsafe fn map_physical_region<T>(
        &self,
        physical_address: usize,
        size: usize,
    ) -> PhysicalMapping<Self, T> {
        let (address, length) = match self.virtual_address(physical_address as u64, size as u64) {
            Some(address) => (address, size),
            None => (
                OUTSIDE_THE_MAP.as_ptr() as u64,
                size.min(OUTSIDE_THE_MAP.len()),
            ),
        };
        let pointer = NonNull::new(address as *mut T).expect("mapped addresses are not null");
        // SAFETY: the region is inside the bootloader's map of physical memory
        // (which stays mapped for the kernel's whole life), or it is the zero
        // page with the length cut to the page's; the crate only reads
        // through it, and a zero header fails its signature check.
        unsafe { PhysicalMapping::new(physical_address, pointer, length, length, *self) }
    }

    fn unmap_physical_region<T>(_region: &PhysicalMapping<Self, T>) {}
}

/// Reads the tables from the RSDP the bootloader found, once, and logs what
/// they hold. `limit` is the end of the bootloader's map of physical memory.
pub fn init(rsdp: Option<u64>, physical_memory_offset: u64, limit: u64) -> &'static Facts {
    FACTS.call_once(|| {
        let memory = PhysicalMemory {
            offset: physical_memory_offset,
            limit,
        };
        let Some(rsdp) = rsdp else {
            serial_println!("acpi: the bootloader found no RSDP; no ACPI tables");
            return Facts::NONE;
        };
        // SAFETY: the bootloader found the RSDP at this physical address (a
        // checksummed structure); every table behind it is reached through
        // `map_physical_region`, which stays inside the mapped memory.
        match unsafe { AcpiTables::from_rsdp(memory, rsdp as usize) } {
            Ok(tables) => read(&tables, memory),
            Err(error) => {
                serial_println!(
                    "acpi: the RSDP at {:#x} is not usable ({:?}); no ACPI tables",
                    rsdp,
                    error
                );
                Facts::NONE
            }
        }
    })
}

fn read(tables: &AcpiTables<PhysicalMemory>, memory: PhysicalMemory) -> Facts {
    let mut facts = Facts::NONE;
    match tables.find_table::<Fadt>() {
        Ok(fadt) => read_fadt(tables, &fadt, memory, &mut facts),
        Err(error) => serial_println!(
            "acpi: no usable FADT ({:?}): no PM timer, power-off or reset register",
            error
        ),
    }
    facts.hpet = hpet(tables);
    facts
}

fn read_fadt(
    tables: &AcpiTables<PhysicalMemory>,
    fadt: &Fadt,
    memory: PhysicalMemory,
    facts: &mut Facts,
) {
    let revision = fadt.header().revision;
    let flags = fadt.flags;
    let boot_arch = fadt.iapc_boot_arch;
    let boot_arch_bits = (u16::from(boot_arch.motherboard_implements_8042()) << 1)
        | (u16::from(boot_arch.dont_probe_vga()) << 2);
    facts.legacy = LegacyDevices::from_fadt(revision, boot_arch_bits);
    serial_println!(
        "acpi: FADT revision {}: 8042 {:?}, VGA {:?}",
        revision,
        facts.legacy.i8042,
        facts.legacy.vga
    );

    facts.pm_timer = match fadt.pm_timer_block() {
        Ok(Some(block)) => match io_port(&block) {
            Some(port) => Some(PmTimer {
                port,
                is_32_bit: flags.pm_timer_is_32_bit(),
            }),
            None => {
                serial_println!("acpi: the PM timer is not in I/O space; not used");
                None
            }
        },
        Ok(None) => None,
        Err(error) => {
            serial_println!("acpi: the PM timer's address is unusable ({:?})", error);
            None
        }
    };

    facts.reset = if revision >= 2 && flags.supports_system_reset_via_fadt() {
        fadt.reset_register()
            .ok()
            .and_then(|gas| register(&gas))
            .and_then(|register| match register {
                Register::Memory(physical) => {
                    memory.virtual_address(physical, 1).map(Register::Memory)
                }
                other => Some(other),
            })
            .map(|register| (register, fadt.reset_value))
    } else {
        None
    };

    facts.soft_off = soft_off(tables, fadt, memory);
}

fn soft_off(
    tables: &AcpiTables<PhysicalMemory>,
    fadt: &Fadt,
    memory: PhysicalMemory,
) -> Option<SoftOff> {
    let pm1a_control = match fadt.pm1a_control_block().map(|gas| io_port(&gas)) {
        Ok(Some(port)) => port,
        _ => {
            serial_println!("acpi: PM1a control is not an I/O port; no ACPI power-off");
            return None;
        }
    };
    let pm1b_control = fadt
        .pm1b_control_block()
        .ok()
        .flatten()
        .and_then(|gas| io_port(&gas));
    let sleep_types = match sleep_types(tables, memory) {
        Ok(types) => types,
        Err(error) => {
            serial_println!("acpi: {}; no ACPI power-off", error);
            return None;
        }
    };
    let (smi_command, acpi_enable) = (fadt.smi_cmd_port, fadt.acpi_enable);
    Some(SoftOff {
        pm1a_control,
        pm1b_control,
        sleep_types,
        smi_command: (smi_command != 0 && acpi_enable != 0)
            .then(|| u16::try_from(smi_command).ok())
            .flatten()
            .map(|port| (port, acpi_enable)),
    })
}

/// The longest AML table read for `\_S5`; real DSDTs stay well below.
const MAX_AML_BYTES: u32 = 4 * 1024 * 1024;

/// `\_S5`'s sleep types from the DSDT, else from the first SSDT holding them.
fn sleep_types(
    tables: &AcpiTables<PhysicalMemory>,
    memory: PhysicalMemory,
) -> Result<SleepTypes, firmware::acpi::S5Error> {
    let dsdt = tables.dsdt().ok();
    let mut last_error = firmware::acpi::S5Error::Missing;
    for table in dsdt.into_iter().chain(tables.ssdts()) {
        let length = table.length.min(MAX_AML_BYTES);
        let Some(address) = memory.virtual_address(table.address as u64, u64::from(length)) else {
            continue;
        };
        // SAFETY: the range is inside the bootloader's map of physical memory
        // (checked just above), which stays mapped and is only read here.
        let aml = unsafe { core::slice::from_raw_parts(address as *const u8, length as usize) };
        match s5_sleep_types(aml) {
            Ok(types) => return Ok(types),
            Err(error) => last_error = error,
        }
    }
    Err(last_error)
}

/// The HPET table's generic address: its address space byte, then the
/// 64-bit address (offsets in the table, after the 36-byte header and the
/// 4-byte event timer block ID).
const HPET_ADDRESS_SPACE_OFFSET: usize = 40;

fn hpet(tables: &AcpiTables<PhysicalMemory>) -> Option<u64> {
    let table = tables.find_table::<HpetTable>().ok()?;
    // `HpetInfo::new` asserts that the HPET is in system memory: check that
    // first, so a table that says otherwise is skipped, not a panic.
    // SAFETY: the mapping covers the whole table (the crate mapped its length
    // from the header and checked its checksum), which is longer than this.
    let address_space = unsafe {
        table
            .virtual_start()
            .as_ptr()
            .cast::<u8>()
            .add(HPET_ADDRESS_SPACE_OFFSET)
            .read()
    };
    if address_space != 0 || (table.header().length as usize) <= HPET_ADDRESS_SPACE_OFFSET {
        serial_println!("acpi: the HPET table does not put it in memory; not used");
        return None;
    }
    drop(table);
    let info = HpetInfo::new(tables).ok()?;
    Some(info.base_address as u64)
}

fn io_port(gas: &GenericAddress) -> Option<u16> {
    match register(gas)? {
        Register::Io(port) => Some(port),
        _ => None,
    }
}

fn register(gas: &GenericAddress) -> Option<Register> {
    match gas.address_space {
        AddressSpace::SystemIo => u16::try_from(gas.address).ok().map(Register::Io),
        // A physical address here; `read_fadt` makes it virtual.
        AddressSpace::SystemMemory => Some(Register::Memory(gas.address)),
        // The ACPI specification's encoding: device in bits 32-47, function
        // in bits 16-31, offset in bits 0-15 (bus 0).
        AddressSpace::PciConfigSpace => Some(Register::PciConfig {
            device: u8::try_from((gas.address >> 32) & 0xFFFF).ok()?,
            function: u8::try_from((gas.address >> 16) & 0xFFFF).ok()?,
            offset: u8::try_from(gas.address & 0xFFFF).ok()?,
        }),
        _ => None,
    }
}
