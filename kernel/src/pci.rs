//! PCI configuration space through the legacy ports (mechanism #1), read
//! only: enough to find the display controller and name its maker.

use x86_64::instructions::port::Port;

const CONFIG_ADDRESS: u16 = 0xCF8;
const CONFIG_DATA: u16 = 0xCFC;
const ENABLE: u32 = 1 << 31;
/// Class code 0x03: display controller.
const CLASS_DISPLAY: u8 = 0x03;
const NO_DEVICE: u16 = 0xFFFF;
/// Header type bit 7: the device has functions 1-7 too.
const MULTI_FUNCTION: u8 = 0x80;

fn read(bus: u8, device: u8, function: u8, offset: u8) -> u32 {
    let address = ENABLE
        | (u32::from(bus) << 16)
        | (u32::from(device) << 11)
        | (u32::from(function) << 8)
        | u32::from(offset & 0xFC);
    // SAFETY: CONFIG_ADDRESS/CONFIG_DATA are the chipset's configuration
    // ports; reading configuration space changes no device state.
    unsafe {
        Port::<u32>::new(CONFIG_ADDRESS).write(address);
        Port::<u32>::new(CONFIG_DATA).read()
    }
}

/// The vendor and device IDs of the first display controller found (the one
/// the firmware most likely made the boot display), scanning every bus.
pub fn display_controller() -> Option<(u16, u16)> {
    for bus in 0..=255u8 {
        for device in 0..32u8 {
            let id = read(bus, device, 0, 0x00);
            if id as u16 == NO_DEVICE {
                continue;
            }
            let header_type = (read(bus, device, 0, 0x0C) >> 16) as u8;
            let functions = if header_type & MULTI_FUNCTION != 0 {
                8
            } else {
                1
            };
            for function in 0..functions {
                let id = read(bus, device, function, 0x00);
                let class = (read(bus, device, function, 0x08) >> 24) as u8;
                if id as u16 != NO_DEVICE && class == CLASS_DISPLAY {
                    return Some((id as u16, (id >> 16) as u16));
                }
            }
        }
    }
    None
}
