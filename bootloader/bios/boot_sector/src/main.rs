#![no_std]
#![no_main]

// Patched (see ../../CHANGES.md): the boot sector is all in `boot.s`; the
// Rust loop that read stage 2 (upstream's `dap.rs`, `fail.rs`, `mbr.rs`) kept
// its state in registers across BIOS calls and is gone.
core::arch::global_asm!(include_str!("boot.s"));

#[panic_handler]
#[cfg(not(test))]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    loop {}
}
