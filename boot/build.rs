//! Builds the BIOS and UEFI disk images from the kernel artifact.
//!
//! The kernel is an artifact dependency (`-Z bindeps`), so cargo compiles it for
//! `x86_64-unknown-none` first and a kernel compile error is shown as cargo's own
//! error. The images land in OUT_DIR; the runner copies them to `target/images/`.

use std::path::PathBuf;

fn main() {
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let kernel = PathBuf::from(
        std::env::var_os("CARGO_BIN_FILE_KERNEL_kernel")
            .expect("cargo sets the kernel artifact path"),
    );

    let mut config = bootloader::BootConfig::default();
    // The kernel owns COM1 and the screen; keep the bootloader quiet on both.
    config.serial_logging = false;
    config.frame_buffer_logging = false;

    let mut builder = bootloader::DiskImageBuilder::new(kernel.clone());
    builder.set_boot_config(&config);
    let bios = out_dir.join("bios.img");
    let uefi = out_dir.join("uefi.img");
    builder
        .create_bios_image(&bios)
        .expect("failed to create the BIOS disk image");
    builder
        .create_uefi_image(&uefi)
        .expect("failed to create the UEFI disk image");

    println!("cargo:rustc-env=BIOS_IMAGE={}", bios.display());
    println!("cargo:rustc-env=UEFI_IMAGE={}", uefi.display());
    println!("cargo:rustc-env=KERNEL_ELF={}", kernel.display());
}
