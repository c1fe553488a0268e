//! Leaving the machine: ACPI soft-off (S5) after Esc, and a reset on
//! Ctrl+Alt+Del, each by the means the ACPI tables name, with the classic PC
//! ways as fallbacks for the reset. Every wait here is bounded by the clock,
//! and a way that fails is logged before the next is tried.

use crate::platform::acpi::{self, Register};
use crate::{serial_println, time};
use demo::facts::Ps2;
use firmware::acpi::{pm1_control_with_sleep_type, Presence, ResetStep, SCI_EN, SLP_EN};
use x86_64::instructions::port::Port;

/// How long the firmware gets to switch the chipset into ACPI mode.
const ACPI_ENABLE_MICROS: u64 = 1_000_000;
/// How long a power-off or reset gets to take effect before the next way is
/// tried.
const TAKE_EFFECT_MICROS: u64 = 500_000;

/// Powers the machine off through ACPI S5; returns (having said why) only
/// if that is not possible or did not work.
pub fn off() {
    crate::input::usb::shut_down();
    let Some(soft_off) = acpi::facts().soft_off else {
        serial_println!(
            "power: no ACPI soft-off on this machine (see the acpi: lines); halting instead"
        );
        return;
    };
    x86_64::instructions::interrupts::disable();
    let mut pm1a = Port::<u16>::new(soft_off.pm1a_control);
    // SAFETY: reading PM1a control (the FADT's port) has no side effect.
    if unsafe { pm1a.read() } & SCI_EN == 0 {
        if let Some((port, value)) = soft_off.smi_command {
            // SAFETY: the FADT names this SMI command port and the value that
            // asks the firmware to hand the chipset to the OS (ACPI mode).
            unsafe { Port::<u8>::new(port).write(value) };
            // SAFETY: as above, a read of PM1a control.
            let enabled = wait(ACPI_ENABLE_MICROS, || unsafe { pm1a.read() } & SCI_EN != 0);
            if !enabled {
                serial_println!(
                    "power: the firmware did not switch to ACPI mode; trying S5 anyway"
                );
            }
        }
    }
    serial_println!(
        "power: switching off (ACPI S5, SLP_TYP {}/{})",
        soft_off.sleep_types.a,
        soft_off.sleep_types.b
    );
    let controls = [
        Some((soft_off.pm1a_control, soft_off.sleep_types.a)),
        soft_off
            .pm1b_control
            .map(|port| (port, soft_off.sleep_types.b)),
    ];
    // Bochs's magic breakpoint, a no-op on every other machine: an emulator
    // whose tests want the last screen stops here (boot/bochs.rs).
    // SAFETY: `xchg bx, bx` exchanges a register with itself: no effect.
    unsafe { core::arch::asm!("xchg bx, bx", options(nomem, nostack, preserves_flags)) };
    // SLP_TYP first, then SLP_EN, as the ACPI specification orders it.
    for enable in [0, SLP_EN] {
        for (port, sleep_type) in controls.into_iter().flatten() {
            let mut control = Port::<u16>::new(port);
            // SAFETY: PM1 control, as the FADT names it; writing the sleep
            // type, then SLP_EN, is what enters S5; the other bits are kept.
            unsafe {
                let value = pm1_control_with_sleep_type(control.read(), sleep_type);
                control.write(value | enable);
            }
        }
    }
    wait(TAKE_EFFECT_MICROS, || false);
    serial_println!("power: still running after ACPI S5; halting instead");
}

/// Resets the machine: the FADT's reset register, port 0xCF9, the 8042's
/// reset line, then a triple fault, each given half a second.
pub fn reset() -> ! {
    serial_println!("power: Ctrl+Alt+Del: resetting");
    crate::input::usb::shut_down();
    x86_64::instructions::interrupts::disable();
    let facts = acpi::facts();
    // The 8042 probe's answer, where there was one, over the FADT's flag.
    let i8042 = match crate::facts::try_get().map(|known| known.ps2) {
        Some(Ps2::Absent) => Presence::Absent,
        Some(Ps2::Ready | Ps2::Failed(_)) => Presence::Present,
        Some(Ps2::Unknown) | None => facts.legacy.i8042,
    };
    for step in ResetStep::order(facts.reset.is_some(), i8042) {
        match step {
            ResetStep::FadtRegister => {
                if let Some((register, value)) = facts.reset {
                    write_register(register, value);
                }
            }
            ResetStep::ResetControlPort => reset_control_port(),
            ResetStep::KeyboardControllerPulse => keyboard_controller_pulse(),
            ResetStep::TripleFault => triple_fault(),
        }
        wait(TAKE_EFFECT_MICROS, || false);
        serial_println!("power: {:?} did not reset the machine", step);
    }
    triple_fault()
}

/// Polls `done` until it holds or `micros` pass; whether it held.
fn wait(micros: u64, mut done: impl FnMut() -> bool) -> bool {
    let deadline = time::micros() + micros;
    while time::micros() < deadline {
        if done() {
            return true;
        }
        core::hint::spin_loop();
    }
    done()
}

/// The FADT's reset register, in whichever space it lives. The FADT says
/// (RESET_REG_SUP) that writing its value there resets the machine.
fn write_register(register: Register, value: u8) {
    match register {
        // SAFETY: the FADT's reset register, as above.
        Register::Io(port) => unsafe { Port::<u8>::new(port).write(value) },
        // SAFETY: the FADT's reset register, as above, at the virtual address
        // the table reader checked lies inside the map of physical memory.
        Register::Memory(address) => unsafe {
            core::ptr::write_volatile(address as *mut u8, value)
        },
        Register::PciConfig {
            device,
            function,
            offset,
        } => {
            const CONFIG_ADDRESS: u16 = 0xCF8;
            const CONFIG_DATA: u16 = 0xCFC;
            let address = (1 << 31)
                | (u32::from(device & 0x1F) << 11)
                | (u32::from(function & 0x07) << 8)
                | u32::from(offset & 0xFC);
            // SAFETY: PCI mechanism #1 on bus 0, the FADT's reset register
            // as above; the byte goes to its lane of the data port.
            unsafe {
                Port::<u32>::new(CONFIG_ADDRESS).write(address);
                Port::<u8>::new(CONFIG_DATA + u16::from(offset & 3)).write(value);
            }
        }
    }
}

/// Port 0xCF9, the Reset Control Register of Intel chipsets (and QEMU's
/// PIIX3 and ICH9): system reset, then a full reset with the CPU.
fn reset_control_port() {
    const RESET_CONTROL: u16 = 0xCF9;
    const SYSTEM_RESET: u8 = 0x02;
    const RESET_CPU: u8 = 0x04;
    const FULL_RESET: u8 = 0x08;
    let mut port = Port::<u8>::new(RESET_CONTROL);
    // SAFETY: on a PC port 0xCF9 is the chipset's reset control; the kernel
    // is resetting the machine, so nothing it holds must survive.
    unsafe {
        let current = port.read() & !(RESET_CPU | FULL_RESET);
        port.write(current | SYSTEM_RESET);
        port.write(current | SYSTEM_RESET | RESET_CPU | FULL_RESET);
    }
}

/// The 8042 keyboard controller's command 0xFE pulses the CPU's reset line.
fn keyboard_controller_pulse() {
    const STATUS_PORT: u16 = 0x64;
    const INPUT_FULL: u8 = 0x02;
    const PULSE_RESET: u8 = 0xFE;
    let mut status = Port::<u8>::new(STATUS_PORT);
    // SAFETY: reading the 8042's status has no side effect.
    let ready = wait(100_000, || unsafe { status.read() } & INPUT_FULL == 0);
    if ready {
        // SAFETY: the controller is ready for a command; this one resets.
        unsafe { status.write(PULSE_RESET) };
    }
}

/// With no interrupt table at all, any exception becomes a triple fault,
/// which every x86 resets on.
fn triple_fault() -> ! {
    let nothing = x86_64::structures::DescriptorTablePointer {
        limit: 0,
        base: x86_64::VirtAddr::new(0),
    };
    // SAFETY: loading an empty IDT and raising an exception is meant to
    // triple-fault: the machine resets, nothing after this runs.
    unsafe {
        x86_64::instructions::tables::lidt(&nothing);
        core::arch::asm!("int3", options(nomem, nostack));
    }
    loop {
        core::hint::spin_loop();
    }
}
