//! Checks on the kernel's machine code, read back from the full kernel ELF
//! (the toolchain's `llvm-objdump`; the file the images carry is the same
//! code without symbols): the two things hardware floating point depends on
//! (`kernel/src/fpu.rs`).
//!
//! - The ELF entry point is `kernel_entry`, which sets CR4.OSFXSR and
//!   CR4.OSXMMEXCPT before it jumps to bootloader_api's `_start`: without it
//!   a BIOS boot would stop at the first SSE instruction.
//! - Every interrupt handler that returns to the interrupted code saves each
//!   XMM register before it can change it and restores it before `iretq`:
//!   the code it interrupted may be half-way through a transform held in
//!   XMM registers.
//!
//! And one check on the UEFI loader's (the built ESP's `BOOTX64.EFI`), for
//! issue 38 (`bootloader/CHANGES.md`): it never reads CR3 (the firmware's
//! page tables are neither read nor written: the loader builds its own), and
//! its only write to CR0 (setting WP) comes right after the write to CR3
//! that switches to the kernel's tables.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

/// The toolchain's own `llvm-objdump` (component `llvm-tools-preview`, which
/// `rust-toolchain.toml` installs).
fn llvm_objdump() -> PathBuf {
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let text = |args: &[&str]| {
        let output = Command::new(&rustc)
            .args(args)
            .output()
            .expect("rustc runs");
        assert!(output.status.success(), "rustc {args:?} failed");
        String::from_utf8(output.stdout).expect("rustc prints UTF-8")
    };
    let sysroot = text(&["--print", "sysroot"]).trim().to_owned();
    let version = text(&["-vV"]);
    let host = version
        .lines()
        .find_map(|line| line.strip_prefix("host: "))
        .expect("rustc -vV names the host");
    let path = PathBuf::from(sysroot)
        .join("lib/rustlib")
        .join(host)
        .join("bin/llvm-objdump");
    assert!(
        path.exists(),
        "{} is missing: install the llvm-tools-preview component (boot/setup.sh does)",
        path.display()
    );
    path
}

/// The kernel's functions by demangled name, each as its instructions
/// (mnemonic and operands, Intel syntax).
fn kernel_functions() -> BTreeMap<String, Vec<String>> {
    let output = Command::new(llvm_objdump())
        .args([
            "-d",
            "--no-show-raw-insn",
            "--x86-asm-syntax=intel",
            "--demangle",
        ])
        .arg(env!("KERNEL_DEBUG_ELF"))
        .output()
        .expect("llvm-objdump runs");
    assert!(output.status.success(), "llvm-objdump failed");
    let text = String::from_utf8_lossy(&output.stdout);
    let mut functions = BTreeMap::new();
    let mut current: Option<(String, Vec<String>)> = None;
    for line in text.lines() {
        if let Some(name) = line
            .split_once(" <")
            .filter(|_| line.ends_with(">:"))
            .map(|(_, rest)| rest.trim_end_matches(">:").to_owned())
        {
            functions.extend(current.take());
            current = Some((name, Vec::new()));
        } else if let Some((_, instructions)) = current.as_mut() {
            // "   48b60:      \tpush\trax"
            if let Some((address, instruction)) = line.trim_start().split_once(':') {
                if !address.is_empty() && address.chars().all(|c| c.is_ascii_hexdigit()) {
                    let words: Vec<&str> = instruction.split_whitespace().collect();
                    instructions.push(words.join(" "));
                }
            }
        }
    }
    functions.extend(current);
    functions
}

fn elf_entry() -> u64 {
    let elf = std::fs::read(env!("KERNEL_DEBUG_ELF")).expect("the kernel ELF is there");
    assert_eq!(&elf[..4], b"\x7fELF");
    u64::from_le_bytes(elf[24..32].try_into().unwrap())
}

fn symbol_address(name: &str) -> Option<u64> {
    let output = Command::new(llvm_objdump())
        .args(["--syms", "--demangle"])
        .arg(env!("KERNEL_DEBUG_ELF"))
        .output()
        .expect("llvm-objdump runs");
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .find(|line| line.split_whitespace().last() == Some(name))
        .and_then(|line| u64::from_str_radix(line.split_whitespace().next()?, 16).ok())
}

#[test]
fn the_entry_point_turns_sse_on_before_rust_code_runs() {
    let entry = symbol_address("kernel_entry").expect("kernel_entry is in the kernel");
    assert_eq!(
        elf_entry(),
        entry,
        "the ELF entry point is not kernel_entry"
    );
    let functions = kernel_functions();
    let code = &functions["kernel_entry"];
    let at = |wanted: &str| {
        code.iter()
            .position(|i| i.starts_with(wanted))
            .unwrap_or_else(|| panic!("no `{wanted}` in kernel_entry: {code:#?}"))
    };
    // CR4 |= OSFXSR | OSXMMEXCPT, CR0.EM and TS cleared, then on to _start.
    assert!(at("or rax, 0x600") < at("mov cr4, rax"));
    assert!(at("mov cr0, rax") < at("jmp"));
    assert!(at("mov cr4, rax") < at("jmp"));
    assert!(code
        .iter()
        .any(|i| i.starts_with("jmp") && i.contains("<_start>")));
    assert!(
        code.iter().all(|i| !i.contains("xmm")),
        "kernel_entry uses SSE before turning it on"
    );
}

/// Whether a handler that returns with `iretq` keeps every XMM register of
/// the code it interrupted: one that calls anything saves all sixteen before
/// the first call and restores them all; a leaf may change only those it
/// saved.
fn keeps_xmm_registers(code: &[String]) -> Result<(), String> {
    let calls = code.iter().any(|i| i.starts_with("call"));
    let saved: Vec<usize> = (0..16)
        .filter(|n| {
            let store = format!(", xmm{n}");
            code.iter()
                .take_while(|i| !i.starts_with("call"))
                .any(|i| i.starts_with("movaps xmmword ptr [rsp") && i.ends_with(&store))
        })
        .collect();
    let restored: Vec<usize> = (0..16)
        .filter(|n| {
            let load = format!("movaps xmm{n}, xmmword ptr [rsp");
            code.iter().any(|i| i.starts_with(&load))
        })
        .collect();
    if calls {
        if saved.len() != 16 || restored != saved {
            return Err(format!(
                "calls out, but saves {saved:?} and restores {restored:?} of XMM0-15"
            ));
        }
        return Ok(());
    }
    for instruction in code {
        let written = instruction
            .split_whitespace()
            .nth(1)
            .and_then(|dest| dest.trim_end_matches(',').strip_prefix("xmm"))
            .and_then(|n| n.parse::<usize>().ok());
        if let Some(register) = written {
            if !saved.contains(&register) {
                return Err(format!(
                    "changes xmm{register} without saving it: {instruction}"
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn interrupt_handlers_keep_the_interrupted_codes_xmm_registers() {
    let functions = kernel_functions();
    let mut checked = Vec::new();
    for (name, code) in &functions {
        let Some(handler) = name.strip_prefix("kernel::interrupts::") else {
            continue;
        };
        // Only the handlers that return to the interrupted code matter; the
        // fault handlers halt for good.
        if !code.iter().any(|i| i == "iretq") {
            continue;
        }
        if let Err(why) = keeps_xmm_registers(code) {
            panic!("{handler}: {why}");
        }
        checked.push(handler.to_owned());
    }
    for expected in ["timer", "keyboard_irq"] {
        assert!(
            checked.iter().any(|h| h == expected),
            "{expected} not found among the returning handlers {checked:?}"
        );
    }
}

/// The check itself fails on handlers that would corrupt the interrupted
/// code's registers.
#[test]
fn the_check_refuses_handlers_that_lose_xmm_registers() {
    let listing = |lines: &[String]| lines.to_vec();
    let saves: Vec<String> = (0..16)
        .map(|n| format!("movaps xmmword ptr [rsp + {:#x}], xmm{n}", 16 * n))
        .collect();
    let restores: Vec<String> = (0..16)
        .map(|n| format!("movaps xmm{n}, xmmword ptr [rsp + {:#x}]", 16 * n))
        .collect();
    let call = vec!["call qword ptr [rip + 0x1234]".to_owned()];
    let good = [saves.clone(), call.clone(), restores.clone()].concat();
    assert_eq!(keeps_xmm_registers(&listing(&good)), Ok(()));
    // One register not saved before the call.
    let mut missing = [saves.clone(), call.clone(), restores.clone()].concat();
    missing.remove(7);
    assert!(keeps_xmm_registers(&missing).is_err());
    // Saved, but not restored.
    let unrestored = [saves, call, restores[..15].to_vec()].concat();
    assert!(keeps_xmm_registers(&unrestored).is_err());
    // A leaf that writes an XMM register it did not save.
    let leaf = vec!["xorps xmm3, xmm3".to_owned(), "iretq".to_owned()];
    assert!(keeps_xmm_registers(&leaf).is_err());
    let quiet_leaf = vec![
        "push rax".to_owned(),
        "pop rax".to_owned(),
        "iretq".to_owned(),
    ];
    assert_eq!(keeps_xmm_registers(&quiet_leaf), Ok(()));
}

/// The UEFI loader's instructions in file order (mnemonic and operands,
/// Intel syntax), from the `EFI/BOOT/BOOTX64.EFI` of the ESP just built.
fn uefi_loader_instructions() -> Vec<String> {
    let pieces = boot::secure_boot::BuiltPieces::of_this_build().expect("the built pieces");
    let files = boot::secure_boot::fat_files(&pieces.esp).expect("the ESP reads");
    let (_, loader) = files
        .iter()
        .find(|(path, _)| path.eq_ignore_ascii_case(boot::secure_boot::REMOVABLE_BOOT_PATH))
        .expect("the ESP has the UEFI loader");
    let path = std::env::temp_dir().join(format!("modex-loader-{}.efi", std::process::id()));
    std::fs::write(&path, loader).unwrap();
    let output = Command::new(llvm_objdump())
        .args(["-d", "--no-show-raw-insn", "--x86-asm-syntax=intel"])
        .arg(&path)
        .output()
        .expect("llvm-objdump runs");
    std::fs::remove_file(&path).unwrap();
    assert!(output.status.success(), "llvm-objdump failed");
    String::from_utf8_lossy(&output.stdout)
        .lines()
        .filter_map(|line| {
            let (address, instruction) = line.trim_start().split_once(':')?;
            (!address.is_empty() && address.chars().all(|c| c.is_ascii_hexdigit()))
                .then(|| instruction.split_whitespace().collect::<Vec<_>>().join(" "))
        })
        .filter(|instruction| !instruction.is_empty())
        .collect()
}

#[test]
fn the_uefi_loader_never_reads_cr3_and_sets_wp_only_on_the_kernels_tables() {
    let code = uefi_loader_instructions();
    assert!(code.len() > 1000, "too few instructions: {}", code.len());
    let reads_cr3: Vec<_> = code
        .iter()
        .filter(|i| i.starts_with("mov ") && i.ends_with(", cr3"))
        .collect();
    assert!(
        reads_cr3.is_empty(),
        "the loader reads CR3 (the firmware's tables): {reads_cr3:?}"
    );
    let cr0_writes: Vec<usize> = (0..code.len())
        .filter(|&n| code[n].starts_with("mov cr0, "))
        .collect();
    assert_eq!(cr0_writes.len(), 1, "one write to CR0 (WP)");
    let at = cr0_writes[0];
    let before = &code[at.saturating_sub(3)..at];
    assert!(
        before.iter().any(|i| i.starts_with("mov cr3, ")),
        "CR0 is written before CR3 holds the kernel's tables: {before:?}"
    );
    assert!(
        before.iter().any(|i| i.contains("0x10000")),
        "the write sets WP (bit 16): {before:?}"
    );
}
