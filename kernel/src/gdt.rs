//! GDT with a TSS whose Interrupt Stack Table gives the double-fault, NMI and
//! machine-check handlers stacks of their own: a kernel stack overflow ends
//! in a report, not a triple fault and a reboot loop, and an NMI or machine
//! check that arrives with the stack nearly used up still has room.

use spin::Lazy;
use x86_64::instructions::segmentation::{Segment, CS, DS, ES, SS};
use x86_64::instructions::tables::load_tss;
use x86_64::structures::gdt::{Descriptor, GlobalDescriptorTable, SegmentSelector};
use x86_64::structures::tss::TaskStateSegment;
use x86_64::VirtAddr;

pub const DOUBLE_FAULT_IST_INDEX: u16 = 0;
pub const NMI_IST_INDEX: u16 = 1;
pub const MACHINE_CHECK_IST_INDEX: u16 = 2;
const DOUBLE_FAULT_STACK_SIZE: usize = 5 * 4096;
/// The NMI handler reads and writes one port; the machine-check handler
/// reads MSRs and then reports as any fault does (the double fault's 20 KiB
/// covers that report with room to spare: tests/stack.rs).
const NMI_STACK_SIZE: usize = 2 * 4096;
const MACHINE_CHECK_STACK_SIZE: usize = 5 * 4096;

#[repr(align(16))]
struct Stack<const SIZE: usize>(#[allow(dead_code)] [u8; SIZE]);
// `static mut` so that they land in writable .bss, not read-only data: only
// the CPU writes them, through the TSS, and no Rust code ever reads or
// borrows them.
static mut DOUBLE_FAULT_STACK: Stack<DOUBLE_FAULT_STACK_SIZE> = Stack([0; DOUBLE_FAULT_STACK_SIZE]);
static mut NMI_STACK: Stack<NMI_STACK_SIZE> = Stack([0; NMI_STACK_SIZE]);
static mut MACHINE_CHECK_STACK: Stack<MACHINE_CHECK_STACK_SIZE> =
    Stack([0; MACHINE_CHECK_STACK_SIZE]);

static TSS: Lazy<TaskStateSegment> = Lazy::new(|| {
    let mut tss = TaskStateSegment::new();
    // The CPU only ever writes below each top, and only while handling that
    // vector; nothing else touches these stacks.
    let double_fault = VirtAddr::from_ptr(&raw const DOUBLE_FAULT_STACK);
    tss.interrupt_stack_table[DOUBLE_FAULT_IST_INDEX as usize] =
        double_fault + DOUBLE_FAULT_STACK_SIZE as u64;
    let nmi = VirtAddr::from_ptr(&raw const NMI_STACK);
    tss.interrupt_stack_table[NMI_IST_INDEX as usize] = nmi + NMI_STACK_SIZE as u64;
    let machine_check = VirtAddr::from_ptr(&raw const MACHINE_CHECK_STACK);
    tss.interrupt_stack_table[MACHINE_CHECK_IST_INDEX as usize] =
        machine_check + MACHINE_CHECK_STACK_SIZE as u64;
    tss
});

struct Selectors {
    code: SegmentSelector,
    data: SegmentSelector,
    tss: SegmentSelector,
}

static GDT: Lazy<(GlobalDescriptorTable, Selectors)> = Lazy::new(|| {
    let mut gdt = GlobalDescriptorTable::new();
    let code = gdt.append(Descriptor::kernel_code_segment());
    let data = gdt.append(Descriptor::kernel_data_segment());
    let tss = gdt.append(Descriptor::tss_segment(&TSS));
    (gdt, Selectors { code, data, tss })
});

pub fn init() {
    let (gdt, selectors) = &*GDT;
    gdt.load();
    // SAFETY: the selectors index descriptors of the GDT just loaded, which is
    // static and so outlives every use of them.
    unsafe {
        CS::set_reg(selectors.code);
        DS::set_reg(selectors.data);
        ES::set_reg(selectors.data);
        SS::set_reg(selectors.data);
        load_tss(selectors.tss);
    }
}
