//! The device layer against the loopback controller over the device tree.
