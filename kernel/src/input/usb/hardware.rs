//! One USB host controller's hardware as its driver reaches it: registers
//! in memory (BAR0 of OHCI, EHCI and xHCI, mapped uncached) or in I/O
//! space (UHCI's BAR4), its PCI configuration space, the DMA pages it owns
//! and the clock. Every access is checked against the window and the pages,
//! and every read is counted, for the bench's reads per idle poll.

use crate::{dma, pci, serial_println, time};
use usb::{Hardware, Memory, PciHardware, Platform};
use x86_64::instructions::port::Port;

/// Where a controller's registers are.
#[derive(Clone, Copy, Debug)]
pub enum Window {
    /// Memory-mapped, uncached at this virtual address, this many bytes.
    Memory { base: u64, bytes: u64 },
    /// I/O ports from `base`, this many.
    Io { base: u16, ports: u32 },
}

/// Reads made through a [`Registers`], for the bench.
#[derive(Clone, Copy, Debug, Default)]
pub struct Reads {
    /// Register reads (memory-mapped or I/O, any width).
    pub registers: u64,
    /// DMA words read.
    pub dma: u64,
}

/// One controller's registers, configuration space and DMA memory.
pub struct Registers {
    window: Window,
    /// Where all physical memory is mapped (DMA pages are reached through it).
    physical_memory_offset: u64,
    /// The DMA pages this controller owns: the only memory it may touch.
    dma: dma::Pages,
    /// Where the controller is on PCI.
    pub function: pci::Function,
    /// Reads so far.
    pub reads: Reads,
}

impl Registers {
    pub fn new(
        window: Window,
        function: pci::Function,
        dma: dma::Pages,
        physical_memory_offset: u64,
    ) -> Registers {
        Registers {
            window,
            physical_memory_offset,
            dma,
            function,
            reads: Reads::default(),
        }
    }

    /// Whether `width` bytes at `offset` lie inside the register window.
    #[inline]
    fn inside(&self, offset: u32, width: u32) -> bool {
        let end = u64::from(offset) + u64::from(width);
        match self.window {
            Window::Memory { bytes, .. } => end <= bytes,
            Window::Io { ports, .. } => end <= u64::from(ports),
        }
    }

    /// Whether the DMA word at `address` is this controller's.
    #[inline]
    fn owns(&self, address: u64) -> bool {
        address >= self.dma.next && address.saturating_add(4) <= self.dma.end
    }
}

impl Memory for Registers {
    fn mem_read(&mut self, address: u64) -> u32 {
        self.reads.dma += 1;
        if !self.owns(address) {
            return 0;
        }
        // SAFETY: the address is inside this controller's DMA pages (checked
        // above), usable RAM mapped at the physical-memory offset, 4-aligned
        // as the drivers only use word offsets into aligned buffers.
        unsafe { ((self.physical_memory_offset + address) as *const u32).read_volatile() }
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        if !self.owns(address) {
            return;
        }
        // SAFETY: as in `mem_read`: only this controller's DMA pages are written.
        unsafe { ((self.physical_memory_offset + address) as *mut u32).write_volatile(value) }
    }
}

impl Hardware for Registers {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        self.reads.registers += 1;
        let offset = offset & !3;
        if !self.inside(offset, 4) {
            // What a PCI read of nothing gives.
            return u32::MAX;
        }
        match self.window {
            // SAFETY: `offset` is inside BAR0 (checked above), which is mapped
            // uncached at `base`; the register is 4-aligned.
            Window::Memory { base, .. } => unsafe {
                ((base + u64::from(offset)) as *const u32).read_volatile()
            },
            // SAFETY: the port is inside the controller's I/O BAR (checked
            // above), which decodes only this controller's registers.
            Window::Io { base, .. } => unsafe { Port::<u32>::new(base + offset as u16).read() },
        }
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        let offset = offset & !3;
        if !self.inside(offset, 4) {
            return;
        }
        match self.window {
            // SAFETY: as in `mmio_read`.
            Window::Memory { base, .. } => unsafe {
                ((base + u64::from(offset)) as *mut u32).write_volatile(value)
            },
            // SAFETY: as in `mmio_read`.
            Window::Io { base, .. } => unsafe {
                Port::<u32>::new(base + offset as u16).write(value)
            },
        }
    }
}

impl Platform for Registers {
    fn now_micros(&mut self) -> u64 {
        time::micros()
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        serial_println!("{}", message);
    }
}

impl PciHardware for Registers {
    fn read16(&mut self, offset: u32) -> u16 {
        self.reads.registers += 1;
        let offset = offset & !1;
        if !self.inside(offset, 2) {
            return u16::MAX;
        }
        match self.window {
            // SAFETY: as in `mmio_read`, a 2-aligned 16-bit register.
            Window::Memory { base, .. } => unsafe {
                ((base + u64::from(offset)) as *const u16).read_volatile()
            },
            // SAFETY: as in `mmio_read`.
            Window::Io { base, .. } => unsafe { Port::<u16>::new(base + offset as u16).read() },
        }
    }

    fn write16(&mut self, offset: u32, value: u16) {
        let offset = offset & !1;
        if !self.inside(offset, 2) {
            return;
        }
        match self.window {
            // SAFETY: as in `read16`.
            Window::Memory { base, .. } => unsafe {
                ((base + u64::from(offset)) as *mut u16).write_volatile(value)
            },
            // SAFETY: as in `read16`.
            Window::Io { base, .. } => unsafe {
                Port::<u16>::new(base + offset as u16).write(value)
            },
        }
    }

    fn pci_config_read(&mut self, offset: u8) -> u32 {
        pci::config_read(self.function, offset & !3)
    }

    fn pci_config_write(&mut self, offset: u8, value: u32) {
        pci::config_write(self.function, offset & !3, value)
    }
}
