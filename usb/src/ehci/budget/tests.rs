use super::*;

#[test]
fn bus_times_are_usb_2_0_5_11_3s() {
    // Linux's usb_calc_bus_time for the same cases.
    assert_eq!(interrupt_in_nanos(Speed::Full, 8), 16_547);
    assert_eq!(interrupt_in_nanos(Speed::Low, 8), 117_897);
    assert_eq!(interrupt_in_nanos(Speed::High, 0), 927);
    assert_eq!(interrupt_in_nanos(Speed::High, 64), 2_171);
    assert_eq!(translator_micros(Speed::Full, 8), 20);
    assert_eq!(translator_micros(Speed::Low, 8), 121);
    assert_eq!(high_speed_micros(Speed::Full, 8), (1, 3));
    assert_eq!(high_speed_micros(Speed::High, 8), (2, 0));
}

#[test]
fn a_translator_ends_work_before_the_last_complete_split() {
    let mut started = [0; 8];
    started[0] = 375;
    assert!(translator_in_time(&started));
    started[0] = 376;
    assert!(!translator_in_time(&started));
    // 3 micro-frames for what starts in 3, 4 for 2..3, and so on.
    let started = [125, 125, 250, 375, 0, 0, 0, 0];
    assert!(!translator_in_time(&started));
    let started = [125, 125, 125, 375, 0, 0, 0, 0];
    assert!(translator_in_time(&started));
    let mut late = [0; 8];
    late[4] = 1;
    assert!(!translator_in_time(&late), "no start-split past 3");
}
