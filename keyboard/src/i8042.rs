//! The 8042 PS/2 controller's logic behind a four-operation port trait
//! ([`Ports`]), so that every odd controller is tried on the host against a
//! register model (the tests below) before a real one is met.
//!
//! Set-up ([`init`]) trusts nothing, after Linux's `i8042.c`:
//!
//! - the status port is probed first: a status of 0xFF is an empty bus, not
//!   a controller (whatever the firmware's tables say);
//! - both ports are disabled and the output buffer flushed (at most
//!   [`FLUSH_LIMIT`] bytes: one that never empties is a dead controller);
//! - the configuration byte is read, changed and read back; a byte that does
//!   not stick is logged, and the keyboard port is enabled all the same;
//! - the keyboard is asked to scan (0xF4). If it does not acknowledge, the
//!   controller's self-test (0xAA, answer 0x55) is run, the set-up redone,
//!   and the keyboard asked once more; if it still says nothing, that is
//!   logged and its port is left enabled and polled.
//!
//! Every wait is bounded by a count of status reads ([`WAIT_LIMIT`]); an
//! ISA-bus read of the status port takes about a microsecond on a real PC,
//! so the longest wait is about a tenth of a second.
//!
//! [`take_byte`] is the one way a byte leaves the output buffer after
//! set-up: status first, data only when the status says a byte is there, so
//! that the interrupt handler and the frame loop's poll, run one at a time,
//! take each byte exactly once.

use core::fmt;

/// The controller's two ports, as the kernel reaches them (`in`/`out` on
/// 0x60 and 0x64) and as the tests' model answers.
pub trait Ports {
    /// Reads the status register (port 0x64).
    fn read_status(&mut self) -> u8;
    /// Reads the output buffer (port 0x60).
    fn read_data(&mut self) -> u8;
    /// Writes the input buffer, for the keyboard or a command's argument
    /// (port 0x60).
    fn write_data(&mut self, byte: u8);
    /// Writes a controller command (port 0x64).
    fn write_command(&mut self, byte: u8);
}

/// Status bit: the output buffer holds a byte for the CPU.
pub const STATUS_OUTPUT_FULL: u8 = 0x01;
/// Status bit: the controller has not yet taken the last byte written.
pub const STATUS_INPUT_FULL: u8 = 0x02;
/// Status bit: the byte in the output buffer came from the second (mouse)
/// port.
pub const STATUS_FROM_AUX: u8 = 0x20;
/// What the status port reads where nothing drives the bus.
pub const STATUS_NOTHING_THERE: u8 = 0xFF;

/// Controller command: read the configuration byte.
pub const COMMAND_READ_CONFIG: u8 = 0x20;
/// Controller command: write the configuration byte (the next data byte).
pub const COMMAND_WRITE_CONFIG: u8 = 0x60;
/// Controller command: disable the second (mouse) port.
pub const COMMAND_DISABLE_AUX: u8 = 0xA7;
/// Controller command: self-test; a working controller answers
/// [`SELF_TEST_PASSED`].
pub const COMMAND_SELF_TEST: u8 = 0xAA;
/// Controller command: disable the keyboard port.
pub const COMMAND_DISABLE_KEYBOARD: u8 = 0xAD;
/// Controller command: enable the keyboard port.
pub const COMMAND_ENABLE_KEYBOARD: u8 = 0xAE;
/// The controller's answer to a passed self-test.
pub const SELF_TEST_PASSED: u8 = 0x55;

/// Configuration bit: IRQ 1 on a keyboard byte.
pub const CONFIG_KEYBOARD_IRQ: u8 = 0x01;
/// Configuration bit: IRQ 12 on a mouse byte.
pub const CONFIG_AUX_IRQ: u8 = 0x02;
/// Configuration bit: the keyboard port's clock is off (port disabled).
pub const CONFIG_KEYBOARD_CLOCK_OFF: u8 = 0x10;
/// Configuration bit: the mouse port's clock is off.
pub const CONFIG_AUX_CLOCK_OFF: u8 = 0x20;
/// Configuration bit: the controller translates set 2 into set 1.
pub const CONFIG_TRANSLATE: u8 = 0x40;

/// Keyboard command: enable scanning.
pub const KEYBOARD_ENABLE_SCANNING: u8 = 0xF4;
/// Keyboard command: get (argument 0) or set the scancode set.
pub const KEYBOARD_SCANCODE_SET: u8 = 0xF0;
/// The keyboard's acknowledgement of a command byte.
pub const KEYBOARD_ACK: u8 = 0xFA;
/// The keyboard's request to send the last byte again.
pub const KEYBOARD_RESEND: u8 = 0xFE;

/// Status reads before a wait gives up (about 0.1 s on a real PC).
pub const WAIT_LIMIT: u32 = 100_000;
/// Bytes a stale output buffer may hold (Linux's `I8042_BUFFER_SIZE`);
/// one still full after this many is stuck.
pub const FLUSH_LIMIT: u32 = 16;
/// Times a keyboard command byte is sent again on a Resend.
const RESEND_LIMIT: u32 = 3;
/// Bytes other than an answer (a key typed during set-up) skipped while
/// waiting for the keyboard's answer.
const STRAY_LIMIT: u32 = 8;

/// The configuration byte the kernel wants, from the firmware's: keyboard
/// port on with its IRQ, mouse port off without one, translation as found.
pub const fn wanted_config(found: u8) -> u8 {
    (found | CONFIG_KEYBOARD_IRQ | CONFIG_AUX_CLOCK_OFF)
        & !(CONFIG_KEYBOARD_CLOCK_OFF | CONFIG_AUX_IRQ)
}

/// A byte taken from the output buffer, by the port it came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Taken {
    /// A keyboard byte.
    Keyboard(u8),
    /// A mouse byte (the mouse port is disabled, but firmware or a KVM switch
    /// may have left one): no scancode.
    Aux(u8),
}

/// Takes the byte in the output buffer, if the status says there is one.
/// Reading the data port when the buffer is empty would return the last byte
/// again on many controllers (QEMU's among them), so the status comes
/// first; a status of 0xFF is no controller at all.
pub fn take_byte(ports: &mut impl Ports) -> Option<Taken> {
    let status = ports.read_status();
    if status == STATUS_NOTHING_THERE || status & STATUS_OUTPUT_FULL == 0 {
        return None;
    }
    let byte = ports.read_data();
    Some(if status & STATUS_FROM_AUX != 0 {
        Taken::Aux(byte)
    } else {
        Taken::Keyboard(byte)
    })
}

/// Why set-up stopped without a usable controller.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure {
    /// The status port reads 0xFF: nothing is there.
    Absent,
    /// The controller never took a command byte.
    InputNeverEmpty,
    /// The controller never answered a command that has an answer.
    NoAnswer,
    /// The output buffer stayed full after [`FLUSH_LIMIT`] bytes.
    OutputStuck,
}

impl Failure {
    /// What went wrong, in a sentence.
    pub const fn message(self) -> &'static str {
        match self {
            Failure::Absent => "nothing at port 0x64 (status reads 0xff): no PS/2 controller",
            Failure::InputNeverEmpty => {
                "PS/2 controller did not answer (input buffer never empties)"
            }
            Failure::NoAnswer => "PS/2 controller did not answer a command",
            Failure::OutputStuck => "PS/2 controller's output buffer never empties",
        }
    }
}

impl fmt::Display for Failure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.message())
    }
}

/// What set-up found and did, for the log and the tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Setup {
    /// The configuration byte the firmware left.
    pub found_config: u8,
    /// The configuration byte written and what read back, when they differ.
    pub config_not_stuck: Option<(u8, u8)>,
    /// The self-test was run (the keyboard did not answer): its answer.
    pub self_test: Option<Option<u8>>,
    /// The keyboard acknowledged "enable scanning".
    pub keyboard_answered: bool,
    /// The controller's translation to set 1 was turned on here (the firmware
    /// left it off and the keyboard speaks set 2).
    pub translation_turned_on: bool,
}

/// Sets the controller up: keyboard port on with IRQ 1, mouse port off,
/// the keyboard scanning, bytes arriving as set 1. Each step worth knowing
/// is written to `log`. Run with interrupts off.
pub fn init(
    ports: &mut impl Ports,
    log: &mut impl FnMut(fmt::Arguments<'_>),
) -> Result<Setup, Failure> {
    let status = ports.read_status();
    if status == STATUS_NOTHING_THERE {
        return Err(Failure::Absent);
    }
    log(format_args!(
        "keyboard: an 8042 answers at port 0x64 (status {status:#04x})"
    ));
    let mut controller = Controller { ports };
    let found_config = controller.configure()?;
    let mut setup = Setup {
        found_config,
        config_not_stuck: None,
        self_test: None,
        keyboard_answered: false,
        translation_turned_on: false,
    };
    setup.config_not_stuck = controller.write_config(wanted_config(found_config), log)?;
    controller.command(COMMAND_ENABLE_KEYBOARD)?;
    match controller.ask_keyboard(KEYBOARD_ENABLE_SCANNING) {
        Ok(()) => setup.keyboard_answered = true,
        Err(answer) => {
            log(format_args!(
                "keyboard: the PS/2 keyboard did not acknowledge enable scanning ({answer}); \
                 running the controller self-test"
            ));
            let result = controller.self_test();
            match result {
                Some(SELF_TEST_PASSED) => log(format_args!(
                    "keyboard: PS/2 controller self-test passed (0x55)"
                )),
                Some(other) => log(format_args!(
                    "keyboard: PS/2 controller self-test answered {other:#04x}, not 0x55"
                )),
                None => log(format_args!(
                    "keyboard: PS/2 controller self-test: no answer"
                )),
            }
            setup.self_test = Some(result);
            // The self-test resets some controllers' configuration byte:
            // set everything up again from what the firmware left.
            controller.configure()?;
            setup.config_not_stuck = controller.write_config(wanted_config(found_config), log)?;
            controller.command(COMMAND_ENABLE_KEYBOARD)?;
            match controller.ask_keyboard(KEYBOARD_ENABLE_SCANNING) {
                Ok(()) => {
                    setup.keyboard_answered = true;
                    log(format_args!(
                        "keyboard: the PS/2 keyboard answered after the self-test"
                    ));
                }
                Err(answer) => log(format_args!(
                    "keyboard: the PS/2 keyboard did not answer after the self-test ({answer}); \
                     its port stays enabled and polled"
                )),
            }
        }
    }
    if found_config & CONFIG_TRANSLATE == 0 && setup.keyboard_answered {
        // The firmware left translation off: the keyboard's own set decides.
        // Set 1 (which some keyboards use) is what the kernel reads; set 2,
        // the usual, needs the controller's translation.
        let set = controller.scancode_set();
        log(format_args!(
            "keyboard: the firmware left translation off; the keyboard says scancode set {set:?}"
        ));
        if set != Some(1) {
            let config = wanted_config(found_config) | CONFIG_TRANSLATE;
            controller.command(COMMAND_DISABLE_KEYBOARD)?;
            controller.flush()?;
            if let Some(not_stuck) = controller.write_config(config, log)? {
                setup.config_not_stuck = Some(not_stuck);
            }
            controller.command(COMMAND_ENABLE_KEYBOARD)?;
            setup.translation_turned_on = true;
        }
    }
    Ok(setup)
}

/// What the firmware's tables (the FADT's IAPC_BOOT_ARCH "8042" flag) say
/// about the controller: a hint, which the probe checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FirmwareSays {
    /// The flag says there is an 8042.
    Present,
    /// The flag says there is none. Firmware gets this wrong: the
    /// controller is probed all the same.
    Absent,
    /// No flag to read (no FADT, or one older than revision 2).
    Nothing,
}

/// [`init`], after logging the firmware's word, which changes nothing: the
/// probe of the status port decides. Both facts are in the log.
pub fn init_with_firmware_hint(
    firmware: FirmwareSays,
    ports: &mut impl Ports,
    log: &mut impl FnMut(fmt::Arguments<'_>),
) -> Result<Setup, Failure> {
    match firmware {
        FirmwareSays::Present => log(format_args!(
            "keyboard: the ACPI tables say there is a PS/2 controller (8042); probing it"
        )),
        FirmwareSays::Absent => log(format_args!(
            "keyboard: the ACPI tables say there is no PS/2 controller (8042); probing it anyway"
        )),
        FirmwareSays::Nothing => log(format_args!(
            "keyboard: the ACPI tables do not say whether there is a PS/2 controller (8042); probing it"
        )),
    }
    init(ports, log)
}

/// Why the keyboard's answer was not an acknowledgement.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum NoAck {
    Silent,
    Answered(u8),
    ControllerBusy,
}

impl fmt::Display for NoAck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            NoAck::Silent => f.write_str("no answer"),
            NoAck::Answered(byte) => write!(f, "answered {byte:#04x}"),
            NoAck::ControllerBusy => f.write_str("the controller did not take the byte"),
        }
    }
}

struct Controller<'a, P: Ports> {
    ports: &'a mut P,
}

impl<P: Ports> Controller<'_, P> {
    /// Both ports off, the output buffer emptied, the configuration byte
    /// read (as Linux does, until two reads agree, at most three).
    fn configure(&mut self) -> Result<u8, Failure> {
        self.command(COMMAND_DISABLE_KEYBOARD)?;
        self.command(COMMAND_DISABLE_AUX)?;
        self.flush()?;
        let mut config = self.read_config()?;
        for _ in 0..2 {
            let again = self.read_config()?;
            if again == config {
                break;
            }
            config = again;
        }
        Ok(config)
    }

    fn wait_until(&mut self, ready: impl Fn(u8) -> bool) -> bool {
        (0..WAIT_LIMIT).any(|_| ready(self.ports.read_status()))
    }

    fn command(&mut self, command: u8) -> Result<(), Failure> {
        if !self.wait_until(|s| s & STATUS_INPUT_FULL == 0) {
            return Err(Failure::InputNeverEmpty);
        }
        self.ports.write_command(command);
        Ok(())
    }

    fn write_data(&mut self, byte: u8) -> bool {
        if !self.wait_until(|s| s & STATUS_INPUT_FULL == 0) {
            return false;
        }
        self.ports.write_data(byte);
        true
    }

    /// The next byte from the output buffer, with its status, or None when
    /// none comes within the bound.
    fn read_answer(&mut self) -> Option<(u8, u8)> {
        for _ in 0..WAIT_LIMIT {
            let status = self.ports.read_status();
            if status & STATUS_OUTPUT_FULL != 0 {
                return Some((status, self.ports.read_data()));
            }
        }
        None
    }

    fn read_config(&mut self) -> Result<u8, Failure> {
        self.command(COMMAND_READ_CONFIG)?;
        self.read_answer()
            .map(|(_, byte)| byte)
            .ok_or(Failure::NoAnswer)
    }

    /// Writes the configuration byte and reads it back: `Some((written,
    /// read))` when it did not stick, which is logged and lived with.
    fn write_config(
        &mut self,
        config: u8,
        log: &mut impl FnMut(fmt::Arguments<'_>),
    ) -> Result<Option<(u8, u8)>, Failure> {
        self.command(COMMAND_WRITE_CONFIG)?;
        if !self.write_data(config) {
            return Err(Failure::InputNeverEmpty);
        }
        let read_back = self.read_config()?;
        if read_back == config {
            return Ok(None);
        }
        log(format_args!(
            "keyboard: PS/2 configuration byte wrote {config:#04x}, read back {read_back:#04x}; \
             the keyboard port is enabled all the same"
        ));
        Ok(Some((config, read_back)))
    }

    /// Empties the output buffer, at most [`FLUSH_LIMIT`] bytes.
    fn flush(&mut self) -> Result<(), Failure> {
        for _ in 0..FLUSH_LIMIT {
            if self.ports.read_status() & STATUS_OUTPUT_FULL == 0 {
                return Ok(());
            }
            let _stale = self.ports.read_data();
        }
        if self.ports.read_status() & STATUS_OUTPUT_FULL == 0 {
            Ok(())
        } else {
            Err(Failure::OutputStuck)
        }
    }

    /// Runs the self-test with the keyboard port off (so no key is taken
    /// for its answer): the answer, or None.
    fn self_test(&mut self) -> Option<u8> {
        self.command(COMMAND_DISABLE_KEYBOARD).ok()?;
        self.flush().ok()?;
        self.command(COMMAND_SELF_TEST).ok()?;
        self.read_answer().map(|(_, byte)| byte)
    }

    /// Sends a keyboard command byte and waits for its ACK, sending it
    /// again on a Resend; keyboard bytes that are no answer (a key pressed
    /// meanwhile) and mouse bytes are skipped.
    fn ask_keyboard(&mut self, byte: u8) -> Result<(), NoAck> {
        let mut last = NoAck::Silent;
        for _ in 0..RESEND_LIMIT {
            if !self.write_data(byte) {
                return Err(NoAck::ControllerBusy);
            }
            let mut resend = false;
            for _ in 0..STRAY_LIMIT {
                let Some((status, answer)) = self.read_answer() else {
                    return Err(last);
                };
                if status & STATUS_FROM_AUX != 0 {
                    continue;
                }
                match answer {
                    KEYBOARD_ACK => return Ok(()),
                    KEYBOARD_RESEND => {
                        last = NoAck::Answered(answer);
                        resend = true;
                        break;
                    }
                    other => last = NoAck::Answered(other),
                }
            }
            if !resend {
                return Err(last);
            }
        }
        Err(last)
    }

    /// The keyboard's scancode set (1, 2 or 3, untranslated), if it says.
    fn scancode_set(&mut self) -> Option<u8> {
        self.ask_keyboard(KEYBOARD_SCANCODE_SET).ok()?;
        self.ask_keyboard(0x00).ok()?;
        let answer = self.read_answer().map(|(_, byte)| byte);
        let _ = self.flush();
        answer
    }
}

#[cfg(test)]
mod model;

#[cfg(test)]
mod tests;
