//! The "write it yourself" exercise of docs/vga.md, which quotes this file
//! from its first `use` to the end (tests/docs.rs checks the quotation):
//! Mode X set, a rectangle filled and a page flipped by hand, with nothing
//! but port writes and video-memory writes on the software VGA. The last
//! lines compare the result with the driver's own mode set.

use modex::mode::MODE_X;
use modex::regs::Port;
use modex::soft::SoftVga;
use modex::{ModeX, VgaBus};

/// An indexed register: the index (low byte) to the index port and the
/// value (high byte) to the data port after it, in one 16-bit OUT.
fn out_indexed(vga: &mut SoftVga, index_port: Port, index: u8, value: u8) {
    vga.write_port16(index_port, u16::from_le_bytes([index, value]));
}

fn set_mode_x(vga: &mut SoftVga) {
    // The dot clock changes only with the sequencer held in synchronous reset.
    out_indexed(vga, Port::SEQUENCER_INDEX, 0x00, 0x01);
    out_indexed(vga, Port::SEQUENCER_INDEX, 0x01, 0x01); // 8-dot characters
    vga.write_port8(Port::MISC_OUTPUT_WRITE, 0xE3); // 25.175 MHz, 480-line syncs
    out_indexed(vga, Port::SEQUENCER_INDEX, 0x04, 0x06); // chain-4 and odd/even off
    out_indexed(vga, Port::SEQUENCER_INDEX, 0x00, 0x03); // run again
    out_indexed(vga, Port::CRTC_INDEX, 0x11, 0x2C); // unlock CRTC 0-7
    let crtc = [
        0x5F, 0x4F, 0x50, 0x82, 0x54, 0x80, 0x0D, 0x3E, 0x00, 0x41, 0x00, 0x00, 0x00, 0x00, 0x00,
        0x00, 0xEA, 0xAC, 0xDF, 0x28, 0x00, 0xE7, 0x06, 0xE3, 0xFF,
    ];
    for (index, value) in (0..).zip(crtc) {
        out_indexed(vga, Port::CRTC_INDEX, index, value);
    }
    out_indexed(vga, Port::GRAPHICS_INDEX, 0x05, 0x40); // write mode 0, 256-colour shift
    out_indexed(vga, Port::GRAPHICS_INDEX, 0x06, 0x05); // graphics, 64 KiB at 0xA0000

    // The Attribute Controller takes index and value on one port, by turns;
    // reading Input Status 1 makes the next write an index.
    vga.read_port8(Port::INPUT_STATUS_1);
    let attributes = (0..16)
        .map(|n| (n, n))
        .chain([(0x10, 0x41), (0x12, 0x0F), (0x13, 0x00)]);
    for (index, value) in attributes {
        vga.write_port8(Port::ATTRIBUTE_INDEX, index);
        vga.write_port8(Port::ATTRIBUTE_INDEX, value);
    }
    vga.write_port8(Port::ATTRIBUTE_INDEX, 0x20); // video on again
}

/// Fills [x0, x1) x [y0, y1) of the page at `page`: one Map Mask per
/// 4-pixel column, then one byte per line through it.
fn fill_rect(vga: &mut SoftVga, page: u16, (x0, y0): (u16, u16), (x1, y1): (u16, u16), colour: u8) {
    for column in x0 / 4..=(x1 - 1) / 4 {
        let inside = |plane: u16| (x0..x1).contains(&(column * 4 + plane));
        let planes = (0..4)
            .filter(|&p| inside(p))
            .fold(0, |mask, p| mask | 1 << p);
        out_indexed(vga, Port::SEQUENCER_INDEX, 0x02, planes); // Map Mask
        for y in y0..y1 {
            vga.write_vram8(page + y * 80 + column, colour);
        }
    }
}

/// Reads Input Status 1 until `done` says yes, a bounded number of times.
fn wait_status(vga: &mut SoftVga, done: impl Fn(u8) -> bool) {
    assert!((0..1_000_000).any(|_| done(vga.read_port8(Port::INPUT_STATUS_1))));
}

fn show_page(vga: &mut SoftVga, page: u16) {
    wait_status(vga, |bits| bits & 0x09 == 0); // in the display: not latched now
    let [high, low] = page.to_be_bytes();
    out_indexed(vga, Port::CRTC_INDEX, 0x0C, high); // Start Address High
    out_indexed(vga, Port::CRTC_INDEX, 0x0D, low); // Start Address Low
    wait_status(vga, |bits| bits & 0x08 != 0); // retrace began: latched
}

#[test]
fn mode_x_by_hand() {
    let mut soft = Box::new(SoftVga::new()); // powers on in text mode 3
    let vga = &mut *soft;
    set_mode_x(vga);
    let page_1 = 80 * 240;
    fill_rect(vga, page_1, (10, 20), (15, 23), 12);
    show_page(vga, page_1);

    let mut screen = vec![0u8; 320 * 240];
    assert_eq!(vga.scanout_indices(&mut screen), (320, 240));
    for (at, &colour) in screen.iter().enumerate() {
        let (x, y) = (at % 320, at / 320);
        let inside = (10..15).contains(&x) && (20..23).contains(&y);
        assert_eq!(colour, if inside { 12 } else { 0 }, "pixel ({x}, {y})");
    }
    // The registers read back as the driver's own mode set leaves them.
    assert_eq!(ModeX::new(vga).verify(&MODE_X), Ok(()));
}
