//! Register models of the host controllers, and the USB devices behind
//! them, for the host tests: each checks what its driver gives it, as the
//! hardware would, and has knobs to make it misbehave.

pub mod devices;
pub mod ehci;
pub mod loopback;
pub mod ohci;
pub mod uhci;
pub mod xhci;
