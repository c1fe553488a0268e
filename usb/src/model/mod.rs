//! Register models of the host controllers, and the USB devices behind
//! them, for the host tests: each checks what its driver gives it, as the
//! hardware would, and has knobs to make it misbehave.

mod xhci;
pub use xhci::*;
pub mod devices;
pub mod loopback;
