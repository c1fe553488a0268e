use core::{arch::asm, fmt::Write};

pub fn print_char(c: u8) {
    // Patched: through the BIOS call wrapper (INT 10h may change BP and the
    // upper halves of registers).
    crate::bios::call(
        0x10,
        crate::bios::Registers {
            eax: 0x0e00 | u32::from(c),
            ebx: 0x0007,
            ..Default::default()
        },
    );
}

pub fn print_str(s: &str) {
    for c in s.chars() {
        if c.is_ascii() {
            print_char(c as u8);
            if c == '\n' {
                print_char(b'\r');
            }
        } else {
            print_char(b'X');
        }
    }
}

pub struct Writer;

impl Write for Writer {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        print_str(s);
        Ok(())
    }
}

#[cfg(all(not(test), target_os = "none"))]
#[panic_handler]
pub fn panic(info: &core::panic::PanicInfo) -> ! {
    let _ = write!(Writer, "\nPANIC: ");
    if let Some(location) = info.location() {
        let _ = writeln!(Writer, "{location} ");
    }
    let _ = writeln!(Writer, " {info}");
    // Patched: on serial too, so a stop is never silent there.
    let _ = writeln!(crate::serial::Com1, "loader: PANIC: {info}");

    loop {
        unsafe {
            asm!("hlt");
        };
    }
}
