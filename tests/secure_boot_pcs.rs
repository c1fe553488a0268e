//! The signed stick on the PCs of issue 39, each made with virt-fw-vars
//! (installed by boot/setup.sh) from OVMF's blank variables: one that trusts
//! only Microsoft's 2023 CAs; one with the third-party CA switched off
//! (Windows' CA only), which refuses shim until the user's certificate is in
//! `db`; a `db` made from the stick's own `.esl` in setup mode; and the
//! Secure Boot row of the report screen and its QR code on each. Host
//! tests: the certificate files, and a stick whose files do not match.

mod common;

use boot::secure_boot::{self as sb, KeySet, Route, SecureBootError, SigningKey};
use boot::{line, Board, Firmware, Qemu, QemuOptions};
use demo::command::{Command, SceneCommand};
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// OVMF's Secure Boot build with SMM under TCG, on a loaded machine.
const SECURE_BOOT_TIMEOUT: Duration = Duration::from_secs(300);

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

/// The runner's stick (the shim route), in `dir`.
fn signed_stick(dir: &Path, key: &SigningKey) -> PathBuf {
    let disk = sb::signed_disk(&pieces(), key, Some(&shim()), Route::Shim).unwrap();
    let path = dir.join("stick.img");
    sb::write_whole(&path, &disk).unwrap();
    path
}

/// OVMF's blank variables with `args` applied by virt-fw-vars, at `path`.
fn vars(path: &Path, args: &[&OsStr]) -> PathBuf {
    common::vars_from(sb::OVMF_BLANK_VARS, path, args)
}

/// Microsoft's keys as a PC of these years ships them, Secure Boot on, as
/// the runner's key sets enroll them: `KeySet::User`'s without the user's
/// certificate (the Windows CA 2023 only: the third-party CA off), or
/// `KeySet::Microsoft2023`'s (the UEFI CA 2023, third-party); KEK is 2023's.
fn microsoft_2023(path: &Path, keys: KeySet, extra: &[&OsStr]) -> PathBuf {
    let mut args: Vec<&OsStr> = keys
        .microsoft_enrollment()
        .iter()
        .map(|arg| arg.as_ref())
        .collect();
    args.extend_from_slice(extra);
    vars(path, &args)
}

/// The runner's variables for `keys` (`--secure-boot KEYS`), made in `dir`
/// for `stick`, and whether the stick's certificate is enrolled in them.
fn runner_vars(dir: &Path, keys: KeySet, stick: &Path) -> (PathBuf, bool) {
    sb::runner_vars(dir, keys, stick).unwrap_or_else(|e| panic!("{keys:?}: {e}"))
}

/// The user's certificate added to shim's MokList in `vars`, as MokManager
/// enrolls it (tests/secure_boot.rs walks MokManager itself).
fn enroll_in_mok(vars: &Path, key: &SigningKey) {
    common::run_virt_fw_vars(&[
        "--inplace".as_ref(),
        vars.as_os_str(),
        "--add-mok".as_ref(),
        sb::SHIM_LOCK_GUID.as_ref(),
        key.cert.as_os_str(),
    ]);
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

fn screens_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/secure-boot-screens");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// At the ready line: two cube keys give the software VGA's pictures, the
/// report screen's Secure Boot row (and its QR code) says `state`, and Esc
/// powers off.
fn cube_keys_report_and_escape(qemu: &mut Qemu, state: &str) {
    common::after_each_key_on(
        qemu,
        &[
            ("r", Command::Scene(SceneCommand::Reset)),
            ("n", Command::Scene(SceneCommand::NextSolid)),
        ],
        |screen, model, _app, what| {
            let expected = common::presented(model, screen.width, screen.height);
            common::assert_pictures_equal(screen, &expected, what);
        },
    );
    report_says(qemu, 2, state);
    common::escape_leaves_the_goodbye_on_the_framebuffer(qemu, "secure boot goodbye");
}

/// The report key after `commands_done` commands: the report's facts hold
/// `Secure Boot: {state}`, the screen's QR code decodes to the report's text
/// (which carries that row), and the key again closes it.
fn report_says(qemu: &mut Qemu, commands_done: u64, state: &str) {
    let printed_before = qemu.serial();
    qemu.send_key("i").unwrap();
    let done = line::CommandDone(commands_done + 1).to_string();
    let console = qemu.wait_for_serial(&done, SECURE_BOOT_TIMEOUT).unwrap();
    let shown = common::ShownReport::parse(&console[printed_before.len()..]);
    let row = format!("Secure Boot: {state}");
    assert!(
        shown.facts.iter().any(|fact| fact == &row),
        "no {row:?} in {:?}",
        shown.facts
    );
    let screen = qemu.screendump().unwrap();
    let codes = common::decode_qr_codes(&screen);
    assert_eq!(codes, [shown.qr_text()], "the QR code holds the report");
    assert!(codes[0].contains(&row), "{}", codes[0]);
    qemu.send_key("i").unwrap();
    let done = line::CommandDone(commands_done + 2).to_string();
    qemu.wait_for_serial(&done, SECURE_BOOT_TIMEOUT).unwrap();
}

/// The facts row the kernel logged at boot.
fn logged_state(console: &str) -> String {
    let prefix = format!("{}Secure Boot: ", line::MACHINE_FACT);
    console
        .lines()
        .find_map(|text| text.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no Secure Boot fact:\n{console}"))
        .to_owned()
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

/// What OVMF prints when it refuses the removable disk's boot file.
const FIRMWARE_REFUSAL: &str = "Access Denied";

/// A PC with the third-party CA switched off: the firmware refuses shim
/// before any of our code runs, with its words on the screen (copied to
/// COM1 by OVMF), and the cube never starts.
#[test]
fn third_party_ca_off_the_firmware_refuses_shim() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let vars = microsoft_2023(&scratch.path().join("win23.fd"), KeySet::User, &[]);
    let mut qemu = secure_boot(&stick, &vars);
    let console = qemu
        .wait_for_screen_text(FIRMWARE_REFUSAL, 1, SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e}"));
    let screen = qemu.screendump().unwrap();
    screen
        .write_png(&screens_dir().join("refused-shim-third-party-ca-off.png"))
        .unwrap();
    assert!(
        screen.pixels.iter().any(|&p| p != screen.pixels[0]),
        "a blank screen"
    );
    // `BdsDxe: failed to load Boot0002 "UEFI QEMU HARDDISK QM00001 " from
    // PciRoot(...)/Sata(...): Access Denied`
    let refusal = console
        .lines()
        .find(|text| text.contains(FIRMWARE_REFUSAL))
        .unwrap();
    assert!(
        refusal.contains("BdsDxe: failed to load") && refusal.contains("HARDDISK"),
        "{refusal}"
    );
    assert!(!console.contains("loader: "), "{console}");
    assert!(!qemu.serial().contains(boot::READY_LINE));
}

/// The same PC with the user's certificate added to `db` (as the setup's
/// key management would), the runner's `--secure-boot user`: the same
/// stick boots, Secure Boot on, the keys act, the report says "on (your key
/// in db)", and Esc powers off.
#[test]
fn key_set_user_third_party_ca_off_with_the_key_in_db_the_stick_boots() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let (vars, enrolled) = runner_vars(scratch.path(), KeySet::User, &stick);
    assert!(enrolled, "the user set's db lacks the stick's certificate");
    let mut qemu = secure_boot(&stick, &vars);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert!(
        console.contains("loader: kernel SHA-256 matches the loader's"),
        "{console}"
    );
    assert_eq!(logged_state(&console), "on (your key in db)");
    cube_keys_report_and_escape(&mut qemu, "on (your key in db)");
}

/// On that PC, one byte of the kernel changed: the loader (started by the
/// firmware through shim, both by the key in `db`) refuses it.
#[test]
fn third_party_ca_off_with_the_key_in_db_a_changed_kernel_is_refused() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let disk = common::with_a_kernel_byte_changed(
        &std::fs::read(signed_stick(scratch.path(), &key)).unwrap(),
    );
    let tampered = scratch.path().join("tampered.img");
    std::fs::write(&tampered, &disk).unwrap();
    let (vars, _) = runner_vars(scratch.path(), KeySet::User, &tampered);
    let mut qemu = secure_boot(&tampered, &vars);
    let refused = "loader: damaged file: kernel-x86_64 (the kernel): SHA-256 expected";
    // Through the UEFI console (the screen, which OVMF copies to COM1).
    qemu.wait_for_screen_text(refused, 1, SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(!qemu.serial().contains(boot::READY_LINE));
}

/// A PC that trusts only Microsoft's 2023 CAs (KEK 2023, the 2023 UEFI CA
/// in `db`), the runner's `--secure-boot 2023`, once the user's
/// certificate is in shim's MOK list: shim is started by its 2023
/// signature, the cube boots, and the report says "on (shim, your key)".
#[test]
fn key_set_2023_only_with_the_key_in_mok_the_stick_boots() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let (vars, enrolled) = runner_vars(scratch.path(), KeySet::Microsoft2023, &stick);
    assert!(!enrolled, "a fresh 2023 set already holds the key");
    enroll_in_mok(&vars, &key);
    let mut qemu = secure_boot(&stick, &vars);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert!(!console.contains("Verification failed"), "{console}");
    assert_eq!(logged_state(&console), "on (shim, your key)");
    cube_keys_report_and_escape(&mut qemu, "on (shim, your key)");
}

/// As a setup's key management enrolls the stick's `.esl` in setup mode
/// (no PK): `db` set from the file's bytes (virt-fw-vars --set-json), then
/// the platform's keys and Secure Boot on. That `db` boots the stick.
#[test]
fn a_db_made_from_the_sticks_esl_in_setup_mode_boots_the_stick() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let disk = std::fs::read(&stick).unwrap();
    let esl = file_on_disk(&disk, sb::DB_ESL_FILE);
    // The setup-mode store: no PK.
    let setup = vars(&scratch.path().join("setup.fd"), &[]);
    let listed =
        common::run_virt_fw_vars(&["--input".as_ref(), setup.as_os_str(), "--print".as_ref()]);
    assert!(!listed.contains("PK "), "the blank store has a PK");
    let hex: String = esl.iter().map(|b| format!("{b:02x}")).collect();
    let json = serde_json::json!({
        "version": 2,
        "variables": [{
            "name": "db",
            "guid": "d719b2cb-3d3a-4596-a3bc-dad00e67656f",
            "attr": 0x27,
            "data": hex,
        }]
    });
    let json_path = scratch.path().join("db.json");
    std::fs::write(&json_path, json.to_string()).unwrap();
    let with_db = scratch.path().join("with-db.fd");
    common::run_virt_fw_vars(&[
        "--input".as_ref(),
        setup.as_os_str(),
        "--output".as_ref(),
        with_db.as_os_str(),
        "--set-json".as_ref(),
        json_path.as_os_str(),
    ]);
    // Setup left: a platform key (the user's own) and Secure Boot on.
    let enforced = scratch.path().join("enforced.fd");
    common::run_virt_fw_vars(&[
        "--input".as_ref(),
        with_db.as_os_str(),
        "--output".as_ref(),
        enforced.as_os_str(),
        "--set-pk".as_ref(),
        sb::KEY_OWNER_GUID.as_ref(),
        key.cert.as_os_str(),
        "--add-kek".as_ref(),
        sb::KEY_OWNER_GUID.as_ref(),
        key.cert.as_os_str(),
        "--sb".as_ref(),
    ]);
    assert!(sb::is_enrolled(
        &std::fs::read(&enforced).unwrap(),
        &key.cert_der
    ));
    let mut qemu = secure_boot(&stick, &enforced);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert_eq!(logged_state(&console), "on (your key in db)");
}

/// The certificate in every form on the stick: DER twice, PEM, a signature
/// list holding it, and an `.auth` that is an append to `db` carrying that
/// list; and shim keeps Microsoft's two signatures with the user's after
/// them.
#[test]
fn the_stick_carries_the_certificate_in_every_form_and_shim_signed_by_the_key() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let disk = std::fs::read(signed_stick(scratch.path(), &key)).unwrap();
    assert_eq!(file_on_disk(&disk, sb::DB_CER_FILE), key.cert_der);
    assert_eq!(
        file_on_disk(&disk, sb::DB_CRT_FILE),
        std::fs::read(&key.cert).unwrap()
    );
    let esl = file_on_disk(&disk, sb::DB_ESL_FILE);
    assert_eq!(
        loader_logic::secure_boot::database_holds_cert(
            &esl,
            &sb::sha256(&key.cert_der),
            sb::sha256
        ),
        Ok(true)
    );
    // efitools reads its certificate back out whole.
    let esl_path = scratch.path().join("db.esl");
    std::fs::write(&esl_path, &esl).unwrap();
    let out = scratch.path().join("out");
    let status = std::process::Command::new("sig-list-to-certs")
        .arg(&esl_path)
        .arg(&out)
        .status()
        .expect("sig-list-to-certs (efitools; boot/setup.sh installs it)");
    assert!(status.success());
    assert_eq!(
        std::fs::read(scratch.path().join("out-0.der")).unwrap(),
        key.cert_der
    );
    let auth = file_on_disk(&disk, sb::DB_AUTH_FILE);
    assert!(auth.ends_with(&esl));
    let shim_path = scratch.path().join("shim.efi");
    std::fs::write(&shim_path, file_on_disk(&disk, sb::REMOVABLE_BOOT_PATH)).unwrap();
    let listed = std::process::Command::new("sbverify")
        .arg("--list")
        .arg(&shim_path)
        .output()
        .unwrap();
    let listed = String::from_utf8_lossy(&listed.stdout);
    assert!(
        listed.contains("Microsoft Corporation UEFI CA 2011"),
        "{listed}"
    );
    assert!(listed.contains("Microsoft UEFI CA 2023"), "{listed}");
    assert!(listed.contains("modex-cube Secure Boot key"), "{listed}");
    let loader = file_on_disk(&disk, sb::SECOND_STAGE_PATH);
    assert_eq!(
        sb::pe_section(&loader, sb::CERT_HASH_SECTION).map(|s| s[..32].to_vec()),
        Some(sb::sha256(&key.cert_der).to_vec())
    );
}

/// Files that do not match the loader's signing key are refused before
/// anything is written, naming the file.
#[test]
fn a_stick_whose_certificate_files_do_not_match_is_refused() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let other = test_key(&scratch.path().join("other"));
    let disk = std::fs::read(signed_stick(scratch.path(), &key)).unwrap();
    let files = sb::fat_files(sb::esp_of_disk(&disk).unwrap()).unwrap();
    assert!(sb::check_stick(&files, &key).is_ok());
    // The whole stick checked against another key.
    let error = sb::check_stick(&files, &other).unwrap_err();
    assert!(matches!(error, SecureBootError::Mismatch { .. }), "{error}");
    // One file of another key's.
    let others = sb::certificate_files(&other).unwrap();
    for name in [
        sb::DB_CER_FILE,
        sb::DB_CRT_FILE,
        sb::DB_ESL_FILE,
        sb::DB_AUTH_FILE,
    ] {
        let mut changed = files.clone();
        let replacement = others.iter().find(|(path, _)| path == name).unwrap();
        let slot = changed.iter_mut().find(|(path, _)| path == name).unwrap();
        *slot = replacement.clone();
        let error = sb::check_stick(&changed, &key).unwrap_err();
        assert!(error.to_string().contains(name), "{name}: {error}");
    }
    // Shim without the user's signature.
    let mut unsigned_shim = files.clone();
    unsigned_shim
        .iter_mut()
        .find(|(path, _)| path == sb::REMOVABLE_BOOT_PATH)
        .unwrap()
        .1 = shim().shim;
    let error = sb::check_stick(&unsigned_shim, &key).unwrap_err();
    assert!(
        error.to_string().contains(sb::REMOVABLE_BOOT_PATH),
        "{error}"
    );
}

/// Shim's newest SBAT revocation level, as this shim carries it (the
/// "latest" string of its `.sbatlevel` section: a version word, the offsets
/// of the "previous" and "latest" strings, then the strings).
fn shims_latest_sbat_level() -> String {
    // Its name is longer than a PE header's 8 bytes: objcopy finds it in
    // the string table.
    let scratch = tempfile::tempdir().unwrap();
    let shim = scratch.path().join("shim.efi");
    let dumped = scratch.path().join("sbatlevel");
    std::fs::write(&shim, self::shim().shim).unwrap();
    let status = std::process::Command::new("objcopy")
        .arg(format!("--dump-section=.sbatlevel={}", dumped.display()))
        .arg(&shim)
        .arg(scratch.path().join("out.efi"))
        .status()
        .expect("objcopy (binutils)");
    assert!(status.success(), "shim has no .sbatlevel section");
    let section = std::fs::read(&dumped).unwrap();
    let u32_at = |at: usize| u32::from_le_bytes(section[at..at + 4].try_into().unwrap()) as usize;
    let latest = &section[4 + u32_at(8)..];
    let end = latest.iter().position(|&b| b == 0).unwrap();
    let text = String::from_utf8(latest[..end].to_vec()).unwrap();
    assert!(text.starts_with("sbat,1,"), "{text:?}");
    text
}

/// The 2023-only PC with the user's key in MOK and `level` as `SbatLevel`.
fn with_sbat_level(dir: &Path, key: &SigningKey, level: &str) -> PathBuf {
    let level_file = dir.join("sbat-level.txt");
    std::fs::write(&level_file, level).unwrap();
    microsoft_2023(
        &dir.join("uefi23-sbat.fd"),
        KeySet::Microsoft2023,
        &[
            "--add-mok".as_ref(),
            sb::SHIM_LOCK_GUID.as_ref(),
            key.cert.as_os_str(),
            "--set-sbat-level".as_ref(),
            level_file.as_os_str(),
        ],
    )
}

/// Shim's newest revocation level applied: nothing of ours is revoked, and
/// the stick boots.
#[test]
fn under_shims_newest_sbat_level_the_stick_boots() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let level = shims_latest_sbat_level();
    let vars = with_sbat_level(scratch.path(), &key, &level);
    let mut qemu = secure_boot(&stick, &vars);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e} under SbatLevel {level:?}"));
    assert_eq!(logged_state(&console), "on (shim, your key)");
}

/// A level that revokes our loader's generation (the next one named, dated
/// after shim's own levels so shim keeps it): shim refuses the loader.
#[test]
fn a_sbat_level_revoking_our_generation_is_refused_by_shim() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let (component, generation) = sb::sbat_component();
    let level = shims_latest_sbat_level();
    let mut lines: Vec<String> = level.lines().map(str::to_owned).collect();
    lines[0] = "sbat,1,2099010100".to_owned();
    lines.push(format!("{component},{}", generation + 1));
    let level = lines.join("\n") + "\n";
    let vars = with_sbat_level(scratch.path(), &key, &level);
    let mut qemu = secure_boot(&stick, &vars);
    // Shim's box, drawn a piece at a time: wait for its end. The same
    // words as for a bad signature; the stick, key and variables are those
    // that boot under shim's own level (the test above): only the level
    // differs.
    let console = qemu
        .wait_for_screen_text("Security Violation", 1, SECURE_BOOT_TIMEOUT)
        .unwrap_or_else(|e| panic!("{e} under SbatLevel {level:?}"));
    assert!(console.contains("Verification failed"), "{console}");
    qemu.screendump()
        .unwrap()
        .write_png(&screens_dir().join("refused-sbat-revoked.png"))
        .unwrap();
    assert!(!qemu.serial().contains(boot::READY_LINE));
}

/// Secure Boot switched off in setup on a PC with Microsoft's 2023 keys
/// (the platform key kept, `SecureBootEnable` cleared afterwards, as the
/// setup's switch does): shim starts the loader unchecked, and the report
/// says "off", never "on".
#[test]
fn with_secure_boot_switched_off_the_report_says_off() {
    let scratch = tempfile::tempdir().unwrap();
    let key = test_key(&scratch.path().join("key"));
    let stick = signed_stick(scratch.path(), &key);
    let on = microsoft_2023(
        &scratch.path().join("uefi23.fd"),
        KeySet::Microsoft2023,
        &[],
    );
    let off = scratch.path().join("uefi23-off.fd");
    common::run_virt_fw_vars(&[
        "--input".as_ref(),
        on.as_os_str(),
        "--output".as_ref(),
        off.as_os_str(),
        "--set-false".as_ref(),
        "SecureBootEnable".as_ref(),
    ]);
    let mut qemu = secure_boot(&stick, &off);
    let console = qemu
        .wait_for_serial(boot::READY_LINE, SECURE_BOOT_TIMEOUT)
        .unwrap();
    assert_eq!(logged_state(&console), "off");
    report_says(&mut qemu, 0, "off");
}
