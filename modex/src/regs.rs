//! VGA I/O ports, register indices and bit fields, named as in the IBM VGA
//! technical reference and FreeVGA. Colour I/O addressing (Misc Output bit 0
//! set) puts the CRTC and Input Status 1 at 0x3Dx; monochrome at 0x3Bx.
//!
//! Everything here is a type, not a bare number: a [`Port`] can only be one of
//! the ports named below, a register index is a variant of its group's enum
//! ([`Sequencer`], [`Crtc`], [`Graphics`], [`Attribute`]), and a set of planes
//! is a [`PlaneMask`]. The bit fields inside registers stay `u8` constants in
//! the modules [`misc`], [`seq`], [`crtc`], [`gc`], [`ac`] and [`status`].
//!
//! # Example
//!
//! ```
//! use modex::regs::{PlaneMask, Port, Sequencer};
//!
//! assert_eq!(Port::SEQUENCER_INDEX.number(), 0x3C4);
//! assert_eq!(Sequencer::MapMask.index(), 2);
//! assert_eq!(PlaneMask::plane(0) | PlaneMask::plane(3), PlaneMask::from_bits_truncate(0b1001));
//! assert_eq!(PlaneMask::ALL.bits(), 0x0F);
//! ```

/// An I/O port of the VGA, or of the one vendor extension the driver knows
/// (Bochs VBE's DISPI pair).
///
/// The field is private, so no code outside this crate can make a `Port`:
/// every value is one of the associated constants. All of them lie in the
/// VGA's 0x3B0..=0x3DF or are Bochs VBE's 0x1CE/0x1CF, and so does the port
/// after each (which a 16-bit access also reaches), except after 0x1CF, the
/// DISPI data port, whose 16-bit register a 16-bit access reaches whole.
/// [`VgaBus`](crate::VgaBus) takes only `Port`s, so a bus over real hardware
/// is never asked to touch anything else (the PCI or reset ports, say).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub struct Port(u16);

impl Port {
    /// Attribute Controller: index and data writes alternate on this port by an
    /// internal flip-flop, which a read of Input Status 1 resets to "index".
    pub const ATTRIBUTE_INDEX: Port = Port(0x3C0);
    /// Attribute Controller data read.
    pub const ATTRIBUTE_DATA_READ: Port = Port(0x3C1);
    /// Miscellaneous Output register, write.
    pub const MISC_OUTPUT_WRITE: Port = Port(0x3C2);
    /// Input Status 0, read (same port as the Misc Output write).
    pub const INPUT_STATUS_0: Port = Port(0x3C2);
    /// Sequencer index.
    pub const SEQUENCER_INDEX: Port = Port(0x3C4);
    /// Sequencer data.
    pub const SEQUENCER_DATA: Port = Port(0x3C5);
    /// DAC pixel mask, ANDed with every pixel before the palette lookup.
    pub const DAC_PIXEL_MASK: Port = Port(0x3C6);
    /// DAC read index (write); DAC state (read).
    pub const DAC_READ_INDEX: Port = Port(0x3C7);
    /// DAC write index.
    pub const DAC_WRITE_INDEX: Port = Port(0x3C8);
    /// DAC data: three accesses (red, green, blue) per entry, 6 bits each.
    pub const DAC_DATA: Port = Port(0x3C9);
    /// Miscellaneous Output register, read.
    pub const MISC_OUTPUT_READ: Port = Port(0x3CC);
    /// Graphics Controller index.
    pub const GRAPHICS_INDEX: Port = Port(0x3CE);
    /// Graphics Controller data.
    pub const GRAPHICS_DATA: Port = Port(0x3CF);
    /// CRT Controller index (colour addressing).
    pub const CRTC_INDEX: Port = Port(0x3D4);
    /// CRT Controller data (colour addressing).
    pub const CRTC_DATA: Port = Port(0x3D5);
    /// Input Status 1 read, Feature Control write (colour addressing).
    pub const INPUT_STATUS_1: Port = Port(0x3DA);
    /// CRT Controller index (monochrome addressing).
    pub const CRTC_INDEX_MONO: Port = Port(0x3B4);
    /// CRT Controller data (monochrome addressing).
    pub const CRTC_DATA_MONO: Port = Port(0x3B5);
    /// Input Status 1 (monochrome addressing).
    pub const INPUT_STATUS_1_MONO: Port = Port(0x3BA);
    /// Bochs VBE (DISPI) 16-bit index port, as emulated by QEMU and Bochs.
    pub const VBE_DISPI_INDEX: Port = Port(0x1CE);
    /// Bochs VBE (DISPI) 16-bit data port.
    pub const VBE_DISPI_DATA: Port = Port(0x1CF);

    /// Every port there is, each number once (Input Status 0 is read at the
    /// Misc Output write port).
    pub const ALL: [Port; 20] = [
        Port::ATTRIBUTE_INDEX,
        Port::ATTRIBUTE_DATA_READ,
        Port::MISC_OUTPUT_WRITE,
        Port::SEQUENCER_INDEX,
        Port::SEQUENCER_DATA,
        Port::DAC_PIXEL_MASK,
        Port::DAC_READ_INDEX,
        Port::DAC_WRITE_INDEX,
        Port::DAC_DATA,
        Port::MISC_OUTPUT_READ,
        Port::GRAPHICS_INDEX,
        Port::GRAPHICS_DATA,
        Port::CRTC_INDEX,
        Port::CRTC_DATA,
        Port::INPUT_STATUS_1,
        Port::CRTC_INDEX_MONO,
        Port::CRTC_DATA_MONO,
        Port::INPUT_STATUS_1_MONO,
        Port::VBE_DISPI_INDEX,
        Port::VBE_DISPI_DATA,
    ];

    /// The port's number, for the `in`/`out` instruction.
    pub const fn number(self) -> u16 {
        self.0
    }

    /// The data port of an index/data pair whose index port this is (the
    /// next port up), if that port is one of the named ones. A 16-bit OUT to
    /// an index port writes this port with the high byte.
    pub fn data(self) -> Option<Port> {
        let next = self.0.wrapping_add(1);
        Port::ALL.into_iter().find(|port| port.0 == next)
    }

    /// The named port numbered `number`, if there is one.
    pub fn from_number(number: u16) -> Option<Port> {
        Port::ALL.into_iter().find(|port| port.0 == number)
    }
}

/// The VGA's I/O ports: the monochrome (0x3Bx), general (0x3Cx) and colour
/// (0x3Dx) ranges.
pub const VGA_PORTS: core::ops::RangeInclusive<u16> = 0x3B0..=0x3DF;

/// Defines the index enum of one register group: its variants with their
/// indices, `COUNT`, `ALL` in index order, `index()` and `from_index()`.
macro_rules! register_group {
    (
        $(#[$meta:meta])*
        $name:ident { $( $(#[$vmeta:meta])* $variant:ident = $index:literal, )* }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
        #[repr(u8)]
        pub enum $name {
            $( $(#[$vmeta])* $variant = $index, )*
        }

        impl $name {
            /// Every register of the group, in index order.
            pub const ALL: [$name; $name::COUNT] = [$( $name::$variant, )*];
            /// How many registers the group has.
            pub const COUNT: usize = [$( $index, )*].len();

            /// The index written to the group's index port.
            pub const fn index(self) -> u8 {
                self as u8
            }

            /// The register's slot in an array of the group's registers.
            pub const fn slot(self) -> usize {
                self as usize
            }

            /// The register with index `index`, if the group has one.
            pub const fn from_index(index: u8) -> Option<$name> {
                if (index as usize) < $name::COUNT {
                    Some($name::ALL[index as usize])
                } else {
                    None
                }
            }
        }
    };
}

register_group! {
    /// Sequencer register indices (written to [`Port::SEQUENCER_INDEX`]).
    Sequencer {
        /// Reset register.
        Reset = 0x00,
        /// Clocking Mode.
        ClockingMode = 0x01,
        /// Map Mask: the planes CPU writes go to.
        MapMask = 0x02,
        /// Character Map Select.
        CharacterMapSelect = 0x03,
        /// Memory Mode.
        MemoryMode = 0x04,
    }
}

register_group! {
    /// CRT Controller register indices (written to [`Port::CRTC_INDEX`]).
    Crtc {
        /// Horizontal Total (characters - 5).
        HorizontalTotal = 0x00,
        /// Horizontal Display End (characters - 1).
        HorizontalDisplayEnd = 0x01,
        /// Start Horizontal Blanking.
        StartHorizontalBlanking = 0x02,
        /// End Horizontal Blanking.
        EndHorizontalBlanking = 0x03,
        /// Start Horizontal Retrace.
        StartHorizontalRetrace = 0x04,
        /// End Horizontal Retrace.
        EndHorizontalRetrace = 0x05,
        /// Vertical Total (lines - 2), low 8 bits.
        VerticalTotal = 0x06,
        /// Overflow: bits 8 and 9 of the vertical counts.
        Overflow = 0x07,
        /// Preset Row Scan.
        PresetRowScan = 0x08,
        /// Maximum Scan Line: scan lines per row - 1, double scan, line compare bit 9.
        MaximumScanLine = 0x09,
        /// Cursor Start.
        CursorStart = 0x0A,
        /// Cursor End.
        CursorEnd = 0x0B,
        /// Start Address High.
        StartAddressHigh = 0x0C,
        /// Start Address Low.
        StartAddressLow = 0x0D,
        /// Cursor Location High.
        CursorLocationHigh = 0x0E,
        /// Cursor Location Low.
        CursorLocationLow = 0x0F,
        /// Vertical Retrace Start, low 8 bits.
        VerticalRetraceStart = 0x10,
        /// Vertical Retrace End: low 4 bits of the end line; bit 7 protects CRTC 0-7.
        VerticalRetraceEnd = 0x11,
        /// Vertical Display End (lines - 1), low 8 bits.
        VerticalDisplayEnd = 0x12,
        /// Offset: the distance between lines, in words (bytes * 2 in byte mode).
        Offset = 0x13,
        /// Underline Location; bit 6 selects doubleword addressing.
        UnderlineLocation = 0x14,
        /// Start Vertical Blanking.
        StartVerticalBlanking = 0x15,
        /// End Vertical Blanking.
        EndVerticalBlanking = 0x16,
        /// CRTC Mode Control; bit 6 selects byte addressing.
        ModeControl = 0x17,
        /// Line Compare, low 8 bits: the scan line where the address restarts at 0.
        LineCompare = 0x18,
    }
}

register_group! {
    /// Graphics Controller register indices (written to [`Port::GRAPHICS_INDEX`]).
    Graphics {
        /// Set/Reset: the per-plane value written where Enable Set/Reset is on.
        SetReset = 0x00,
        /// Enable Set/Reset.
        EnableSetReset = 0x01,
        /// Color Compare, for read mode 1.
        ColorCompare = 0x02,
        /// Data Rotate: rotate count (bits 0-2) and function select (bits 3-4).
        DataRotate = 0x03,
        /// Read Map Select: the plane read mode 0 returns.
        ReadMapSelect = 0x04,
        /// Graphics Mode.
        Mode = 0x05,
        /// Miscellaneous Graphics.
        Misc = 0x06,
        /// Color Don't Care, for read mode 1.
        ColorDontCare = 0x07,
        /// Bit Mask: bits taken from the data; the others come from the latches.
        BitMask = 0x08,
    }
}

register_group! {
    /// Attribute Controller register indices (written to [`Port::ATTRIBUTE_INDEX`]).
    Attribute {
        /// Palette register 0: the colour for attribute 0.
        Palette0 = 0x00,
        /// Palette register 1.
        Palette1 = 0x01,
        /// Palette register 2.
        Palette2 = 0x02,
        /// Palette register 3.
        Palette3 = 0x03,
        /// Palette register 4.
        Palette4 = 0x04,
        /// Palette register 5.
        Palette5 = 0x05,
        /// Palette register 6.
        Palette6 = 0x06,
        /// Palette register 7.
        Palette7 = 0x07,
        /// Palette register 8.
        Palette8 = 0x08,
        /// Palette register 9.
        Palette9 = 0x09,
        /// Palette register 10.
        Palette10 = 0x0A,
        /// Palette register 11.
        Palette11 = 0x0B,
        /// Palette register 12.
        Palette12 = 0x0C,
        /// Palette register 13.
        Palette13 = 0x0D,
        /// Palette register 14.
        Palette14 = 0x0E,
        /// Palette register 15.
        Palette15 = 0x0F,
        /// Attribute Mode Control.
        ModeControl = 0x10,
        /// Overscan (border) colour.
        OverscanColor = 0x11,
        /// Color Plane Enable.
        ColorPlaneEnable = 0x12,
        /// Horizontal Pixel Panning.
        HorizontalPixelPanning = 0x13,
        /// Color Select.
        ColorSelect = 0x14,
    }
}

/// The index/data pairs a vendor's extended registers sit in, beyond the
/// standard indices of [`Sequencer`], [`Graphics`] and [`Crtc`].
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
pub enum IndexedPair {
    /// The Sequencer's pair, 0x3C4/0x3C5.
    Sequencer,
    /// The Graphics Controller's pair, 0x3CE/0x3CF.
    Graphics,
    /// The CRTC's pair under colour addressing, 0x3D4/0x3D5.
    Crtc,
}

impl IndexedPair {
    /// The pair's index port.
    pub const fn index_port(self) -> Port {
        match self {
            IndexedPair::Sequencer => Port::SEQUENCER_INDEX,
            IndexedPair::Graphics => Port::GRAPHICS_INDEX,
            IndexedPair::Crtc => Port::CRTC_INDEX,
        }
    }

    /// The pair's data port.
    pub const fn data_port(self) -> Port {
        match self {
            IndexedPair::Sequencer => Port::SEQUENCER_DATA,
            IndexedPair::Graphics => Port::GRAPHICS_DATA,
            IndexedPair::Crtc => Port::CRTC_DATA,
        }
    }
}

/// A set of the four bit planes: the Map Mask, and the per-plane masks of the
/// Graphics Controller. Only the low four bits exist.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug, Default)]
pub struct PlaneMask(u8);

impl PlaneMask {
    /// No plane.
    pub const NONE: PlaneMask = PlaneMask(0);
    /// All four planes.
    pub const ALL: PlaneMask = PlaneMask(0x0F);

    /// Plane `plane` alone (0 to 3; higher numbers wrap round, as the low two
    /// bits of an x coordinate select the plane).
    pub const fn plane(plane: u8) -> PlaneMask {
        PlaneMask(1 << (plane % PLANE_COUNT as u8))
    }

    /// Planes `first` to 3.
    pub const fn from_plane(first: u8) -> PlaneMask {
        PlaneMask((0x0F << (first % PLANE_COUNT as u8)) & 0x0F)
    }

    /// Planes 0 to `last`.
    pub const fn up_to_plane(last: u8) -> PlaneMask {
        PlaneMask(0x0F >> (PLANE_COUNT as u8 - 1 - last % PLANE_COUNT as u8))
    }

    /// The planes of the low four bits of `bits` (bit n is plane n).
    pub const fn from_bits_truncate(bits: u8) -> PlaneMask {
        PlaneMask(bits & 0x0F)
    }

    /// The register value: bit n set for plane n.
    pub const fn bits(self) -> u8 {
        self.0
    }

    /// Whether `plane` is in the set.
    pub const fn contains_plane(self, plane: u8) -> bool {
        plane < PLANE_COUNT as u8 && self.0 & (1 << plane) != 0
    }

    /// Whether no plane is in the set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// Planes in both sets.
    pub const fn intersection(self, other: PlaneMask) -> PlaneMask {
        PlaneMask(self.0 & other.0)
    }

    /// Planes in either set.
    pub const fn union(self, other: PlaneMask) -> PlaneMask {
        PlaneMask(self.0 | other.0)
    }
}

impl core::ops::BitOr for PlaneMask {
    type Output = PlaneMask;
    fn bitor(self, other: PlaneMask) -> PlaneMask {
        self.union(other)
    }
}

impl core::ops::BitAnd for PlaneMask {
    type Output = PlaneMask;
    fn bitand(self, other: PlaneMask) -> PlaneMask {
        self.intersection(other)
    }
}

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

/// Sequencer register bits.
pub mod seq {
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

/// CRT Controller register bits.
pub mod crtc {
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

/// Graphics Controller register bits.
pub mod gc {
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

/// Attribute Controller register bits.
pub mod ac {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// What the kernel's port bus promises in its SAFETY comments: a `Port`
    /// is a VGA port or a Bochs VBE port, and so is the port a 16-bit access
    /// also reaches (the DISPI data register being 16 bits wide).
    #[test]
    fn every_port_is_the_vgas_or_bochs_vbes() {
        for port in Port::ALL {
            let number = port.number();
            let dispi = matches!(port, Port::VBE_DISPI_INDEX | Port::VBE_DISPI_DATA);
            assert!(VGA_PORTS.contains(&number) || dispi, "{number:#x}");
            assert!(
                VGA_PORTS.contains(&(number + 1)) || dispi,
                "{number:#x} + 1"
            );
        }
        let mut numbers = Port::ALL.map(Port::number);
        numbers.sort_unstable();
        assert!(numbers.windows(2).all(|pair| pair[0] != pair[1]));
    }

    #[test]
    fn index_ports_lead_to_their_data_ports() {
        for pair in [
            IndexedPair::Sequencer,
            IndexedPair::Graphics,
            IndexedPair::Crtc,
        ] {
            assert_eq!(pair.index_port().data(), Some(pair.data_port()));
        }
        assert_eq!(Port::CRTC_INDEX_MONO.data(), Some(Port::CRTC_DATA_MONO));
        assert_eq!(
            Port::from_number(0xCF9),
            None,
            "the reset port is not a VGA port"
        );
    }

    #[test]
    fn register_groups_index_in_order() {
        assert_eq!(Sequencer::ALL.map(Sequencer::index), [0, 1, 2, 3, 4]);
        assert_eq!(Crtc::ALL.last().map(|r| r.index()), Some(0x18));
        assert_eq!(Graphics::COUNT, 9);
        assert_eq!(Attribute::COUNT, 0x15);
        for register in Crtc::ALL {
            assert_eq!(Crtc::from_index(register.index()), Some(register));
        }
        assert_eq!(Crtc::from_index(0x19), None);
    }

    #[test]
    fn plane_masks_cover_the_planes_asked_for() {
        assert_eq!(PlaneMask::from_plane(1).bits(), 0b1110);
        assert_eq!(PlaneMask::up_to_plane(1).bits(), 0b0011);
        assert_eq!(PlaneMask::from_plane(0), PlaneMask::ALL);
        assert_eq!(PlaneMask::up_to_plane(3), PlaneMask::ALL);
        assert_eq!(PlaneMask::plane(6), PlaneMask::plane(2));
        assert!(PlaneMask::plane(2).contains_plane(2));
        assert!(!PlaneMask::plane(2).contains_plane(4));
        assert_eq!(PlaneMask::from_bits_truncate(0xFF), PlaneMask::ALL);
        assert!((PlaneMask::plane(0) & PlaneMask::plane(1)).is_empty());
    }
}
