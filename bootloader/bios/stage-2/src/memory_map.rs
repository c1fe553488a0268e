// From http://wiki.osdev.org/Detecting_Memory_(x86)#Getting_an_E820_Memory_Map

use crate::split_array_ref;
use bootloader_x86_64_bios_common::{E820MemoryRegion, racy_cell::RacyCell};

static MEMORY_MAP: RacyCell<[E820MemoryRegion; 100]> = RacyCell::new(
    [E820MemoryRegion {
        start_addr: 0,
        len: 0,
        region_type: 0,
        acpi_extended_attributes: 0,
    }; 100],
);

/// use the INT 0x15, eax= 0xE820 BIOS function to get a memory map
///
/// Patched: the walk is `loader_logic::e820::walk` (host-tested): it ends on
/// CF set or EBX=0 with the entries it has, drops and counts the entries past
/// the table, and is bounded in calls. Err only when there are no entries.
pub unsafe fn query_memory_map()
-> Result<(&'static mut [E820MemoryRegion], loader_logic::e820::Walk), loader_logic::e820::Walk> {
    use loader_logic::e820::{Answer, walk}; // Patched
    const SMAP: u32 = 0x534D4150;
    // Patched: a bound on calls, far above any real list.
    const MAX_CALLS: usize = 1024;

    let memory_map = unsafe { MEMORY_MAP.get_mut() };

    let found = walk(memory_map, MAX_CALLS, |continuation| {
        let mut buf = [0u8; 24]; // Patched: the BIOS writes it
        // Patched: through the BIOS call wrapper; the buffer (on the stack,
        // below 64 KiB) as segment:offset; CF set ends the list.
        let (segment, offset) = crate::bios::far_pointer(buf.as_mut_ptr() as u32);
        let out = crate::bios::call(
            0x15,
            crate::bios::Registers {
                eax: 0xe820,
                ebx: continuation,
                ecx: buf.len() as u32,
                edx: SMAP,
                edi: offset.into(),
                es: segment,
                ..Default::default()
            },
        );
        if out.carry() {
            return Answer::Carry; // Patched
        }
        if out.eax != SMAP {
            return Answer::NotSmap; // Patched
        }
        let offset = out.ebx; // Patched: the continuation
        let buf_written_len = out.ecx; // Patched

        let mut entry = None; // Patched
        let written = (buf_written_len as usize).min(buf.len()); // Patched
        if written >= 20 {
            let buf = &buf[..written];

            let (&base_raw, rest) = split_array_ref(buf);
            let (&len_raw, rest) = split_array_ref(rest);
            let (&kind_raw, rest) = split_array_ref(rest);
            let acpi_extended_raw: [u8; 4] = rest.try_into().unwrap_or_default();

            let len = u64::from_ne_bytes(len_raw);
            if len != 0 {
                entry = Some(E820MemoryRegion {
                    start_addr: u64::from_ne_bytes(base_raw),
                    len,
                    region_type: u32::from_ne_bytes(kind_raw),
                    acpi_extended_attributes: u32::from_ne_bytes(acpi_extended_raw),
                });
            }
        }
        Answer::Entry {
            entry,
            next: offset,
        }
    });

    if found.stored == 0 {
        return Err(found); // Patched
    }
    Ok((&mut memory_map[..found.stored], found))
}
