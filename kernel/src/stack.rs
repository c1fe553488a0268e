//! The kernel stack, measured: painted at boot, its high-water mark read back
//! on demand (at Esc, in a fault report). What the paint means is decided in
//! `memory::stack`; here are only the memory accesses.

use memory::stack::{paint_range, unpainted_from, StackUse, PAINT, WORD_BYTES};
use spin::Once;

/// The stack the bootloader made: its lowest address and its length.
static STACK: Once<(u64, u64)> = Once::new();

/// Paints the stack from its bottom up to a margin below this function's
/// frame. Call first thing at boot, with interrupts still off, so that
/// nothing else uses the stack below here meanwhile.
#[inline(never)]
pub fn paint(bottom: u64, len: u64) {
    let local = 0u8;
    let here = core::ptr::addr_of!(local) as u64;
    let range = paint_range(bottom, len, here);
    for address in range.clone().step_by(WORD_BYTES as usize) {
        // SAFETY: `paint_range` keeps `address` inside the stack the bootloader
        // mapped writable ([bottom, bottom + len), from BootInfo) and at least
        // PAINT_MARGIN below this frame, where no frame lives: the stack grows
        // down, interrupts are off and this target has no red zone. The address
        // is word-aligned.
        unsafe { (address as *mut u64).write_volatile(PAINT) }
    }
    STACK.call_once(|| (bottom, len));
}

/// The most of the stack used since [`paint`], if it was painted.
pub fn usage() -> Option<StackUse> {
    let &(bottom, len) = STACK.get()?;
    // Interrupt handlers run on this stack; with them held off, the words
    // below this frame do not change while they are read.
    let still_painted = x86_64::instructions::interrupts::without_interrupts(|| {
        let local = 0u8;
        let here = core::ptr::addr_of!(local) as u64;
        let words = (bottom..here.min(bottom + len))
            .step_by(WORD_BYTES as usize)
            .map(|address| {
                // SAFETY: `address` is word-aligned and inside the mapped stack,
                // below this frame; reading it has no side effect.
                unsafe { (address as *const u64).read_volatile() }
            });
        unpainted_from(words)
    });
    Some(StackUse::new(len, still_painted))
}

/// Logs the high-water mark on serial (or that the stack was never painted).
pub fn report() {
    match usage() {
        Some(used) => crate::serial_println!("{}", used),
        None => crate::serial_println!("stack: not painted at boot, use unknown"),
    }
}
