//! Is there a video BIOS worth calling? Checked from the first MiB alone,
//! before any call is made: the option ROM's signature at C000:0 and the
//! real-mode interrupt vector 0x10 pointing into that ROM or into the system
//! BIOS. An absent, erased or bogus ROM, or a vector into RAM, rules the call
//! out.

/// The video BIOS option ROM's physical address (C000:0).
pub const OPTION_ROM: u32 = 0xC_0000;
/// The system BIOS's 64 KiB segment (F000:0).
pub const SYSTEM_BIOS: u32 = 0xF_0000;
/// Interrupt vector 0x10 in the real-mode interrupt table: offset, segment.
pub const INT_10_VECTOR: u32 = 0x10 * 4;
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
    } else {
        return Err(NoVideoBios::VectorOutsideBios(segment, offset));
    };
    Ok(VideoBios {
        rom_bytes,
        vector: (segment, offset),
        handler,
    })
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
}
