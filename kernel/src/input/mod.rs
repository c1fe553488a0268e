//! The keyboards' hardware: the 8042 PS/2 controller ([`ps2`]) and USB host
//! controllers of every kind ([`usb`]: UHCI, OHCI, EHCI, xHCI). What the
//! bytes and reports mean is decided in the portable crates `keyboard` and
//! `usb`; both paths end in the one scancode queue the frame loop reads.

pub mod ps2;
pub mod usb;
