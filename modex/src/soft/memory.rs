//! Video memory: four 64 KiB planes, the latches, and the CPU's read and
//! write paths through the Sequencer and Graphics Controller.
//!
//! CPU address decoding, by the Sequencer's Memory Mode:
//!
//! * chain-4: the low two address bits pick the plane, the byte within the
//!   plane is `address >> 2` (QEMU's compact mapping, which its scan-out
//!   expects; real hardware keeps the address and shifts on display). Direct
//!   access: no latches, no write modes.
//! * odd/even (writes: Memory Mode bit 2 clear; reads: Graphics Mode bit 4
//!   set): even addresses go to planes 0/2, odd ones to 1/3, at
//!   `address >> 1`, the compact mapping QEMU uses for text mode.
//! * otherwise planar (Mode X): every plane at `address`, through the latches.

use crate::regs::{gc, seq, Graphics, PlaneMask, Sequencer, PLANE_COUNT};

use super::registers::Registers;

/// Bytes in each plane.
pub const PLANE_BYTES: usize = 0x1_0000;
/// Plane offsets per block of write tracking: a fifth of a Mode X row (80
/// offsets), so a row starting on a block boundary is exactly five blocks.
pub(super) const BLOCK_OFFSETS: usize = 16;
/// Blocks of write tracking in a plane.
pub(super) const BLOCKS: usize = PLANE_BYTES / BLOCK_OFFSETS;

/// Planes of even and odd addresses in odd/even mode.
const EVEN_PLANES: u8 = 0b0101;
const ODD_PLANES: u8 = 0b1010;
/// Chain-4: address bits selecting the plane.
const CHAIN_4_PLANE_BITS: u32 = 0b11;
/// Odd/even: the bit selecting the plane.
const ODD_EVEN_PLANE_BIT: u32 = 0b1;
/// Read Map Select's plane-pair bit, which odd/even reads keep.
const READ_MAP_PAIR_BIT: u8 = 0b10;
/// Bytes of the 0xA0000 window each memory map decodes: the 128 KiB and the
/// 64 KiB maps start at 0xA0000; the 32 KiB maps at 0xB0000 and 0xB8000 are
/// outside the bus's window.
const MEMORY_MAP_WINDOW_BYTES: [u32; 4] = [0x2_0000, 0x1_0000, 0, 0];

/// How a CPU address reaches the planes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Addressing {
    Chain4,
    OddEven,
    Planar,
}

/// The Graphics Controller's logical functions (Data Rotate bits 3-4).
#[derive(Clone, Copy)]
enum Function {
    Replace,
    And,
    Or,
    Xor,
}

#[derive(Clone)]
pub(super) struct VideoMemory {
    pub(super) planes: [[u8; PLANE_BYTES]; PLANE_COUNT],
    pub(super) latches: [u8; PLANE_COUNT],
    /// CPU writes so far that reached a plane offset (whatever the Map Mask
    /// let through): each stamps its block with the new count, so a
    /// presenter that noted the count can tell which memory changed since.
    pub(super) writes: u64,
    /// Per block of plane offsets (all four planes), the write count just
    /// after its last write; 0 if never written.
    pub(super) block_written: [u64; BLOCKS],
}

impl VideoMemory {
    pub(super) const fn new() -> Self {
        Self {
            planes: [[0; PLANE_BYTES]; PLANE_COUNT],
            latches: [0; PLANE_COUNT],
            writes: 0,
            block_written: [0; BLOCKS],
        }
    }

    /// Every byte, latch and write stamp back to zero, in place.
    pub(super) fn clear(&mut self) {
        self.planes.as_flattened_mut().fill(0);
        self.latches = [0; PLANE_COUNT];
        self.writes = 0;
        self.block_written.fill(0);
    }

    /// Notes a write at plane offset `offset` (in any plane): one store, as
    /// it runs on every CPU write. Reads (which load the latches) never call it.
    fn note_write(&mut self, offset: usize) {
        self.writes += 1;
        self.block_written[offset / BLOCK_OFFSETS] = self.writes;
    }

    /// One CPU byte write at `offset` in the 0xA0000 window.
    pub(super) fn write(&mut self, registers: &Registers, offset: u16, value: u8) {
        let Some(address) = window_address(registers, offset) else {
            return;
        };
        let map_mask = map_mask(registers);
        match write_addressing(registers) {
            Addressing::Chain4 => {
                let plane = (address & CHAIN_4_PLANE_BITS) as usize;
                let offset = plane_offset(address >> 2);
                self.note_write(offset);
                if map_mask & (1 << plane) != 0 {
                    self.planes[plane][offset] = value;
                }
            }
            Addressing::OddEven => {
                let planes = if address & ODD_EVEN_PLANE_BIT == 0 {
                    EVEN_PLANES
                } else {
                    ODD_PLANES
                };
                let offset = plane_offset(address >> 1);
                self.note_write(offset);
                self.write_latched(registers, offset, value, map_mask & planes);
            }
            Addressing::Planar => {
                let offset = plane_offset(address);
                self.note_write(offset);
                self.write_latched(registers, offset, value, map_mask)
            }
        }
    }

    /// One CPU byte read at `offset` in the 0xA0000 window.
    pub(super) fn read(&mut self, registers: &Registers, offset: u16) -> u8 {
        let Some(address) = window_address(registers, offset) else {
            return 0xFF;
        };
        let read_map = registers.graphics(Graphics::ReadMapSelect);
        let (offset, plane) = match read_addressing(registers) {
            Addressing::Chain4 => {
                let plane = (address & CHAIN_4_PLANE_BITS) as usize;
                return self.planes[plane][plane_offset(address >> 2)];
            }
            Addressing::OddEven => {
                let plane = (read_map & READ_MAP_PAIR_BIT) | (address & ODD_EVEN_PLANE_BIT) as u8;
                (plane_offset(address >> 1), plane)
            }
            Addressing::Planar => (plane_offset(address), read_map),
        };
        for (latch, plane) in self.latches.iter_mut().zip(&self.planes) {
            *latch = plane[offset];
        }
        if registers.graphics(Graphics::Mode) & gc::MODE_READ_COMPARE != 0 {
            self.color_compare(registers)
        } else {
            self.latches[usize::from(plane) % PLANE_COUNT]
        }
    }

    /// Read mode 1: a bit is set where every plane that Color Don't Care
    /// includes matches Color Compare.
    fn color_compare(&self, registers: &Registers) -> u8 {
        let compare = registers.graphics(Graphics::ColorCompare);
        let care = registers.graphics(Graphics::ColorDontCare);
        let mut differences = 0;
        for (plane, &latch) in self.latches.iter().enumerate() {
            if care & (1 << plane) != 0 {
                differences |= latch ^ expand_bit(compare, plane);
            }
        }
        !differences
    }

    /// The write modes, logical function and Bit Mask against the latches,
    /// into the planes of `planes`.
    fn write_latched(&mut self, registers: &Registers, offset: usize, value: u8, planes: u8) {
        let mode = registers.graphics(Graphics::Mode) & gc::MODE_WRITE_MASK;
        let rotate = registers.graphics(Graphics::DataRotate);
        let rotated = value.rotate_right(u32::from(rotate & gc::ROTATE_COUNT_MASK));
        let function = Function::from_data_rotate(rotate);
        let set_reset = registers.graphics(Graphics::SetReset);
        let enable_set_reset = registers.graphics(Graphics::EnableSetReset);
        let bit_mask = registers.graphics(Graphics::BitMask);

        for plane in 0..PLANE_COUNT {
            if planes & (1 << plane) == 0 {
                continue;
            }
            let latch = self.latches[plane];
            let (data, mask) = match mode {
                // Write mode 1: the latches as they are (video-to-video copies).
                1 => (latch, 0xFF),
                // Write mode 2: the value's low nibble is a colour, one bit per plane.
                2 => (function.apply(expand_bit(value, plane), latch), bit_mask),
                // Write mode 3: Set/Reset is the colour, the rotated value ANDs the Bit Mask.
                3 => (
                    function.apply(expand_bit(set_reset, plane), latch),
                    bit_mask & rotated,
                ),
                // Write mode 0: the rotated value, or Set/Reset where enabled.
                _ => {
                    let source = if enable_set_reset & (1 << plane) != 0 {
                        expand_bit(set_reset, plane)
                    } else {
                        rotated
                    };
                    (function.apply(source, latch), bit_mask)
                }
            };
            self.planes[plane][offset] = (data & mask) | (latch & !mask);
        }
    }
}

impl Function {
    fn from_data_rotate(data_rotate: u8) -> Self {
        match (data_rotate >> gc::FUNCTION_SHIFT) & 0b11 {
            1 => Self::And,
            2 => Self::Or,
            3 => Self::Xor,
            _ => Self::Replace,
        }
    }

    fn apply(self, data: u8, latch: u8) -> u8 {
        match self {
            Self::Replace => data,
            Self::And => data & latch,
            Self::Or => data | latch,
            Self::Xor => data ^ latch,
        }
    }
}

/// 0xFF if bit `plane` of `bits` is set, else 0.
fn expand_bit(bits: u8, plane: usize) -> u8 {
    if bits & (1 << plane) != 0 {
        0xFF
    } else {
        0x00
    }
}

/// Plane offsets wrap at the plane size.
fn plane_offset(address: u32) -> usize {
    address as usize % PLANE_BYTES
}

/// The address within the memory map selected by Graphics Misc, if the map
/// decodes this part of the window. Bochs VBE maps its memory from A0000.
fn window_address(registers: &Registers, offset: u16) -> Option<u32> {
    let map = (registers.graphics(Graphics::Misc) & gc::MISC_MEMORY_MAP_MASK)
        >> gc::MISC_MEMORY_MAP_SHIFT;
    let decoded =
        registers.vbe_enabled() || u32::from(offset) < MEMORY_MAP_WINDOW_BYTES[usize::from(map)];
    decoded.then_some(u32::from(offset))
}

/// Bochs VBE enables every plane (as QEMU overrides the sequencer for it).
fn map_mask(registers: &Registers) -> u8 {
    if registers.vbe_enabled() {
        PlaneMask::ALL.bits()
    } else {
        registers.sequencer(Sequencer::MapMask)
    }
}

/// Bochs VBE forces chain-4 (its banked window is linear).
fn chain_4(registers: &Registers) -> bool {
    registers.vbe_enabled() || registers.sequencer(Sequencer::MemoryMode) & seq::MEMORY_CHAIN_4 != 0
}

fn write_addressing(registers: &Registers) -> Addressing {
    if chain_4(registers) {
        Addressing::Chain4
    } else if registers.sequencer(Sequencer::MemoryMode) & seq::MEMORY_ODD_EVEN_DISABLE == 0 {
        Addressing::OddEven
    } else {
        Addressing::Planar
    }
}

fn read_addressing(registers: &Registers) -> Addressing {
    if chain_4(registers) {
        Addressing::Chain4
    } else if registers.graphics(Graphics::Mode) & gc::MODE_HOST_ODD_EVEN != 0 {
        Addressing::OddEven
    } else {
        Addressing::Planar
    }
}
