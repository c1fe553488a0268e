//! USB keyboards on every host controller PCI offers (UHCI, OHCI, EHCI and
//! xHCI), polled from the main loops. This is the hardware end only: PCI,
//! the register windows, DMA memory, the order controllers are taken and
//! started in, and their shutdown; the drivers and the device layer are
//! the portable crate `usb`, tested on the host against register models.
//!
//! The order is Linux's: every controller is taken from the firmware
//! first; then each EHCI is started (it claims every port, and hands
//! full- and low-speed devices to its companions), then the companions
//! (UHCI, OHCI), then the xHCIs (Intel's switchable ports routed to them
//! as now). Before power-off or reset the companions and xHCIs halt
//! first, the EHCIs last (their CONFIGFLAG cleared hands every port back).

mod hardware;
mod host;

use crate::{dma, facts, input::ps2, pci, serial_println, time};
use bootloader_api::info::MemoryRegions;
use core::fmt::{self, Write};
use core::sync::atomic::{AtomicU64, Ordering};
use hardware::{Reads, Registers, Window};
use host::Host;
use protocol::line::{self, UsbKeyboards};
use spin::Mutex;
use usb::bus::Bus;
use usb::driver::Driver;
use usb::host::{ControllerKind, Handoff, HostController};

/// Controllers driven; more are named and left alone. ICH9 has two EHCIs
/// and six UHCIs.
const MAX_CONTROLLERS: usize = 8;
/// Controllers counted on PCI, to say how many were left.
const MAX_FOUND: usize = 32;
/// DMA memory per xHCI: rings, contexts, report buffers, scratchpads.
const XHCI_DMA_BYTES: u64 = 2 << 20;
/// DMA memory per EHCI, OHCI or UHCI: frame list, queue heads, transfer
/// descriptors, buffers (the driver allocates inside it).
const USB2_DMA_BYTES: u64 = 256 << 10;
/// Page-table pages a register mapping may need (PDPT, PD, PT).
const MAPPING_BYTES: u64 = 3 * dma::PAGE;
/// Keyboards remembered per controller, to say each new one once.
const MAX_KEYBOARDS: usize = 16;

/// The longest text a keyboard's location takes (a root port and five hub
/// tiers: `255.15.15.15.15.15`), with room to spare.
const LOCATION_BYTES: usize = 24;

/// A place in the controller table. `repr(u8)`, so that an empty place is a
/// zero tag and the table starts all zero, in `.bss` rather than in the kernel
/// file (`tests/size.rs`): an `Option` would mark `None` with a spare non-zero
/// value inside a driver.
#[repr(u8)]
// The place is the controller's storage (no heap): an empty place's unused
// bytes are the point.
#[allow(clippy::large_enum_variant)]
enum Controller {
    Absent,
    /// A controller under the device layer.
    Running(Bus<Host>),
    /// Taken from the firmware, not started yet (the device layer is
    /// made once the driver knows its ports).
    Taken(Host),
}

impl Controller {
    fn kind(&self) -> Option<ControllerKind> {
        match self {
            Controller::Absent => None,
            Controller::Running(bus) => Some(bus.kind()),
            Controller::Taken(host) => Some(host.kind()),
        }
    }

    /// The device layer over the controller, if it runs.
    fn running(&mut self) -> Option<&mut Bus<Host>> {
        match self {
            Controller::Running(bus) => Some(bus),
            Controller::Absent | Controller::Taken(_) => None,
        }
    }
}

/// A keyboard's location as text (the device layer's `Display`), kept to
/// say each new keyboard once.
#[derive(Clone, Copy, PartialEq, Eq)]
struct Text {
    bytes: [u8; LOCATION_BYTES],
    len: u8,
}

impl Text {
    const EMPTY: Text = Text {
        bytes: [0; LOCATION_BYTES],
        len: 0,
    };

    fn of(value: impl fmt::Display) -> Text {
        let mut text = Text::EMPTY;
        // A location longer than the buffer is cut: still told apart from
        // every other one the hub tiers allow.
        let _ = write!(text, "{value}");
        text
    }

    fn as_str(&self) -> &str {
        core::str::from_utf8(&self.bytes[..usize::from(self.len)]).unwrap_or("?")
    }
}

impl Write for Text {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        for &byte in s.as_bytes() {
            let at = usize::from(self.len);
            if at == LOCATION_BYTES {
                return Err(fmt::Error);
            }
            self.bytes[at] = byte;
            self.len += 1;
        }
        Ok(())
    }
}

impl fmt::Display for Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The keyboards a controller had when its last enumeration work began
/// (or at boot), so that each new one is said once when the work is done.
#[derive(Clone, Copy)]
struct Keyboards {
    known: [Text; MAX_KEYBOARDS],
    count: u8,
}

impl Keyboards {
    const NONE: Keyboards = Keyboards {
        known: [Text::EMPTY; MAX_KEYBOARDS],
        count: 0,
    };

    fn contains(&self, location: &Text) -> bool {
        self.known[..usize::from(self.count)].contains(location)
    }

    /// The controller's keyboards now.
    fn of(bus: &Bus<Host>) -> Keyboards {
        let mut now = Keyboards::NONE;
        for location in bus.keyboards() {
            if usize::from(now.count) < MAX_KEYBOARDS {
                now.known[usize::from(now.count)] = Text::of(location);
                now.count += 1;
            }
        }
        now
    }
}

/// The controllers, each with the keyboards said so far.
struct Table {
    controllers: [Controller; MAX_CONTROLLERS],
    keyboards: [Keyboards; MAX_CONTROLLERS],
}

static TABLE: Mutex<Table> = Mutex::new(Table {
    controllers: [const { Controller::Absent }; MAX_CONTROLLERS],
    keyboards: [Keyboards::NONE; MAX_CONTROLLERS],
});

/// Each controller's longest poll since its enumeration work began (a
/// device plugged in after boot), said when the work is done: what the
/// frame loop was held up for.
static LONGEST_ENUMERATION_POLL: [AtomicU64; MAX_CONTROLLERS] =
    [const { AtomicU64::new(0) }; MAX_CONTROLLERS];

/// A controller's name for people: `EHCI`.
fn label(kind: ControllerKind) -> &'static str {
    match kind {
        ControllerKind::Uhci => "UHCI",
        ControllerKind::Ohci => "OHCI",
        ControllerKind::Ehci => "EHCI",
        ControllerKind::Xhci => "xHCI",
    }
}

/// DMA memory a controller of this kind gets, and whether its registers
/// need a mapping.
fn memory_needed(kind: ControllerKind) -> u64 {
    match kind {
        ControllerKind::Xhci => XHCI_DMA_BYTES + MAPPING_BYTES,
        ControllerKind::Ehci | ControllerKind::Ohci => USB2_DMA_BYTES + MAPPING_BYTES,
        ControllerKind::Uhci => USB2_DMA_BYTES,
    }
}

/// Finds every USB host controller, takes them all from the firmware, then
/// starts them in Linux's order (EHCIs, their companions, xHCIs) and sets up
/// the keyboards on each (boot enumeration, bounded; the rest a step per
/// poll). Every step is bounded; a controller that fails is logged and left,
/// and the PS/2 keyboard (if any) is all there is.
#[optimize(size)] // run once at start-up: small beats fast
pub fn init(regions: &MemoryRegions, physical_memory_offset: u64) {
    let (found, count) = pci::usb_controllers::<MAX_FOUND>();
    if count == 0 {
        serial_println!("usb: no USB host controller");
        return;
    }
    if count > MAX_FOUND {
        serial_println!(
            "usb: {} USB functions; only the first {} looked at",
            count,
            MAX_FOUND
        );
    }
    let mut chosen = [None; MAX_CONTROLLERS];
    let mut used = 0;
    for usb in found.into_iter().flatten() {
        let Some(kind) = ControllerKind::from_prog_if(usb.prog_if) else {
            serial_println!(
                "usb: {} has programming interface {:02x}h, no host controller; left alone",
                usb.function,
                usb.prog_if
            );
            continue;
        };
        if used == MAX_CONTROLLERS {
            serial_println!(
                "usb: {} {}: more than {} controllers; left alone",
                label(kind),
                usb.function,
                MAX_CONTROLLERS
            );
            continue;
        }
        chosen[used] = Some((usb.function, kind));
        used += 1;
    }
    let needed: u64 = chosen
        .iter()
        .flatten()
        .map(|&(_, kind)| memory_needed(kind))
        .sum();
    if needed == 0 {
        return;
    }
    let Some(mut memory) = dma::take(regions, needed) else {
        serial_println!("usb: no usable memory below 4 GiB for DMA; USB keyboards not used");
        return;
    };
    let mut table = TABLE.lock();
    let table = &mut *table;
    // Every controller taken from the firmware before any is started.
    for (place, &(function, kind)) in table.controllers.iter_mut().zip(chosen.iter().flatten()) {
        if let Some(controller) = open(function, kind, &mut memory, physical_memory_offset) {
            *place = controller;
        }
    }
    // The EHCIs first, so that their companions find only the devices
    // handed to them; then the companions; then the xHCIs.
    for pass in [
        ControllerKind::Ehci,
        ControllerKind::Ohci,
        ControllerKind::Uhci,
        ControllerKind::Xhci,
    ] {
        for (place, keyboards) in table.controllers.iter_mut().zip(table.keyboards.iter_mut()) {
            if place.kind() != Some(pass) {
                continue;
            }
            if let Controller::Taken(host) = core::mem::replace(place, Controller::Absent) {
                *place = start(host);
            }
            if let Some(bus) = place.running() {
                enumerate_at_boot(bus);
                *keyboards = Keyboards::of(bus);
                let function = bus.controller().hardware().function;
                for location in &keyboards.known[..usize::from(keyboards.count)] {
                    say_keyboard(pass, function, location);
                }
            }
        }
    }
    record_facts(table);
}

/// Makes the controller's driver, with its registers and DMA memory, and
/// takes the controller from the firmware. `None` (logged) if it cannot be
/// driven.
#[optimize(size)] // run once at start-up: small beats fast
fn open(
    function: pci::Function,
    kind: ControllerKind,
    memory: &mut dma::Pages,
    physical_memory_offset: u64,
) -> Option<Controller> {
    // In D3hot its BARs are not decoded: nothing below would work.
    match pci::wake_to_d0(function) {
        Some((from, true)) => {
            serial_println!(
                "usb: {} {}: brought from D{} to D0",
                label(kind),
                function,
                from
            )
        }
        Some((from, false)) => {
            serial_println!(
                "usb: {} {}: stayed in D{} though told to go to D0; not used",
                label(kind),
                function,
                from
            );
            return None;
        }
        None => {}
    }
    let window = match kind {
        ControllerKind::Uhci => io_window(function)?,
        _ => {
            let mut mapping = memory.split(MAPPING_BYTES)?;
            memory_window(function, kind, &mut mapping, physical_memory_offset)?
        }
    };
    let dma_bytes = match kind {
        ControllerKind::Xhci => XHCI_DMA_BYTES,
        _ => USB2_DMA_BYTES,
    };
    let dma = memory.split(dma_bytes)?;
    let registers = Registers::new(window, function, dma, physical_memory_offset);
    let (base, bytes) = (dma.next, dma.end - dma.next);
    let window_bytes = match window {
        Window::Memory { bytes, .. } => bytes as u32,
        Window::Io { ports, .. } => ports,
    };
    let host = match Driver::new(kind, registers, window_bytes, base, bytes) {
        Ok(host) => host,
        Err(problem) => {
            serial_println!("usb: {} {}: {}", label(kind), function, problem);
            return None;
        }
    };
    if let Driver::Xhci(xhci) = &host {
        let capabilities = xhci.capabilities();
        serial_println!(
            "usb: xHCI {}, {} ports, {}-byte contexts, {} scratchpad pages",
            function,
            capabilities.ports,
            capabilities.layout.context_bytes,
            capabilities.scratchpads
        );
    }
    take_from_firmware(host, kind, function)
}

/// Takes the controller from the firmware and says how that went; a
/// controller the firmware never let go of is left alone (`None`).
#[optimize(size)] // run once at start-up: small beats fast
fn take_from_firmware(
    mut host: Host,
    kind: ControllerKind,
    function: pci::Function,
) -> Option<Controller> {
    let name = label(kind);
    let handoff = host.take_ownership();
    match handoff {
        Handoff::NotOwned => {
            serial_println!("usb: {} {}: the firmware did not own it", name, function);
        }
        Handoff::Released { micros } => {
            serial_println!(
                "usb: {} {}: the firmware handed it over in {} us",
                name,
                function,
                micros
            );
        }
        Handoff::Forced => {
            serial_println!(
                "usb: {} {}: the firmware did not let go of it within 1 s; taken anyway",
                name,
                function
            );
        }
        Handoff::NeverReleased => {
            serial_println!(
                "usb: {} {}: the firmware never let go of it; left alone",
                name,
                function
            );
            return None;
        }
    }
    Some(Controller::Taken(host))
}

/// UHCI's registers: I/O BAR4, with I/O decoding and bus mastering on.
fn io_window(function: pci::Function) -> Option<Window> {
    // USBCMD to PORTSC2 (0x00-0x13) at least.
    const UHCI_REGISTER_PORTS: u32 = 0x14;
    let Some(bar) = pci::enable_io_and_bus_master(function, pci::BAR4) else {
        serial_println!("usb: UHCI {}: BAR4 is not an I/O BAR", function);
        return None;
    };
    if bar.base == 0 || bar.ports < UHCI_REGISTER_PORTS {
        serial_println!(
            "usb: UHCI {}: I/O BAR4 of {} ports at {:#x} makes no sense",
            function,
            bar.ports,
            bar.base
        );
        return None;
    }
    Some(Window::Io {
        base: bar.base,
        ports: bar.ports,
    })
}

/// An OHCI's, EHCI's or xHCI's registers: memory BAR0, with memory decoding
/// and bus mastering on, mapped uncached.
fn memory_window(
    function: pci::Function,
    kind: ControllerKind,
    mapping: &mut dma::Pages,
    physical_memory_offset: u64,
) -> Option<Window> {
    let name = label(kind);
    let Some(bar) = pci::enable_memory_and_bus_master(function) else {
        serial_println!("usb: {} {}: BAR0 is not a memory BAR", name, function);
        return None;
    };
    if bar.address == 0 {
        serial_println!(
            "usb: {} {}: BAR0 was never assigned an address",
            name,
            function
        );
        return None;
    }
    // The smallest BAR that holds the registers: an OHCI's 0x100 bytes, an
    // EHCI's capability and operational registers, an xHCI's 4 KiB.
    let smallest = match kind {
        ControllerKind::Xhci => 0x1000,
        _ => 0x100,
    };
    if bar.bytes < smallest || bar.bytes > 1 << 24 {
        serial_println!(
            "usb: {} {}: BAR0 of {} bytes makes no sense",
            name,
            function,
            bar.bytes
        );
        return None;
    }
    match dma::map_uncached(bar.address, bar.bytes, mapping, physical_memory_offset) {
        Ok(base) => Some(Window::Memory {
            base,
            bytes: bar.bytes,
        }),
        Err(problem) => {
            serial_println!("usb: {} {}: {}", name, function, problem);
            None
        }
    }
}

/// Resets and starts a controller taken from the firmware, and puts the
/// device layer over it; `Absent` (logged, and halted again) if it would
/// not start.
#[optimize(size)] // run once at start-up: small beats fast
fn start(mut host: Host) -> Controller {
    host::route_ports_to_xhci(&mut host);
    match host.reset_and_start() {
        Ok(()) => Controller::Running(Bus::new(host)),
        Err(problem) => {
            let function = host.hardware().function;
            serial_println!(
                "usb: {} {}: {}; USB keyboards on it not used",
                label(host.kind()),
                function,
                problem
            );
            // Whatever the reset left running is stopped.
            host.halt();
            Controller::Absent
        }
    }
}

/// Boot enumeration: bounded by the device layer, then it carries on from
/// the frame loop's polls.
fn enumerate_at_boot(bus: &mut Bus<Host>) {
    if bus.enumerate() == 0 {
        let function = bus.controller().hardware().function;
        serial_println!(
            "usb: no USB keyboard on the {} {} at boot; its ports stay watched",
            label(bus.kind()),
            function
        );
    }
}

/// Says a keyboard's controller and location (`usb: keyboard on ...`).
fn say_keyboard(kind: ControllerKind, function: pci::Function, location: &Text) {
    serial_println!(
        "{}",
        line::UsbKeyboardOn {
            kind: kind.name(),
            function,
            location,
        }
    );
}

/// The facts record's USB part: controllers driven, and the keyboards on
/// each kind.
fn record_facts(table: &Table) {
    let mut keyboards = UsbKeyboards::default();
    let mut controllers = 0;
    for (place, known) in table.controllers.iter().zip(table.keyboards.iter()) {
        let Some(kind) = place.kind() else {
            continue;
        };
        controllers += 1;
        if let Some(index) = line::usb_host_index(kind.name()) {
            keyboards.on[index] = keyboards.on[index].saturating_add(known.count);
        }
    }
    facts::record(|facts| {
        facts.usb_controllers = controllers;
        facts.usb_keyboards = keyboards;
    });
}

/// Before power-off or reset: every controller halted, the companions and
/// xHCIs first (an xHCI also reset, its ports switched off, and Intel's
/// switched ports handed back to the EHCI), the EHCIs last (CONFIGFLAG
/// cleared hands every port back to the companions), as Linux's shutdown
/// path does. One line each. Each controller is then forgotten.
pub fn shut_down() {
    // Nothing else runs now; a lock held means a poll was interrupted, and
    // its controllers are left as they are rather than waited for.
    let Some(mut table) = TABLE.try_lock() else {
        serial_println!("usb: controllers busy; not shut down");
        return;
    };
    for ehci_pass in [false, true] {
        for place in table.controllers.iter_mut() {
            if place.kind().is_none() || (place.kind() == Some(ControllerKind::Ehci)) != ehci_pass {
                continue;
            }
            let mut controller = core::mem::replace(place, Controller::Absent);
            let Some(bus) = controller.running() else {
                continue;
            };
            let kind = bus.kind();
            let function = bus.controller().hardware().function;
            let halted = bus.shut_down();
            let said = line::UsbHalted {
                kind: kind.name(),
                function,
                halted,
            };
            match (halted, kind) {
                (true, ControllerKind::Xhci) => {
                    serial_println!("{} and reset, ports switched off", said)
                }
                (true, _) => serial_println!("{}", said),
                (false, _) => serial_println!("{}still running after the bounded wait", said),
            }
            host::hand_ports_back(bus.controller());
        }
    }
}

/// How many controllers run, by kind, for the bench: `(kind, function)`.
pub fn running() -> (
    [Option<(ControllerKind, pci::Function)>; MAX_CONTROLLERS],
    usize,
) {
    let mut running = [None; MAX_CONTROLLERS];
    let mut count = 0;
    if let Some(mut table) = TABLE.try_lock() {
        for place in table.controllers.iter_mut() {
            if let Some(bus) = place.running() {
                running[count] = Some((bus.kind(), bus.controller().hardware().function));
                count += 1;
            }
        }
    }
    (running, count)
}

/// Polls the one controller at `function` `calls` times (for the bench):
/// the reads its polls made.
pub fn poll_one(function: pci::Function, calls: u64) -> Option<Reads> {
    let mut table = TABLE.try_lock()?;
    let bus = table
        .controllers
        .iter_mut()
        .filter_map(Controller::running)
        .find_map(|bus| (bus.controller().hardware().function == function).then_some(bus))?;
    let before = bus.controller().hardware().reads;
    for _ in 0..calls {
        bus.poll(&mut push);
    }
    let after = bus.controller().hardware().reads;
    Some(Reads {
        registers: after.registers - before.registers,
        dma: after.dma - before.dma,
    })
}

/// Hands a keyboard's scancode byte to the frame loop.
fn push(byte: u8) {
    // SCANCODES has a single producer, IRQ 1. With interrupts off the
    // IRQ handler cannot run in the middle of this push, and there is
    // only one core, so the two producers never overlap.
    x86_64::instructions::interrupts::without_interrupts(|| {
        ps2::SCANCODES.push(byte);
    });
}

/// Takes the keyboards' reports and repeats; their scancodes join the PS/2
/// keyboard's in `ps2::SCANCODES`. Called from the main loops only.
pub fn poll() {
    let Some(mut table) = TABLE.try_lock() else {
        return;
    };
    let table = &mut *table;
    let mut keyboards_changed = false;
    for ((place, known), longest) in table
        .controllers
        .iter_mut()
        .zip(table.keyboards.iter_mut())
        .zip(LONGEST_ENUMERATION_POLL.iter())
    {
        if let Some(bus) = place.running() {
            keyboards_changed |= poll_controller(bus, known, longest);
        }
    }
    if keyboards_changed {
        record_facts(table);
    }
}

/// One controller's poll; whether its keyboards changed.
#[inline]
fn poll_controller(bus: &mut Bus<Host>, known: &mut Keyboards, longest: &AtomicU64) -> bool {
    // Only a poll with enumeration work reads the clock: the idle poll
    // stays as cheap as it was.
    let enumerating = !bus.enumeration_idle();
    let start = if enumerating { time::micros() } else { 0 };
    bus.poll(&mut push);
    let idle = bus.enumeration_idle();
    if !enumerating {
        if !idle {
            // Work begins (a device plugged in): the keyboards there are
            // now, so that the new ones can be said when it is done.
            *known = Keyboards::of(bus);
        }
        return false;
    }
    let took = time::micros().saturating_sub(start);
    longest.fetch_max(took, Ordering::Relaxed);
    if !idle {
        return false;
    }
    serial_println!(
        "usb: enumeration work done; its longest poll took {} us",
        longest.swap(0, Ordering::Relaxed)
    );
    let now = Keyboards::of(bus);
    let (kind, function) = (bus.kind(), bus.controller().hardware().function);
    for location in now.known[..usize::from(now.count)]
        .iter()
        .filter(|location| !known.contains(location))
    {
        say_keyboard(kind, function, location);
    }
    *known = now;
    true
}
