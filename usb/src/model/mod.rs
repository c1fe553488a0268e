//! Register models of the host controllers, and the USB devices behind
//! them, for the host tests: each checks what its driver gives it, as the
//! hardware would, and has knobs to make it misbehave.

pub mod devices;
pub mod ehci;
pub mod loopback;
pub mod ohci;
pub mod uhci;
pub mod xhci;

use crate::host::{HostController, ResetOutcome};
use crate::Platform;

/// Model time one call may take: its own work, never a wait.
pub const CALL_MICROS_BOUND: u64 = 1_000;

/// Resets root port `port` as the device layer does: begun, then polled
/// to its end ([`reset_polled`]).
pub fn reset_root_port(driver: &mut impl HostController, port: u8) -> ResetOutcome {
    driver.port_reset_begin(port);
    reset_polled(driver, port)
}

/// Polls root port `port`'s reset until the driver says what is there,
/// each poll within [`CALL_MICROS_BOUND`] (none blocks), bounded by 1 s
/// of model time.
pub fn reset_polled(driver: &mut impl HostController, port: u8) -> ResetOutcome {
    let deadline = driver.hardware().now_micros() + 1_000_000;
    loop {
        let before = driver.hardware().now_micros();
        let outcome = driver.port_reset_poll(port);
        let took = driver.hardware().now_micros() - before;
        assert!(took <= CALL_MICROS_BOUND, "a reset poll took {took} us");
        if let Some(outcome) = outcome {
            return outcome;
        }
        assert!(before < deadline, "port {port}'s reset never ended");
    }
}
