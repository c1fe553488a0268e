//! What the kernel can learn from and say to QEMU, and nothing else: the
//! `isa-debug-exit` device ends the emulator with a status, and `fw_cfg` carries
//! a boot option from the QEMU command line (`-fw_cfg name=opt/modex/boot,string=...`).
//! Both are probed only when CPUID says a hypervisor is present, so on a real PC
//! not one of these ports is touched.

use firmware::fw_cfg;
use protocol::Exit;
use x86_64::instructions::port::Port;

/// `-device isa-debug-exit,iobase=0xf4,iosize=0x04`: QEMU exits with
/// `(code << 1) | 1`, so the host sees 33 for success and 35 for failure.
const DEBUG_EXIT_PORT: u16 = 0xF4;

/// Ends QEMU with `exit`'s status if the debug-exit device is fitted;
/// returns if it is not.
pub fn exit(exit: Exit) {
    if !hypervisor_present() {
        return;
    }
    // SAFETY: with a hypervisor present the port is QEMU's isa-debug-exit (or
    // unassigned, when a write is ignored).
    unsafe { Port::<u32>::new(DEBUG_EXIT_PORT).write(exit.code()) };
}

/// CPUID leaf 1, ECX bit 31: set by every hypervisor, clear on real hardware.
pub fn hypervisor_present() -> bool {
    const HYPERVISOR_BIT: u32 = 1 << 31;
    let leaf1 = core::arch::x86_64::__cpuid(1);
    leaf1.ecx & HYPERVISOR_BIT != 0
}

const FW_CFG_SELECTOR: u16 = 0x510;
const FW_CFG_DATA: u16 = 0x511;

/// The boot option given on the QEMU command line, copied into `buffer`
/// (`firmware::fw_cfg` reads the file directory; this supplies the ports).
pub fn boot_option(buffer: &mut [u8; 64]) -> Option<&str> {
    if !hypervisor_present() {
        return None;
    }
    fw_cfg::boot_option(&mut FwCfgPorts::new(), buffer)
}

struct FwCfgPorts {
    selector: Port<u16>,
    data: Port<u8>,
}

impl FwCfgPorts {
    fn new() -> Self {
        FwCfgPorts {
            selector: Port::new(FW_CFG_SELECTOR),
            data: Port::new(FW_CFG_DATA),
        }
    }
}

impl fw_cfg::FwCfg for FwCfgPorts {
    fn select(&mut self, key: u16) {
        // SAFETY: only reached under a hypervisor, where 0x510 is QEMU's fw_cfg
        // selector (or unassigned).
        unsafe { self.selector.write(key) };
    }

    fn read_byte(&mut self) -> u8 {
        // SAFETY: as for `select`; reading fw_cfg data has no side effect but
        // advancing its offset.
        unsafe { self.data.read() }
    }
}
