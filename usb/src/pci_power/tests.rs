//! Waking a controller against a model of its configuration space: a
//! capability list (MSI, then Power Management), PMCSR's PowerState taking
//! what is written, PME_Status write-1-to-clear.

use super::*;
use std::vec::Vec;

/// A function's configuration space, a dword per 4 bytes.
struct Config {
    dwords: [u32; 64],
    writes: Vec<(u8, u32)>,
    /// PMCSR ignores writes (a function stuck in its state).
    stuck: bool,
}

const PM: u8 = 0x50;

impl Config {
    /// A USB controller whose list holds MSI at 0x40, then Power
    /// Management at 0x50, in `state` with PME_Enable and PME_Status set.
    fn in_state(state: u32) -> Config {
        let mut dwords = [0; 64];
        dwords[1] = STATUS_CAPABILITIES | 0x0006;
        dwords[0x34 / 4] = 0x40;
        dwords[0x40 / 4] = u32::from(PM) << 8 | 0x05;
        dwords[usize::from(PM) / 4] = 0x0003_0001;
        dwords[usize::from(PM) / 4 + 1] = PME_STATUS | 1 << 8 | state;
        Config {
            dwords,
            writes: Vec::new(),
            stuck: false,
        }
    }

    fn read(&self, offset: u8) -> u32 {
        self.dwords[usize::from(offset) / 4]
    }

    fn write(&mut self, offset: u8, value: u32) {
        self.writes.push((offset, value));
        if offset == PM + 4 && !self.stuck {
            let old = self.dwords[usize::from(offset) / 4];
            let status = old & PME_STATUS & !value;
            self.dwords[usize::from(offset) / 4] =
                (old & !0x7FFF & !PME_STATUS) | (value & 0x7FFF) | status;
        }
    }

    fn wake(&mut self) -> Wake {
        let cell = core::cell::RefCell::new(self);
        wake(&mut |o| cell.borrow().read(o), &mut |o, v| {
            cell.borrow_mut().write(o, v)
        })
    }

    fn state(&self) -> u32 {
        self.read(PM + 4) & POWER_STATE
    }
}

#[test]
fn a_controller_in_d3hot_is_brought_to_d0_after_10_ms() {
    let mut config = Config::in_state(3);
    assert_eq!(
        config.wake(),
        Wake::Waking {
            pmcsr: PM + 4,
            from: 3,
            wait_micros: 10_000
        }
    );
    assert_eq!(config.state(), 0, "in D0");
    assert_eq!(config.writes.len(), 1);
    let pmcsr = config.read(PM + 4);
    assert_eq!(pmcsr & (1 << 8), 1 << 8, "PME_Enable kept");
    assert_eq!(pmcsr & PME_STATUS, PME_STATUS, "PME_Status not cleared");
    assert!(is_on(&mut |o| config.read(o), PM + 4));
}

#[test]
fn d2_waits_200_us_d1_none_and_d0_is_left_alone() {
    for (state, wait) in [(2, 200), (1, 0)] {
        let mut config = Config::in_state(state);
        assert_eq!(
            config.wake(),
            Wake::Waking {
                pmcsr: PM + 4,
                from: state as u8,
                wait_micros: wait
            }
        );
        assert_eq!(config.state(), 0);
    }
    let mut config = Config::in_state(0);
    assert_eq!(config.wake(), Wake::AlreadyOn);
    assert!(config.writes.is_empty(), "nothing written in D0");
}

#[test]
fn a_function_stuck_in_d3_is_not_said_to_be_on() {
    let mut config = Config::in_state(3);
    config.stuck = true;
    assert!(matches!(config.wake(), Wake::Waking { from: 3, .. }));
    assert!(!is_on(&mut |o| config.read(o), PM + 4));
}

#[test]
fn no_capability_list_or_a_looping_one_is_no_power_management() {
    let mut config = Config::in_state(3);
    config.dwords[1] &= !STATUS_CAPABILITIES;
    assert_eq!(config.wake(), Wake::NoCapability);
    // MSI pointing at itself: walked a bounded number of times.
    let mut config = Config::in_state(3);
    config.dwords[0x40 / 4] = 0x40 << 8 | 0x05;
    assert_eq!(config.wake(), Wake::NoCapability);
    // A pointer into the header.
    let mut config = Config::in_state(3);
    config.dwords[0x34 / 4] = 0x10;
    assert_eq!(config.wake(), Wake::NoCapability);
    assert!(config.writes.is_empty());
}
