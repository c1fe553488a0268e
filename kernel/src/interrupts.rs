//! The IDT: every CPU exception (reported, then a clean halt; a breakpoint
//! resumes), the NMI (counted, logged, resumed: `nmi.rs`), and the two
//! hardware interrupts the kernel uses, the PIT tick (IRQ 0) and the
//! keyboard (IRQ 1), routed through the remapped 8259 PICs.

use crate::{fault, gdt, input::ps2, nmi, time::pit};
use pic8259::ChainedPics;
use spin::{Lazy, Mutex};
use x86_64::structures::idt::{InterruptDescriptorTable, InterruptStackFrame, PageFaultErrorCode};

/// The PICs' vectors start after the 32 the CPU reserves for exceptions.
pub const PIC_1_OFFSET: u8 = 32;
pub const PIC_2_OFFSET: u8 = PIC_1_OFFSET + 8;
const TIMER_VECTOR: u8 = PIC_1_OFFSET;
const KEYBOARD_VECTOR: u8 = PIC_1_OFFSET + 1;
/// IRQ 7 and 15 fire spuriously when an interrupt goes away before the CPU
/// acknowledges it; they must not be acknowledged like real ones.
const SPURIOUS_MASTER_VECTOR: u8 = PIC_1_OFFSET + 7;
const SPURIOUS_SLAVE_VECTOR: u8 = PIC_2_OFFSET + 7;

// SAFETY: the offsets map the PICs above the CPU's exception vectors, so no
// IRQ is ever mistaken for an exception.
static PICS: Mutex<ChainedPics> =
    Mutex::new(unsafe { ChainedPics::new(PIC_1_OFFSET, PIC_2_OFFSET) });

/// The PIC masks as the firmware and the loader left them, read before the
/// kernel changes them: a BIOS call gets them back (`with_pics_for_the_bios`).
static FIRMWARE_MASKS: Mutex<[u8; 2]> = Mutex::new([0xFF, 0xFF]);

static IDT: Lazy<InterruptDescriptorTable> = Lazy::new(|| {
    let mut idt = InterruptDescriptorTable::new();
    // Every exception vector the CPU defines has a handler that names it,
    // so none of them can become a double fault. Vectors with no entry
    // (the reserved ones and those no device here raises) reach the CPU as
    // a segment-not-present fault whose error code names the vector.
    idt.divide_error.set_handler_fn(divide_error);
    idt.debug.set_handler_fn(debug);
    idt.breakpoint.set_handler_fn(breakpoint);
    idt.overflow.set_handler_fn(overflow);
    idt.bound_range_exceeded
        .set_handler_fn(bound_range_exceeded);
    idt.invalid_opcode.set_handler_fn(invalid_opcode);
    // Neither should ever happen (src/fpu.rs turns SSE on and masks every
    // SIMD exception); if one does, it is reported, not silently a #DF.
    idt.device_not_available
        .set_handler_fn(device_not_available);
    idt.invalid_tss.set_handler_fn(invalid_tss);
    idt.segment_not_present.set_handler_fn(segment_not_present);
    idt.stack_segment_fault.set_handler_fn(stack_segment);
    idt.general_protection_fault
        .set_handler_fn(general_protection);
    idt.page_fault.set_handler_fn(page_fault);
    idt.x87_floating_point.set_handler_fn(x87_floating_point);
    idt.alignment_check.set_handler_fn(alignment_check);
    idt.simd_floating_point.set_handler_fn(simd_floating_point);
    idt.virtualization.set_handler_fn(virtualization);
    idt.cp_protection_exception
        .set_handler_fn(control_protection);
    idt.hv_injection_exception.set_handler_fn(hv_injection);
    idt.vmm_communication_exception
        .set_handler_fn(vmm_communication);
    idt.security_exception.set_handler_fn(security);
    // SAFETY: each IST index names a stack that gdt::init puts in the TSS
    // for that vector alone.
    unsafe {
        idt.double_fault
            .set_handler_fn(double_fault)
            .set_stack_index(gdt::DOUBLE_FAULT_IST_INDEX);
        idt.non_maskable_interrupt
            .set_handler_fn(non_maskable_interrupt)
            .set_stack_index(gdt::NMI_IST_INDEX);
        idt.machine_check
            .set_handler_fn(machine_check)
            .set_stack_index(gdt::MACHINE_CHECK_IST_INDEX);
    }
    idt[TIMER_VECTOR].set_handler_fn(timer);
    idt[KEYBOARD_VECTOR].set_handler_fn(keyboard_irq);
    idt[SPURIOUS_MASTER_VECTOR].set_handler_fn(spurious);
    idt[SPURIOUS_SLAVE_VECTOR].set_handler_fn(spurious_slave);
    idt
});

pub fn init() {
    IDT.load();
    // SAFETY: the IDT is loaded with handlers for every vector the PICs can
    // raise from the lines left unmasked below.
    unsafe {
        let mut pics = PICS.lock();
        *FIRMWARE_MASKS.lock() = pics.read_masks();
        pics.initialize();
        // Unmask only IRQ 0 (timer), 1 (keyboard) and 2 (the slave's cascade).
        pics.write_masks(0b1111_1000, 0b1111_1111);
    }
}

/// Masks IRQ 1 at the master PIC for good (boot option `irq1=masked`): the
/// keyboard is then read only by the loops' poll, as on a machine whose
/// firmware never delivers the interrupt.
pub fn mask_keyboard_irq() {
    const IRQ1: u8 = 1 << 1;
    x86_64::instructions::interrupts::without_interrupts(|| {
        let mut pics = PICS.lock();
        // SAFETY: masking one more line only stops IRQ 1 being delivered;
        // the keyboard's bytes are still taken by `ps2::poll`.
        unsafe {
            let [master, slave] = pics.read_masks();
            pics.write_masks(master | IRQ1, slave);
        }
    });
}

/// The masks the firmware left at the PICs, for the log.
pub fn firmware_masks() -> [u8; 2] {
    *FIRMWARE_MASKS.lock()
}

/// Runs `f` with the PICs as a real-mode BIOS expects them: its vectors
/// (08h and 70h), the firmware's masks with the watchdog's IRQ 0 open
/// (`memory::trampoline::bios_world`); then the kernel's vectors and masks
/// again. Reinitialising drops whatever the BIOS left in service. Call with
/// interrupts off, so no handler waits on the PIC lock held here.
pub fn with_pics_for_the_bios<R>(f: impl FnOnce() -> R) -> R {
    use memory::trampoline::bios_world;
    let mut pics = PICS.lock();
    // SAFETY: interrupts are off, so no IRQ arrives while the vectors are
    // the BIOS's; the trampoline enables them only in real mode, where the
    // BIOS's handlers stand at those vectors.
    let kernel_masks = unsafe { pics.read_masks() };
    // SAFETY: as above; the bases and masks are the BIOS's own.
    unsafe {
        let mut bios_pics = ChainedPics::new(bios_world::MASTER_VECTORS, bios_world::SLAVE_VECTORS);
        bios_pics.initialize();
        let [master, slave] = bios_world::masks(*FIRMWARE_MASKS.lock());
        bios_pics.write_masks(master, slave);
    }
    let result = f();
    // SAFETY: back to the kernel's vectors, for which the IDT has handlers,
    // and the masks it had.
    unsafe {
        pics.initialize();
        pics.write_masks(kernel_masks[0], kernel_masks[1]);
    }
    result
}

fn end_of_interrupt(vector: u8) {
    // SAFETY: called once at the end of the handler of `vector`, which the
    // PICs raised.
    unsafe { PICS.lock().notify_end_of_interrupt(vector) };
}

extern "x86-interrupt" fn timer(_frame: InterruptStackFrame) {
    pit::tick();
    end_of_interrupt(TIMER_VECTOR);
}

extern "x86-interrupt" fn keyboard_irq(_frame: InterruptStackFrame) {
    ps2::on_interrupt();
    end_of_interrupt(KEYBOARD_VECTOR);
}

extern "x86-interrupt" fn spurious(_frame: InterruptStackFrame) {}

/// A spurious IRQ 15 is the slave's: the master saw a real IRQ 2 (the
/// cascade) and is owed its end of interrupt; the slave is not.
extern "x86-interrupt" fn spurious_slave(_frame: InterruptStackFrame) {
    end_of_interrupt(PIC_1_OFFSET + 2);
}

/// Not the kernel's fault, nor a reason to stop: count it and carry on.
extern "x86-interrupt" fn non_maskable_interrupt(_frame: InterruptStackFrame) {
    nmi::on_nmi();
}

extern "x86-interrupt" fn breakpoint(frame: InterruptStackFrame) {
    // A breakpoint is a request to look, not an error: report and go on.
    crate::serial_println!(
        "EXCEPTION: breakpoint at {:#x}",
        frame.instruction_pointer.as_u64()
    );
}

/// Handlers that report `$name` and halt, for exceptions with no error code.
macro_rules! halting_handlers {
    ($($handler:ident: $name:literal,)*) => {$(
        extern "x86-interrupt" fn $handler(frame: InterruptStackFrame) {
            fault::halt_with($name, &frame, None, None);
        }
    )*};
}

/// As [`halting_handlers`], for exceptions that push an error code.
macro_rules! halting_handlers_with_error {
    ($($handler:ident: $name:literal,)*) => {$(
        extern "x86-interrupt" fn $handler(frame: InterruptStackFrame, error: u64) {
            fault::halt_with($name, &frame, Some(error), None);
        }
    )*};
}

// The names are the Intel SDM's (volume 3, table 6-1), with the vector.
halting_handlers! {
    divide_error: "divide error",
    debug: "debug exception (vector 1)",
    overflow: "overflow (vector 4)",
    bound_range_exceeded: "BOUND range exceeded (vector 5)",
    invalid_opcode: "invalid opcode",
    device_not_available: "device not available (SSE used while CR0.TS or EM set)",
    x87_floating_point: "x87 floating-point error (vector 16)",
    simd_floating_point: "SIMD floating-point exception",
    virtualization: "virtualization exception (vector 20)",
    hv_injection: "hypervisor injection exception (vector 28)",
}

halting_handlers_with_error! {
    invalid_tss: "invalid TSS (vector 10)",
    stack_segment: "stack-segment fault",
    general_protection: "general protection fault",
    alignment_check: "alignment check (vector 17)",
    control_protection: "control protection exception (vector 21)",
    vmm_communication: "VMM communication exception (vector 29)",
    security: "security exception (vector 30)",
}

/// A segment that is not present, or, with the error code's IDT bit, an
/// interrupt vector with no handler (a reserved exception vector, or a
/// device's interrupt the kernel never asked for): the vector is named.
extern "x86-interrupt" fn segment_not_present(frame: InterruptStackFrame, error: u64) {
    const IDT_BIT: u64 = 1 << 1;
    if error & IDT_BIT == 0 {
        fault::halt_with("segment not present (vector 11)", &frame, Some(error), None);
    }
    let mut name = kernel_log::LogLine::<64>::new();
    let _ = match unhandled_vector(error, frame.instruction_pointer.as_u64()) {
        [Some(vector), None] | [None, Some(vector)] => core::fmt::Write::write_fmt(
            &mut name,
            format_args!("interrupt vector {vector} has no handler (segment not present)"),
        ),
        [Some(first), Some(second)] => core::fmt::Write::write_fmt(
            &mut name,
            format_args!("interrupt vector {first} or {second} has no handler"),
        ),
        [None, None] => core::fmt::Write::write_str(&mut name, "an IDT entry is not present"),
    };
    fault::halt_with(name.as_str(), &frame, Some(error), None);
}

/// The vectors a segment-not-present error code for an IDT entry can mean.
/// The SDM puts the vector in the selector index (bits 3-15); QEMU's TCG
/// puts twice the vector there in long mode (it counts the 16-byte gates in
/// 8-byte units). So each reading is kept only if that IDT entry truly has
/// no handler, and an `int n` at `rip` settles it.
fn unhandled_vector(error: u64, rip: u64) -> [Option<u64>; 2] {
    const EXTERNAL_BIT: u64 = 1 << 0;
    const INT_IMMEDIATE: u8 = 0xCD;
    let index = (error >> 3) & 0x1FFF;
    if error & EXTERNAL_BIT == 0 {
        // SAFETY: #NP for an `int n` is a fault at that instruction, so `rip`
        // is the address the CPU was executing: mapped, and readable (the
        // kernel's code pages are). For any other cause the bytes are only
        // compared, never trusted alone.
        let [opcode, vector] = unsafe { core::ptr::read_volatile(rip as *const [u8; 2]) };
        let vector = u64::from(vector);
        if opcode == INT_IMMEDIATE && (index == vector || index == 2 * vector) {
            return [Some(vector), None];
        }
    }
    let has_no_handler = |vector: u64| vector <= 0xFF && !gate_present(vector as u8);
    [
        Some(index).filter(|&v| has_no_handler(v)),
        Some(index / 2).filter(|&v| index % 2 == 0 && index != 0 && has_no_handler(v)),
    ]
}

/// Whether the loaded IDT's gate for `vector` is present.
fn gate_present(vector: u8) -> bool {
    const GATE_BYTES: u64 = 16;
    const PRESENT: u8 = 1 << 7;
    let table = x86_64::instructions::tables::sidt();
    let at = table.base.as_u64() + GATE_BYTES * u64::from(vector);
    if GATE_BYTES * u64::from(vector) + GATE_BYTES - 1 > u64::from(table.limit) {
        return false;
    }
    // SAFETY: the IDT is the kernel's static table, loaded at init and
    // mapped for good; the gate's type-and-attributes byte (offset 5) lies
    // within the limit checked above.
    unsafe { core::ptr::read_volatile((at + 5) as *const u8) & PRESENT != 0 }
}

/// A machine check: the first bank that holds a valid error gives the error
/// code row (its `IA32_MCi_STATUS`) and the address row (`IA32_MCi_ADDR`),
/// so the report carries what the hardware logged.
extern "x86-interrupt" fn machine_check(frame: InterruptStackFrame) -> ! {
    let (status, address) = machine_check_bank().unzip();
    fault::halt_with(
        "machine check (vector 18)",
        &frame,
        status,
        address.flatten(),
    );
}

/// The first machine-check bank with a valid error, as (status, address if
/// the status says the address is valid); `None` without MCA.
fn machine_check_bank() -> Option<(u64, Option<u64>)> {
    const CPUID_MCA: u32 = 1 << 14;
    const IA32_MCG_CAP: u32 = 0x179;
    const IA32_MC0_STATUS: u32 = 0x401;
    const STATUS_VALID: u64 = 1 << 63;
    const STATUS_ADDRESS_VALID: u64 = 1 << 58;
    let features = core::arch::x86_64::__cpuid(1);
    if features.edx & CPUID_MCA == 0 {
        return None;
    }
    // SAFETY: with MCA, IA32_MCG_CAP exists, and its count says how many
    // banks' MSRs exist (IA32_MCi_STATUS at 0x401 + 4i, ADDR one above).
    let banks = unsafe { x86_64::registers::model_specific::Msr::new(IA32_MCG_CAP).read() } & 0xFF;
    (0..banks as u32).find_map(|bank| {
        let status_msr = IA32_MC0_STATUS + 4 * bank;
        // SAFETY: as above: bank < the count the CPU gave.
        let status = unsafe { x86_64::registers::model_specific::Msr::new(status_msr).read() };
        (status & STATUS_VALID != 0).then(|| {
            let address = (status & STATUS_ADDRESS_VALID != 0).then(|| {
                // SAFETY: as above.
                unsafe { x86_64::registers::model_specific::Msr::new(status_msr + 1).read() }
            });
            (status, address)
        })
    })
}

extern "x86-interrupt" fn page_fault(frame: InterruptStackFrame, error: PageFaultErrorCode) {
    let address = x86_64::registers::control::Cr2::read_raw();
    fault::halt_with("page fault", &frame, Some(error.bits()), Some(address));
}

extern "x86-interrupt" fn double_fault(frame: InterruptStackFrame, error: u64) -> ! {
    fault::halt_with(
        "double fault (kernel stack overflow?)",
        &frame,
        Some(error),
        None,
    );
}
