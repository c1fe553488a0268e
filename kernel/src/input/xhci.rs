//! USB keyboards through xHCI controllers, polled from the main loops. This
//! file is the hardware end only: PCI, the register mapping, DMA memory and
//! the clock; the driver itself is `usb::xhci`, tested on the host.

use crate::{dma, input::ps2, pci, serial_println, time};
use bootloader_api::info::MemoryRegions;
use core::sync::atomic::{AtomicU64, Ordering};
use spin::Mutex;
use usb::xhci::{Handoff, Xhci};
use usb::{Hardware, Memory};

/// Controllers driven; more are named and left alone.
const MAX_CONTROLLERS: usize = 4;
/// DMA memory per controller: rings, contexts, report buffers, scratchpads.
const DMA_BYTES_PER_CONTROLLER: u64 = 2 << 20;
/// Page-table pages the register mapping may need (PDPT, PD, PT).
const MAPPING_BYTES: u64 = 3 * dma::PAGE;

/// One controller's registers and DMA memory, as the driver reaches them.
pub struct Mmio {
    /// Where BAR0 is mapped (uncached).
    registers: u64,
    /// Where all physical memory is mapped (DMA pages are reached through it).
    physical_memory_offset: u64,
    /// The DMA pages this controller owns: the only memory it may touch.
    dma: dma::Pages,
    /// Where the controller is on PCI.
    function: pci::Function,
}

impl Memory for Mmio {
    fn mem_read(&mut self, address: u64) -> u32 {
        if address < self.dma.next || address + 4 > self.dma.end {
            return 0;
        }
        // SAFETY: the address is inside this controller's DMA pages (checked
        // above), usable RAM mapped at the physical-memory offset, 4-aligned
        // as the driver only uses word offsets into page-aligned buffers.
        unsafe { ((self.physical_memory_offset + address) as *const u32).read_volatile() }
    }

    fn mem_write(&mut self, address: u64, value: u32) {
        if address < self.dma.next || address + 4 > self.dma.end {
            return;
        }
        // SAFETY: as in `mem_read`: only this controller's DMA pages are written.
        unsafe { ((self.physical_memory_offset + address) as *mut u32).write_volatile(value) }
    }
}

impl Hardware for Mmio {
    fn mmio_read(&mut self, offset: u32) -> u32 {
        // SAFETY: the driver keeps `offset` inside BAR0 (it knows the BAR's
        // size), which is mapped uncached at `registers`.
        unsafe { ((self.registers + u64::from(offset & !3)) as *const u32).read_volatile() }
    }

    fn mmio_write(&mut self, offset: u32, value: u32) {
        // SAFETY: as in `mmio_read`.
        unsafe { ((self.registers + u64::from(offset & !3)) as *mut u32).write_volatile(value) }
    }

    fn now_micros(&mut self) -> u64 {
        time::micros()
    }

    fn log(&mut self, message: core::fmt::Arguments<'_>) {
        serial_println!("{}", message);
    }
}

/// A place in the controller table. `repr(u8)`, so that an empty place is a
/// zero tag and the table starts all zero, in `.bss` rather than in the kernel
/// file (`tests/size.rs`): an `Option` would mark `None` with a spare non-zero
/// value inside the driver.
#[repr(u8)]
// The place is the controller's storage (no heap): an empty place's unused
// bytes are the point.
#[allow(clippy::large_enum_variant)]
enum Controller {
    Absent,
    Running(Xhci<Mmio>),
}

impl Controller {
    fn running(&mut self) -> Option<&mut Xhci<Mmio>> {
        match self {
            Controller::Running(xhci) => Some(xhci),
            Controller::Absent => None,
        }
    }

    fn take(&mut self) -> Option<Xhci<Mmio>> {
        match core::mem::replace(self, Controller::Absent) {
            Controller::Running(xhci) => Some(xhci),
            Controller::Absent => None,
        }
    }
}

static CONTROLLERS: Mutex<[Controller; MAX_CONTROLLERS]> =
    Mutex::new([const { Controller::Absent }; MAX_CONTROLLERS]);

/// Each controller's longest poll since its enumeration work began (a
/// device plugged in after boot), said when the work is done: what the
/// frame loop was held up for.
static LONGEST_ENUMERATION_POLL: [AtomicU64; MAX_CONTROLLERS] =
    [const { AtomicU64::new(0) }; MAX_CONTROLLERS];

/// Finds the xHCI controllers, takes them from the firmware, and sets up the
/// keyboards on them (boot enumeration, bounded; the rest a step per poll).
/// Every step is bounded; a failure is logged and the PS/2 keyboard (if
/// any) is all there is.
pub fn init(regions: &MemoryRegions, physical_memory_offset: u64) {
    let (found, count) = pci::xhci_controllers::<MAX_CONTROLLERS>();
    if count == 0 {
        serial_println!("usb: no xHCI controller");
        return;
    }
    if count > MAX_CONTROLLERS {
        serial_println!(
            "usb: {} xHCI controllers; the first {} are used",
            count,
            MAX_CONTROLLERS
        );
    }
    let used = count.min(MAX_CONTROLLERS) as u64;
    let Some(mut memory) = dma::take(regions, used * (DMA_BYTES_PER_CONTROLLER + MAPPING_BYTES))
    else {
        serial_println!("usb: no usable memory below 4 GiB for DMA; USB keyboards not used");
        return;
    };
    let mut controllers = CONTROLLERS.lock();
    for (slot, function) in controllers.iter_mut().zip(found.into_iter().flatten()) {
        let (Some(mut mapping), Some(dma)) = (
            memory.split(MAPPING_BYTES),
            memory.split(DMA_BYTES_PER_CONTROLLER),
        ) else {
            break;
        };
        if let Some(xhci) = start(function, dma, &mut mapping, physical_memory_offset) {
            *slot = Controller::Running(xhci);
        }
    }
}

fn start(
    function: pci::Function,
    dma: dma::Pages,
    mapping: &mut dma::Pages,
    physical_memory_offset: u64,
) -> Option<Xhci<Mmio>> {
    let Some(bar) = pci::enable_memory_and_bus_master(function) else {
        serial_println!("usb: xHCI {}: BAR0 is not a memory BAR", function);
        return None;
    };
    if bar.address == 0 {
        serial_println!("usb: xHCI {}: BAR0 was never assigned an address", function);
        return None;
    }
    if bar.bytes < 0x1000 || bar.bytes > 1 << 24 {
        serial_println!(
            "usb: xHCI {}: BAR0 of {} bytes makes no sense",
            function,
            bar.bytes
        );
        return None;
    }
    let registers = match dma::map_uncached(bar.address, bar.bytes, mapping, physical_memory_offset)
    {
        Ok(registers) => registers,
        Err(problem) => {
            serial_println!("usb: xHCI {}: {}", function, problem);
            return None;
        }
    };
    let hardware = Mmio {
        registers,
        physical_memory_offset,
        dma,
        function,
    };
    let mut xhci = match Xhci::new(hardware, bar.bytes as u32, dma.next, dma.end - dma.next) {
        Ok(xhci) => xhci,
        Err(problem) => {
            serial_println!("usb: xHCI {}: {}", function, problem);
            return None;
        }
    };
    let capabilities = xhci.capabilities();
    serial_println!(
        "usb: xHCI {}, {} ports, {}-byte contexts, {} scratchpad pages",
        function,
        capabilities.ports,
        capabilities.layout.context_bytes,
        capabilities.scratchpads
    );
    match xhci.take_ownership() {
        Handoff::Forced => {
            serial_println!("usb: the firmware did not let go of the xHCI within 1 s; taken anyway")
        }
        Handoff::Released(micros) => {
            serial_println!("usb: the firmware handed the xHCI over in {} us", micros)
        }
        Handoff::NoLegacyCapability | Handoff::NotOwned => {}
    }
    if let Some(routed) = pci::route_intel_ports_to_xhci(function) {
        serial_println!(
            "usb: Intel PCH ports switched to the xHCI (XUSB2PR {:#x})",
            routed
        );
    }
    if let Err(problem) = xhci.reset_and_start() {
        serial_println!(
            "usb: xHCI {}: {}; USB keyboards not used",
            function,
            problem
        );
        return None;
    }
    if let Err(problem) = xhci.no_op() {
        serial_println!(
            "usb: xHCI {}: command ring: {}; USB keyboards not used",
            function,
            problem
        );
        return None;
    }
    // Boot enumeration: at most `BOOT_ENUMERATION_MICROS`, then it carries
    // on from the frame loop's polls (the driver says so).
    if xhci.enumerate() == 0 {
        serial_println!(
            "usb: no USB keyboard on the xHCI {} at boot; its ports stay watched",
            function
        );
    }
    crate::facts::record(|facts| facts.usb_controllers += 1);
    Some(xhci)
}

/// Before power-off or reset: every controller halted and reset, its ports'
/// power switched off, and Intel's switched ports handed back to the EHCI,
/// as Linux's shutdown path does. Each controller is then forgotten.
pub fn shut_down() {
    // Nothing else runs now; a lock held means a poll was interrupted, and
    // its controller is left as it is rather than waited for.
    let Some(mut controllers) = CONTROLLERS.try_lock() else {
        serial_println!("usb: controllers busy; not shut down");
        return;
    };
    for slot in controllers.iter_mut() {
        let Some(mut xhci) = slot.take() else {
            continue;
        };
        let function = xhci.hardware().function;
        match xhci.shut_down() {
            Ok(()) => serial_println!(
                "usb: xHCI {} halted and reset, ports switched off",
                function
            ),
            Err(problem) => serial_println!("usb: xHCI {}: shut down: {}", function, problem),
        }
        if let Some((usb2, superspeed)) = pci::hand_intel_ports_back_to_ehci(function) {
            serial_println!(
                "usb: Intel PCH ports handed back to the EHCI (XUSB2PR {:#x}, USB3_PSSEN {:#x})",
                usb2,
                superspeed
            );
        }
    }
}

/// How many controllers are running (for the bench).
pub fn running() -> usize {
    CONTROLLERS.try_lock().map_or(0, |controllers| {
        controllers
            .iter()
            .filter(|c| matches!(c, Controller::Running(_)))
            .count()
    })
}

/// Takes the keyboards' reports and repeats; their scancodes join the PS/2
/// keyboard's in `ps2::SCANCODES`. Called from the main loops only.
pub fn poll() {
    let Some(mut controllers) = CONTROLLERS.try_lock() else {
        return;
    };
    for (xhci, longest) in controllers
        .iter_mut()
        .zip(LONGEST_ENUMERATION_POLL.iter())
        .filter_map(|(controller, longest)| Some((controller.running()?, longest)))
    {
        // Only a poll with enumeration work reads the clock: the idle
        // poll stays as cheap as it was.
        let enumerating = !xhci.enumeration_idle();
        let start = if enumerating { time::micros() } else { 0 };
        xhci.poll(&mut |byte| {
            // SCANCODES has a single producer, IRQ 1. With interrupts off the
            // IRQ handler cannot run in the middle of this push, and there is
            // only one core, so the two producers never overlap.
            x86_64::instructions::interrupts::without_interrupts(|| {
                ps2::SCANCODES.push(byte);
            });
        });
        if enumerating {
            let took = time::micros().saturating_sub(start);
            longest.fetch_max(took, Ordering::Relaxed);
            if xhci.enumeration_idle() {
                serial_println!(
                    "usb: enumeration work done; its longest poll took {} us",
                    longest.swap(0, Ordering::Relaxed)
                );
            }
        }
    }
}
