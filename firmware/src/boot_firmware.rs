//! Which firmware started the machine, told by the memory map the bootloader
//! passes on: a BIOS boot's map comes from E820, whose reserved and ACPI
//! ranges the bootloader reports as BIOS kinds; a UEFI boot's map comes from
//! the firmware's memory descriptors, whose runtime, ACPI and reserved ranges
//! it reports as UEFI kinds. Every real map has some of one and none of the
//! other.

/// The firmware that booted the machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Firmware {
    /// A PC BIOS, or a UEFI firmware's compatibility module (CSM): video BIOS
    /// calls and true Mode X are possible.
    Bios,
    /// UEFI: no video BIOS to call, and the card may scan out the firmware's
    /// framebuffer whatever the VGA registers say.
    Uefi,
    /// The map named neither (it had only usable and bootloader ranges).
    Unknown,
}

/// Where a memory-map entry's kind came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RegionOrigin {
    /// A kind from the BIOS's E820 map (reserved, ACPI, NVS...).
    Bios,
    /// A kind from UEFI's memory descriptors (runtime services, ACPI...).
    Uefi,
    /// Usable memory or the bootloader's own: says nothing of the firmware.
    Neutral,
}

/// The firmware, from the origins of every entry of the memory map. UEFI wins
/// if both appear: no BIOS call may ever be made on a UEFI machine.
pub fn firmware_from_regions(origins: impl IntoIterator<Item = RegionOrigin>) -> Firmware {
    let (mut bios, mut uefi) = (false, false);
    for origin in origins {
        bios |= origin == RegionOrigin::Bios;
        uefi |= origin == RegionOrigin::Uefi;
    }
    match (bios, uefi) {
        (_, true) => Firmware::Uefi,
        (true, false) => Firmware::Bios,
        (false, false) => Firmware::Unknown,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use RegionOrigin::{Bios, Neutral, Uefi};

    #[test]
    fn the_map_names_the_firmware() {
        assert_eq!(
            firmware_from_regions([Neutral, Bios, Neutral]),
            Firmware::Bios
        );
        assert_eq!(firmware_from_regions([Neutral, Uefi, Uefi]), Firmware::Uefi);
        assert_eq!(firmware_from_regions([Neutral, Neutral]), Firmware::Unknown);
        assert_eq!(firmware_from_regions([]), Firmware::Unknown);
    }

    #[test]
    fn uefi_wins_so_no_bios_call_is_made_on_a_mixed_map() {
        assert_eq!(firmware_from_regions([Bios, Uefi]), Firmware::Uefi);
    }
}
