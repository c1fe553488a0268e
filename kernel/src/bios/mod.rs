//! The card's own video BIOS, called from the 64-bit kernel: the way DOS
//! programs (Abrash's included) left whatever mode the card was in, by asking
//! its BIOS for mode 13h, before tweaking the registers into Mode X. Only the
//! card's BIOS knows how to leave its own extended modes.
//!
//! Used only on a BIOS boot whose video BIOS passed `modex::card::check_video_bios`,
//! never on UEFI and never from a fault handler.
//!
//! Each call runs in the BIOS's own world (issue 66): the PICs at its
//! vectors with its masks, PIT channel 0 at its 18.2 Hz, interrupts on in
//! real mode, so a mode set that waits on the tick or on INT 15h AH=86h
//! returns; and a watchdog on IRQ 0 abandons a call that has not returned
//! within `bios_world::limit_millis()`, after which the BIOS is not called
//! again.

mod area;
mod trampoline;

use crate::interrupts;
use crate::time::pit;
use bootloader_api::info::MemoryRegions;
use firmware::boot_firmware::Firmware;
use memory::trampoline::bios_world;
use modex::card::{check_video_bios, BiosCallFailure, NoVideoBios, VideoBios as RomCheck};
use trampoline::layout;
use x86_64::registers::control::{Cr4, Cr4Flags};

pub use area::AreaError;

/// The registers an `int 0x10` takes and gives back.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Registers {
    pub eax: u32,
    pub ebx: u32,
    pub ecx: u32,
    pub edx: u32,
    pub esi: u32,
    pub edi: u32,
    pub ebp: u32,
    pub ds: u16,
    pub es: u16,
    /// FLAGS after the call (carry set means failure for many functions).
    pub flags: u16,
}

/// Why the video BIOS will not be called.
#[derive(Clone, Copy, Debug)]
pub enum Unavailable {
    /// The machine did not boot through a BIOS.
    NotABiosBoot(Firmware),
    /// The ROM or the INT 10h vector failed the checks.
    NoVideoBios(NoVideoBios),
    /// CR4.PCIDE is on: paging could not be switched off and on again.
    PcidEnabled,
    /// No place for the trampoline.
    Area(AreaError),
    /// IRQ 0 was not seen to arrive: the watchdog could not bound a call.
    NoTimerTicks,
}

/// The watchdog abandoned a call: the BIOS had not returned from it within
/// `bios_world::limit_millis()`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TimedOut;

impl core::fmt::Display for Unavailable {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Unavailable::NotABiosBoot(firmware) => write!(f, "not a BIOS boot ({firmware:?})"),
            Unavailable::NoVideoBios(why) => write!(f, "no usable video BIOS ({why:?})"),
            Unavailable::PcidEnabled => f.write_str("CR4.PCIDE is set"),
            Unavailable::Area(why) => write!(f, "no place for the trampoline ({why:?})"),
            Unavailable::NoTimerTicks => {
                f.write_str("no PIT ticks arrive, so a call could not be bounded")
            }
        }
    }
}

/// A video BIOS that can be called.
pub struct VideoBios {
    /// The trampoline's area: physical address = virtual address.
    area: u64,
    /// What the checks found.
    pub rom: RomCheck,
}

impl VideoBios {
    /// Checks everything a call needs and installs the trampoline. Nothing
    /// is called yet.
    pub fn find(
        booted_by: Firmware,
        regions: &MemoryRegions,
        physical_memory_offset: u64,
    ) -> Result<VideoBios, Unavailable> {
        if booted_by != Firmware::Bios {
            return Err(Unavailable::NotABiosBoot(booted_by));
        }
        let read_low = |address: u32| {
            let pointer = (physical_memory_offset + u64::from(address)) as *const u8;
            // SAFETY: all physical memory is mapped at the offset; the first
            // MiB is RAM or ROM, and reading it has no side effects.
            unsafe { pointer.read_volatile() }
        };
        let rom = check_video_bios(read_low).map_err(Unavailable::NoVideoBios)?;
        if Cr4::read().contains(Cr4Flags::PCID) {
            return Err(Unavailable::PcidEnabled);
        }
        if !pit::ticks_arrive() {
            return Err(Unavailable::NoTimerTicks);
        }
        let area = area::find(regions).map_err(Unavailable::Area)?;
        area::identity_map(area, regions, physical_memory_offset).map_err(Unavailable::Area)?;
        install(area);
        Ok(VideoBios { area, rom })
    }

    /// The area's physical address, for the log.
    pub fn area(&self) -> u64 {
        self.area
    }

    /// Calls `int 0x10` in real mode with `registers`; returns them as the
    /// BIOS left them, or `TimedOut` if the watchdog had to abandon the
    /// call. Interrupts are off until real mode, and on in it with the PICs
    /// at the BIOS's vectors, so an IRQ reaches the BIOS's handlers, never
    /// the kernel's IDT.
    pub fn int10(&mut self, registers: Registers) -> Result<Registers, TimedOut> {
        let base = self.area as *mut u8;
        let put32 = |at: usize, value: u32| {
            // SAFETY: `at` is inside the identity-mapped area, which this
            // object owns; the offsets are the trampoline's layout.
            unsafe { base.add(at).cast::<u32>().write_unaligned(value) }
        };
        let put16 = |at: usize, value: u16| {
            // SAFETY: as above.
            unsafe { base.add(at).cast::<u16>().write_unaligned(value) }
        };
        let r = layout::REGISTERS;
        for (i, value) in [
            registers.eax,
            registers.ebx,
            registers.ecx,
            registers.edx,
            registers.esi,
            registers.edi,
            registers.ebp,
        ]
        .into_iter()
        .enumerate()
        {
            put32(r + 4 * i, value);
        }
        put16(layout::DS, registers.ds);
        put16(layout::ES, registers.es);
        put16(layout::WATCHDOG_TICKS, bios_world::WATCHDOG_TICKS);
        put16(layout::TIMED_OUT, 0);

        let entry = self.area + trampoline::entry_offset() as u64;
        x86_64::instructions::interrupts::without_interrupts(|| {
            interrupts::with_pics_for_the_bios(|| {
                pit::at_the_bios_rate(|| {
                    // SAFETY: the trampoline was installed at `area` by `find`,
                    // identity-mapped; it preserves the callee-saved registers and
                    // restores GDT, IDT, control registers, EFER, stack and
                    // selectors before it returns. Interrupts are off but in real
                    // mode, where IRQs reach the BIOS's handlers. MXCSR and
                    // the x87 control word are kept around it, so a video BIOS
                    // that changed the rounding could not change the pictures.
                    unsafe {
                        core::arch::asm!(
                            "sub rsp, 16",
                            "stmxcsr [rsp]",
                            "fnstcw [rsp + 4]",
                            "call {entry}",
                            "fldcw [rsp + 4]",
                            "ldmxcsr [rsp]",
                            "add rsp, 16",
                            entry = in(reg) entry,
                            in("rdi") self.area,
                            clobber_abi("C"),
                        );
                    }
                })
            })
        });

        let get32 = |at: usize| {
            // SAFETY: inside the area, as above.
            unsafe { base.add(at).cast::<u32>().read_unaligned() }
        };
        let get16 = |at: usize| {
            // SAFETY: inside the area, as above.
            unsafe { base.add(at).cast::<u16>().read_unaligned() }
        };
        if get16(layout::TIMED_OUT) != 0 {
            return Err(TimedOut);
        }
        Ok(Registers {
            eax: get32(r),
            ebx: get32(r + 4),
            ecx: get32(r + 8),
            edx: get32(r + 12),
            esi: get32(r + 16),
            edi: get32(r + 20),
            ebp: get32(r + 24),
            ds: get16(layout::DS),
            es: get16(layout::ES),
            flags: get16(layout::FLAGS),
        })
    }

    /// INT 10h AH=00h: sets a standard BIOS video mode, then AH=0Fh reads
    /// the current mode back. Ok only if the BIOS reports the mode asked for.
    pub fn set_mode(&mut self, mode: u8) -> Result<(), BiosCallFailure> {
        let timed_out = |function: u8| {
            move |TimedOut| BiosCallFailure::DidNotReturn {
                function,
                within_millis: bios_world::limit_millis(),
            }
        };
        self.int10(Registers {
            eax: u32::from(mode),
            ..Registers::default()
        })
        .map_err(timed_out(0x00))?;
        let current = self
            .int10(Registers {
                eax: 0x0F00,
                ..Registers::default()
            })
            .map_err(timed_out(0x0F))?;
        // AL = mode (bit 7: memory was not cleared), AH = columns.
        match (current.eax & 0x7F) as u8 {
            found if found == mode => Ok(()),
            found => Err(BiosCallFailure::ReportedMode(found)),
        }
    }
}

/// Copies the trampoline into the area and fills in its data block.
fn install(area: u64) {
    let image = trampoline::image();
    assert!(
        image.len() <= layout::STACK_TOP - 0x400,
        "the trampoline overlaps its stack"
    );
    let base = area as *mut u8;
    // SAFETY: the area is 16 KiB of free memory identity-mapped by `find`;
    // the image is shorter than its code part (asserted above).
    unsafe { core::ptr::copy_nonoverlapping(image.as_ptr(), base, image.len()) };
    let put = |at: usize, bytes: &[u8]| {
        // SAFETY: every `at` is a data-block offset inside the area.
        unsafe { core::ptr::copy_nonoverlapping(bytes.as_ptr(), base.add(at), bytes.len()) }
    };
    let gdt = trampoline::descriptors(area as u32);
    for (i, descriptor) in gdt.iter().enumerate() {
        put(layout::GDT + 8 * i, &descriptor.to_le_bytes());
    }
    let limit = (layout::GDT_ENTRIES * 8 - 1) as u16;
    put(layout::GDTR, &limit.to_le_bytes());
    put(layout::GDTR + 2, &(area + layout::GDT as u64).to_le_bytes());
    // The real-mode interrupt vector table: 256 vectors at address 0.
    put(layout::REAL_IDTR, &0x03FFu16.to_le_bytes());
    put(layout::REAL_IDTR + 2, &0u64.to_le_bytes());
    put(layout::REAL_SEGMENT, &((area >> 4) as u16).to_le_bytes());
}
