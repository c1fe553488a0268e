//! Is there a video BIOS worth calling? Checked from the first MiB alone,
//! before any call is made: the option ROM's signature at C000:0 and the
//! real-mode interrupt vector 0x10 pointing into that ROM, into the system
//! BIOS, or into another option ROM that hooked it (as real PCs' network,
//! RAID and CSM ROMs do, and chain to the card's). An absent, erased or bogus
//! ROM, or a vector into RAM, rules the call out.

/// The video BIOS option ROM's physical address (C000:0).
pub const OPTION_ROM: u32 = 0xC_0000;
/// The system BIOS's 64 KiB segment (F000:0).
pub const SYSTEM_BIOS: u32 = 0xF_0000;
/// Interrupt vector 0x10 in the real-mode interrupt table: offset, segment.
pub const INT_10_VECTOR: u32 = 0x10 * 4;
/// The end of the window where the firmware puts option ROMs (C0000-DFFFF).
pub const OPTION_ROM_AREA_END: u32 = 0xE_0000;
/// Option ROMs start on 2 KiB boundaries in that window.
const OPTION_ROM_ALIGN: u32 = 2048;
/// Option ROMs are sized in 512-byte blocks; a video BIOS is at most 64 KiB.
const ROM_BLOCK: u32 = 512;
const MAX_ROM_BLOCKS: u8 = 128;

/// Where the INT 10h vector leads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handler {
    /// Into the video option ROM, as the card's BIOS installs itself.
    OptionRom,
    /// Into the system BIOS, which some machines put in front of the card's.
    SystemBios,
    /// Into another option ROM, starting at this physical address, which
    /// hooked INT 10h after the card's BIOS.
    AnotherOptionRom(u32),
}

/// A video BIOS that passed the checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VideoBios {
    /// The option ROM's length in bytes.
    pub rom_bytes: u32,
    /// The INT 10h vector as segment:offset.
    pub vector: (u16, u16),
    /// Where it leads.
    pub handler: Handler,
}

/// Why no BIOS call will be made.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NoVideoBios {
    /// C000:0 does not start with 0x55 0xAA.
    NoSignature([u8; 2]),
    /// The ROM's size byte is 0 or over 64 KiB.
    BadSize(u8),
    /// INT 10h points neither into the ROM nor into the system BIOS.
    VectorOutsideBios(u16, u16),
}

/// Checks the video BIOS, reading physical bytes below 1 MiB with `read`.
pub fn check_video_bios(read: impl Fn(u32) -> u8) -> Result<VideoBios, NoVideoBios> {
    let signature = [read(OPTION_ROM), read(OPTION_ROM + 1)];
    if signature != [0x55, 0xAA] {
        return Err(NoVideoBios::NoSignature(signature));
    }
    let blocks = read(OPTION_ROM + 2);
    if blocks == 0 || blocks > MAX_ROM_BLOCKS {
        return Err(NoVideoBios::BadSize(blocks));
    }
    let rom_bytes = u32::from(blocks) * ROM_BLOCK;
    let word = |at: u32| u16::from_le_bytes([read(at), read(at + 1)]);
    let (offset, segment) = (word(INT_10_VECTOR), word(INT_10_VECTOR + 2));
    let target = u32::from(segment) * 16 + u32::from(offset);
    let handler = if (OPTION_ROM..OPTION_ROM + rom_bytes).contains(&target) {
        Handler::OptionRom
    } else if (SYSTEM_BIOS..SYSTEM_BIOS + 0x1_0000).contains(&target) {
        Handler::SystemBios
    } else if let Some(start) = option_rom_holding(&read, target) {
        Handler::AnotherOptionRom(start)
    } else {
        return Err(NoVideoBios::VectorOutsideBios(segment, offset));
    };
    Ok(VideoBios {
        rom_bytes,
        vector: (segment, offset),
        handler,
    })
}

/// The start of the option ROM in the window after the card's whose bytes
/// hold `target`: the nearest signature at or below it must be a ROM whose
/// size byte reaches past it.
fn option_rom_holding(read: &impl Fn(u32) -> u8, target: u32) -> Option<u32> {
    if !(OPTION_ROM..OPTION_ROM_AREA_END).contains(&target) {
        return None;
    }
    let mut start = target - target % OPTION_ROM_ALIGN;
    while start >= OPTION_ROM {
        if [read(start), read(start + 1)] == [0x55, 0xAA] {
            let blocks = read(start + 2);
            let fits = blocks != 0 && blocks <= MAX_ROM_BLOCKS;
            let end = start + u32::from(blocks) * ROM_BLOCK;
            return (fits && target < end).then_some(start);
        }
        start -= OPTION_ROM_ALIGN;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec;
    use std::vec::Vec;

    /// The first MiB with a 32 KiB video BIOS whose INT 10h entry is C000:0123.
    fn low_memory() -> Vec<u8> {
        let mut memory = vec![0u8; 0x10_0000];
        memory[OPTION_ROM as usize..][..3].copy_from_slice(&[0x55, 0xAA, 64]);
        set_vector(&mut memory, 0xC000, 0x0123);
        memory
    }

    fn set_vector(memory: &mut [u8], segment: u16, offset: u16) {
        let at = INT_10_VECTOR as usize;
        memory[at..at + 2].copy_from_slice(&offset.to_le_bytes());
        memory[at + 2..at + 4].copy_from_slice(&segment.to_le_bytes());
    }

    fn check(memory: &[u8]) -> Result<VideoBios, NoVideoBios> {
        check_video_bios(|at| memory[at as usize])
    }

    #[test]
    fn a_rom_with_its_vector_passes() {
        let bios = check(&low_memory()).unwrap();
        assert_eq!(bios.rom_bytes, 32 * 1024);
        assert_eq!(bios.vector, (0xC000, 0x0123));
        assert_eq!(bios.handler, Handler::OptionRom);
    }

    #[test]
    fn a_vector_into_the_system_bios_passes() {
        let mut memory = low_memory();
        set_vector(&mut memory, 0xF000, 0xF065);
        assert_eq!(check(&memory).unwrap().handler, Handler::SystemBios);
    }

    #[test]
    fn no_signature_no_call() {
        let mut memory = low_memory();
        memory[OPTION_ROM as usize] = 0xFF;
        assert_eq!(check(&memory), Err(NoVideoBios::NoSignature([0xFF, 0xAA])));
        // What a UEFI machine without a compatibility module shows: nothing.
        assert!(check(&vec![0u8; 0x10_0000]).is_err());
    }

    #[test]
    fn a_bogus_size_no_call() {
        let mut memory = low_memory();
        memory[OPTION_ROM as usize + 2] = 0;
        assert_eq!(check(&memory), Err(NoVideoBios::BadSize(0)));
        memory[OPTION_ROM as usize + 2] = 200;
        assert_eq!(check(&memory), Err(NoVideoBios::BadSize(200)));
    }

    #[test]
    fn a_vector_into_ram_or_past_the_rom_no_call() {
        let mut memory = low_memory();
        set_vector(&mut memory, 0x0000, 0x7C00);
        assert_eq!(
            check(&memory),
            Err(NoVideoBios::VectorOutsideBios(0x0000, 0x7C00))
        );
        // Just past the 32 KiB ROM (in the next ROM's space).
        set_vector(&mut memory, 0xC800, 0x0000);
        assert!(check(&memory).is_err());
    }

    #[test]
    fn a_vector_into_an_option_rom_that_hooked_int_10h_passes() {
        // A 2 KiB ROM at CD800, as SeaBIOS places the tests' hostile ROM.
        let mut memory = low_memory();
        memory[0xC_D800..][..3].copy_from_slice(&[0x55, 0xAA, 4]);
        set_vector(&mut memory, 0xCD80, 0x006A);
        assert_eq!(
            check(&memory).unwrap().handler,
            Handler::AnotherOptionRom(0xC_D800)
        );
        // Past that ROM's end, in no ROM.
        set_vector(&mut memory, 0xCE00, 0x0010);
        assert!(check(&memory).is_err());
        // A ROM whose size byte is bogus is not one.
        memory[0xC_D802] = 0;
        set_vector(&mut memory, 0xCD80, 0x006A);
        assert!(check(&memory).is_err());
        // Above the window (E0000 and up is the system BIOS's, not a ROM's).
        set_vector(&mut memory, 0xE000, 0x0000);
        assert!(check(&memory).is_err());
    }
}
