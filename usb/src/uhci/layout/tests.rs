use super::*;

#[test]
fn every_period_is_visited_exactly_at_its_period() {
    for index in 0..PERIODS {
        let frames: std::vec::Vec<u32> = (0..FRAMES)
            .filter(|&f| index == 0 || frame_skeleton(f) == index)
            .collect();
        let period = 1u32 << index;
        assert_eq!(frames.len() as u32, FRAMES / period, "period {period}");
        for pair in frames.windows(2) {
            assert_eq!(pair[1] - pair[0], period, "period {period}");
        }
    }
}

#[test]
fn intervals_round_down_to_a_power_of_two_up_to_32() {
    let cases = [
        (0, 0),
        (1, 0),
        (2, 1),
        (3, 1),
        (7, 2),
        (8, 3),
        (10, 3),
        (31, 4),
    ];
    for (interval, index) in cases {
        assert_eq!(period_index(interval), index, "interval {interval}");
    }
    assert_eq!(period_index(32), 5);
    assert_eq!(period_index(255), 5);
}

#[test]
fn lengths_are_n_minus_one_with_0x7ff_for_nothing() {
    assert_eq!(td_token(PID_IN, 0, 0, false, 0) >> 21, 0x7FF);
    assert_eq!(td_token(PID_IN, 0, 0, false, 8) >> 21, 7);
    assert_eq!(td_actual_length(0x7FF), 0);
    assert_eq!(td_actual_length(TD_ACTIVE | 7), 8);
    let token = td_token(PID_OUT, 0x7F, 0xF, true, 64);
    assert_eq!(token & 0xFF, 0xE1);
    assert_eq!((token >> 8) & 0x7F, 0x7F);
    assert_eq!((token >> 15) & 0xF, 0xF);
    assert_ne!(token & 1 << 19, 0, "DATA1");
}

#[test]
fn the_layout_fits_256_kib_and_refuses_what_does_not_fit() {
    let layout = Layout::new(0x10_0000, 256 * 1024).unwrap();
    assert_eq!(layout.frame_list(), 0x10_0000);
    let last = layout.device_buffer(MAX_DEVICES - 1) + 8 + MAX_CONTROL_DATA as u32;
    assert!(u64::from(last) <= 0x10_0000 + 256 * 1024);
    assert_eq!(Layout::new(0x10_0010, 256 * 1024).unwrap().base, 0x10_1000);
    assert!(Layout::new(0x10_0000, 64 * 1024).is_none());
    assert!(Layout::new(0xFFFF_F000, 256 * 1024).is_none());
    assert!(Layout::new(u64::MAX - 10, 256 * 1024).is_none());
    for slot in 0..MAX_DEVICES {
        assert_eq!(layout.device_qh(slot) % 16, 0);
        assert_eq!(layout.device_td(slot, 0) % 16, 0);
        assert_eq!(layout.device_buffer(slot) % 4, 0);
    }
}
