//! Whether this PC's processor can run the kernel, asked of CPUID before
//! any loader switches on what the kernel needs: long mode (64-bit mode),
//! PAE (its page tables) and SSE2 (the kernel's floating point,
//! `kernel/x86_64-modex-kernel.json`). A CPU without them (the Atom N270
//! of 2008's netbooks, a Pentium M, a Pentium 4 before EM64T, a VIA C7, a
//! Geode) would otherwise fault when EFER.LME or CR4.PAE is set, and reset in
//! a loop with nothing on screen. Linux's `arch/x86/boot/cpu.c` refuses such
//! a CPU in words; so do the loaders, naming the CPU.
//!
//! NX is not required: without it the page tables carry no no-execute bits
//! (`bootloader/common`'s `no_execute`), and the kernel says `nx: off` in
//! its facts.
//!
//! The loaders read CPUID ([`CpuidReadings::read`]; a BIOS stage first
//! checks that the instruction exists) and hand the readings to [`check`].

use core::fmt;

/// CPUID leaf 1, EDX: PAE.
pub const LEAF_1_EDX_PAE: u32 = 1 << 6;
/// CPUID leaf 1, EDX: SSE2.
pub const LEAF_1_EDX_SSE2: u32 = 1 << 26;
/// CPUID leaf 8000_0001h, EDX: long mode (Intel 64, AMD64).
pub const LEAF_8000_0001_EDX_LONG_MODE: u32 = 1 << 29;
/// CPUID leaf 8000_0001h, EDX: no-execute pages.
pub const LEAF_8000_0001_EDX_NX: u32 = 1 << 20;

/// What CPUID said, as far as the check needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CpuidReadings {
    /// Leaf 0's vendor string (EBX, EDX, ECX), as `GenuineIntel`.
    pub vendor: [u8; 12],
    /// Leaf 0's EAX: the highest basic leaf.
    pub max_basic_leaf: u32,
    /// Leaf 1's EAX: family, model and stepping (0 if leaf 1 is missing).
    pub signature: u32,
    /// Leaf 1's EDX (0 if leaf 1 is missing).
    pub features: u32,
    /// Leaf 8000_0000h's EAX: the highest extended leaf.
    pub max_extended_leaf: u32,
    /// Leaf 8000_0001h's EDX (0 if that leaf is missing).
    pub extended_features: u32,
    /// Leaves 8000_0002h-4h: the brand string (zeros if missing).
    pub brand: [u8; 48],
}

impl CpuidReadings {
    /// Reads the leaves the check needs. The caller knows that CPUID exists
    /// (every UEFI PC's CPU has it; a BIOS stage tests EFLAGS.ID first).
    #[cfg(any(target_arch = "x86", target_arch = "x86_64"))]
    pub fn read() -> CpuidReadings {
        #[cfg(target_arch = "x86")]
        use core::arch::x86::__cpuid;
        #[cfg(target_arch = "x86_64")]
        use core::arch::x86_64::__cpuid;
        let leaf_0 = __cpuid(0);
        let mut vendor = [0; 12];
        vendor[..4].copy_from_slice(&leaf_0.ebx.to_le_bytes());
        vendor[4..8].copy_from_slice(&leaf_0.edx.to_le_bytes());
        vendor[8..].copy_from_slice(&leaf_0.ecx.to_le_bytes());
        let (signature, features) = if leaf_0.eax >= 1 {
            let leaf_1 = __cpuid(1);
            (leaf_1.eax, leaf_1.edx)
        } else {
            (0, 0)
        };
        // A CPU without extended leaves answers 8000_0000h with whatever its
        // highest basic leaf holds; only a value in the extended range counts.
        let mut readings = CpuidReadings {
            vendor,
            max_basic_leaf: leaf_0.eax,
            signature,
            features,
            max_extended_leaf: __cpuid(0x8000_0000).eax,
            extended_features: 0,
            brand: [0; 48],
        };
        if readings.has_extended(0x8000_0001) {
            readings.extended_features = __cpuid(0x8000_0001).edx;
        }
        if readings.has_extended(0x8000_0004) {
            for (index, leaf) in (0x8000_0002..=0x8000_0004).enumerate() {
                let part = __cpuid(leaf);
                for (word, value) in [part.eax, part.ebx, part.ecx, part.edx]
                    .into_iter()
                    .enumerate()
                {
                    let at = 16 * index + 4 * word;
                    readings.brand[at..at + 4].copy_from_slice(&value.to_le_bytes());
                }
            }
        }
        readings
    }

    /// The display family (base family, plus the extended family when the
    /// base is 0Fh), as the SDM and Linux's `x86_family` compute it.
    pub fn family(&self) -> u32 {
        let base = (self.signature >> 8) & 0xF;
        if base == 0xF {
            base + ((self.signature >> 20) & 0xFF)
        } else {
            base
        }
    }

    /// The display model (with the extended model for families 6 and 0Fh).
    pub fn model(&self) -> u32 {
        let base = (self.signature >> 4) & 0xF;
        match (self.signature >> 8) & 0xF {
            0x6 | 0xF => base | (((self.signature >> 16) & 0xF) << 4),
            _ => base,
        }
    }

    /// Whether extended leaf `leaf` exists. A CPU without extended leaves
    /// answers 8000_0000h with whatever its highest basic leaf holds, so
    /// only a count in the extended range is believed.
    fn has_extended(&self, leaf: u32) -> bool {
        (0x8000_0000..=0x8000_00FF).contains(&self.max_extended_leaf)
            && self.max_extended_leaf >= leaf
    }

    /// Long mode, as leaf 8000_0001h says.
    pub fn long_mode(&self) -> bool {
        self.has_extended(0x8000_0001) && self.extended_features & LEAF_8000_0001_EDX_LONG_MODE != 0
    }

    /// No-execute pages, as leaf 8000_0001h says.
    pub fn nx(&self) -> bool {
        self.has_extended(0x8000_0001) && self.extended_features & LEAF_8000_0001_EDX_NX != 0
    }
}

/// What the processor lacks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lack {
    /// No CPUID instruction at all: a 486 or older.
    Cpuid,
    /// No long mode: a 32-bit CPU.
    LongMode,
    /// Long mode but no PAE (no such CPU is known; a hypervisor may say so).
    Pae,
    /// Long mode but no SSE2 (likewise).
    Sse2,
}

/// Why the loader stops: what is missing, and which CPU it is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Refusal {
    /// What the processor lacks.
    pub lack: Lack,
    /// What CPUID said; `None` when it does not exist.
    pub cpu: Option<CpuidReadings>,
}

/// The processor's readings, or why it cannot run the kernel.
pub fn check(cpu: CpuidReadings) -> Result<CpuidReadings, Refusal> {
    let lack = if !cpu.long_mode() {
        Lack::LongMode
    } else if cpu.features & LEAF_1_EDX_PAE == 0 {
        Lack::Pae
    } else if cpu.features & LEAF_1_EDX_SSE2 == 0 {
        Lack::Sse2
    } else {
        return Ok(cpu);
    };
    Err(Refusal {
        lack,
        cpu: Some(cpu),
    })
}

/// The refusal of a CPU without CPUID.
pub const NO_CPUID: Refusal = Refusal {
    lack: Lack::Cpuid,
    cpu: None,
};

/// How every refusal starts (the loaders put `loader: stopped: ` before it).
pub const REFUSAL_START: &str = "this PC's processor ";

/// Printable ASCII of `bytes`, without the padding spaces and zeros
/// around it (brand strings are padded either way).
fn trimmed(bytes: &[u8]) -> impl fmt::Display + '_ {
    struct Trimmed<'a>(&'a [u8]);
    impl fmt::Display for Trimmed<'_> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            let is_padding = |b: &u8| *b == 0 || *b == b' ';
            let start = self
                .0
                .iter()
                .position(|b| !is_padding(b))
                .unwrap_or(self.0.len());
            let end = self
                .0
                .iter()
                .rposition(|b| !is_padding(b))
                .map_or(start, |e| e + 1);
            let mut last_was_space = false;
            for &byte in &self.0[start..end] {
                let shown = if byte.is_ascii_graphic() { byte } else { b' ' };
                // Brand strings pad inside too ("CPU N270   @ 1.60GHz").
                if shown == b' ' && last_was_space {
                    continue;
                }
                last_was_space = shown == b' ';
                fmt::Write::write_char(f, char::from(shown))?;
            }
            Ok(())
        }
    }
    Trimmed(bytes)
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(REFUSAL_START)?;
        let Some(cpu) = self.cpu else {
            return f.write_str(
                "has no CPUID instruction (a 486 or older); the cube needs an x86-64 processor",
            );
        };
        write!(
            f,
            "({}, family {} model {}",
            trimmed(&cpu.vendor),
            cpu.family(),
            cpu.model()
        )?;
        if cpu.brand.iter().any(|&b| b != 0) {
            write!(f, ", {}", trimmed(&cpu.brand))?;
        }
        f.write_str(") ")?;
        match self.lack {
            Lack::Cpuid | Lack::LongMode => {
                f.write_str("is a 32-bit CPU: it has no 64-bit mode")?
            }
            Lack::Pae => f.write_str("has 64-bit mode but no PAE")?,
            Lack::Sse2 => f.write_str("has 64-bit mode but no SSE2")?,
        }
        f.write_str("; the cube needs an x86-64 processor")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::string::ToString;

    fn brand(text: &str) -> [u8; 48] {
        let mut brand = [0; 48];
        brand[..text.len()].copy_from_slice(text.as_bytes());
        brand
    }

    /// An Atom N270 as QEMU's `-cpu n270` describes it: family 6 model 28,
    /// PAE and SSE2, extended leaves but no long mode.
    fn atom_n270() -> CpuidReadings {
        CpuidReadings {
            vendor: *b"GenuineIntel",
            max_basic_leaf: 10,
            signature: 0x0001_06C2,
            features: 0xBFE9_FBFF,
            max_extended_leaf: 0x8000_000A,
            extended_features: 0x0010_0000,
            brand: brand("Intel(R) Atom(TM) CPU N270   @ 1.60GHz"),
        }
    }

    /// A Pentium III (family 6 model 7): no extended leaves at all; its
    /// answer to 8000_0000h is a basic leaf's value, not an extended count.
    fn pentium_3() -> CpuidReadings {
        CpuidReadings {
            vendor: *b"GenuineIntel",
            max_basic_leaf: 2,
            signature: 0x0000_0673,
            features: 0x0383_F9FF,
            max_extended_leaf: 0x0303_0201,
            extended_features: 0,
            brand: [0; 48],
        }
    }

    fn a_64_bit_cpu() -> CpuidReadings {
        CpuidReadings {
            vendor: *b"AuthenticAMD",
            max_basic_leaf: 13,
            signature: 0x0080_0F82,
            features: 0x178B_FBFF,
            max_extended_leaf: 0x8000_0008,
            extended_features: 0x2FD3_FBFF,
            brand: brand("AMD Ryzen 7 2700X Eight-Core Processor          "),
        }
    }

    #[test]
    fn an_x86_64_processor_is_taken() {
        let cpu = a_64_bit_cpu();
        assert_eq!(check(cpu), Ok(cpu));
        assert_eq!((cpu.family(), cpu.model()), (0x17, 8));
        assert!(cpu.nx());
    }

    #[test]
    fn a_32_bit_atom_is_refused_by_name() {
        let refusal = check(atom_n270()).unwrap_err();
        assert_eq!(refusal.lack, Lack::LongMode);
        assert_eq!(
            refusal.to_string(),
            "this PC's processor (GenuineIntel, family 6 model 28, Intel(R) Atom(TM) CPU \
             N270 @ 1.60GHz) is a 32-bit CPU: it has no 64-bit mode; the cube needs an x86-64 \
             processor"
        );
    }

    #[test]
    fn a_cpu_without_extended_leaves_has_no_long_mode_whatever_its_registers_hold() {
        let mut cpu = pentium_3();
        // Junk in EDX from the basic leaf answered in place of 8000_0001h.
        cpu.extended_features = u32::MAX;
        assert!(!cpu.long_mode());
        let refusal = check(cpu).unwrap_err();
        assert_eq!(refusal.lack, Lack::LongMode);
        assert!(
            refusal
                .to_string()
                .contains("(GenuineIntel, family 6 model 7)"),
            "{refusal}"
        );
    }

    #[test]
    fn long_mode_without_pae_or_sse2_is_refused_too() {
        let mut no_pae = a_64_bit_cpu();
        no_pae.features &= !LEAF_1_EDX_PAE;
        assert_eq!(check(no_pae).unwrap_err().lack, Lack::Pae);
        let mut no_sse2 = a_64_bit_cpu();
        no_sse2.features &= !LEAF_1_EDX_SSE2;
        assert_eq!(check(no_sse2).unwrap_err().lack, Lack::Sse2);
        assert!(check(no_sse2).unwrap_err().to_string().contains("no SSE2"));
    }

    #[test]
    fn a_cpu_without_cpuid_is_named_for_what_it_lacks() {
        assert_eq!(
            NO_CPUID.to_string(),
            "this PC's processor has no CPUID instruction (a 486 or older); the cube \
             needs an x86-64 processor"
        );
    }

    #[test]
    fn the_family_counts_the_extended_family_past_0fh() {
        // A Pentium 4 (family 0Fh, model 2) and an Athlon 64 (0Fh + 0 too).
        let pentium_4 = CpuidReadings {
            signature: 0x0000_0F29,
            ..pentium_3()
        };
        assert_eq!((pentium_4.family(), pentium_4.model()), (15, 2));
    }
}
