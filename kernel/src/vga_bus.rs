//! The real VGA bus: I/O ports through `in`/`out`, video memory through the
//! bootloader's mapping of physical memory at 0xA0000. This is the only place
//! the Mode X driver's traffic meets the hardware.
//!
//! The ports come as `modex::regs::Port`, which only names the VGA's ports
//! (0x3B0-0x3DF) and Bochs VBE's (0x1CE, 0x1CF): no caller, safe or not, can
//! make this bus touch any other port (PCI configuration, the reset port).

use modex::regs::Port as VgaPort;
use modex::VgaBus;
use x86_64::instructions::port::Port;

const VGA_WINDOW_PHYSICAL: u64 = 0xA0000;
const VGA_WINDOW_BYTES: usize = 0x10000;

pub struct PortBus {
    window: *mut u8,
}

impl PortBus {
    /// # Safety
    /// `physical_memory_offset` must be the virtual address at which all of
    /// physical memory (at least up to 0xB0000) is mapped, and no other code may
    /// use the VGA ports or window while this bus exists. (Which ports the bus
    /// can reach needs no promise: `VgaPort` names only the VGA's and Bochs
    /// VBE's.)
    pub unsafe fn new(physical_memory_offset: u64) -> Self {
        PortBus {
            window: (physical_memory_offset + VGA_WINDOW_PHYSICAL) as *mut u8,
        }
    }
}

impl VgaBus for PortBus {
    fn write_port8(&mut self, port: VgaPort, value: u8) {
        // SAFETY: `VgaPort` can only be a VGA or Bochs VBE port (its field is
        // private to modex, whose tests check every value), and those ports
        // belong to this bus by the contract of `new`.
        unsafe { Port::<u8>::new(port.number()).write(value) }
    }

    fn write_port16(&mut self, port: VgaPort, value: u16) {
        // SAFETY: as for `write_port8`; a 16-bit OUT also writes the next port,
        // which for every `VgaPort` is again a VGA port or, after 0x1CF, the
        // rest of Bochs VBE's 16-bit data register.
        unsafe { Port::<u16>::new(port.number()).write(value) }
    }

    fn read_port8(&mut self, port: VgaPort) -> u8 {
        // SAFETY: as for `write_port8`.
        unsafe { Port::<u8>::new(port.number()).read() }
    }

    fn read_port16(&mut self, port: VgaPort) -> u16 {
        // SAFETY: as for `write_port16`.
        unsafe { Port::<u16>::new(port.number()).read() }
    }

    fn write_vram8(&mut self, offset: u16, value: u8) {
        // SAFETY: any u16 offset lies inside the 64 KiB window mapped by `new`'s
        // contract; volatile because every store is a bus cycle to the card.
        unsafe { self.window.add(offset as usize).write_volatile(value) }
    }

    fn read_vram8(&mut self, offset: u16) -> u8 {
        // SAFETY: as for `write_vram8`; the read also loads the VGA latches.
        unsafe { self.window.add(offset as usize).read_volatile() }
    }

    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        let end = (offset as usize + count as usize).min(VGA_WINDOW_BYTES);
        for address in offset as usize..end {
            // SAFETY: `address` stays below the window's end.
            unsafe { self.window.add(address).write_volatile(value) }
        }
    }

    /// The kernel's clock, which never stands still (`time::micros`), so the
    /// driver's waits on Input Status 1 end by time however fast a read is.
    fn now_micros(&mut self) -> Option<u64> {
        Some(crate::time::micros())
    }
}
