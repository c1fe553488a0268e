use super::model::Model;
use super::*;
use std::format;
use std::string::String;
use std::vec::Vec;

/// Set-up on `model`, its log lines collected.
fn set_up(model: &mut Model, firmware: FirmwareSays) -> (Result<Setup, Failure>, Vec<String>) {
    let mut log = Vec::new();
    let result = init_with_firmware_hint(firmware, model, &mut |line| log.push(format!("{line}")));
    (result, log)
}

fn logged(log: &[String], text: &str) -> bool {
    log.iter().any(|line| line.contains(text))
}

/// Every keyboard byte `take_byte` gives until the buffer is empty.
fn take_all(model: &mut Model) -> Vec<u8> {
    let mut keys = Vec::new();
    while let Some(taken) = take_byte(model) {
        if let Taken::Keyboard(byte) = taken {
            keys.push(byte);
        }
    }
    keys
}

/// What any finished set-up must leave: the keyboard port on with IRQ 1,
/// the mouse port off without IRQ 12, and a key typed afterwards read.
fn assert_keyboard_usable(model: &mut Model) {
    assert!(
        model.keyboard_port_enabled(),
        "config {:#04x}",
        model.config
    );
    assert_eq!(model.config & CONFIG_AUX_IRQ, 0);
    assert_ne!(model.config & CONFIG_AUX_CLOCK_OFF, 0);
    model.keyboard_sends(&[0x1E, 0x9E]);
    assert_eq!(take_all(model), [0x1E, 0x9E]);
}

#[test]
fn a_healthy_controller_is_set_up_without_a_self_test() {
    let mut model = Model::healthy();
    let (result, log) = set_up(&mut model, FirmwareSays::Present);
    let setup = result.unwrap();
    assert_eq!(setup.config_not_stuck, None);
    assert_eq!(setup.self_test, None);
    assert!(setup.keyboard_answered);
    assert!(!setup.translation_turned_on);
    assert!(!model.self_tested);
    assert!(logged(&log, "say there is a PS/2 controller"), "{log:?}");
    assert!(logged(&log, "answers at port 0x64"), "{log:?}");
    assert_eq!(model.config & CONFIG_KEYBOARD_IRQ, CONFIG_KEYBOARD_IRQ);
    assert_keyboard_usable(&mut model);
}

#[test]
fn stale_bytes_are_flushed_before_the_configuration_is_read() {
    let mut model = Model::healthy();
    // A key pressed during boot and a mouse byte the firmware left.
    model.keyboard_sends(&[0x1C, 0x9C]);
    model.mouse_sends(&[0x08]);
    let (result, _) = set_up(&mut model, FirmwareSays::Present);
    result.unwrap();
    assert_keyboard_usable(&mut model);
}

#[test]
fn a_configuration_byte_that_does_not_stick_is_logged_and_the_keyboard_still_enabled() {
    let mut model = Model::healthy();
    // This controller keeps the mouse IRQ bit set whatever is written.
    model.stuck_bits = CONFIG_AUX_IRQ;
    model.stuck_value = CONFIG_AUX_IRQ;
    let (result, log) = set_up(&mut model, FirmwareSays::Present);
    let setup = result.unwrap();
    let (written, read) = setup.config_not_stuck.expect("noticed");
    assert_eq!(written & CONFIG_AUX_IRQ, 0);
    assert_eq!(read, written | CONFIG_AUX_IRQ);
    assert!(logged(&log, "configuration byte wrote"), "{log:?}");
    assert!(logged(&log, "enabled all the same"), "{log:?}");
    assert!(setup.keyboard_answered);
    assert!(model.keyboard_port_enabled());
    model.keyboard_sends(&[0x10, 0x90]);
    assert_eq!(take_all(&mut model), [0x10, 0x90]);
}

#[test]
fn a_keyboard_that_answers_only_after_the_self_test_gets_one() {
    let mut model = Model::healthy();
    model.keyboard_needs_self_test = true;
    // And the self-test resets the configuration byte, as some do.
    model.self_test_resets_config_to = Some(CONFIG_KEYBOARD_CLOCK_OFF | CONFIG_AUX_CLOCK_OFF);
    let (result, log) = set_up(&mut model, FirmwareSays::Present);
    let setup = result.unwrap();
    assert_eq!(setup.self_test, Some(Some(SELF_TEST_PASSED)));
    assert!(setup.keyboard_answered);
    assert!(model.self_tested && model.scanning);
    assert!(
        logged(&log, "did not acknowledge enable scanning"),
        "{log:?}"
    );
    assert!(logged(&log, "self-test passed"), "{log:?}");
    assert!(logged(&log, "answered after the self-test"), "{log:?}");
    // Set up again after the reset: translation and IRQ 1 as wanted.
    assert_eq!(model.config, wanted_config(setup.found_config));
    assert_ne!(model.config & CONFIG_TRANSLATE, 0);
    assert_keyboard_usable(&mut model);
}

#[test]
fn an_absent_controller_costs_one_status_read_and_no_write() {
    let mut model = Model::healthy();
    model.absent = true;
    let (result, log) = set_up(&mut model, FirmwareSays::Nothing);
    assert_eq!(result, Err(Failure::Absent));
    assert_eq!(model.status_reads, 1);
    assert!(model.writes.is_empty());
    assert!(logged(&log, "do not say whether"), "{log:?}");
    assert!(format!("{}", Failure::Absent).contains("status reads 0xff"));
    // And polling it finds nothing, ever.
    assert_eq!(take_byte(&mut model), None);
}

#[test]
fn the_firmware_saying_no_8042_while_one_answers_is_a_hint_overruled_by_the_probe() {
    let mut model = Model::healthy();
    let (result, log) = set_up(&mut model, FirmwareSays::Absent);
    assert!(result.unwrap().keyboard_answered);
    // Both facts logged: the firmware's word, then the probe's.
    let firmware = log
        .iter()
        .position(|l| l.contains("say there is no PS/2 controller (8042); probing it anyway"));
    let probe = log.iter().position(|l| l.contains("answers at port 0x64"));
    assert!(
        firmware.is_some() && probe.is_some() && firmware < probe,
        "{log:?}"
    );
    assert_keyboard_usable(&mut model);
}

#[test]
fn a_keyboard_that_never_acknowledges_costs_bounded_waits_and_is_logged() {
    let mut model = Model::healthy();
    model.keyboard_silent = true;
    let (result, log) = set_up(&mut model, FirmwareSays::Present);
    let setup = result.unwrap();
    assert!(!setup.keyboard_answered);
    assert_eq!(setup.self_test, Some(Some(SELF_TEST_PASSED)));
    assert!(
        logged(&log, "did not answer after the self-test"),
        "{log:?}"
    );
    assert!(logged(&log, "stays enabled and polled"), "{log:?}");
    // Two unanswered waits, and the rest a few reads each.
    let bound = 2 * u64::from(WAIT_LIMIT) + 1_000;
    assert!(
        (2 * u64::from(WAIT_LIMIT)..bound).contains(&model.status_reads),
        "{} status reads",
        model.status_reads
    );
    // Its port is left on: a keyboard plugged in later is read.
    assert!(model.keyboard_port_enabled());
    model.keyboard_sends(&[0x02]);
    assert_eq!(take_all(&mut model), [0x02]);
}

#[test]
fn a_controller_that_never_takes_a_byte_fails_within_one_wait() {
    let mut model = Model::healthy();
    model.input_stuck = true;
    let (result, _) = set_up(&mut model, FirmwareSays::Present);
    assert_eq!(result, Err(Failure::InputNeverEmpty));
    assert!(model.status_reads <= u64::from(WAIT_LIMIT) + 1);
}

#[test]
fn an_output_buffer_that_never_empties_fails_the_flush() {
    let mut model = Model::healthy();
    model.output_stuck = true;
    let (result, _) = set_up(&mut model, FirmwareSays::Present);
    assert_eq!(result, Err(Failure::OutputStuck));
    assert!(model.status_reads < 100);
}

#[test]
fn translation_left_off_is_turned_on_for_a_set_2_keyboard_only() {
    for (set, turned_on) in [(2, true), (1, false)] {
        let mut model = Model::healthy();
        model.config &= !CONFIG_TRANSLATE;
        model.keyboard_set = set;
        let (result, log) = set_up(&mut model, FirmwareSays::Present);
        let setup = result.unwrap();
        assert_eq!(setup.translation_turned_on, turned_on, "set {set}");
        assert_eq!(model.config & CONFIG_TRANSLATE != 0, turned_on, "set {set}");
        assert!(
            logged(&log, &format!("says scancode set Some({set})")),
            "{log:?}"
        );
        assert_keyboard_usable(&mut model);
    }
}

#[test]
fn mouse_bytes_are_never_taken_as_keys() {
    let mut model = Model::healthy();
    set_up(&mut model, FirmwareSays::Present).0.unwrap();
    model.mouse_sends(&[0x08, 0x01, 0x02]);
    model.keyboard_sends(&[0x1E]);
    assert_eq!(take_byte(&mut model), Some(Taken::Aux(0x08)));
    assert_eq!(take_all(&mut model), [0x1E]);
}

/// The interrupt handler and the frame loop's poll both take bytes, one at
/// a time (the poll with interrupts off): in any interleaving, with keys
/// arriving in between, every byte is taken once and in order.
#[test]
fn bytes_are_taken_exactly_once_whichever_path_gets_there_first() {
    let mut model = Model::healthy();
    set_up(&mut model, FirmwareSays::Present).0.unwrap();
    let sent: Vec<u8> = (0..5_000u32).map(|i| (i % 0x58) as u8 + 1).collect();
    let mut from_interrupt = Vec::new();
    let mut from_poll = Vec::new();
    let mut taken_in_order = Vec::new();
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next_to_send = 0;
    while taken_in_order.len() < sent.len() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        match state % 4 {
            // Keys arrive in bursts of up to three bytes.
            0 => {
                let end = (next_to_send + (state >> 8) as usize % 4).min(sent.len());
                model.keyboard_sends(&sent[next_to_send..end]);
                next_to_send = end;
            }
            // IRQ 1: one byte, if there is one (a stale IRQ finds none).
            1 => {
                if let Some(Taken::Keyboard(byte)) = take_byte(&mut model) {
                    from_interrupt.push(byte);
                    taken_in_order.push(byte);
                }
            }
            // The poll: everything there is, up to a bound.
            _ => {
                for _ in 0..16 {
                    match take_byte(&mut model) {
                        Some(Taken::Keyboard(byte)) => {
                            from_poll.push(byte);
                            taken_in_order.push(byte);
                        }
                        Some(Taken::Aux(_)) => {}
                        None => break,
                    }
                }
            }
        }
    }
    assert_eq!(taken_in_order, sent);
    assert_eq!(model.pending(), 0);
    assert!(!from_interrupt.is_empty() && !from_poll.is_empty());
    assert_eq!(take_byte(&mut model), None);
}

/// The model catches the mistake `take_byte` avoids: a read of the data
/// port without the status first takes the last byte a second time.
#[test]
fn reading_data_without_the_status_would_take_a_byte_twice() {
    let mut model = Model::healthy();
    set_up(&mut model, FirmwareSays::Present).0.unwrap();
    model.keyboard_sends(&[0x1E]);
    assert_eq!(model.read_data(), 0x1E);
    assert_eq!(model.read_data(), 0x1E);
    assert_eq!(take_byte(&mut model), None);
}
