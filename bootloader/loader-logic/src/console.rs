//! Where a UEFI loader's line goes (issue 48): on the firmware's console,
//! the screen, always; and on COM1 written by the loader itself only where
//! the firmware does not copy its console there already. OVMF makes COM1's
//! terminal one of its consoles, so a line written to both came out twice
//! on serial.
//!
//! The loader reads the device path of each console output device the
//! firmware has (`EFI_CONSOLE_OUT_DEVICE_GUID`'s handles) and asks
//! [`reaches_com1`]; [`com1_too`] then decides per line. Anything not
//! understood keeps the loader's own COM1 copy: a line twice is better than
//! none.
//!
//! ```
//! use loader_logic::console::{com1_too, reaches_com1};
//!
//! // OVMF's serial terminal: PciRoot(0x0)/Pci(0x1F,0x0)/Serial(0x0)/
//! // Uart(115200,8,N,1)/VenPcAnsi(), here without the vendor node.
//! let mut path = vec![2, 1, 12, 0, 0xD0, 0x41, 0x03, 0x0A, 0, 0, 0, 0];
//! path.extend([1, 1, 6, 0, 0, 0x1F]);
//! path.extend([2, 1, 12, 0, 0xD0, 0x41, 0x01, 0x05, 0, 0, 0, 0]);
//! path.extend([3, 14, 19, 0, 0, 0, 0, 0, 0, 0xC2, 1, 0, 0, 0, 0, 0, 8, 1, 1]);
//! path.extend([0x7F, 0xFF, 4, 0]);
//! assert!(reaches_com1(&path));
//! assert!(!com1_too(true, || true));
//! assert!(com1_too(false, || true), "the console write failed: COM1 too");
//! ```

/// A device path node's type: ACPI.
const ACPI: u8 = 0x02;
/// Its subtype: `ACPI_HID_DEVICE_PATH` (HID and UID, 12 bytes).
const ACPI_HID: u8 = 0x01;
/// A node's type: messaging.
const MESSAGING: u8 = 0x03;
/// Its subtype: `UART_DEVICE_PATH`.
const UART: u8 = 0x0E;
/// A node's type: the end of an instance (subtype 0x01) or of the path
/// (subtype 0xFF).
const END: u8 = 0x7F;
const END_ENTIRE: u8 = 0xFF;
/// `EISA_PNP_ID(0x0501)`, a 16550-compatible serial port, as ACPI names it.
const PNP0501: u32 = 0x0501_41D0;

/// Whether the device path `path` (its bytes, as the firmware keeps them) is
/// a terminal on the first ISA serial port: an ACPI `PNP0501` node with UID
/// 0 (COM1 at 0x3F8 on OVMF and most PCs) and after it a UART node, in the
/// same instance. A node shorter than its header or longer than the bytes
/// left ends the walk with `false`.
pub fn reaches_com1(path: &[u8]) -> bool {
    let mut rest = path;
    let mut on_com1 = false;
    while let [kind, sub_kind, low, high, ..] = *rest {
        let length = usize::from(u16::from_le_bytes([low, high]));
        let Some(node) = rest.get(..length).filter(|_| length >= 4) else {
            return false;
        };
        match (kind, sub_kind) {
            (END, END_ENTIRE) => return false,
            (END, _) => on_com1 = false,
            (ACPI, ACPI_HID) if length == 12 => {
                let hid = u32::from_le_bytes([node[4], node[5], node[6], node[7]]);
                let uid = u32::from_le_bytes([node[8], node[9], node[10], node[11]]);
                on_com1 = hid == PNP0501 && uid == 0;
            }
            (MESSAGING, UART) if on_com1 => return true,
            _ => {}
        }
        rest = &rest[length..];
    }
    false
}

/// Whether the loader writes a line to COM1 itself: when the line did not
/// reach the firmware's console (no console, or its write failed), or the
/// console does not reach COM1 (asked only when the line reached it: the
/// question needs boot services).
pub fn com1_too(written_to_console: bool, console_reaches_com1: impl FnOnce() -> bool) -> bool {
    !(written_to_console && console_reaches_com1())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn acpi(hid: u32, uid: u32) -> Vec<u8> {
        let mut node = Vec::from([ACPI, ACPI_HID, 12, 0]);
        node.extend(hid.to_le_bytes());
        node.extend(uid.to_le_bytes());
        node
    }

    fn uart() -> Vec<u8> {
        let mut node = Vec::from([MESSAGING, UART, 19, 0]);
        node.extend([0u8; 4]);
        node.extend(115_200u64.to_le_bytes());
        node.extend([8, 1, 1]);
        node
    }

    const PCI_ROOT: u32 = 0x0A03_41D0;
    const END_INSTANCE: [u8; 4] = [END, 0x01, 4, 0];
    const END_PATH: [u8; 4] = [END, END_ENTIRE, 4, 0];
    /// `Pci(0x1F,0x0)`.
    const PCI: [u8; 6] = [1, 1, 6, 0, 0, 0x1F];

    fn path(nodes: &[&[u8]]) -> Vec<u8> {
        nodes.concat()
    }

    #[test]
    fn a_terminal_on_com1_reaches_it_and_nothing_else_does() {
        let com1 = path(&[
            &acpi(PCI_ROOT, 0),
            &PCI,
            &acpi(PNP0501, 0),
            &uart(),
            &END_PATH,
        ]);
        assert!(reaches_com1(&com1));
        // COM2, a GOP, a serial port with no terminal on it.
        let com2 = path(&[
            &acpi(PCI_ROOT, 0),
            &PCI,
            &acpi(PNP0501, 1),
            &uart(),
            &END_PATH,
        ]);
        assert!(!reaches_com1(&com2));
        let gop = path(&[&acpi(PCI_ROOT, 0), &[1, 1, 6, 0, 0, 2], &END_PATH]);
        assert!(!reaches_com1(&gop));
        let port = path(&[&acpi(PCI_ROOT, 0), &PCI, &acpi(PNP0501, 0), &END_PATH]);
        assert!(!reaches_com1(&port));
        // The UART in another instance than the port.
        let split = path(&[&acpi(PNP0501, 0), &END_INSTANCE, &uart(), &END_PATH]);
        assert!(!reaches_com1(&split));
        // After the end of the path nothing counts.
        let after = path(&[&acpi(PNP0501, 0), &END_PATH, &uart()]);
        assert!(!reaches_com1(&after));
    }

    #[test]
    fn a_damaged_path_is_not_taken_to_reach_com1() {
        let com1 = path(&[&acpi(PNP0501, 0), &uart(), &END_PATH]);
        // Cut inside the UART node; a node claiming 2 bytes; one claiming
        // more than there is.
        assert!(!reaches_com1(&com1[..16]));
        let mut short = com1.clone();
        short[2] = 2;
        assert!(!reaches_com1(&short));
        let mut long = com1.clone();
        long[14] = 200;
        assert!(!reaches_com1(&long));
        assert!(!reaches_com1(&[]));
    }

    #[test]
    fn com1_is_written_unless_the_console_took_the_line_and_reaches_com1() {
        assert!(!com1_too(true, || true));
        assert!(com1_too(true, || false));
        let unasked = || panic!("asked with no line on the console");
        assert!(com1_too(false, unasked));
    }
}
