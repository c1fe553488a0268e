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
    let kernel_with_debug = build_kernel(&out_dir);
    let kernel = strip(&kernel_with_debug, &out_dir);
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
        let esp = fitted_fat(&esp).map_err(|e| format!("refitting the ESP: {e}"))?;
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
    println!(
        "cargo:rustc-env=KERNEL_DEBUG_ELF={}",
        kernel_with_debug.display()
    );
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

/// The same files in a FAT just big enough for them. The bootloader sizes
/// its FAT at the files rounded up to a MiB, plus another MiB: 3 MiB for
/// about 1 MiB of files, which made the one image 5.3 MB. The one image is
/// what a BIOS boot reads and a USB stick is written with; nothing is added
/// to its FAT later.
fn fitted_fat(esp: &[u8]) -> std::io::Result<Vec<u8>> {
    use std::io::{Cursor, Read, Write};
    let old = fatfs::FileSystem::new(Cursor::new(esp.to_vec()), fatfs::FsOptions::new())?;
    let mut label = [b' '; 11];
    for (slot, byte) in label.iter_mut().zip(old.volume_label_as_bytes()) {
        *slot = *byte;
    }
    // Every file with its path, directories first (a walk in order).
    let mut directories = Vec::new();
    let mut files = Vec::new();
    let mut pending = vec![(String::new(), old.root_dir())];
    while let Some((prefix, directory)) = pending.pop() {
        for entry in directory.iter() {
            let entry = entry?;
            let name = entry.file_name();
            if name == "." || name == ".." {
                continue;
            }
            let path = format!("{prefix}{name}");
            if entry.is_dir() {
                directories.push(path.clone());
                pending.push((format!("{path}/"), entry.to_dir()));
            } else {
                let mut bytes = Vec::new();
                entry.to_file().read_to_end(&mut bytes)?;
                files.push((path, bytes));
            }
        }
    }
    // Room for each file in whole 4 KiB clusters (the largest fatfs picks at
    // this size), plus 64 KiB for the boot sector, the FATs and directories;
    // checked by writing, and grown if ever short.
    const ROOM: usize = 64 * 1024;
    let mut bytes = files
        .iter()
        .map(|(_, data)| data.len().next_multiple_of(4096))
        .sum::<usize>()
        + ROOM;
    for _attempt in 0..8 {
        let mut volume = vec![0u8; bytes];
        fatfs::format_volume(
            Cursor::new(&mut volume[..]),
            fatfs::FormatVolumeOptions::new().volume_label(label),
        )?;
        let written = (|| {
            let fs = fatfs::FileSystem::new(Cursor::new(&mut volume[..]), fatfs::FsOptions::new())?;
            let root = fs.root_dir();
            for directory in &directories {
                root.create_dir(directory)?;
            }
            for (path, data) in &files {
                let mut file = root.create_file(path)?;
                file.truncate()?;
                file.write_all(data)?;
            }
            drop(root);
            fs.unmount()
        })();
        match written {
            Ok(()) => return Ok(volume),
            // fatfs's only word for a full volume.
            Err(error) if error.to_string().contains("No space left") => bytes += ROOM,
            Err(error) => return Err(error),
        }
    }
    Err(std::io::Error::other(format!(
        "the files did not fit in {bytes} bytes"
    )))
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

/// Profile settings for the kernel alone, in both profiles: one codegen unit,
/// so LLVM sees the whole crate at once and builds each generic and inlined
/// helper once rather than once per unit that uses it: the release kernel
/// file went from 704,016 to 649,352 bytes with it alone (docs/performance.md
/// has the steps and the frame bench beside them). Given here, not in
/// Cargo.toml, so the runner and the host crates keep their parallel builds.
const KERNEL_PROFILE: &[&str] = &[
    "profile.dev.codegen-units=1",
    "profile.release.codegen-units=1",
];

/// Everything the kernel is built from: a change anywhere here runs this
/// script again, and the second cargo decides what to rebuild.
const KERNEL_SOURCES: &[&str] = &[
    "kernel",
    "protocol",
    "keyboard",
    "usb",
    "clock",
    "firmware",
    "memory",
    "kernel-log",
    "modex",
    "engine",
    "demo",
    // The Secure Boot record's format, shared with the UEFI loader.
    "bootloader/loader-logic",
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
        // Line tables are enough to turn a fault's rip into a source line
        // (with the full ELF; the image's copy is stripped, `strip`).
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
                .chain(KERNEL_PROFILE)
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

/// The kernel file the images carry: `kernel` without its debug sections
/// and symbol table (`llvm-objcopy --strip-all`, from the toolchain's
/// llvm-tools), written to `out_dir/kernel`; what is loaded (code, data, the
/// dynamic relocations) is unchanged. The full ELF stays where cargo built
/// it (`target/kernel/x86_64-modex-kernel/<profile>/kernel`), for turning a
/// fault's addresses into functions and source lines. Debug sections were
/// three fifths of the file, the symbols a fifth of the rest, and every BIOS
/// boot reads the whole file through INT 13h.
fn strip(kernel: &Path, out_dir: &Path) -> PathBuf {
    let objcopy = llvm_tool("llvm-objcopy");
    let stripped = out_dir.join("kernel");
    let status = std::process::Command::new(&objcopy)
        .arg("--strip-all")
        .arg(kernel)
        .arg(&stripped)
        .status();
    match status {
        Ok(status) if status.success() => stripped,
        Ok(status) => fail(&format!(
            "{} --strip-all {} failed ({status})",
            objcopy.display(),
            kernel.display()
        )),
        Err(error) => fail(&format!(
            "cannot run {}: {error}; install the llvm-tools-preview component \
             (rust-toolchain.toml names it; boot/setup.sh installs it)",
            objcopy.display()
        )),
    }
}

/// A tool of the toolchain's `llvm-tools-preview` component, in the
/// sysroot's host directory.
fn llvm_tool(name: &str) -> PathBuf {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    let sysroot = std::process::Command::new(rustc)
        .args(["--print", "sysroot"])
        .output()
        .ok()
        .filter(|output| output.status.success())
        .and_then(|output| String::from_utf8(output.stdout).ok())
        .unwrap_or_else(|| fail("cannot ask rustc for its sysroot"));
    let host = std::env::var("HOST").expect("cargo sets HOST");
    Path::new(sysroot.trim())
        .join("lib/rustlib")
        .join(host)
        .join("bin")
        .join(name)
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
