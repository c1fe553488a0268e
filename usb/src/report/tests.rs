use super::*;
use std::vec::Vec;

fn feed(keyboard: &mut BootKeyboard, report: [u8; 8], now: u64) -> Vec<u8> {
    let mut bytes = Vec::new();
    keyboard.report(&report, now, &mut |b| bytes.push(b));
    bytes
}

fn tick(keyboard: &mut BootKeyboard, now: u64) -> Vec<u8> {
    let mut bytes = Vec::new();
    keyboard.tick(now, &mut |b| bytes.push(b));
    bytes
}

#[test]
fn a_press_and_release_give_make_then_break() {
    let mut keyboard = BootKeyboard::new();
    assert_eq!(feed(&mut keyboard, [0, 0, 0x15, 0, 0, 0, 0, 0], 0), [0x13]); // r
    assert_eq!(feed(&mut keyboard, [0; 8], 10), [0x93]);
    assert_eq!(feed(&mut keyboard, [0; 8], 20), []);
}

#[test]
fn extended_keys_get_their_e0_prefix_both_ways() {
    let mut keyboard = BootKeyboard::new();
    // Left arrow, then keypad Enter added, then both released.
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0x50, 0, 0, 0, 0, 0], 0),
        [0xE0, 0x4B]
    );
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0x50, 0x58, 0, 0, 0, 0], 1),
        [0xE0, 0x1C]
    );
    assert_eq!(feed(&mut keyboard, [0; 8], 2), [0xE0, 0xCB, 0xE0, 0x9C]);
    // Keypad 4 has no prefix: the demo tells it from Left that way.
    assert_eq!(feed(&mut keyboard, [0, 0, 0x5C, 0, 0, 0, 0, 0], 3), [0x4B]);
}

#[test]
fn modifiers_are_keys_of_their_own() {
    let mut keyboard = BootKeyboard::new();
    // Left Shift, then Right Ctrl too, with A; then all up.
    assert_eq!(feed(&mut keyboard, [0x02, 0, 0, 0, 0, 0, 0, 0], 0), [0x2A]);
    assert_eq!(
        feed(&mut keyboard, [0x12, 0, 0x04, 0, 0, 0, 0, 0], 1),
        [0xE0, 0x1D, 0x1E]
    );
    assert_eq!(feed(&mut keyboard, [0; 8], 2), [0xAA, 0xE0, 0x9D, 0x9E]);
    // Right Alt and both GUI keys are E0 keys.
    assert_eq!(
        feed(&mut keyboard, [0xC8, 0, 0, 0, 0, 0, 0, 0], 3),
        [0xE0, 0x5B, 0xE0, 0x38, 0xE0, 0x5C]
    );
}

#[test]
fn a_rollover_error_report_changes_nothing() {
    let mut keyboard = BootKeyboard::new();
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0x04, 0x05, 0, 0, 0, 0], 0),
        [0x1E, 0x30]
    );
    // Too many keys: every slot says ErrorRollOver; nothing is released.
    assert_eq!(feed(&mut keyboard, [0, 0, 1, 1, 1, 1, 1, 1], 1), []);
    // Back to two keys: no new makes either, as nothing changed.
    assert_eq!(feed(&mut keyboard, [0, 0, 0x04, 0x05, 0, 0, 0, 0], 2), []);
    assert_eq!(feed(&mut keyboard, [0, 0, 0x05, 0, 0, 0, 0, 0], 3), [0x9E]);
}

#[test]
fn a_held_key_repeats_at_the_ps2_defaults_and_stops_on_release() {
    let mut keyboard = BootKeyboard::new();
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0x21, 0, 0, 0, 0, 0], 1_000),
        [0x05]
    ); // 4
    assert_eq!(tick(&mut keyboard, 1_000 + REPEAT_DELAY_MICROS - 1), []);
    assert_eq!(tick(&mut keyboard, 1_000 + REPEAT_DELAY_MICROS), [0x05]);
    assert_eq!(tick(&mut keyboard, 1_000 + REPEAT_DELAY_MICROS + 1), []);
    // A second later: about 10.9 more.
    let mut repeats = 0;
    for ms in 0..1000 {
        repeats += tick(&mut keyboard, 1_000 + REPEAT_DELAY_MICROS + 1 + ms * 1000).len();
    }
    assert_eq!(repeats, 10);
    assert_eq!(
        feed(&mut keyboard, [0; 8], 3_000_000),
        [0x85],
        "a release gives its break code"
    );
    assert_eq!(tick(&mut keyboard, 10_000_000), []);
}

#[test]
fn the_last_key_pressed_is_the_one_that_repeats() {
    let mut keyboard = BootKeyboard::new();
    feed(&mut keyboard, [0, 0, 0x04, 0, 0, 0, 0, 0], 0);
    feed(&mut keyboard, [0, 0, 0x04, 0x50, 0, 0, 0, 0], 100_000);
    assert_eq!(tick(&mut keyboard, 600_000), [0xE0, 0x4B]);
    // Releasing A (not the repeating key) leaves Left repeating.
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0, 0x50, 0, 0, 0, 0], 650_000),
        [0x9E]
    );
    assert_eq!(tick(&mut keyboard, 700_000), [0xE0, 0x4B]);
}

#[test]
fn a_long_stall_gives_a_few_repeats_not_a_flood() {
    let mut keyboard = BootKeyboard::new();
    feed(&mut keyboard, [0, 0, 0x04, 0, 0, 0, 0, 0], 0);
    assert_eq!(tick(&mut keyboard, 60_000_000).len(), 4);
    assert_eq!(tick(&mut keyboard, 60_000_001), []);
}

#[test]
fn pause_sends_its_e1_sequence_once_and_short_reports_are_ignored() {
    let mut keyboard = BootKeyboard::new();
    assert_eq!(
        feed(&mut keyboard, [0, 0, 0x48, 0, 0, 0, 0, 0], 0),
        PAUSE_BYTES
    );
    assert_eq!(feed(&mut keyboard, [0; 8], 1), []);
    let mut bytes = Vec::new();
    keyboard.report(&[0, 0, 0x04], 2, &mut |b| bytes.push(b));
    assert_eq!(bytes, []);
}

#[test]
fn release_all_lets_go_of_everything() {
    let mut keyboard = BootKeyboard::new();
    feed(&mut keyboard, [0x01, 0, 0x04, 0, 0, 0, 0, 0], 0);
    let mut bytes = Vec::new();
    keyboard.release_all(&mut |b| bytes.push(b));
    assert_eq!(bytes, [0x9D, 0x9E]);
    assert_eq!(tick(&mut keyboard, 10_000_000), []);
}
