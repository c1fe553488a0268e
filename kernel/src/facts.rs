//! The machine's facts (`demo::facts::MachineFacts`), filled in by each
//! subsystem as boot finds them, logged once when boot is done, and read by
//! the report screen and the fault panel. The record is behind a spin lock
//! that is only ever held for a copy or a field write, so the fault handler's
//! `try_lock` finds it free unless the fault struck inside one.

use crate::serial_println;
use demo::facts::{Cpu, MachineFacts};
use spin::Mutex;

static FACTS: Mutex<MachineFacts> = Mutex::new(MachineFacts::new(
    env!("CARGO_PKG_VERSION"),
    env!("GIT_COMMIT"),
));

/// Changes the record.
pub fn record(change: impl FnOnce(&mut MachineFacts)) {
    change(&mut FACTS.lock());
}

/// A copy of the record.
pub fn get() -> MachineFacts {
    *FACTS.lock()
}

/// A copy of the record, if the lock is free (for the fault handler, which
/// may have interrupted its holder).
pub fn try_get() -> Option<MachineFacts> {
    FACTS.try_lock().map(|facts| *facts)
}

/// Fills in what the CPU says of itself: CPUID's identification and whether
/// no-execute is on (EFER.NXE, which the bootloader sets only where CPUID
/// offers NX).
pub fn record_cpu() {
    let cpu = cpu_identity();
    let nx = x86_64::registers::model_specific::Efer::read()
        .contains(x86_64::registers::model_specific::EferFlags::NO_EXECUTE_ENABLE);
    record(|facts| {
        facts.cpu = cpu;
        facts.nx = Some(nx);
    });
}

/// Logs every fact, one line each, after `protocol::line::MACHINE_FACT`.
pub fn log() {
    get().rows(|row| serial_println!("{}{}", protocol::line::MACHINE_FACT, row));
}

fn cpu_identity() -> Cpu {
    use core::arch::x86_64::__cpuid;
    let mut identity = Cpu {
        vendor: [0; 12],
        brand: [0; 48],
    };
    // CPUID is safe to call on x86-64: it only reads identification.
    let leaf0 = __cpuid(0);
    for (chunk, register) in identity
        .vendor
        .as_chunks_mut::<4>()
        .0
        .iter_mut()
        .zip([leaf0.ebx, leaf0.edx, leaf0.ecx])
    {
        chunk.copy_from_slice(&register.to_le_bytes());
    }
    // Leaf 0x8000_0000 reports the highest extended leaf.
    let highest = __cpuid(0x8000_0000).eax;
    if highest >= 0x8000_0004 {
        for (index, leaf) in (0x8000_0002u32..=0x8000_0004).enumerate() {
            let regs = __cpuid(leaf);
            for (word, register) in [regs.eax, regs.ebx, regs.ecx, regs.edx]
                .into_iter()
                .enumerate()
            {
                let at = index * 16 + word * 4;
                identity.brand[at..at + 4].copy_from_slice(&register.to_le_bytes());
            }
        }
    }
    identity
}
