//! A register model of the 8042 and the keyboard behind it, with the faults
//! real ones have switched on by its fields: nothing on the bus, a
//! configuration byte that does not stick, a keyboard that answers only after
//! the controller's self-test, a keyboard that never answers, an input buffer
//! that never empties, an output buffer that never empties.

use super::*;
use std::collections::VecDeque;
use std::vec::Vec;

/// Status bits a real controller shows besides the buffers: the system flag
/// (bit 2) and "keyboard not inhibited" (bit 4).
const STATUS_IDLE_BITS: u8 = 0x14;

#[derive(Debug)]
pub struct Model {
    /// Nothing on the bus: every read is 0xFF, every write lost.
    pub absent: bool,
    /// Configuration bits the controller keeps whatever is written...
    pub stuck_bits: u8,
    /// ...at these values.
    pub stuck_value: u8,
    /// The keyboard says nothing until the controller's self-test has run.
    pub keyboard_needs_self_test: bool,
    /// The keyboard never says anything.
    pub keyboard_silent: bool,
    /// The self-test sets the configuration byte to this (some controllers
    /// reset it).
    pub self_test_resets_config_to: Option<u8>,
    /// The controller never takes a written byte.
    pub input_stuck: bool,
    /// The output buffer refills forever (a stuck or babbling device).
    pub output_stuck: bool,
    /// The keyboard's own scancode set (answer to F0 00).
    pub keyboard_set: u8,
    pub config: u8,
    pub self_tested: bool,
    pub scanning: bool,
    /// Bytes for the CPU, by port (true: mouse).
    output: VecDeque<(u8, bool)>,
    /// Bytes the keyboard has sent while its port was off.
    keyboard_waiting: VecDeque<u8>,
    /// What a read of the data port returns when nothing is there: the last
    /// byte again, as QEMU's controller does.
    last_data: u8,
    /// The next data byte is the configuration byte.
    config_next: bool,
    /// The keyboard waits for the argument of this command.
    keyboard_argument_of: Option<u8>,
    pub status_reads: u64,
    /// Every byte written, by port (true: the command port).
    pub writes: Vec<(bool, u8)>,
}

impl Model {
    /// A healthy controller as firmware leaves it: translation on, both ports
    /// enabled with IRQs, a keyboard in set 2.
    pub fn healthy() -> Model {
        Model {
            absent: false,
            stuck_bits: 0,
            stuck_value: 0,
            keyboard_needs_self_test: false,
            keyboard_silent: false,
            self_test_resets_config_to: None,
            input_stuck: false,
            output_stuck: false,
            keyboard_set: 2,
            config: CONFIG_TRANSLATE | CONFIG_KEYBOARD_IRQ | CONFIG_AUX_IRQ,
            self_tested: false,
            scanning: true,
            output: VecDeque::new(),
            keyboard_waiting: VecDeque::new(),
            last_data: 0,
            config_next: false,
            keyboard_argument_of: None,
            status_reads: 0,
            writes: Vec::new(),
        }
    }

    pub fn keyboard_port_enabled(&self) -> bool {
        self.config & CONFIG_KEYBOARD_CLOCK_OFF == 0
    }

    /// The keyboard sends these bytes (when its port is on, they reach the
    /// output buffer; until then the keyboard holds them).
    pub fn keyboard_sends(&mut self, bytes: &[u8]) {
        self.keyboard_waiting.extend(bytes);
        self.move_keyboard_bytes();
    }

    /// The mouse port delivers these bytes (as firmware or a KVM may leave).
    pub fn mouse_sends(&mut self, bytes: &[u8]) {
        self.output.extend(bytes.iter().map(|&b| (b, true)));
    }

    /// Bytes not yet taken by the CPU.
    pub fn pending(&self) -> usize {
        self.output.len() + self.keyboard_waiting.len()
    }

    fn move_keyboard_bytes(&mut self) {
        if self.keyboard_port_enabled() {
            self.output
                .extend(self.keyboard_waiting.drain(..).map(|b| (b, false)));
        }
    }

    fn keyboard_answers(&self) -> bool {
        !self.keyboard_silent && (!self.keyboard_needs_self_test || self.self_tested)
    }

    fn answer(&mut self, bytes: &[u8]) {
        // Answers come ahead of keys the keyboard still holds.
        self.output.extend(bytes.iter().map(|&b| (b, false)));
    }

    fn keyboard_receives(&mut self, byte: u8) {
        if !self.keyboard_answers() {
            return;
        }
        if let Some(command) = self.keyboard_argument_of.take() {
            if command == KEYBOARD_SCANCODE_SET && byte == 0 {
                let set = self.keyboard_set;
                self.answer(&[KEYBOARD_ACK, set]);
            } else {
                if command == KEYBOARD_SCANCODE_SET {
                    self.keyboard_set = byte;
                }
                self.answer(&[KEYBOARD_ACK]);
            }
            return;
        }
        match byte {
            KEYBOARD_ENABLE_SCANNING => {
                self.scanning = true;
                self.answer(&[KEYBOARD_ACK]);
            }
            0xF5 => {
                self.scanning = false;
                self.answer(&[KEYBOARD_ACK]);
            }
            0xF2 => self.answer(&[KEYBOARD_ACK, 0xAB, 0x83]),
            0xFF => self.answer(&[KEYBOARD_ACK, 0xAA]),
            KEYBOARD_SCANCODE_SET | 0xED | 0xF3 => {
                self.keyboard_argument_of = Some(byte);
                self.answer(&[KEYBOARD_ACK]);
            }
            _ => self.answer(&[KEYBOARD_ACK]),
        }
    }
}

impl Ports for Model {
    fn read_status(&mut self) -> u8 {
        self.status_reads += 1;
        if self.absent {
            return STATUS_NOTHING_THERE;
        }
        self.move_keyboard_bytes();
        if self.output_stuck && self.output.is_empty() {
            self.output.push_back((0x00, false));
        }
        let mut status = STATUS_IDLE_BITS;
        if let Some(&(_, aux)) = self.output.front() {
            status |= STATUS_OUTPUT_FULL;
            if aux {
                status |= STATUS_FROM_AUX;
            }
        }
        if self.input_stuck {
            status |= STATUS_INPUT_FULL;
        }
        status
    }

    fn read_data(&mut self) -> u8 {
        if self.absent {
            return 0xFF;
        }
        if let Some((byte, _)) = self.output.pop_front() {
            self.last_data = byte;
        }
        self.last_data
    }

    fn write_data(&mut self, byte: u8) {
        self.writes.push((false, byte));
        if self.absent || self.input_stuck {
            return;
        }
        if self.config_next {
            self.config_next = false;
            self.config = (byte & !self.stuck_bits) | (self.stuck_value & self.stuck_bits);
            self.move_keyboard_bytes();
            return;
        }
        self.keyboard_receives(byte);
    }

    fn write_command(&mut self, byte: u8) {
        self.writes.push((true, byte));
        if self.absent || self.input_stuck {
            return;
        }
        match byte {
            COMMAND_READ_CONFIG => {
                let config = self.config;
                self.answer(&[config]);
            }
            COMMAND_WRITE_CONFIG => self.config_next = true,
            COMMAND_DISABLE_AUX => self.config |= CONFIG_AUX_CLOCK_OFF,
            0xA8 => self.config &= !CONFIG_AUX_CLOCK_OFF,
            COMMAND_DISABLE_KEYBOARD => self.config |= CONFIG_KEYBOARD_CLOCK_OFF,
            COMMAND_ENABLE_KEYBOARD => {
                self.config &= !CONFIG_KEYBOARD_CLOCK_OFF;
                self.move_keyboard_bytes();
            }
            COMMAND_SELF_TEST => {
                self.self_tested = true;
                if let Some(config) = self.self_test_resets_config_to {
                    self.config = config;
                }
                self.answer(&[SELF_TEST_PASSED]);
            }
            _ => {}
        }
    }
}
