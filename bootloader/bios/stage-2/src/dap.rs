use crate::bios::{self, Registers}; // Patched

#[derive(Debug, Clone, Copy)]
#[allow(dead_code)]
#[repr(C, packed)]
pub struct DiskAddressPacket {
    /// Size of the DAP structure
    packet_size: u8,
    /// always zero
    zero: u8,
    /// Number of sectors to transfer
    number_of_sectors: u16,
    /// Offset to memory buffer
    offset: u16,
    /// Segment of memory buffer
    segment: u16,
    /// Start logical block address
    start_lba: u64,
}

impl DiskAddressPacket {
    pub fn from_lba(
        start_lba: u64,
        number_of_sectors: u16,
        target_addr: u16,
        target_addr_segment: u16,
    ) -> Self {
        Self {
            packet_size: 0x10,
            zero: 0,
            number_of_sectors,
            offset: target_addr,
            segment: target_addr_segment,
            start_lba,
        }
    }

    /// Patched (see ../../../CHANGES.md): INT 13h AH=42h through the BIOS
    /// call wrapper; the BIOS's status byte (AH) on failure, never a stop here.
    /// `&mut`: the BIOS writes the packet (the count of sectors it moved), so
    /// the compiler must not take it as unchanged from one call to the next.
    pub fn perform_load(&mut self, disk_number: u16) -> Result<(), u8> {
        let (segment, offset) = bios::far_pointer(core::ptr::from_mut(self) as u32);
        let out = bios::call(
            0x13,
            Registers {
                eax: 0x4200,
                edx: disk_number.into(),
                esi: offset.into(),
                ds: segment,
                ..Registers::default()
            },
        );
        if out.carry() { Err(out.ah()) } else { Ok(()) }
    }
}

/// Patched: INT 13h AH=00h, the disk reset done between two tries of a read.
pub fn reset(disk_number: u16) {
    bios::call(
        0x13,
        Registers {
            edx: disk_number.into(),
            ..Registers::default()
        },
    );
}
