//! VGA I/O ports, register indices and bit fields, named as in the IBM VGA
//! technical reference and FreeVGA. Colour I/O addressing (Misc Output bit 0
//! set) puts the CRTC and Input Status 1 at 0x3Dx; monochrome at 0x3Bx.

/// Attribute Controller: index and data writes alternate on this port by an
/// internal flip-flop, which a read of Input Status 1 resets to "index".
pub const ATTRIBUTE_INDEX: u16 = 0x3C0;
/// Attribute Controller data read.
pub const ATTRIBUTE_DATA_READ: u16 = 0x3C1;
/// Miscellaneous Output register, write.
pub const MISC_OUTPUT_WRITE: u16 = 0x3C2;
/// Input Status 0, read (same port as the Misc Output write).
pub const INPUT_STATUS_0: u16 = 0x3C2;
/// Sequencer index.
pub const SEQUENCER_INDEX: u16 = 0x3C4;
/// Sequencer data.
pub const SEQUENCER_DATA: u16 = 0x3C5;
/// DAC pixel mask, ANDed with every pixel before the palette lookup.
pub const DAC_PIXEL_MASK: u16 = 0x3C6;
/// DAC read index (write); DAC state (read).
pub const DAC_READ_INDEX: u16 = 0x3C7;
/// DAC write index.
pub const DAC_WRITE_INDEX: u16 = 0x3C8;
/// DAC data: three accesses (red, green, blue) per entry, 6 bits each.
pub const DAC_DATA: u16 = 0x3C9;
/// Miscellaneous Output register, read.
pub const MISC_OUTPUT_READ: u16 = 0x3CC;
/// Graphics Controller index.
pub const GRAPHICS_INDEX: u16 = 0x3CE;
/// Graphics Controller data.
pub const GRAPHICS_DATA: u16 = 0x3CF;
/// CRT Controller index (colour addressing).
pub const CRTC_INDEX: u16 = 0x3D4;
/// CRT Controller data (colour addressing).
pub const CRTC_DATA: u16 = 0x3D5;
/// Input Status 1 read, Feature Control write (colour addressing).
pub const INPUT_STATUS_1: u16 = 0x3DA;
/// CRT Controller index (monochrome addressing).
pub const CRTC_INDEX_MONO: u16 = 0x3B4;
/// CRT Controller data (monochrome addressing).
pub const CRTC_DATA_MONO: u16 = 0x3B5;
/// Input Status 1 (monochrome addressing).
pub const INPUT_STATUS_1_MONO: u16 = 0x3BA;
/// Bochs VBE (DISPI) 16-bit index port, as emulated by QEMU and Bochs.
pub const VBE_DISPI_INDEX: u16 = 0x1CE;
/// Bochs VBE (DISPI) 16-bit data port.
pub const VBE_DISPI_DATA: u16 = 0x1CF;

/// All four planes, for the Map Mask and the per-plane Graphics Controller masks.
pub const ALL_PLANES: u8 = 0x0F;
/// The VGA has four bit planes.
pub const PLANE_COUNT: usize = 4;

/// Miscellaneous Output bits.
pub mod misc {
    /// CRTC and Input Status 1 at 0x3Dx rather than 0x3Bx.
    pub const COLOR_IO_ADDRESSING: u8 = 0x01;
    /// Dot clock select: 0 = 25.175 MHz, 1 = 28.322 MHz.
    pub const CLOCK_SELECT_MASK: u8 = 0x0C;
    /// Shift of the dot clock select field.
    pub const CLOCK_SELECT_SHIFT: u8 = 2;
}

/// Sequencer register indices and bits.
pub mod seq {
    /// Reset register.
    pub const RESET: u8 = 0x00;
    /// Clocking Mode.
    pub const CLOCKING_MODE: u8 = 0x01;
    /// Map Mask: the planes CPU writes go to.
    pub const MAP_MASK: u8 = 0x02;
    /// Character Map Select.
    pub const CHARACTER_MAP_SELECT: u8 = 0x03;
    /// Memory Mode.
    pub const MEMORY_MODE: u8 = 0x04;
    /// Number of sequencer registers.
    pub const COUNT: usize = 5;

    /// Reset value holding the sequencer in synchronous reset (bit 1 clear).
    pub const RESET_SYNCHRONOUS: u8 = 0x01;
    /// Reset value letting the sequencer run.
    pub const RESET_RUNNING: u8 = 0x03;
    /// Clocking Mode: 8-dot characters (else 9).
    pub const CLOCKING_8_DOT: u8 = 0x01;
    /// Clocking Mode: screen off.
    pub const CLOCKING_SCREEN_OFF: u8 = 0x20;
    /// Memory Mode: more than 64 KiB installed.
    pub const MEMORY_EXTENDED: u8 = 0x02;
    /// Memory Mode: odd/even addressing for CPU writes disabled.
    pub const MEMORY_ODD_EVEN_DISABLE: u8 = 0x04;
    /// Memory Mode: chain-4, the low two address bits select the plane.
    pub const MEMORY_CHAIN_4: u8 = 0x08;
}

/// CRT Controller register indices and bits.
pub mod crtc {
    /// Horizontal Total (characters - 5).
    pub const HORIZONTAL_TOTAL: u8 = 0x00;
    /// Horizontal Display End (characters - 1).
    pub const HORIZONTAL_DISPLAY_END: u8 = 0x01;
    /// Start Horizontal Blanking.
    pub const START_HORIZONTAL_BLANKING: u8 = 0x02;
    /// End Horizontal Blanking.
    pub const END_HORIZONTAL_BLANKING: u8 = 0x03;
    /// Start Horizontal Retrace.
    pub const START_HORIZONTAL_RETRACE: u8 = 0x04;
    /// End Horizontal Retrace.
    pub const END_HORIZONTAL_RETRACE: u8 = 0x05;
    /// Vertical Total (lines - 2), low 8 bits.
    pub const VERTICAL_TOTAL: u8 = 0x06;
    /// Overflow: bits 8 and 9 of the vertical counts.
    pub const OVERFLOW: u8 = 0x07;
    /// Preset Row Scan.
    pub const PRESET_ROW_SCAN: u8 = 0x08;
    /// Maximum Scan Line: scan lines per row - 1, double scan, line compare bit 9.
    pub const MAXIMUM_SCAN_LINE: u8 = 0x09;
    /// Cursor Start.
    pub const CURSOR_START: u8 = 0x0A;
    /// Cursor End.
    pub const CURSOR_END: u8 = 0x0B;
    /// Start Address High.
    pub const START_ADDRESS_HIGH: u8 = 0x0C;
    /// Start Address Low.
    pub const START_ADDRESS_LOW: u8 = 0x0D;
    /// Cursor Location High.
    pub const CURSOR_LOCATION_HIGH: u8 = 0x0E;
    /// Cursor Location Low.
    pub const CURSOR_LOCATION_LOW: u8 = 0x0F;
    /// Vertical Retrace Start, low 8 bits.
    pub const VERTICAL_RETRACE_START: u8 = 0x10;
    /// Vertical Retrace End: low 4 bits of the end line; bit 7 protects CRTC 0-7.
    pub const VERTICAL_RETRACE_END: u8 = 0x11;
    /// Vertical Display End (lines - 1), low 8 bits.
    pub const VERTICAL_DISPLAY_END: u8 = 0x12;
    /// Offset: the distance between lines, in words (bytes * 2 in byte mode).
    pub const OFFSET: u8 = 0x13;
    /// Underline Location; bit 6 selects doubleword addressing.
    pub const UNDERLINE_LOCATION: u8 = 0x14;
    /// Start Vertical Blanking.
    pub const START_VERTICAL_BLANKING: u8 = 0x15;
    /// End Vertical Blanking.
    pub const END_VERTICAL_BLANKING: u8 = 0x16;
    /// CRTC Mode Control; bit 6 selects byte addressing.
    pub const MODE_CONTROL: u8 = 0x17;
    /// Line Compare, low 8 bits: the scan line where the address restarts at 0.
    pub const LINE_COMPARE: u8 = 0x18;
    /// Number of CRTC registers.
    pub const COUNT: usize = 0x19;

    /// Vertical Retrace End: CRTC registers 0-7 are write-protected (except
    /// Overflow bit 4, the line compare bit 8).
    pub const PROTECT_0_7: u8 = 0x80;
    /// Vertical Retrace End: the 4-bit end line compare value.
    pub const VERTICAL_RETRACE_END_MASK: u8 = 0x0F;
    /// Overflow: bit 8 of Vertical Total.
    pub const OVERFLOW_VERTICAL_TOTAL_8: u8 = 0x01;
    /// Overflow: bit 8 of Vertical Display End.
    pub const OVERFLOW_VERTICAL_DISPLAY_END_8: u8 = 0x02;
    /// Overflow: bit 8 of Vertical Retrace Start.
    pub const OVERFLOW_VERTICAL_RETRACE_START_8: u8 = 0x04;
    /// Overflow: bit 8 of Line Compare; stays writable when CRTC 0-7 are protected.
    pub const OVERFLOW_LINE_COMPARE_8: u8 = 0x10;
    /// Overflow: bit 9 of Vertical Total.
    pub const OVERFLOW_VERTICAL_TOTAL_9: u8 = 0x20;
    /// Overflow: bit 9 of Vertical Display End.
    pub const OVERFLOW_VERTICAL_DISPLAY_END_9: u8 = 0x40;
    /// Overflow: bit 9 of Vertical Retrace Start.
    pub const OVERFLOW_VERTICAL_RETRACE_START_9: u8 = 0x80;
    /// Maximum Scan Line: the scan-lines-per-row field.
    pub const MAXIMUM_SCAN_LINE_MASK: u8 = 0x1F;
    /// Maximum Scan Line: scan every line twice.
    pub const SCAN_DOUBLING: u8 = 0x80;
    /// Maximum Scan Line: bit 9 of the line compare.
    pub const LINE_COMPARE_9: u8 = 0x40;
}

/// Graphics Controller register indices and bits.
pub mod gc {
    /// Set/Reset: the per-plane value written where Enable Set/Reset is on.
    pub const SET_RESET: u8 = 0x00;
    /// Enable Set/Reset.
    pub const ENABLE_SET_RESET: u8 = 0x01;
    /// Color Compare, for read mode 1.
    pub const COLOR_COMPARE: u8 = 0x02;
    /// Data Rotate: rotate count (bits 0-2) and function select (bits 3-4).
    pub const DATA_ROTATE: u8 = 0x03;
    /// Read Map Select: the plane read mode 0 returns.
    pub const READ_MAP_SELECT: u8 = 0x04;
    /// Graphics Mode.
    pub const MODE: u8 = 0x05;
    /// Miscellaneous Graphics.
    pub const MISC: u8 = 0x06;
    /// Color Don't Care, for read mode 1.
    pub const COLOR_DONT_CARE: u8 = 0x07;
    /// Bit Mask: bits taken from the data; the others come from the latches.
    pub const BIT_MASK: u8 = 0x08;
    /// Number of Graphics Controller registers.
    pub const COUNT: usize = 9;

    /// Data Rotate: the rotate count field.
    pub const ROTATE_COUNT_MASK: u8 = 0x07;
    /// Data Rotate: shift of the logical function field (0 none, 1 AND, 2 OR, 3 XOR).
    pub const FUNCTION_SHIFT: u8 = 3;
    /// Graphics Mode: the write mode field.
    pub const MODE_WRITE_MASK: u8 = 0x03;
    /// Graphics Mode: read mode 1 (colour compare) rather than 0.
    pub const MODE_READ_COMPARE: u8 = 0x08;
    /// Graphics Mode: odd/even addressing for CPU reads.
    pub const MODE_HOST_ODD_EVEN: u8 = 0x10;
    /// Graphics Mode: 256-colour shift mode.
    pub const MODE_SHIFT_256: u8 = 0x40;
    /// Miscellaneous: graphics rather than text.
    pub const MISC_GRAPHICS: u8 = 0x01;
    /// Miscellaneous: chain odd maps to even.
    pub const MISC_CHAIN_ODD_EVEN: u8 = 0x02;
    /// Miscellaneous: the memory map field (0 A0000 128K, 1 A0000 64K, 2 B0000 32K, 3 B8000 32K).
    pub const MISC_MEMORY_MAP_MASK: u8 = 0x0C;
    /// Shift of the memory map field.
    pub const MISC_MEMORY_MAP_SHIFT: u8 = 2;
}

/// Attribute Controller register indices and bits.
pub mod ac {
    /// The 16 palette registers start here.
    pub const PALETTE: u8 = 0x00;
    /// Attribute Mode Control.
    pub const MODE_CONTROL: u8 = 0x10;
    /// Overscan (border) colour.
    pub const OVERSCAN_COLOR: u8 = 0x11;
    /// Color Plane Enable.
    pub const COLOR_PLANE_ENABLE: u8 = 0x12;
    /// Horizontal Pixel Panning.
    pub const HORIZONTAL_PIXEL_PANNING: u8 = 0x13;
    /// Color Select.
    pub const COLOR_SELECT: u8 = 0x14;
    /// Number of Attribute Controller registers.
    pub const COUNT: usize = 0x15;

    /// Index port: the register index field.
    pub const INDEX_MASK: u8 = 0x1F;
    /// Index port: Palette Address Source. Clear while the palette is being
    /// loaded, which blanks the screen; set to show video again.
    pub const PALETTE_ADDRESS_SOURCE: u8 = 0x20;
}

/// Input Status 1 bits.
pub mod status {
    /// Display disabled: the beam is in horizontal or vertical blanking.
    pub const DISPLAY_DISABLED: u8 = 0x01;
    /// Vertical retrace in progress.
    pub const VERTICAL_RETRACE: u8 = 0x08;
}

/// Bochs VBE (DISPI) register indices and values.
pub mod vbe {
    /// The ENABLE register.
    pub const INDEX_ENABLE: u16 = 0x04;
    /// ENABLE value: VBE off, the standard VGA drives the display.
    pub const DISABLED: u16 = 0x00;
    /// ENABLE bit: VBE linear modes on.
    pub const ENABLED: u16 = 0x01;
}
