//! The stick for PCs with Secure Boot left on: the user's own signing key
//! (made once, kept outside `target/`), the UEFI loader with an `.sbat`
//! section and an Authenticode signature (sbsigntool), and an EFI system
//! partition with Microsoft-signed shim as `EFI/BOOT/BOOTX64.EFI`,
//! MokManager beside it, the signed loader as shim's second stage
//! (`grubx64.efi`) and the certificate as a file a user recognises in
//! MokManager's file browser.
//!
//! One stick serves both routes (issue 39): shim keeps Microsoft's
//! signatures and gets the user's beside them, so a PC that trusts
//! Microsoft's third-party CA starts it by those, and a PC that does not
//! (the CA switched off) starts it once the user's certificate is in the
//! firmware's `db`; shim then finds the same certificate in `db` for the
//! loader. For the firmware's key management the certificate is there in
//! every form setups take: DER `.cer`, PEM `.crt`, an EFI signature list
//! `.esl` and an append-write `.auth` signed with the user's key (efitools).
//!
//! The rest of the disk is the same as `modex-cube.img`'s (see
//! `boot/disk_layout.rs`), so the stick still boots under BIOS and under UEFI
//! with Secure Boot off (where shim starts the loader without checking it).
//!
//! The key is made and checked with `openssl`, the loader signed with
//! `sbsign`, its section added with `objcopy`: the field's tools, installed
//! by `boot/setup.sh`.

use std::io::{self, Read, Seek, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::disk_layout;

/// The certificate's name on the stick: what the user picks in MokManager's
/// "Enroll key from disk".
pub const ENROLL_FILE_NAME: &str = "ENROLL_THIS_KEY_IN_MOKMANAGER.cer";
/// Where shim looks for its second stage, beside itself.
pub const SECOND_STAGE_PATH: &str = "EFI/BOOT/grubx64.efi";
/// Where shim looks for MokManager, beside itself.
pub const MOK_MANAGER_PATH: &str = "EFI/BOOT/mmx64.efi";
/// The kernel file the loaders read from the ESP.
pub const KERNEL_FILE_NAME: &str = "kernel-x86_64";
/// What UEFI firmware starts from a removable disk.
pub const REMOVABLE_BOOT_PATH: &str = "EFI/BOOT/BOOTX64.EFI";

/// The loader's SBAT data (shim refuses a second stage without it): the
/// format's own line, then this loader's component with its generation
/// number, which is raised when a revocation is needed.
pub const SBAT_CSV: &str = "sbat,1,SBAT Version,sbat,1,https://github.com/rhboot/shim/blob/main/SBAT.md\n\
modex-cube.loader,1,modex-cube,bootloader-x86_64-uefi,0.11.17,https://github.com/rust-osdev/bootloader\n";

/// The loader's own SBAT component and its generation, from [`SBAT_CSV`]'s
/// second line: what a revocation (`SbatLevel`) names to refuse it.
pub fn sbat_component() -> (&'static str, u32) {
    let line = SBAT_CSV
        .lines()
        .nth(1)
        .expect("SBAT_CSV has the loader's line");
    let mut fields = line.split(',');
    let name = fields.next().expect("a component name");
    let generation = fields
        .next()
        .and_then(|g| g.parse().ok())
        .expect("a generation number");
    (name, generation)
}

/// The file names of a signing key in its folder.
pub const KEY_FILE: &str = "modex-cube-db.key";
/// The certificate, PEM, as sbsign wants it.
pub const CERT_FILE: &str = "modex-cube-db.crt";
/// The certificate, DER, as MokManager and firmware setup screens want it.
pub const CERT_DER_FILE: &str = "modex-cube-db.cer";

/// The certificate files on the stick's root for the firmware's key
/// management (issue 39): DER, PEM, an EFI signature list, and the list as a
/// signed append to `db` (`.auth`).
pub const DB_CER_FILE: &str = "modex-cube-db.cer";
/// The PEM copy on the stick.
pub const DB_CRT_FILE: &str = "modex-cube-db.crt";
/// The EFI signature list on the stick.
pub const DB_ESL_FILE: &str = "modex-cube-db.esl";
/// The signed append to `db` on the stick.
pub const DB_AUTH_FILE: &str = "modex-cube-db.auth";
/// The owner GUID the signature list gives the certificate.
pub const KEY_OWNER_GUID: &str = "a9c2b5a0-0f5c-4f5e-9bd1-6d0e6b0c1e2d";
/// Shim's vendor GUID: the owner of MokList, where MokManager enrolls a key.
pub const SHIM_LOCK_GUID: &str = "605dab50-e046-4300-abb6-3dd810dd8b23";

/// The environment variable that moves the key's folder.
pub const KEY_DIR_VARIABLE: &str = "MODEX_CUBE_SECURE_BOOT_DIR";
/// The environment variable that moves shim's folder (as `boot/setup.sh` reads it).
pub const SHIM_DIR_VARIABLE: &str = "MODEX_CUBE_SHIM_DIR";

/// Why the signed stick could not be made; each names the file and the fix.
#[derive(Debug, thiserror::Error)]
pub enum SecureBootError {
    /// A file the user named or the runner needs is not there or unreadable.
    #[error("cannot read {what} {}: {error}; {fix}", path.display())]
    Unreadable {
        /// What the file is ("the signing key", "shim", ...).
        what: &'static str,
        /// The file.
        path: PathBuf,
        /// Why it could not be read.
        error: io::Error,
        /// What to do.
        fix: &'static str,
    },
    /// The key folder holds some of the key's files but not all: nothing is
    /// made over them.
    #[error(
        "{} has {present} but not {missing}: the runner never overwrites a key; \
         move the folder away to make a new key, or give --sign-key and --sign-cert",
        dir.display()
    )]
    IncompleteKeyFolder {
        /// The folder.
        dir: PathBuf,
        /// The files there.
        present: String,
        /// The files missing.
        missing: String,
    },
    /// The key is not the certificate's.
    #[error(
        "the key {} does not match the certificate {}: give the certificate made with that key",
        key.display(),
        cert.display()
    )]
    KeyCertMismatch {
        /// The private key.
        key: PathBuf,
        /// The certificate.
        cert: PathBuf,
    },
    /// A file is not what it should be (not a key, not a certificate).
    #[error("{} is not {what}: {detail}", path.display())]
    BadFile {
        /// The file.
        path: PathBuf,
        /// What it should be.
        what: &'static str,
        /// What the tool said.
        detail: String,
    },
    /// A tool is missing or failed.
    #[error("{tool} failed: {detail}")]
    Tool {
        /// The tool.
        tool: &'static str,
        /// Its message, or how to install it.
        detail: String,
    },
    /// Writing a file failed.
    #[error("cannot write {}: {error}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        error: io::Error,
    },
    /// The ESP could not be made.
    #[error("the EFI system partition: {0}")]
    Esp(String),
    /// A file on the stick does not match the key that signed the loader:
    /// nothing is written.
    #[error("{file} on the stick does not match the loader's signing key: {reason}")]
    Mismatch {
        /// The file on the stick.
        file: String,
        /// What differs.
        reason: String,
    },
    /// The disk could not be laid out.
    #[error("{0}")]
    Layout(#[from] disk_layout::LayoutError),
}

type Result<T> = std::result::Result<T, SecureBootError>;

/// A signing key and its certificate, in both forms.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SigningKey {
    /// The private key, PEM. Never copied into an image.
    pub key: PathBuf,
    /// The certificate, PEM.
    pub cert: PathBuf,
    /// The certificate, DER: what goes on the stick for MokManager.
    pub cert_der: Vec<u8>,
}

/// `$MODEX_CUBE_SECURE_BOOT_DIR`, or `${XDG_CONFIG_HOME:-~/.config}/modex-cube/secure-boot`:
/// outside the clone, so a new clone (and `cargo clean`) finds the key that
/// was enrolled.
pub fn default_key_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(KEY_DIR_VARIABLE).filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    config_home().join("modex-cube").join("secure-boot")
}

fn config_home() -> PathBuf {
    std::env::var_os("XDG_CONFIG_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| home().join(".config"))
}

fn home() -> PathBuf {
    std::env::var_os("HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/"))
}

/// `$MODEX_CUBE_SHIM_DIR`, or `${XDG_CACHE_HOME:-~/.cache}/modex-cube/shim`,
/// where `boot/setup.sh` unpacks shim and MokManager.
pub fn default_shim_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os(SHIM_DIR_VARIABLE).filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| home().join(".cache"))
        .join("modex-cube")
        .join("shim")
}

/// Whether `make_or_reuse_key` made the key or found it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KeyOrigin {
    /// Made now: the user must enroll it once.
    Made,
    /// Found where an earlier run made it.
    Found,
}

/// The key in `dir`: made there on first use (RSA 2048, self-signed for ten
/// years, with a DER copy), and from then on only read. A folder with some
/// of the files but not all is refused, never completed over.
pub fn make_or_reuse_key(dir: &Path) -> Result<(SigningKey, KeyOrigin)> {
    let files = [KEY_FILE, CERT_FILE, CERT_DER_FILE];
    let present: Vec<&str> = files
        .iter()
        .copied()
        .filter(|name| dir.join(name).exists())
        .collect();
    if present.len() == files.len() {
        let key = given_key(&dir.join(KEY_FILE), &dir.join(CERT_FILE))?;
        return Ok((key, KeyOrigin::Found));
    }
    if !present.is_empty() {
        let missing: Vec<&str> = files
            .iter()
            .copied()
            .filter(|name| !present.contains(name))
            .collect();
        return Err(SecureBootError::IncompleteKeyFolder {
            dir: dir.to_owned(),
            present: present.join(", "),
            missing: missing.join(", "),
        });
    }
    let parent = dir.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|error| SecureBootError::Write {
        path: parent.to_owned(),
        error,
    })?;
    // Made in a fresh folder beside the final one, then renamed into place:
    // a run stopped halfway leaves no half key, and of two runs at once only
    // one key survives (the rename onto a non-empty folder fails).
    let staging = tempfile::Builder::new()
        .prefix(".secure-boot-new-")
        .tempdir_in(parent)
        .map_err(|error| SecureBootError::Write {
            path: parent.to_owned(),
            error,
        })?;
    let subject = format!(
        "/CN=modex-cube Secure Boot key of {}/O=modex-cube",
        std::env::var("USER").unwrap_or_else(|_| "this user".to_owned())
    );
    run_tool(
        "openssl",
        Command::new("openssl")
            .args(["req", "-new", "-x509", "-newkey", "rsa:2048", "-nodes"])
            .args(["-sha256", "-days", "3650", "-subj", &subject])
            .arg("-keyout")
            .arg(staging.path().join(KEY_FILE))
            .arg("-out")
            .arg(staging.path().join(CERT_FILE)),
    )?;
    run_tool(
        "openssl",
        Command::new("openssl")
            .args(["x509", "-outform", "DER", "-in"])
            .arg(staging.path().join(CERT_FILE))
            .arg("-out")
            .arg(staging.path().join(CERT_DER_FILE)),
    )?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = std::fs::set_permissions(
            staging.path().join(KEY_FILE),
            std::fs::Permissions::from_mode(0o600),
        );
    }
    let staged = staging.keep();
    if let Err(error) = std::fs::rename(&staged, dir) {
        let _ = std::fs::remove_dir_all(&staged);
        // Another run made it first: use that one.
        if files.iter().all(|name| dir.join(name).exists()) {
            let key = given_key(&dir.join(KEY_FILE), &dir.join(CERT_FILE))?;
            return Ok((key, KeyOrigin::Found));
        }
        return Err(SecureBootError::Write {
            path: dir.to_owned(),
            error,
        });
    }
    let key = given_key(&dir.join(KEY_FILE), &dir.join(CERT_FILE))?;
    Ok((key, KeyOrigin::Made))
}

/// A key and certificate the user gave: both readable, a private key and a
/// certificate, and the one the other's.
pub fn given_key(key: &Path, cert: &Path) -> Result<SigningKey> {
    for (path, what) in [(key, "the signing key"), (cert, "the certificate")] {
        std::fs::File::open(path)
            .and_then(|mut file| file.read(&mut [0u8; 1]))
            .map_err(|error| SecureBootError::Unreadable {
                what,
                path: path.to_owned(),
                error,
                fix: "give a readable file with --sign-key and --sign-cert, \
                      or leave both out to use (or make) the key in ~/.config/modex-cube/secure-boot",
            })?;
    }
    const KEY: &str = "a PEM private key";
    const CERT: &str = "a PEM X.509 certificate";
    let key_public = openssl_reading(key, KEY, &["pkey", "-pubout", "-in"])?;
    let cert_public = openssl_reading(cert, CERT, &["x509", "-noout", "-pubkey", "-in"])?;
    if key_public != cert_public {
        return Err(SecureBootError::KeyCertMismatch {
            key: key.to_owned(),
            cert: cert.to_owned(),
        });
    }
    let cert_der = openssl_reading(cert, CERT, &["x509", "-outform", "DER", "-in"])?;
    Ok(SigningKey {
        key: key.to_owned(),
        cert: cert.to_owned(),
        cert_der,
    })
}

/// Shim and MokManager, as `boot/setup.sh` unpacked them.
#[derive(Clone, Debug)]
pub struct Shim {
    /// Microsoft-signed shim.
    pub shim: Vec<u8>,
    /// MokManager, signed by Debian's key that shim carries.
    pub mok_manager: Vec<u8>,
}

impl Shim {
    /// Reads `shimx64.efi` and `mmx64.efi` from `dir`.
    pub fn read(dir: &Path) -> Result<Shim> {
        let read = |name: &str, what: &'static str| {
            let path = dir.join(name);
            std::fs::read(&path).map_err(|error| SecureBootError::Unreadable {
                what,
                path,
                error,
                fix: "run boot/setup.sh, which fetches shim and MokManager from Debian's \
                      shim-signed and shim-helpers-amd64-signed packages",
            })
        };
        Ok(Shim {
            shim: read("shimx64.efi", "shim")?,
            mok_manager: read("mmx64.efi", "MokManager")?,
        })
    }
}

/// The loader with the `.sbat` section added (objcopy), placed after the
/// image's last section.
pub fn with_sbat(loader: &[u8]) -> Result<Vec<u8>> {
    let scratch = scratch_dir()?;
    let input = scratch.path().join("loader.efi");
    let sbat = scratch.path().join("sbat.csv");
    let output = scratch.path().join("loader-sbat.efi");
    write(&input, loader)?;
    write(&sbat, SBAT_CSV.as_bytes())?;
    let end = pe_image_end(loader).ok_or_else(|| SecureBootError::Tool {
        tool: "objcopy",
        detail: "the UEFI loader is not a PE32+ image".to_owned(),
    })?;
    run_tool(
        "objcopy",
        Command::new("objcopy")
            .arg("--add-section")
            .arg(format!(".sbat={}", sbat.display()))
            .args([
                "--set-section-flags",
                ".sbat=contents,alloc,load,readonly,data",
            ])
            .arg("--change-section-vma")
            .arg(format!(".sbat={end:#x}"))
            .arg(&input)
            .arg(&output),
    )?;
    read_back(&output)
}

/// The virtual address (image base included) just past the PE image's last
/// section, rounded up to its section alignment: where a new section goes.
pub fn pe_image_end(pe: &[u8]) -> Option<u64> {
    let u16_at = |at: usize| Some(u16::from_le_bytes(pe.get(at..at + 2)?.try_into().ok()?));
    let u32_at = |at: usize| Some(u32::from_le_bytes(pe.get(at..at + 4)?.try_into().ok()?));
    let u64_at = |at: usize| Some(u64::from_le_bytes(pe.get(at..at + 8)?.try_into().ok()?));
    let header = u32_at(0x3C)? as usize;
    if pe.get(header..header + 4)? != b"PE\0\0" {
        return None;
    }
    let optional = header + 24;
    if u16_at(optional)? != 0x20B {
        return None; // not PE32+
    }
    let image_base = u64_at(optional + 24)?;
    let alignment = u64::from(u32_at(optional + 32)?);
    let size_of_image = u64::from(u32_at(optional + 56)?);
    Some(image_base + size_of_image.next_multiple_of(alignment.max(1)))
}

/// The named PE section's raw bytes (its size in the file, trimmed to its
/// virtual size).
pub fn pe_section<'a>(pe: &'a [u8], name: &str) -> Option<&'a [u8]> {
    pe.get(pe_section_range(pe, name)?)
}

/// The SHA-256 of `bytes`.
pub fn sha256(bytes: &[u8]) -> [u8; 32] {
    use sha2::Digest;
    sha2::Sha256::digest(bytes).into()
}

/// The section the UEFI loader keeps its signing certificate's SHA-256 in
/// (bootloader/uefi/src/secure_boot_state.rs, `KEY_CERT_SHA256`): the loader
/// looks for that certificate in `db` and shim's MOK list to say who
/// checked it.
pub const CERT_HASH_SECTION: &str = ".kcert";

/// The kernel file's SHA-256 as the loader carries it, in its hash slot
/// (`loader_logic::file_hash`), or `None` for a loader without one.
pub fn loader_kernel_hash(loader: &[u8]) -> Option<[u8; 32]> {
    let slot = loader_logic::file_hash::slot_of(loader).ok()?;
    Some(slot.hashes[loader_logic::file_hash::File::Kernel as usize])
}

/// The loader with `kernel_sha256` in its hash slot. The image build has
/// written the same hash there already (every stick is checked, issue 48);
/// written again before signing, so that the signature surely covers the
/// hash of the kernel on this stick, and no rebuild of the loader is needed
/// for a new kernel.
pub fn with_kernel_hash(loader: &[u8], kernel_sha256: &[u8; 32]) -> Result<Vec<u8>> {
    use loader_logic::file_hash::{self, File};
    let mut patched = loader.to_vec();
    let mut slot = file_hash::slot_of(loader)
        .map_err(|why| SecureBootError::Esp(format!("the UEFI loader: {why}")))?;
    slot.hashes[File::Kernel as usize] = *kernel_sha256;
    file_hash::patch(&mut patched, &slot.hashes)
        .map_err(|why| SecureBootError::Esp(format!("the UEFI loader: {why}")))?;
    Ok(patched)
}

/// The loader with `cert_sha256` in its [`CERT_HASH_SECTION`], written
/// before signing like the kernel's hash.
pub fn with_cert_hash(loader: &[u8], cert_sha256: &[u8; 32]) -> Result<Vec<u8>> {
    with_section_bytes(loader, CERT_HASH_SECTION, cert_sha256)
}

fn with_section_bytes(loader: &[u8], section: &str, bytes: &[u8; 32]) -> Result<Vec<u8>> {
    let range = pe_section_range(loader, section)
        .filter(|range| range.len() >= bytes.len())
        .ok_or_else(|| {
            SecureBootError::Esp(format!(
                "the UEFI loader has no {section} section of 32 bytes \
                 (it is not this project's patched loader)"
            ))
        })?;
    let mut patched = loader.to_vec();
    patched[range.start..range.start + 32].copy_from_slice(bytes);
    Ok(patched)
}

/// Where the named PE section's raw bytes are in the file.
pub fn pe_section_range(pe: &[u8], name: &str) -> Option<std::ops::Range<usize>> {
    let u16_at = |at: usize| Some(u16::from_le_bytes(pe.get(at..at + 2)?.try_into().ok()?));
    let u32_at = |at: usize| Some(u32::from_le_bytes(pe.get(at..at + 4)?.try_into().ok()?));
    let header = u32_at(0x3C)? as usize;
    let sections = usize::from(u16_at(header + 6)?);
    let optional_size = usize::from(u16_at(header + 20)?);
    let table = header + 24 + optional_size;
    (0..sections).find_map(|index| {
        let entry = table + index * 40;
        let raw_name = pe.get(entry..entry + 8)?;
        let end = raw_name.iter().position(|&b| b == 0).unwrap_or(8);
        if &raw_name[..end] != name.as_bytes() {
            return None;
        }
        let virtual_size = u32_at(entry + 8)? as usize;
        let raw_size = u32_at(entry + 16)? as usize;
        let raw_at = u32_at(entry + 20)? as usize;
        let range = raw_at..raw_at + raw_size.min(virtual_size);
        pe.get(range.clone()).map(|_| range)
    })
}

/// The loader signed with Authenticode by `key` (sbsign).
pub fn sign(loader: &[u8], key: &SigningKey) -> Result<Vec<u8>> {
    let scratch = scratch_dir()?;
    let input = scratch.path().join("loader.efi");
    let output = scratch.path().join("loader.signed.efi");
    write(&input, loader)?;
    run_tool(
        "sbsign",
        Command::new("sbsign")
            .arg("--key")
            .arg(&key.key)
            .arg("--cert")
            .arg(&key.cert)
            .arg("--output")
            .arg(&output)
            .arg(&input),
    )?;
    read_back(&output)
}

/// How the signed loader is started on the stick.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Route {
    /// Shim (signed by Microsoft and by the user's key) as `BOOTX64.EFI`,
    /// MokManager beside it, the loader as `grubx64.efi`: for PCs that trust
    /// Microsoft's third-party CA, and for those that trust only the user's
    /// certificate in `db`. The runner's stick.
    Shim,
    /// The signed loader itself as `BOOTX64.EFI`: for firmware whose `db`
    /// holds the user's certificate.
    Direct,
}

/// The pieces of the one image that `boot/build.rs` made.
#[derive(Clone, Debug)]
pub struct BuiltPieces {
    /// The BIOS boot sector.
    pub boot_sector: Vec<u8>,
    /// The BIOS stage 2.
    pub stage_2: Vec<u8>,
    /// The EFI system partition of `modex-cube.img`.
    pub esp: Vec<u8>,
}

impl BuiltPieces {
    /// The pieces of this build (from cargo's OUT_DIR).
    pub fn of_this_build() -> Result<BuiltPieces> {
        let read = |path: &str| {
            std::fs::read(path).map_err(|error| SecureBootError::Unreadable {
                what: "the built image's piece",
                path: PathBuf::from(path),
                error,
                fix: "build again (cargo build)",
            })
        };
        Ok(BuiltPieces {
            boot_sector: read(env!("BIOS_BOOT_SECTOR"))?,
            stage_2: read(env!("BIOS_STAGE_2"))?,
            esp: read(env!("HYBRID_ESP"))?,
        })
    }
}

/// Every file of a FAT volume, by its path (`EFI/BOOT/BOOTX64.EFI`).
pub fn fat_files(volume: &[u8]) -> Result<Vec<(String, Vec<u8>)>> {
    // fatfs wants storage it could write; it writes nothing unless asked.
    let fs = fatfs::FileSystem::new(io::Cursor::new(volume.to_vec()), fatfs::FsOptions::new())
        .map_err(|e| SecureBootError::Esp(format!("cannot read the FAT: {e}")))?;
    let mut files = Vec::new();
    let mut folders = vec![(String::new(), fs.root_dir())];
    while let Some((prefix, dir)) = folders.pop() {
        for entry in dir.iter() {
            let entry = entry.map_err(|e| SecureBootError::Esp(e.to_string()))?;
            let name = entry.file_name();
            if name == "." || name == ".." {
                continue;
            }
            let path = format!("{prefix}{name}");
            if entry.is_dir() {
                folders.push((format!("{path}/"), entry.to_dir()));
            } else {
                let mut bytes = Vec::new();
                entry
                    .to_file()
                    .read_to_end(&mut bytes)
                    .map_err(|e| SecureBootError::Esp(format!("reading {path}: {e}")))?;
                files.push((path, bytes));
            }
        }
    }
    files.sort();
    Ok(files)
}

/// A FAT volume holding `files` (paths with `/`), sized with room to spare.
pub fn fat_volume(files: &[(String, Vec<u8>)], label: [u8; 11]) -> Result<Vec<u8>> {
    const MIB: usize = 1 << 20;
    let payload: usize = files.iter().map(|(_, bytes)| bytes.len() + 4096).sum();
    let size = (payload + 2 * MIB).next_multiple_of(MIB);
    let mut volume = io::Cursor::new(vec![0u8; size]);
    fatfs::format_volume(
        &mut volume,
        fatfs::FormatVolumeOptions::new().volume_label(label),
    )
    .map_err(|e| SecureBootError::Esp(format!("cannot format: {e}")))?;
    volume.rewind().expect("a cursor seeks");
    {
        let fs = fatfs::FileSystem::new(&mut volume, fatfs::FsOptions::new())
            .map_err(|e| SecureBootError::Esp(e.to_string()))?;
        for (path, bytes) in files {
            let root = fs.root_dir();
            let mut dir = root.clone();
            let mut parts: Vec<&str> = path.split('/').collect();
            let name = parts.pop().expect("split gives one part at least");
            for part in parts {
                dir = match dir.open_dir(part) {
                    Ok(existing) => existing,
                    Err(_) => dir
                        .create_dir(part)
                        .map_err(|e| SecureBootError::Esp(format!("{path}: {e}")))?,
                };
            }
            let mut file = dir
                .create_file(name)
                .map_err(|e| SecureBootError::Esp(format!("{path}: {e}")))?;
            file.truncate()
                .and_then(|()| file.write_all(bytes))
                .map_err(|e| SecureBootError::Esp(format!("{path}: {e}")))?;
        }
        fs.unmount()
            .map_err(|e| SecureBootError::Esp(e.to_string()))?;
    }
    Ok(volume.into_inner())
}

/// The signed stick: the built image's BIOS pieces and ESP files, with the
/// UEFI loader (`EFI/BOOT/BOOTX64.EFI` of the built ESP) given its `.sbat`
/// section and signed by `key`, and, on the shim route, shim and MokManager.
/// Returns the whole disk; the private key is not in it.
pub fn signed_disk(
    pieces: &BuiltPieces,
    key: &SigningKey,
    shim: Option<&Shim>,
    route: Route,
) -> Result<Vec<u8>> {
    let mut files = fat_files(&pieces.esp)?;
    let loader_at = files
        .iter()
        .position(|(path, _)| path.eq_ignore_ascii_case(REMOVABLE_BOOT_PATH))
        .ok_or_else(|| {
            SecureBootError::Esp(format!("the built ESP has no {REMOVABLE_BOOT_PATH}"))
        })?;
    let (_, loader) = files.remove(loader_at);
    let kernel = files
        .iter()
        .find(|(path, _)| path == KERNEL_FILE_NAME)
        .ok_or_else(|| SecureBootError::Esp(format!("the built ESP has no {KERNEL_FILE_NAME}")))?;
    let loader = with_kernel_hash(&loader, &sha256(&kernel.1))?;
    let loader = with_cert_hash(&loader, &sha256(&key.cert_der))?;
    let signed = sign(&with_sbat(&loader)?, key)?;
    match (route, shim) {
        (Route::Shim, Some(shim)) => {
            // Microsoft's signatures stay; the user's is added after them.
            files.push((REMOVABLE_BOOT_PATH.to_owned(), sign(&shim.shim, key)?));
            files.push((MOK_MANAGER_PATH.to_owned(), shim.mok_manager.clone()));
            files.push((SECOND_STAGE_PATH.to_owned(), signed));
        }
        (Route::Shim, None) => {
            return Err(SecureBootError::Esp(
                "the shim route needs shim and MokManager".to_owned(),
            ))
        }
        (Route::Direct, _) => files.push((REMOVABLE_BOOT_PATH.to_owned(), signed)),
    }
    files.extend(certificate_files(key)?);
    files.sort();
    // First in the root folder, so MokManager's file browser lists it first,
    // already highlighted.
    files.insert(0, (ENROLL_FILE_NAME.to_owned(), key.cert_der.clone()));
    check_stick(&files, key)?;
    let esp = fat_volume(&files, *b"MODEX-CUBE ")?;
    Ok(disk_layout::hybrid_image(
        &pieces.boot_sector,
        &pieces.stage_2,
        &esp,
    )?)
}

/// The certificate in every form a firmware setup's key management takes:
/// DER, PEM, an EFI signature list (`cert-to-efi-sig-list`), and that list
/// as an append to `db` signed with the key (`sign-efi-sig-list -a`), which
/// a setup in setup mode takes and which never replaces the `db` it adds to.
pub fn certificate_files(key: &SigningKey) -> Result<Vec<(String, Vec<u8>)>> {
    let scratch = scratch_dir()?;
    let esl = scratch.path().join(DB_ESL_FILE);
    let auth = scratch.path().join(DB_AUTH_FILE);
    run_tool(
        "cert-to-efi-sig-list",
        Command::new("cert-to-efi-sig-list")
            .args(["-g", KEY_OWNER_GUID])
            .arg(&key.cert)
            .arg(&esl),
    )?;
    run_tool(
        "sign-efi-sig-list",
        Command::new("sign-efi-sig-list")
            .args(["-a", "-g", KEY_OWNER_GUID, "-k"])
            .arg(&key.key)
            .arg("-c")
            .arg(&key.cert)
            .arg("db")
            .arg(&esl)
            .arg(&auth),
    )?;
    let pem = std::fs::read(&key.cert).map_err(|error| SecureBootError::Unreadable {
        what: "the certificate",
        path: key.cert.clone(),
        error,
        fix: "give a readable file with --sign-cert",
    })?;
    Ok(vec![
        (DB_CER_FILE.to_owned(), key.cert_der.clone()),
        (DB_CRT_FILE.to_owned(), pem),
        (DB_ESL_FILE.to_owned(), read_back(&esl)?),
        (DB_AUTH_FILE.to_owned(), read_back(&auth)?),
    ])
}

/// Checks a stick's files before anything is written: every certificate
/// file is the certificate of `key`, the signature list holds it, the
/// `.auth` carries that list, the loader carries its hash, and the loader
/// (and shim, on the shim route) verify with it (sbverify).
pub fn check_stick(files: &[(String, Vec<u8>)], key: &SigningKey) -> Result<()> {
    let file = |name: &str| {
        files
            .iter()
            .find(|(path, _)| path == name)
            .map(|(_, bytes)| bytes.as_slice())
            .ok_or_else(|| SecureBootError::Mismatch {
                file: name.to_owned(),
                reason: "it is missing".to_owned(),
            })
    };
    let mismatch = |name: &str, reason: &str| SecureBootError::Mismatch {
        file: name.to_owned(),
        reason: reason.to_owned(),
    };
    let wanted = sha256(&key.cert_der);
    for name in [ENROLL_FILE_NAME, DB_CER_FILE] {
        if file(name)? != key.cert_der {
            return Err(mismatch(name, "another certificate"));
        }
    }
    let pem = String::from_utf8_lossy(file(DB_CRT_FILE)?).into_owned();
    if pem_to_der(&pem).as_deref() != Some(key.cert_der.as_slice()) {
        return Err(mismatch(DB_CRT_FILE, "another certificate"));
    }
    let esl = file(DB_ESL_FILE)?;
    match loader_logic::secure_boot::database_holds_cert(esl, &wanted, sha256) {
        Ok(true) => {}
        Ok(false) => return Err(mismatch(DB_ESL_FILE, "the list holds another certificate")),
        Err(_) => return Err(mismatch(DB_ESL_FILE, "not an EFI signature list")),
    }
    if !file(DB_AUTH_FILE)?.ends_with(esl) {
        return Err(mismatch(DB_AUTH_FILE, "it does not carry the .esl's list"));
    }
    let second_stage = if files.iter().any(|(path, _)| path == SECOND_STAGE_PATH) {
        SECOND_STAGE_PATH
    } else {
        REMOVABLE_BOOT_PATH
    };
    let loader = file(second_stage)?;
    if pe_section(loader, CERT_HASH_SECTION).map(|bytes| &bytes[..32]) != Some(&wanted[..]) {
        return Err(mismatch(
            second_stage,
            "its .kcert is not the certificate's SHA-256",
        ));
    }
    for name in [second_stage, REMOVABLE_BOOT_PATH] {
        signed_by(file(name)?, key).map_err(|reason| mismatch(name, &reason))?;
    }
    Ok(())
}

/// Whether one of the PE image's signatures is the key's and verifies
/// (sbverify). sbverify alone is not enough on an image with several
/// signatures, shim's: it accepts Microsoft's whatever certificate it is
/// given. So the signature holding the certificate is found, every other is
/// removed from a copy, and that copy is verified.
fn signed_by(image: &[u8], key: &SigningKey) -> std::result::Result<(), String> {
    let scratch = scratch_dir().map_err(|e| e.to_string())?;
    let path = scratch.path().join("image.efi");
    std::fs::write(&path, image).map_err(|e| e.to_string())?;
    let listed = tool_output(Command::new("sbverify").arg("--list").arg(&path))?;
    let count = String::from_utf8_lossy(&listed)
        .lines()
        .filter(|line| line.starts_with("signature "))
        .count();
    let signature = scratch.path().join("signature.p7");
    let ours = (1..=count).find(|&number| {
        let _ = std::fs::remove_file(&signature);
        tool_output(
            Command::new("sbattach")
                .arg("--detach")
                .arg(&signature)
                .args(["--signum", &number.to_string()])
                .arg(&path),
        )
        .is_ok()
            && std::fs::read(&signature).is_ok_and(|bytes| {
                bytes
                    .windows(key.cert_der.len())
                    .any(|window| window == key.cert_der)
            })
    });
    let Some(ours) = ours else {
        return Err(format!("none of its {count} signatures is by this key"));
    };
    // The signatures before ours go; each removal renumbers the rest.
    for _ in 1..ours {
        tool_output(
            Command::new("sbattach")
                .args(["--remove", "--signum", "1"])
                .arg(&path),
        )?;
    }
    // And those after it.
    for _ in ours..count {
        tool_output(
            Command::new("sbattach")
                .args(["--remove", "--signum", "2"])
                .arg(&path),
        )?;
    }
    tool_output(
        Command::new("sbverify")
            .arg("--cert")
            .arg(&key.cert)
            .arg(&path),
    )
    .map(|_| ())
    .map_err(|detail| format!("sbverify: {detail}"))
}

/// The DER bytes of a PEM certificate's first block.
fn pem_to_der(pem: &str) -> Option<Vec<u8>> {
    let body: String = pem
        .lines()
        .skip_while(|line| !line.starts_with("-----BEGIN CERTIFICATE"))
        .skip(1)
        .take_while(|line| !line.starts_with("-----END"))
        .collect();
    base64_decode(body.trim())
}

fn base64_decode(text: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let bytes: Vec<u8> = text.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(bytes.len() * 3 / 4);
    for chunk in bytes.chunks(4) {
        let mut word = 0u32;
        for (at, &c) in chunk.iter().enumerate() {
            word |= value(c)? << (18 - 6 * at);
        }
        out.extend(&word.to_be_bytes()[1..chunk.len()]);
    }
    Some(out)
}

/// Writes `bytes` to `path` whole: a temporary file beside it, renamed into
/// place, so no half-written image is ever there.
pub fn write_whole(path: &Path, bytes: &[u8]) -> Result<()> {
    let partial = path.with_extension(format!("partial.{}", std::process::id()));
    let result = std::fs::write(&partial, bytes).and_then(|()| std::fs::rename(&partial, path));
    if let Err(error) = result {
        let _ = std::fs::remove_file(&partial);
        return Err(SecureBootError::Write {
            path: path.to_owned(),
            error,
        });
    }
    Ok(())
}

/// The signed stick's file name in `target/images/`.
pub const SIGNED_IMAGE_NAME: &str = "modex-cube-secure-boot.img";

/// The EFI system partition of a disk laid out by `disk_layout::hybrid_image`:
/// the MBR's second entry.
pub fn esp_of_disk(disk: &[u8]) -> Option<&[u8]> {
    let entry = disk.get(446 + 16..446 + 32)?;
    let start = u32::from_le_bytes(entry[8..12].try_into().ok()?) as usize;
    let sectors = u32::from_le_bytes(entry[12..16].try_into().ok()?) as usize;
    disk.get(start * disk_layout::SECTOR..(start + sectors) * disk_layout::SECTOR)
}

/// The certificate on a signed stick (its `.cer` file).
pub fn cert_of_image(image: &Path) -> Result<Vec<u8>> {
    let disk = std::fs::read(image).map_err(|error| SecureBootError::Unreadable {
        what: "the image",
        path: image.to_owned(),
        error,
        fix: "build it again with --secure-boot",
    })?;
    let esp = esp_of_disk(&disk)
        .ok_or_else(|| SecureBootError::Esp(format!("{} has no ESP", image.display())))?;
    fat_files(esp)?
        .into_iter()
        .find(|(path, _)| path == ENROLL_FILE_NAME)
        .map(|(_, bytes)| bytes)
        .ok_or_else(|| {
            SecureBootError::Esp(format!("{} has no {ENROLL_FILE_NAME}", image.display()))
        })
}

/// OVMF's Secure Boot build (SMM, variables in a second flash).
pub const OVMF_SECURE_BOOT_CODE: &str = "/usr/share/OVMF/OVMF_CODE_4M.secboot.fd";
/// OVMF's variables with Microsoft's keys enrolled and Secure Boot on.
pub const OVMF_MICROSOFT_VARS: &str = "/usr/share/OVMF/OVMF_VARS_4M.ms.fd";

/// OVMF's variables with no keys (setup mode): what virt-fw-vars enrolls a
/// key set onto.
pub const OVMF_BLANK_VARS: &str = "/usr/share/OVMF/OVMF_VARS_4M.fd";

/// Which PC the runner's `--secure-boot` plays: the keys in its firmware's
/// variables (issue 48).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum KeySet {
    /// Microsoft's 2011 KEK and `db` (Windows Production PCA 2011, UEFI CA
    /// 2011), OVMF's `.ms` variables as Debian ships them: most PCs in use.
    /// Shim starts by its 2011 signature; the user's key goes in MokList
    /// through MokManager.
    #[default]
    #[value(name = "2011")]
    Microsoft2011,
    /// Only Microsoft's 2023 keys (KEK CA 2023, `db` the Microsoft UEFI CA
    /// 2023: virt-fw-vars's `uefi23`), as on PCs made since 2023. Shim starts
    /// by its 2023 signature; the user's key goes in MokList through
    /// MokManager.
    #[value(name = "2023")]
    Microsoft2023,
    /// Microsoft's third-party CA off (KEK CA 2023, `db` the Windows UEFI
    /// CA 2023 only: `win23`) and the user's certificate added to `db`:
    /// shim and the loader start by the user's signature alone.
    User,
}

impl KeySet {
    /// The variables file's name under the runner's `target/secure-boot/`.
    pub fn vars_file_name(self) -> &'static str {
        match self {
            // Today's name, so a key enrolled before key sets existed stays.
            KeySet::Microsoft2011 => "OVMF_VARS_4M.ms.fd",
            KeySet::Microsoft2023 => "OVMF_VARS_4M.2023.fd",
            KeySet::User => "OVMF_VARS_4M.user-db.fd",
        }
    }

    /// The virt-fw-vars arguments that enroll Microsoft's part of the set
    /// onto [`OVMF_BLANK_VARS`] and switch Secure Boot on (the 2011 set is a
    /// copy of OVMF's own file instead: none).
    pub fn microsoft_enrollment(self) -> &'static [&'static str] {
        match self {
            KeySet::Microsoft2011 => &[],
            KeySet::Microsoft2023 => &[
                "--enroll-microsoft",
                "--microsoft-kek",
                "2023",
                "--microsoft-db",
                "uefi23",
                "--sb",
            ],
            KeySet::User => &[
                "--enroll-microsoft",
                "--microsoft-kek",
                "2023",
                "--microsoft-db",
                "win23",
                "--sb",
            ],
        }
    }

    /// Whether the user's certificate reaches the firmware through
    /// MokManager (shim's route) rather than by the set itself.
    pub fn enrolls_through_mokmanager(self) -> bool {
        self != KeySet::User
    }
}

/// virt-fw-vars (PyPI's virt-firmware): the venv `boot/setup.sh` makes in
/// `target/tools/virt-firmware`, else one on `PATH`.
pub fn virt_fw_vars() -> Result<PathBuf> {
    let venv =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("target/tools/virt-firmware/bin/virt-fw-vars");
    if venv.is_file() {
        return Ok(venv);
    }
    let on_path = std::env::var_os("PATH").and_then(|path| {
        std::env::split_paths(&path)
            .map(|dir| dir.join("virt-fw-vars"))
            .find(|tool| tool.is_file())
    });
    on_path.ok_or_else(|| SecureBootError::Tool {
        tool: "virt-fw-vars",
        detail: format!(
            "not in {} nor on PATH; boot/setup.sh installs it (PyPI's virt-firmware)",
            venv.display()
        ),
    })
}

/// The runner's Secure Boot variables for `keys` in `dir` (kept there, so
/// what MokManager enrolls stays), made from the system's OVMF files when
/// missing, and for the user set made again when `db` lacks the stick's
/// certificate. Returns the file and whether the stick's certificate is
/// already enrolled (in `db` or MokList).
pub fn runner_vars(dir: &Path, keys: KeySet, image: &Path) -> Result<(PathBuf, bool)> {
    std::fs::create_dir_all(dir).map_err(|error| SecureBootError::Write {
        path: dir.to_owned(),
        error,
    })?;
    let vars = dir.join(keys.vars_file_name());
    let cert = cert_of_image(image)?;
    let enrolled = |vars: &Path| std::fs::read(vars).is_ok_and(|bytes| is_enrolled(&bytes, &cert));
    if vars.exists() && (keys.enrolls_through_mokmanager() || enrolled(&vars)) {
        return Ok((vars.clone(), enrolled(&vars)));
    }
    let unreadable = |path: &str, error| SecureBootError::Unreadable {
        what: "OVMF's variables",
        path: PathBuf::from(path),
        error,
        fix: "install OVMF with boot/setup.sh",
    };
    let fresh = if keys == KeySet::Microsoft2011 {
        std::fs::read(OVMF_MICROSOFT_VARS).map_err(|e| unreadable(OVMF_MICROSOFT_VARS, e))?
    } else {
        std::fs::metadata(OVMF_BLANK_VARS).map_err(|e| unreadable(OVMF_BLANK_VARS, e))?;
        let scratch = scratch_dir()?;
        let made = scratch.path().join(keys.vars_file_name());
        let mut command = Command::new(virt_fw_vars()?);
        command
            .args(["--input", OVMF_BLANK_VARS, "--output"])
            .arg(&made)
            .args(keys.microsoft_enrollment());
        if keys == KeySet::User {
            let cert_file = scratch.path().join(DB_CER_FILE);
            write(&cert_file, &cert)?;
            command.args(["--add-db", KEY_OWNER_GUID]).arg(&cert_file);
        }
        run_tool("virt-fw-vars", &mut command)?;
        read_back(&made)?
    };
    write_whole(&vars, &fresh)?;
    Ok((vars.clone(), enrolled(&vars)))
}

/// Whether the certificate is in the variable store: in MokList (enrolled
/// through MokManager) or in `db`. Both keep the DER bytes whole.
pub fn is_enrolled(vars: &[u8], cert_der: &[u8]) -> bool {
    !cert_der.is_empty() && vars.windows(cert_der.len()).any(|w| w == cert_der)
}

/// What `openssl ARGS path` prints; a failure says the file is not `what`.
fn openssl_reading(path: &Path, what: &'static str, args: &[&str]) -> Result<Vec<u8>> {
    tool_output(Command::new("openssl").args(args).arg(path)).map_err(|detail| {
        SecureBootError::BadFile {
            path: path.to_owned(),
            what,
            detail,
        }
    })
}

fn scratch_dir() -> Result<tempfile::TempDir> {
    tempfile::Builder::new()
        .prefix("modex-cube-sign-")
        .tempdir()
        .map_err(|error| SecureBootError::Write {
            path: std::env::temp_dir(),
            error,
        })
}

fn write(path: &Path, bytes: &[u8]) -> Result<()> {
    std::fs::write(path, bytes).map_err(|error| SecureBootError::Write {
        path: path.to_owned(),
        error,
    })
}

fn read_back(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|error| SecureBootError::Unreadable {
        what: "a tool's output",
        path: path.to_owned(),
        error,
        fix: "see the tool's message above",
    })
}

fn tool_output(command: &mut Command) -> std::result::Result<Vec<u8>, String> {
    let output = command
        .output()
        .map_err(|e| format!("cannot run {:?}: {e}", command.get_program()))?;
    if output.status.success() {
        Ok(output.stdout)
    } else {
        Err(String::from_utf8_lossy(&output.stderr).trim().to_owned())
    }
}

fn run_tool(tool: &'static str, command: &mut Command) -> Result<()> {
    let output = command.output().map_err(|e| SecureBootError::Tool {
        tool,
        detail: format!("cannot run it ({e}); boot/setup.sh installs it"),
    })?;
    if output.status.success() {
        Ok(())
    } else {
        Err(SecureBootError::Tool {
            tool,
            detail: String::from_utf8_lossy(&output.stderr).trim().to_owned(),
        })
    }
}
