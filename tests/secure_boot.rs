//! The signed stick (boot/secure_boot.rs) under Secure Boot: OVMF's Secure
//! Boot build with Microsoft's keys, where only shim is trusted until the
//! user enrolls their key through MokManager; our certificate in `db`; a
//! loader signed by another key; and the same stick without Secure Boot.
//! Host tests: the key made once, the `.sbat` section, bad input.

mod common;

use boot::secure_boot::{self as sb, KeySet, Route, SecureBootError, SigningKey};
use boot::{Board, Firmware, Qemu, QemuOptions};
use demo::command::{Command, SceneCommand};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// OVMF's Secure Boot build with SMM under TCG, on a loaded machine.
const SECURE_BOOT_TIMEOUT: Duration = Duration::from_secs(300);

/// A key made for one test, in its own folder.
fn test_key(dir: &Path) -> SigningKey {
    sb::make_or_reuse_key(dir).expect("openssl makes a key").0
}

fn shim() -> sb::Shim {
    sb::Shim::read(&sb::default_shim_dir()).unwrap_or_else(|e| panic!("{e}"))
}

fn pieces() -> sb::BuiltPieces {
    boot::images::publish().expect("the build script made the images");
    sb::BuiltPieces::of_this_build().unwrap()
}

/// A signed stick in `dir`, and its path.
fn signed_stick(dir: &Path, key: &SigningKey, route: Route) -> PathBuf {
    let disk = sb::signed_disk(&pieces(), key, Some(&shim()), route).unwrap();
    let path = dir.join(format!("{route:?}.img"));
    sb::write_whole(&path, &disk).unwrap();
    path
}

/// Where a certificate is enrolled in a copy of OVMF's variables.
#[derive(Clone, Copy)]
enum Enrolled {
    /// In `db`: the firmware itself trusts what it signs.
    Db,
    /// In shim's MOK list: shim trusts what it signs.
    Mok,
}

/// OVMF's variables with Microsoft's keys, and `key`'s certificate enrolled
/// as `how` (written with virt-fw-vars, which boot/setup.sh installs), at
/// `path`.
fn microsoft_vars_with(path: &Path, how: Enrolled, key: &SigningKey) -> PathBuf {
    let (flag, owner) = match how {
        Enrolled::Db => ("--add-db", sb::KEY_OWNER_GUID),
        Enrolled::Mok => ("--add-mok", sb::SHIM_LOCK_GUID),
    };
    common::vars_from(
        sb::OVMF_MICROSOFT_VARS,
        path,
        &[flag.as_ref(), owner.as_ref(), key.cert.as_os_str()],
    )
}

fn secure_boot(image: &Path, vars: &Path) -> Qemu {
    let mut options = QemuOptions::new(image);
    options.firmware = Firmware::Uefi;
    options.board = Board::Q35;
    options.secure_boot_vars = Some(vars.to_owned());
    options.keep_after_power_off = true;
    options.debug_exit = false;
    Qemu::start(&options).unwrap_or_else(|e| panic!("{e}"))
}

fn file_on_disk(disk: &[u8], wanted: &str) -> Vec<u8> {
    let esp = sb::esp_of_disk(disk).expect("an ESP");
    sb::fat_files(esp)
        .unwrap()
        .into_iter()
        .find(|(path, _)| path == wanted)
        .unwrap_or_else(|| panic!("no {wanted} on the stick"))
        .1
}

/// Where the MokManager screenshots go: target/secure-boot-screens/, or,
/// with `MODEX_CUBE_UPDATE_DOCS_PICTURES=1`, the documentation's
/// docs/secure-boot/ (a test run leaves the sources alone otherwise).
fn docs_picture(name: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = if std::env::var_os("MODEX_CUBE_UPDATE_DOCS_PICTURES").is_some_and(|v| v == "1") {
        root.join("docs/secure-boot")
    } else {
        root.join("target/secure-boot-screens")
    };
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn save_screen(qemu: &mut Qemu, name: &str) {
    let picture = qemu.screendump().unwrap();
    picture.write_png(&docs_picture(name)).unwrap();
}

/// Waits for `text` to have been printed `count` times on the console
/// (OVMF copies its text console, shim's and MokManager's screens included,
/// to serial).
fn wait_text(qemu: &mut Qemu, text: &str, count: usize) {
    qemu.wait_for_screen_text(text, count, SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn the_key_is_made_once_and_never_overwritten() {
    let home = tempfile::tempdir().unwrap();
    let dir = home.path().join("secure-boot");
    let (first, origin) = sb::make_or_reuse_key(&dir).unwrap();
    assert_eq!(origin, sb::KeyOrigin::Made);
    let key_bytes = std::fs::read(&first.key).unwrap();
    let (again, origin) = sb::make_or_reuse_key(&dir).unwrap();
    assert_eq!(origin, sb::KeyOrigin::Found);
    assert_eq!(again, first);
    assert_eq!(std::fs::read(&again.key).unwrap(), key_bytes);
    assert_eq!(
        std::fs::read(dir.join(sb::CERT_DER_FILE)).unwrap(),
        first.cert_der
    );
    // A folder with the key but not all of its files is not completed over.
    std::fs::remove_file(dir.join(sb::CERT_DER_FILE)).unwrap();
    let error = sb::make_or_reuse_key(&dir).unwrap_err();
    assert!(
        matches!(error, SecureBootError::IncompleteKeyFolder { .. }),
        "{error}"
    );
    assert!(error.to_string().contains(sb::CERT_DER_FILE), "{error}");
    assert_eq!(std::fs::read(dir.join(sb::KEY_FILE)).unwrap(), key_bytes);
}

#[test]
fn bad_keys_are_refused_naming_the_file_and_the_fix() {
    let scratch = tempfile::tempdir().unwrap();
    let one = test_key(&scratch.path().join("one"));
    let other = test_key(&scratch.path().join("other"));
    let missing = scratch.path().join("no-such.key");
    let error = sb::given_key(&missing, &one.cert).unwrap_err().to_string();
    assert!(error.contains("no-such.key"), "{error}");
    assert!(error.contains("--sign-key"), "{error}");
    // A folder where a file should be: opened, but unreadable.
    let error = sb::given_key(&one.key, scratch.path()).unwrap_err();
    assert!(
        matches!(error, SecureBootError::Unreadable { .. }),
        "{error}"
    );
    let error = sb::given_key(&one.key, &other.cert).unwrap_err();
    assert!(
        matches!(error, SecureBootError::KeyCertMismatch { .. }),
        "{error}"
    );
    assert!(error.to_string().contains("does not match"), "{error}");
    let error = sb::given_key(&one.cert, &one.cert).unwrap_err();
    assert!(matches!(error, SecureBootError::BadFile { .. }), "{error}");
    assert!(error.to_string().contains("private key"), "{error}");
}

/// The runner itself, with a missing shim or a bad key: it refuses, naming
/// the file and the fix, and leaves no image behind.
#[test]
fn the_runner_refuses_bad_input_and_leaves_no_image() {
    let scratch = tempfile::tempdir().unwrap();
    let target = scratch.path().join("target");
    let key = test_key(&scratch.path().join("key"));
    let run = |args: &[&std::ffi::OsStr], shim_dir: &Path| {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_modex-cube"))
            .args(args)
            .env("CARGO_TARGET_DIR", &target)
            .env(sb::SHIM_DIR_VARIABLE, shim_dir)
            .env(sb::KEY_DIR_VARIABLE, scratch.path().join("unused-key-dir"))
            .output()
            .unwrap();
        assert!(!output.status.success());
        String::from_utf8_lossy(&output.stderr).into_owned()
    };
    let empty = scratch.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fn sign<'a>(key: &'a Path, cert: &'a Path) -> [&'a std::ffi::OsStr; 8] {
        [
            "--sign-key".as_ref(),
            key.as_os_str(),
            "--sign-cert".as_ref(),
            cert.as_os_str(),
            "--image".as_ref(),
            "one".as_ref(),
            "--write-usb".as_ref(),
            "/nonexistent-device".as_ref(),
        ]
    }
    let message = run(&sign(&key.key, &key.cert), &empty);
    assert!(message.contains("shimx64.efi"), "{message}");
    assert!(message.contains("boot/setup.sh"), "{message}");
    let missing = scratch.path().join("missing.crt");
    let message = run(&sign(&key.key, &missing), &sb::default_shim_dir());
    assert!(message.contains("missing.crt"), "{message}");
    assert!(
        !target.join("images").join(sb::SIGNED_IMAGE_NAME).exists(),
        "an image was left"
    );
    let leftovers: Vec<_> = std::fs::read_dir(target.join("images"))
        .map(|dir| dir.flatten().map(|e| e.file_name()).collect())
        .unwrap_or_default();
    assert!(
        leftovers
            .iter()
            .all(|name| !name.to_string_lossy().contains("secure-boot")),
        "{leftovers:?}"
    );
}

/// The stick's files: shim, MokManager, the loader with its `.sbat` section
/// and a signature sbverify accepts with the certificate, the certificate as
/// the `.cer` file; and never the private key, in any form.
#[test]
fn the_stick_holds_shim_the_signed_loader_and_the_certificate_but_no_private_key() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Shim);
    let disk = std::fs::read(&stick).unwrap();
    let shim = shim();
    // Shim as Debian ships it, with the user's signature added after
    // Microsoft's (issue 39): its code and SBAT data unchanged.
    let stick_shim = file_on_disk(&disk, sb::REMOVABLE_BOOT_PATH);
    for section in [".text", ".sbat", ".data"] {
        assert_eq!(
            sb::pe_section(&stick_shim, section),
            sb::pe_section(&shim.shim, section),
            "{section}"
        );
        assert!(sb::pe_section(&shim.shim, section).is_some(), "{section}");
    }
    assert_eq!(file_on_disk(&disk, sb::MOK_MANAGER_PATH), shim.mok_manager);
    assert_eq!(file_on_disk(&disk, sb::ENROLL_FILE_NAME), key.cert_der);
    let loader = file_on_disk(&disk, sb::SECOND_STAGE_PATH);
    assert_eq!(
        sb::pe_section(&loader, ".sbat"),
        Some(sb::SBAT_CSV.as_bytes())
    );
    let loader_path = scratch.path().join("grubx64.efi");
    std::fs::write(&loader_path, &loader).unwrap();
    let verified = std::process::Command::new("sbverify")
        .arg("--cert")
        .arg(&key.cert)
        .arg(&loader_path)
        .status()
        .expect("sbverify (boot/setup.sh installs sbsigntool)");
    assert!(verified.success());
    // The private key: its PEM file, its DER form, and its modulus-bearing
    // base64 lines.
    let pem = std::fs::read_to_string(&key.key).unwrap();
    let der = std::process::Command::new("openssl")
        .args(["pkey", "-outform", "DER", "-in"])
        .arg(&key.key)
        .output()
        .unwrap()
        .stdout;
    assert!(der.len() > 1000);
    let contains = |needle: &[u8]| disk.windows(needle.len()).any(|w| w == needle);
    assert!(!contains(&der), "the key's DER is on the stick");
    for line in pem.lines().filter(|line| !line.starts_with("-----")) {
        assert!(
            !contains(line.as_bytes()),
            "a line of the key is on the stick"
        );
    }
    // The BIOS route is the built image's: same boot sector and stage 2.
    let built = pieces();
    assert_eq!(disk[..440], built.boot_sector[..440]);
}

#[test]
fn the_signed_stick_boots_under_seabios_and_under_ovmf_without_secure_boot() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Shim);
    for firmware in [Firmware::Bios, Firmware::Uefi] {
        let mut options = QemuOptions::new(&stick);
        options.firmware = firmware;
        if firmware == Firmware::Uefi {
            options.board = Board::Q35;
        }
        let mut qemu = Qemu::start(&options).unwrap();
        let console = qemu
            .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
            .unwrap_or_else(|e| panic!("{firmware:?}: {e}"));
        // The report says so (issue 39): no Secure Boot under BIOS; under
        // OVMF's plain build, whose blank variables have no platform key,
        // setup mode; never "on".
        let state = match firmware {
            Firmware::Bios => "not UEFI",
            Firmware::Uefi => "setup mode",
            // 32-bit OVMF's empty variables (tests/uefi32.rs).
            Firmware::Uefi32 => "setup mode",
        };
        let row = format!("Secure Boot: {state}");
        assert!(
            console
                .lines()
                .any(|text| text.trim_end() == format!("{}{row}", boot::line::MACHINE_FACT)),
            "{console}"
        );
        qemu.send_key("i").unwrap();
        let done = boot::line::CommandDone(1).to_string();
        let console = qemu.wait_for_serial(&done, SECURE_BOOT_TIMEOUT).unwrap();
        let shown = common::ShownReport::parse(&console);
        assert!(shown.facts.contains(&row), "{:?}", shown.facts);
        let codes = common::decode_qr_codes(&qemu.screendump().unwrap());
        assert_eq!(codes, [shown.qr_text()], "{firmware:?}");
        assert!(codes[0].contains(&row), "{}", codes[0]);
    }
}

/// Our certificate in `db` (written with virt-fw-vars): the firmware starts
/// the signed loader itself, no shim.
#[test]
fn with_our_certificate_in_db_the_loader_boots_without_shim() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Direct);
    let disk = std::fs::read(&stick).unwrap();
    assert!(sb::pe_section(&file_on_disk(&disk, sb::REMOVABLE_BOOT_PATH), ".sbat").is_some());
    let vars = microsoft_vars_with(&scratch.path().join("vars-with-db.fd"), Enrolled::Db, &key);
    assert!(sb::is_enrolled(
        &std::fs::read(&vars).unwrap(),
        &key.cert_der
    ));
    let mut qemu = secure_boot(&stick, &vars);
    qemu.wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
}

/// The certificates' subjects in a variables file's `name` variable (KEK,
/// db), as `virt-fw-vars --print --verbose` lists them.
fn subjects_in(vars: &Path, name: &str) -> Vec<String> {
    let listing = common::run_virt_fw_vars(&[
        "--input".as_ref(),
        vars.as_os_str(),
        "--print".as_ref(),
        "--verbose".as_ref(),
    ]);
    let header = format!("name={name} ");
    listing
        .lines()
        .skip_while(|line| !line.starts_with(&header))
        .skip(1)
        .take_while(|line| !line.starts_with("name="))
        .filter_map(|line| line.trim().strip_prefix("subject "))
        .map(str::to_owned)
        .collect()
}

/// The runner's variables for each `--secure-boot` key set hold exactly
/// that set's KEK and `db`, with Secure Boot on (a platform key), and the
/// user's certificate only where the set puts it.
#[test]
fn each_runner_key_set_holds_its_kek_and_db() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Shim);
    let ours = "CN=modex-cube Secure Boot key of";
    let cases: [(KeySet, &str, &[&str], bool); 3] = [
        (
            KeySet::Microsoft2011,
            "CN=Microsoft Corporation KEK CA 2011",
            &[
                "CN=Microsoft Windows Production PCA 2011",
                "CN=Microsoft Corporation UEFI CA 2011",
            ],
            false,
        ),
        (
            KeySet::Microsoft2023,
            "CN=Microsoft Corporation KEK 2K CA 2023",
            &["CN=Microsoft UEFI CA 2023"],
            false,
        ),
        (
            KeySet::User,
            "CN=Microsoft Corporation KEK 2K CA 2023",
            &["CN=Windows UEFI CA 2023", ours],
            true,
        ),
    ];
    for (keys, kek, db, in_db) in cases {
        let dir = scratch.path().join(keys.vars_file_name());
        let (vars, enrolled) = sb::runner_vars(&dir, keys, &stick).unwrap();
        assert_eq!(enrolled, in_db, "{keys:?}");
        assert_eq!(vars.file_name().unwrap(), keys.vars_file_name());
        assert!(
            subjects_in(&vars, "KEK").iter().any(|s| s == kek),
            "{keys:?}: KEK {:?}",
            subjects_in(&vars, "KEK")
        );
        let found = subjects_in(&vars, "db");
        assert_eq!(found.len(), db.len(), "{keys:?}: db {found:?}");
        for (found, wanted) in found.iter().zip(db) {
            assert!(found.starts_with(wanted), "{keys:?}: db {found:?}");
        }
        assert_eq!(subjects_in(&vars, "PK").len(), 1, "{keys:?}: setup mode");
        // Made once: a second run keeps the file (and what MokManager
        // wrote into it).
        let before = std::fs::metadata(&vars).unwrap().modified().unwrap();
        sb::runner_vars(&dir, keys, &stick).unwrap();
        let after = std::fs::metadata(&vars).unwrap().modified().unwrap();
        assert_eq!(before, after, "{keys:?}: made again");
    }
    // A stick signed with another key: the user set's db is made again to
    // hold that key, where the user set's PC would refuse the stick.
    let other = test_key(&scratch.path().join("other"));
    let other_stick = scratch.path().join("other");
    let other_stick = signed_stick(&other_stick, &other, Route::Shim);
    let dir = scratch.path().join(KeySet::User.vars_file_name());
    let (vars, enrolled) = sb::runner_vars(&dir, KeySet::User, &other_stick).unwrap();
    assert!(enrolled);
    let db = std::fs::read(&vars).unwrap();
    assert!(sb::is_enrolled(&db, &other.cert_der));
    assert!(!sb::is_enrolled(&db, &key.cert_der));
}

/// A first boot on a PC that trusts only Microsoft's 2011 keys, the
/// runner's plain `--secure-boot` (`2011`): shim refuses the loader
/// ("Verification failed") and starts MokManager, where the user enrolls the
/// stick's certificate with the keyboard alone; the next boot, Secure Boot
/// still enforced, reaches the cube, the report says "on (shim, your key)",
/// its keys work, and Esc powers off.
#[test]
fn key_set_2011_mokmanager_enrolls_the_key_then_the_cube_boots() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Shim);
    let (vars, enrolled) = sb::runner_vars(scratch.path(), KeySet::Microsoft2011, &stick)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(!enrolled);
    assert!(!sb::is_enrolled(
        &std::fs::read(&vars).unwrap(),
        &key.cert_der
    ));

    let mut qemu = secure_boot(&stick, &vars);
    wait_text(&mut qemu, "Verification failed", 1);
    save_screen(&mut qemu, "1-verification-failed.png");
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "Press any key to perform MOK management", 1);
    save_screen(&mut qemu, "2-press-any-key.png");
    qemu.send_key("spc").unwrap();
    wait_text(&mut qemu, "Enroll key from disk", 1);
    save_screen(&mut qemu, "3-mok-management.png");
    qemu.send_key("down").unwrap();
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "Select Key", 1);
    save_screen(&mut qemu, "4-select-the-disk.png");
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, sb::ENROLL_FILE_NAME, 1);
    save_screen(&mut qemu, "5-select-the-file.png");
    // The certificate is the first file, already highlighted.
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "View key 0", 1);
    save_screen(&mut qemu, "6-enroll-mok.png");
    qemu.send_key("down").unwrap();
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "Enroll the key(s)?", 1);
    save_screen(&mut qemu, "7-enroll-the-keys.png");
    qemu.send_key("down").unwrap();
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "Reboot", 1);
    save_screen(&mut qemu, "8-reboot.png");
    qemu.send_key("ret").unwrap();
    // QEMU's -no-reboot turns the reset into a stop (-no-shutdown keeps
    // QEMU for the screendumps).
    qemu.wait_powered_off(SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("MokManager's reboot did not happen: {e}"));
    drop(qemu);
    assert!(sb::is_enrolled(
        &std::fs::read(&vars).unwrap(),
        &key.cert_der
    ));

    let mut qemu = secure_boot(&stick, &vars);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert!(!console.contains("Verification failed"), "{console}");
    assert!(
        console.contains("loader: kernel SHA-256 matches the loader's"),
        "{console}"
    );
    let fact = format!(
        "{}Secure Boot: on (shim, your key)",
        boot::line::MACHINE_FACT
    );
    assert!(
        console.lines().any(|text| text.trim_end() == fact),
        "no {fact:?} in {console}"
    );
    save_screen(&mut qemu, "9-the-cube.png");
    common::after_each_key_on(
        &mut qemu,
        &[
            ("r", Command::Scene(SceneCommand::Reset)),
            ("n", Command::Scene(SceneCommand::NextSolid)),
        ],
        |screen, model, _app, what| {
            let expected = common::presented(model, screen.width, screen.height);
            common::assert_pictures_equal(screen, &expected, what);
        },
    );
    common::escape_leaves_the_goodbye_on_the_framebuffer(&mut qemu, "secure boot goodbye");
}

/// A loader signed by a key that was never enrolled: shim refuses it with
/// "Verification failed: (0x1A) Security Violation" on screen and starts
/// MokManager instead; the cube never starts.
#[test]
fn a_loader_signed_by_another_key_is_refused_by_shim() {
    let scratch = tempfile::tempdir().unwrap();
    let enrolled = test_key(&scratch.path().join("enrolled"));
    let other = test_key(&scratch.path().join("other"));
    let stick = signed_stick(scratch.path(), &other, Route::Shim);
    let vars = microsoft_vars_with(
        &scratch.path().join("vars-with-mok.fd"),
        Enrolled::Mok,
        &enrolled,
    );
    let mut qemu = secure_boot(&stick, &vars);
    // Shim draws its box a piece at a time: wait for the end of the message.
    let console = qemu
        .wait_for_screen_text("Security Violation", 1, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert!(console.contains("Verification failed"), "{console}");
    save_screen(&mut qemu, "refused-another-key.png");
    qemu.send_key("ret").unwrap();
    wait_text(&mut qemu, "Press any key to perform MOK management", 1);
    assert!(!qemu.serial().contains(boot::READY_LINE));
}

/// The hash the runner writes into the loader before signing it is the
/// SHA-256 of the kernel file on the same stick; the unsigned images' loader
/// carries the same (issue 48: every stick is checked).
#[test]
fn the_signed_loader_carries_the_sha256_of_the_kernel_on_the_stick() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let disk = std::fs::read(signed_stick(scratch.path(), &key, Route::Shim)).unwrap();
    let loader = file_on_disk(&disk, sb::SECOND_STAGE_PATH);
    let kernel = file_on_disk(&disk, sb::KERNEL_FILE_NAME);
    let embedded = sb::loader_kernel_hash(&loader).expect("a hash slot");
    assert_eq!(embedded[..32], sb::sha256(&kernel));
    // And as the field's tool computes it.
    std::fs::write(scratch.path().join("kernel"), &kernel).unwrap();
    let output = std::process::Command::new("sha256sum")
        .arg(scratch.path().join("kernel"))
        .output()
        .unwrap();
    let hex: String = embedded[..32].iter().map(|b| format!("{b:02x}")).collect();
    assert!(String::from_utf8_lossy(&output.stdout).starts_with(&hex));
    let built = pieces();
    let unsigned = sb::fat_files(&built.esp)
        .unwrap()
        .into_iter()
        .find(|(path, _)| path.eq_ignore_ascii_case(sb::REMOVABLE_BOOT_PATH))
        .unwrap()
        .1;
    assert_eq!(sb::loader_kernel_hash(&unsigned), Some(sb::sha256(&kernel)));
}

/// One byte of the kernel file changed on the stick's FAT: the signed
/// loader refuses it before it runs, with the reason on the screen (the
/// UEFI console, which OVMF also copies to serial) and on COM1.
#[test]
fn a_tampered_kernel_is_refused_by_the_signed_loader() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key, Route::Direct);
    let disk = common::with_a_kernel_byte_changed(&std::fs::read(&stick).unwrap());
    let tampered = scratch.path().join("tampered.img");
    std::fs::write(&tampered, &disk).unwrap();
    assert_ne!(
        sb::sha256(&file_on_disk(&disk, sb::KERNEL_FILE_NAME)),
        sb::loader_kernel_hash(&file_on_disk(&disk, sb::REMOVABLE_BOOT_PATH)).unwrap()
    );

    let vars = microsoft_vars_with(&scratch.path().join("vars-with-db.fd"), Enrolled::Db, &key);
    let mut qemu = secure_boot(&tampered, &vars);
    // Through the UEFI console (the screen, which OVMF copies to COM1).
    let refused = "loader: damaged file: kernel-x86_64 (the kernel): SHA-256 expected";
    wait_text(&mut qemu, refused, 1);
    let screen = qemu.screendump().unwrap();
    screen
        .write_png(&docs_picture("refused-tampered-kernel.png"))
        .unwrap();
    assert!(
        screen.pixels.iter().any(|&p| p != screen.pixels[0]),
        "a blank screen"
    );
    assert!(!qemu.serial().contains(boot::READY_LINE));
}
