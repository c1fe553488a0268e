//! The IDT: CPU exceptions (reported, then a clean halt) and the two hardware
//! interrupts the kernel uses, the PIT tick (IRQ 0) and the keyboard (IRQ 1),
//! routed through the remapped 8259 PICs.

use crate::{fault, gdt, input::ps2, time::pit};
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

// SAFETY: the offsets map the PICs above the CPU's exception vectors, so no
// IRQ is ever mistaken for an exception.
static PICS: Mutex<ChainedPics> =
    Mutex::new(unsafe { ChainedPics::new(PIC_1_OFFSET, PIC_2_OFFSET) });

static IDT: Lazy<InterruptDescriptorTable> = Lazy::new(|| {
    let mut idt = InterruptDescriptorTable::new();
    idt.divide_error.set_handler_fn(divide_error);
    idt.breakpoint.set_handler_fn(breakpoint);
    idt.invalid_opcode.set_handler_fn(invalid_opcode);
    idt.general_protection_fault
        .set_handler_fn(general_protection);
    idt.stack_segment_fault.set_handler_fn(stack_segment);
    idt.page_fault.set_handler_fn(page_fault);
    // Neither should ever happen (src/fpu.rs turns SSE on and masks every
    // SIMD exception); if one does, it is reported, not silently a #DF.
    idt.device_not_available
        .set_handler_fn(device_not_available);
    idt.simd_floating_point.set_handler_fn(simd_floating_point);
    // SAFETY: the IST index names the stack that gdt::init puts in the TSS,
    // used by nothing else.
    unsafe {
        idt.double_fault
            .set_handler_fn(double_fault)
            .set_stack_index(gdt::DOUBLE_FAULT_IST_INDEX);
    }
    idt[TIMER_VECTOR].set_handler_fn(timer);
    idt[KEYBOARD_VECTOR].set_handler_fn(keyboard_irq);
    idt[SPURIOUS_MASTER_VECTOR].set_handler_fn(spurious);
    idt
});

pub fn init() {
    IDT.load();
    // SAFETY: the IDT is loaded with handlers for every vector the PICs can
    // raise from the lines left unmasked below.
    unsafe {
        let mut pics = PICS.lock();
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

/// Runs `f` with every IRQ masked at both PICs, then restores the masks (a
/// real-mode BIOS call must not see an IRQ meant for the kernel's vectors).
/// Call with interrupts off, so no handler waits on the PIC lock held here.
pub fn with_all_irqs_masked<R>(f: impl FnOnce() -> R) -> R {
    let mut pics = PICS.lock();
    // SAFETY: reading and writing the PICs' mask registers changes only which
    // IRQs are delivered; the old masks are put back below.
    let masks = unsafe { pics.read_masks() };
    // SAFETY: as above.
    unsafe { pics.write_masks(0xFF, 0xFF) };
    let result = f();
    // SAFETY: as above.
    unsafe { pics.write_masks(masks[0], masks[1]) };
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

extern "x86-interrupt" fn breakpoint(frame: InterruptStackFrame) {
    // A breakpoint is a request to look, not an error: report and go on.
    crate::serial_println!(
        "EXCEPTION: breakpoint at {:#x}",
        frame.instruction_pointer.as_u64()
    );
}

extern "x86-interrupt" fn divide_error(frame: InterruptStackFrame) {
    fault::halt_with("divide error", &frame, None, None);
}

extern "x86-interrupt" fn invalid_opcode(frame: InterruptStackFrame) {
    fault::halt_with("invalid opcode", &frame, None, None);
}

extern "x86-interrupt" fn device_not_available(frame: InterruptStackFrame) {
    fault::halt_with(
        "device not available (SSE used while CR0.TS or EM set)",
        &frame,
        None,
        None,
    );
}

extern "x86-interrupt" fn simd_floating_point(frame: InterruptStackFrame) {
    fault::halt_with("SIMD floating-point exception", &frame, None, None);
}

extern "x86-interrupt" fn general_protection(frame: InterruptStackFrame, error: u64) {
    fault::halt_with("general protection fault", &frame, Some(error), None);
}

extern "x86-interrupt" fn stack_segment(frame: InterruptStackFrame, error: u64) {
    fault::halt_with("stack-segment fault", &frame, Some(error), None);
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
