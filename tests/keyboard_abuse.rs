//! Keyboard abuse under QEMU: a burst of 2,000 keys — random keys, long holds
//! that make the keyboard repeat, combinations, the extended (E0) keys and
//! Pause with its E1 sequence, the lock keys — and the kernel keeps running;
//! afterwards R brings back the initial picture, pixel for pixel.

mod common;

use boot::{line, Qemu};
use common::{assert_same_picture, boot_bios, model_picture, soft_vga_in_mode_x, BOOT_TIMEOUT};
use demo::app::App;
use demo::command::{Command, SceneCommand};
use modex::ModeX;
use std::time::Duration;

/// QEMU key names; Esc is left out (it ends the demo, as it should).
const KEYS: &[&str] = &[
    "a",
    "b",
    "c",
    "d",
    "e",
    "f",
    "g",
    "h",
    "i",
    "j",
    "k",
    "l",
    "m",
    "n",
    "o",
    "p",
    "q",
    "r",
    "s",
    "t",
    "u",
    "v",
    "w",
    "x",
    "y",
    "z",
    "0",
    "1",
    "2",
    "3",
    "4",
    "5",
    "6",
    "7",
    "8",
    "9",
    "kp_0",
    "kp_1",
    "kp_2",
    "kp_3",
    "kp_4",
    "kp_5",
    "kp_6",
    "kp_7",
    "kp_8",
    "kp_9",
    "kp_add",
    "kp_subtract",
    "kp_multiply",
    "kp_divide",
    "kp_enter",
    "kp_decimal",
    "f1",
    "f2",
    "f3",
    "f4",
    "f5",
    "f6",
    "f7",
    "f8",
    "f9",
    "f10",
    "f11",
    "f12",
    "left",
    "right",
    "up",
    "down",
    "home",
    "end",
    "pgup",
    "pgdn",
    "insert",
    "delete",
    "spc",
    "ret",
    "tab",
    "backspace",
    "minus",
    "equal",
    "comma",
    "dot",
    "slash",
    "semicolon",
    "apostrophe",
    "bracket_left",
    "bracket_right",
    "backslash",
    "grave_accent",
    "shift",
    "shift_r",
    "ctrl",
    "ctrl_r",
    "alt",
    "alt_r",
    "caps_lock",
    "num_lock",
    "scroll_lock",
    "pause",
    "print",
    "menu",
    "shift-a",
    "ctrl-f1",
    "alt-4",
    "shift-left",
    "ctrl_r-kp_8",
];
const BURST: usize = 2000;

#[test]
fn a_burst_of_two_thousand_keys_leaves_the_kernel_running_and_r_resets_it() {
    let mut qemu = boot_bios(None);
    qemu.wait_for_serial(boot::READY_LINE, BOOT_TIMEOUT)
        .unwrap();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in 0..BURST {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let key = KEYS[(state % KEYS.len() as u64) as usize];
        // Now and then a hold long enough for typematic repeat.
        let hold = if i % 200 == 199 { 700 } else { 2 };
        qemu.send_key_held(key, hold).unwrap();
        // QEMU's own input queue holds about a thousand events and drops the
        // rest, so feed it in bursts of 50 keys it can play in time.
        if i % 50 == 49 {
            std::thread::sleep(Duration::from_millis(400));
        }
    }
    // QEMU plays the keys in order, holds included: wait until the kernel has
    // seen no new command while QEMU ran three seconds of CPU time (the
    // guest's progress, whatever the host's load).
    const QUIET: Duration = Duration::from_secs(3);
    let cpu = |qemu: &Qemu| qemu.cpu_time().expect("QEMU ended during the burst");
    let mut last = (0, cpu(&qemu));
    while cpu(&qemu) - last.1 < QUIET {
        let done = commands_done(&qemu.serial());
        if done != last.0 {
            last = (done, cpu(&qemu));
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    assert!(
        qemu.is_running(),
        "QEMU ended during the burst:\n{}",
        qemu.serial()
    );

    // The keys got through: most of them are commands (or pauses).
    let received = commands_done(&qemu.serial());
    println!("{received} of {BURST} keys reached the demo as commands");
    assert!(
        received >= BURST * 6 / 10,
        "only {received} of {BURST} keys arrived as commands"
    );

    // R resumes if the burst left the demo paused, then R resets.
    for _ in 0..2 {
        let next = commands_done(&qemu.serial()) + 1;
        qemu.send_key("r").unwrap();
        qemu.wait_for_serial(&line::CommandDone(next as u64).to_string(), BOOT_TIMEOUT)
            .unwrap();
    }
    let console = qemu.serial();
    assert!(
        console
            .lines()
            .last()
            .is_some_and(|l| l.contains("paused=false")),
        "{}",
        console.lines().last().unwrap()
    );
    assert!(
        !console.contains("EXCEPTION") && !console.contains("PANIC"),
        "{console}"
    );

    let mut soft = soft_vga_in_mode_x();
    let mut app = App::new();
    app.apply(Command::Scene(SceneCommand::Reset));
    app.step(&mut ModeX::new(&mut *soft), &|| 0u64);
    assert_same_picture(
        &qemu.screendump().unwrap(),
        &model_picture(&soft),
        "after the burst and R",
    );
}

/// The count in the kernel's last "demo: command N done" line.
fn commands_done(console: &str) -> usize {
    console
        .lines()
        .rev()
        .find_map(line::CommandDone::parse)
        .map_or(0, |count| count as usize)
}
