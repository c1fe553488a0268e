//! Builds the disk images from the kernel artifact: `modex-cube.img`, the one
//! image that boots under BIOS and UEFI (see `boot/disk_layout.rs`), and the
//! single-firmware `bios.img` and `uefi.img`.
//!
//! The kernel is built here by a second cargo, for the kernel's own target
//! (`kernel/x86_64-modex-kernel.json`: `x86_64-unknown-none` with SSE2 floating
//! point, so the pipeline's arithmetic is instructions, not library calls).
//! That target has no prebuilt `core`, so the build is `-Z build-std`, which
//! cargo cannot combine with an artifact dependency (it panics in
//! `unit_dependencies`); the bootloader builds its own stages the same way. A
//! kernel compile error is shown with cargo's own messages. The bootloader is the patched copy in `bootloader/` (see its
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
    let kernel = build_kernel(&out_dir);
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
        // The pieces again, for the runner's signed stick (boot/secure_boot.rs),
        // which lays out the same disk around an ESP with shim in it.
        for (name, bytes) in [
            ("hybrid-esp.fat", &esp[..]),
            ("bios-boot-sector.bin", bootloader::bios_boot_sector()),
            ("bios-stage-2.bin", bootloader::bios_stage_2()),
        ] {
            std::fs::write(out_dir.join(name), bytes)
                .map_err(|e| format!("writing {name}: {e}"))?;
        }
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
    for (variable, name) in [
        ("HYBRID_ESP", "hybrid-esp.fat"),
        ("BIOS_BOOT_SECTOR", "bios-boot-sector.bin"),
        ("BIOS_STAGE_2", "bios-stage-2.bin"),
    ] {
        println!(
            "cargo:rustc-env={variable}={}",
            out_dir.join(name).display()
        );
    }
    // The commit the kernel's report names (kernel/build.rs reads it the same
    // way, and a moved HEAD rebuilds the kernel, so this script runs again):
    // the tests compare with this, not with whatever HEAD is when they run.
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".to_owned());
    println!("cargo:rustc-env=KERNEL_COMMIT={commit}");
}

/// The kernel's target, beside its manifest.
const KERNEL_TARGET: &str = "kernel/x86_64-modex-kernel.json";

/// Profile settings for the standard crates that `-Z build-std` compiles.
const STD_CRATES_OPTIMISED: &[&str] = &[
    "profile.dev.package.core.opt-level=3",
    "profile.dev.package.core.debug-assertions=false",
    "profile.dev.package.core.overflow-checks=false",
    "profile.dev.package.compiler_builtins.opt-level=3",
    "profile.dev.package.compiler_builtins.debug-assertions=false",
    "profile.dev.package.compiler_builtins.overflow-checks=false",
];

/// Everything the kernel is built from: a change anywhere here runs this
/// script again, and the second cargo decides what to rebuild.
const KERNEL_SOURCES: &[&str] = &[
    "kernel",
    "protocol",
    "keyboard",
    "xhci-keyboard",
    "clock",
    "firmware",
    "memory",
    "kernel-log",
    "modex",
    "engine",
    "demo",
    "Cargo.toml",
    "Cargo.lock",
    "rust-toolchain.toml",
];

/// Builds the kernel with a second cargo into its own target directory beside
/// this build's (`target/kernel/`), with this build's profile, and returns the
/// ELF file's path.
fn build_kernel(out_dir: &Path) -> PathBuf {
    for source in KERNEL_SOURCES {
        println!("cargo:rerun-if-changed={source}");
    }
    // The kernel's commit (kernel/build.rs) follows HEAD; so must this script.
    for git_path in ["HEAD", "packed-refs"] {
        if let Some(file) = git(&["rev-parse", "--git-path", git_path]) {
            println!("cargo:rerun-if-changed={file}");
        }
    }
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        if let Some(file) = git(&["rev-parse", "--git-path", &branch]) {
            println!("cargo:rerun-if-changed={file}");
        }
    }
    // OUT_DIR is <target>/<profile>/build/<package>[-/]<hash>/out.
    let target_dir = out_dir
        .ancestors()
        .find(|dir| dir.file_name().is_some_and(|name| name == "build"))
        .and_then(|build| build.parent()?.parent())
        .map(|target| target.join("kernel"))
        .unwrap_or_else(|| out_dir.join("kernel"));
    let release = std::env::var("PROFILE").as_deref() == Ok("release");
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut command = std::process::Command::new(cargo);
    command
        .args([
            "build",
            "--package",
            "kernel",
            "--bin",
            "kernel",
            "--locked",
        ])
        .args(["--target", KERNEL_TARGET, "-Zjson-target-spec"])
        .args(["-Zbuild-std=core,compiler_builtins"])
        .args(["-Zbuild-std-features=compiler-builtins-mem"])
        .arg("--target-dir")
        .arg(&target_dir)
        .args(["--profile", if release { "release" } else { "dev" }])
        // Line tables are enough to turn a fault's rip into a source line;
        // full debug info would more than double the kernel in the image,
        // and every BIOS boot reads the whole file through INT 13h.
        .env("CARGO_PROFILE_DEV_DEBUG", "line-tables-only")
        .env("CARGO_PROFILE_RELEASE_DEBUG", "line-tables-only")
        // `core` and `compiler_builtins` as optimised as the prebuilt ones
        // of a built-in target, also in the test profile: its debug
        // assertions made the framebuffer's presents 20 % slower (`memcpy`,
        // slice copies). The kernel's own crates keep theirs. (Given here,
        // not in Cargo.toml, where every other cargo command would warn
        // that no package of the workspace is called `core`.)
        .args(
            STD_CRATES_OPTIMISED
                .iter()
                .flat_map(|setting| ["--config", setting]),
        )
        // This build's flags and wrappers (clippy's) are not the kernel's.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("RUSTC_WORKSPACE_WRAPPER")
        .env_remove("RUSTC_WRAPPER");
    match command.status() {
        Ok(status) if status.success() => {}
        Ok(status) => fail(&format!(
            "building the kernel failed ({status}); cargo's messages are above"
        )),
        Err(error) => fail(&format!("cannot run cargo to build the kernel: {error}")),
    }
    let target_name = Path::new(KERNEL_TARGET)
        .file_stem()
        .expect("the target file has a name");
    target_dir
        .join(target_name)
        .join(if release { "release" } else { "debug" })
        .join("kernel")
}

fn git(args: &[&str]) -> Option<String> {
    let output = std::process::Command::new("git").args(args).output().ok()?;
    let text = String::from_utf8(output.stdout).ok()?;
    let text = text.trim();
    (output.status.success() && !text.is_empty()).then(|| text.to_owned())
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
