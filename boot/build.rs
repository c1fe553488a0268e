//! Builds the disk images from the kernel artifact: `modex-cube.img`, the one
//! image that boots under BIOS and UEFI (see `boot/disk_layout.rs`), and the
//! single-firmware `bios.img` and `uefi.img`.
//!
//! The kernel is an artifact dependency (`-Z bindeps`), so cargo compiles it for
//! `x86_64-unknown-none` first and a kernel compile error is shown as cargo's own
//! error. The bootloader is the patched copy in `bootloader/` (see its
//! CHANGES.md). The images land in OUT_DIR, each written whole to a temporary
//! name and then renamed, so no half image is ever there; the runner copies
//! them to `target/images/`.

#[path = "disk_layout.rs"]
#[allow(dead_code)] // the tests use more of it than the build does
mod disk_layout;

use std::path::{Path, PathBuf};

fn main() {
    println!("cargo:rerun-if-changed=boot/build.rs");
    println!("cargo:rerun-if-changed=boot/disk_layout.rs");
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let kernel = PathBuf::from(
        std::env::var_os("CARGO_BIN_FILE_KERNEL_kernel")
            .expect("cargo sets the kernel artifact path"),
    );
    let kernel_bytes = match std::fs::metadata(&kernel) {
        Ok(meta) => meta.len(),
        Err(error) => fail(&format!(
            "the kernel {} is missing: {error}",
            kernel.display()
        )),
    };
    if let Err(why) = disk_layout::check_kernel_size(kernel_bytes) {
        fail(&format!("{why}: {}", kernel.display()));
    }

    let mut config = bootloader::BootConfig::default();
    // The kernel owns COM1 and the screen; keep the bootloader quiet on both.
    config.serial_logging = false;
    config.frame_buffer_logging = false;

    let mut builder = bootloader::DiskImageBuilder::new(kernel.clone());
    builder.set_boot_config(&config);

    let bios = out_dir.join("bios.img");
    write_whole(&bios, |partial| {
        builder
            .create_bios_image(partial)
            .map_err(|e| format!("{e:#}"))
    });
    let uefi = out_dir.join("uefi.img");
    write_whole(&uefi, |partial| {
        builder
            .create_uefi_image(partial)
            .map_err(|e| format!("{e:#}"))
    });
    let one = out_dir.join("modex-cube.img");
    write_whole(&one, |partial| {
        let esp_path = partial.with_extension("esp");
        builder
            .create_bios_uefi_fat_partition(&esp_path)
            .map_err(|e| format!("the EFI system partition: {e:#}"))?;
        let esp = std::fs::read(&esp_path).map_err(|e| format!("reading the ESP back: {e}"))?;
        let _ = std::fs::remove_file(&esp_path);
        let disk = disk_layout::hybrid_image(
            bootloader::bios_boot_sector(),
            bootloader::bios_stage_2(),
            &esp,
        )
        .map_err(|e| e.to_string())?;
        std::fs::write(partial, disk).map_err(|e| e.to_string())
    });

    println!("cargo:rustc-env=ONE_IMAGE={}", one.display());
    println!("cargo:rustc-env=BIOS_IMAGE={}", bios.display());
    println!("cargo:rustc-env=UEFI_IMAGE={}", uefi.display());
    println!("cargo:rustc-env=KERNEL_ELF={}", kernel.display());
    // The commit the kernel's report names (kernel/build.rs reads it the same
    // way, and a moved HEAD rebuilds the kernel, so this script runs again):
    // the tests compare with this, not with whatever HEAD is when they run.
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|output| output.status.success())
        .map(|output| String::from_utf8_lossy(&output.stdout).trim().to_owned())
        .filter(|commit| !commit.is_empty())
        .unwrap_or_else(|| "unknown".to_owned());
    println!("cargo:rustc-env=KERNEL_COMMIT={commit}");
}

/// Makes `path` with `make`, which writes a temporary file beside it; only a
/// finished image is renamed into place. Any failure ends the build naming
/// the image and what went wrong.
fn write_whole(path: &Path, make: impl FnOnce(&Path) -> Result<(), String>) {
    let partial = path.with_extension("img.partial");
    let _ = std::fs::remove_file(path);
    if let Err(why) = make(&partial) {
        let _ = std::fs::remove_file(&partial);
        fail(&format!("cannot build {}: {why}", path.display()));
    }
    if let Err(error) = std::fs::rename(&partial, path) {
        fail(&format!(
            "cannot rename the finished {}: {error}",
            path.display()
        ));
    }
}

fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(1)
}
