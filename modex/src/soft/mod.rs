//! A software VGA: enough of the IBM VGA (and of QEMU's emulation of it, the
//! reference for its choices) to run the Mode X driver on the host and see
//! every pixel.
//!
//! * `registers`: the register files and I/O port decoding;
//! * `memory`: four 64 KiB planes, latches, the CPU read and write paths;
//! * `scanout`, `text_scanout`: the displayed picture, in 256-colour
//!   graphics modes and in text modes;
//! * `timing`: a deterministic clock, the beam, Input Status 1, and the
//!   start address latched at the start of each vertical retrace;
//! * `probe`: bus operation counts and a write guard.
//!
//! It is `no_std` and heap-free, and large (~300 KiB: the planes, and a
//! write stamp per 16 plane offsets): keep it in a `Box` and drive it
//! through `&mut SoftVga`, which is a [`VgaBus`] too.
//!
//! Where the model and QEMU (7.2, the installed oracle) part ways, and why:
//!
//! * Input Status 1 is timed from the CRTC like real hardware: vertical
//!   retrace lasts until the line matching Vertical Retrace End's low 4 bits
//!   (2 lines in Mode X; QEMU's `retrace=precise` reports 14, its default
//!   `dumb` mode just toggles the bits on every read), and bit 0 covers all
//!   blanking (QEMU: horizontal retrace only). The start address is latched
//!   at the start of vertical retrace; QEMU shows it at its next refresh.
//! * Bochs VBE: only the enable is modelled; while it is on, memory behaves
//!   as chain-4 through all planes and there is no scan-out.
//! * The DAC keeps 6 bits per component (QEMU keeps 8 and masks on
//!   display); the pixel mask is applied on scan-out (QEMU ignores it).
//! * The sequencer's reset register is stored but does not stop anything.
//! * Power-on is the BIOS's mode 3 with video memory cleared (no BIOS font).

mod memory;
#[cfg(test)]
mod poll_tests;
mod probe;
mod registers;
mod scanout;
mod text_scanout;
mod tiles;
mod timing;

use crate::regs::{Attribute, Crtc, Graphics, IndexedPair, Port, Sequencer};
use core::ops::Range;

use crate::mode::TEXT_80X25;
use crate::palette::{Rgb6, EGA_PALETTE};
use crate::regs::{status, PLANE_COUNT};
use crate::{poll_by_reads, VgaBus, CPU_WINDOW_BYTES};

use memory::VideoMemory;
use probe::WriteGuard;
use registers::Registers;

pub use memory::PLANE_BYTES;
pub use probe::BusCounts;
pub use scanout::dac_6_to_8;
pub use timing::{CrtTiming, PORT_ACCESS_NS, VRAM_ACCESS_NS};

pub(crate) use tiles::{PictureSource, TileSet, TILE_PIXELS};

const NANOS_PER_MICRO: u64 = 1_000;

/// The software VGA.
///
/// # Example
///
/// Port writes reach its registers as on a VGA, and every bus operation is
/// counted:
///
/// ```
/// use modex::regs::{Port, Sequencer};
/// use modex::soft::SoftVga;
/// use modex::VgaBus;
///
/// let mut soft = Box::new(SoftVga::new()); // text mode 3, as the BIOS leaves it
/// let map_mask = u16::from_le_bytes([Sequencer::MapMask.index(), 0x05]);
/// soft.write_port16(Port::SEQUENCER_INDEX, map_mask);
/// assert_eq!(soft.sequencer(Sequencer::MapMask), 0x05);
/// assert_eq!(soft.counts().port_writes, 1);
/// ```
#[derive(Clone)]
pub struct SoftVga {
    registers: Registers,
    memory: VideoMemory,
    timing: CrtTiming,
    now_ns: u64,
    /// No vertical retrace starts before this time, so the clock moves up
    /// to it without asking the timing: the page update's writes and the
    /// flip's status reads advance the clock thousands of times a frame.
    /// Zero, or the present time, asks at the next step.
    next_retrace_ns: u64,
    /// Input Status 1's beam bits until `status_until_ns`
    /// ([`CrtTiming::status_until`]). Zero, or the present time, asks the
    /// timing at the next read.
    status_bits: u8,
    status_until_ns: u64,
    /// The start address the CRTC latched at the last vertical retrace.
    displayed_start: u16,
    frame_count: u64,
    retrace_stuck: Option<bool>,
    /// Register writes so far (any port): a text picture may change with any.
    register_writes: u64,
    /// Writes so far to the ports that can change a colour on screen: DAC
    /// data and pixel mask, the Attribute Controller's index (Palette
    /// Address Source blanks) and Clocking Mode (screen off).
    colour_writes: u64,
    counts: BusCounts,
    guard: WriteGuard,
}

/// The clock and the counts, not the registers or the 256 KiB of video
/// memory, which have their own accessors.
impl core::fmt::Debug for SoftVga {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("SoftVga")
            .field("timing", &self.timing)
            .field("now_ns", &self.now_ns)
            .field("frame_count", &self.frame_count)
            .field("displayed_start", &self.displayed_start)
            .field("counts", &self.counts)
            .finish_non_exhaustive()
    }
}

impl Default for SoftVga {
    fn default() -> Self {
        Self::new()
    }
}

impl SoftVga {
    /// A VGA as the BIOS leaves it at boot: mode 3 (80x25 colour text)
    /// registers, the EGA palette in the DAC, Bochs VBE off; video memory
    /// cleared (the model has no BIOS font), clock at 0.
    ///
    /// `const`, so a kernel can keep its model in a static: built by value it
    /// needs several copies of its ~300 KiB on the stack.
    pub const fn new() -> Self {
        let registers = Registers::with_mode(&TEXT_80X25, &EGA_PALETTE);
        let timing = CrtTiming::from_registers(&registers);
        Self {
            displayed_start: registers.start_address(),
            registers,
            memory: VideoMemory::new(),
            timing,
            now_ns: 0,
            next_retrace_ns: 0,
            status_bits: 0,
            status_until_ns: 0,
            frame_count: 0,
            retrace_stuck: None,
            register_writes: 0,
            colour_writes: 0,
            counts: BusCounts {
                port_writes: 0,
                port_reads: 0,
                vram_writes: 0,
                vram_reads: 0,
            },
            guard: WriteGuard::new(),
        }
    }

    /// Every register, counter and byte of video memory zero: no state a VGA
    /// is ever in, only storage for one. [`SoftVga::power_on`] makes it what
    /// [`SoftVga::new`] gives. For a kernel's static: an all-zero static
    /// lands in `.bss` and costs the kernel file nothing, where `new`'s few
    /// non-zero registers put all ~300 KiB in `.data`.
    pub const fn unpowered() -> Self {
        Self {
            registers: Registers::unpowered(),
            memory: VideoMemory::new(),
            timing: CrtTiming {
                dot_clock_hz: 0,
                dots_per_character: 0,
                characters_per_line: 0,
                display_characters: 0,
                lines_per_frame: 0,
                display_lines: 0,
                retrace_start_line: 0,
                retrace_lines: 0,
            },
            now_ns: 0,
            next_retrace_ns: 0,
            status_bits: 0,
            status_until_ns: 0,
            displayed_start: 0,
            frame_count: 0,
            // `None` is the byte 2; power-on sets it.
            retrace_stuck: Some(false),
            register_writes: 0,
            colour_writes: 0,
            counts: BusCounts {
                port_writes: 0,
                port_reads: 0,
                vram_writes: 0,
                vram_reads: 0,
            },
            guard: WriteGuard::new(),
        }
    }

    /// Power-on in place: the state [`SoftVga::new`] gives, whatever the
    /// state before, without building a second ~300 KiB model on the stack.
    pub fn power_on(&mut self) {
        let registers = Registers::with_mode(&TEXT_80X25, &EGA_PALETTE);
        self.timing = CrtTiming::from_registers(&registers);
        self.displayed_start = registers.start_address();
        self.registers = registers;
        self.memory.clear();
        self.now_ns = 0;
        self.next_retrace_ns = 0;
        self.status_until_ns = 0;
        self.frame_count = 0;
        self.retrace_stuck = None;
        self.register_writes = 0;
        self.colour_writes = 0;
        self.counts = BusCounts::default();
        self.guard = WriteGuard::new();
    }

    // --- Registers, as the hardware holds them.

    /// Miscellaneous Output.
    pub fn misc_output(&self) -> u8 {
        self.registers.misc_output
    }

    /// A Sequencer register.
    pub fn sequencer(&self, register: Sequencer) -> u8 {
        self.registers.sequencer(register)
    }

    /// A CRTC register.
    pub fn crtc(&self, register: Crtc) -> u8 {
        self.registers.crtc(register)
    }

    /// A Graphics Controller register.
    pub fn graphics(&self, register: Graphics) -> u8 {
        self.registers.graphics(register)
    }

    /// An Attribute Controller register.
    pub fn attribute(&self, register: Attribute) -> u8 {
        self.registers.attribute[register.slot()]
    }

    /// The index last written to `pair`'s index port: the register its
    /// data port reaches now.
    pub fn pair_index(&self, pair: IndexedPair) -> u8 {
        self.registers.pair_index(pair)
    }

    /// DAC entry `index`, 6 bits per component.
    pub fn dac_entry(&self, index: u8) -> Rgb6 {
        self.registers.dac.palette[usize::from(index)]
    }

    /// The DAC pixel mask.
    pub fn dac_pixel_mask(&self) -> u8 {
        self.registers.dac.pixel_mask
    }

    /// Whether Bochs VBE (DISPI) is enabled.
    pub fn vbe_enabled(&self) -> bool {
        self.registers.vbe_enabled()
    }

    // --- Video memory.

    /// Plane `plane` (0..=3).
    pub fn plane(&self, plane: usize) -> &[u8; PLANE_BYTES] {
        &self.memory.planes[plane]
    }

    /// The four latches, as the last planar read loaded them.
    pub fn latches(&self) -> [u8; PLANE_COUNT] {
        self.memory.latches
    }

    // --- Time.

    /// The simulated clock.
    pub fn now_ns(&self) -> u64 {
        self.now_ns
    }

    /// Lets time pass without bus activity.
    pub fn advance_ns(&mut self, ns: u64) {
        let until = self.now_ns.saturating_add(ns);
        if until >= self.next_retrace_ns {
            let retraces = self.timing.retraces_started_by(until)
                - self.timing.retraces_started_by(self.now_ns);
            if retraces > 0 {
                // The CRTC latches the start address at the start of vertical retrace.
                self.frame_count += retraces;
                self.displayed_start = self.registers.start_address();
            }
            self.next_retrace_ns = self.timing.next_retrace_ns(until);
        }
        self.now_ns = until;
    }

    /// Lets a whole frame pass, so a vertical retrace latches the start
    /// address as it stands: a real VGA shows any change within a frame.
    /// Used to present a screen that no page flip waited for (text written
    /// after a mode set, whose start address is latched only at a retrace).
    pub fn let_a_frame_pass(&mut self) {
        self.advance_ns(self.timing.frame_ns().max(1));
    }

    /// The frame timing the registers program now.
    pub fn timing(&self) -> CrtTiming {
        self.timing
    }

    /// The start address latched at the last vertical retrace: the one displayed.
    pub fn displayed_start(&self) -> u16 {
        self.displayed_start
    }

    /// Vertical retraces started so far.
    pub fn frame_count(&self) -> u64 {
        self.frame_count
    }

    /// Forces Input Status 1's vertical retrace bit to a constant (None: follow
    /// the clock), to test that waits on it are bounded. The CRT itself keeps
    /// time: start addresses are still latched by the clock, so the picture
    /// still follows page flips.
    pub fn set_retrace_stuck(&mut self, stuck: Option<bool>) {
        self.retrace_stuck = stuck;
    }

    /// Writes so far that may have changed a colour on screen (the DAC, the
    /// pixel mask, blanking): unchanged, the colours are as they were.
    pub(crate) fn colour_writes(&self) -> u64 {
        self.colour_writes
    }

    // --- Probes.

    /// Bus operations so far.
    pub fn counts(&self) -> BusCounts {
        self.counts
    }

    /// Zeroes the bus operation counts.
    pub fn reset_counts(&mut self) {
        self.counts = BusCounts::default();
    }

    /// Video memory writes outside `allowed` (CPU offsets) are counted as
    /// violations from now on; None allows everything. Clears past violations.
    pub fn set_write_guard(&mut self, allowed: Option<Range<u16>>) {
        self.guard.set(allowed);
    }

    /// Writes outside the guarded range since it was set.
    pub fn guard_violations(&self) -> u64 {
        self.guard.violations()
    }

    /// The offset of the first write outside the guarded range.
    pub fn first_violation(&self) -> Option<u16> {
        self.guard.first_violation()
    }

    // --- Bus internals.

    fn port_write(&mut self, port: Port, value: u8) {
        self.register_writes += 1;
        let colour = match port {
            Port::DAC_DATA | Port::DAC_PIXEL_MASK | Port::ATTRIBUTE_INDEX => true,
            // Not the Map Mask, written every frame: Clocking Mode's screen off.
            Port::SEQUENCER_DATA => {
                self.registers.sequencer_index() == Sequencer::ClockingMode.index()
            }
            _ => false,
        };
        if colour {
            self.colour_writes += 1;
        }
        self.registers.write_port(port, value);
        // Misc Output, Clocking Mode and the CRTC set the timing; new timing
        // re-times the beam, so the next step asks it again.
        let timing = CrtTiming::from_registers(&self.registers);
        if timing != self.timing {
            self.timing = timing;
            self.next_retrace_ns = self.now_ns;
            self.status_until_ns = self.now_ns;
        }
    }

    fn input_status_1(&mut self) -> u8 {
        self.registers.reset_attribute_flip_flop();
        if self.now_ns >= self.status_until_ns {
            (self.status_bits, self.status_until_ns) = self.timing.status_until(self.now_ns);
        }
        let bits = self.status_bits;
        match self.retrace_stuck {
            None => bits,
            Some(true) => bits | status::VERTICAL_RETRACE,
            Some(false) => bits & !status::VERTICAL_RETRACE,
        }
    }

    fn vram_write(&mut self, offset: u16, value: u8) {
        self.guard.check(offset);
        self.memory.write(&self.registers, offset, value);
    }
}

impl VgaBus for SoftVga {
    fn write_port8(&mut self, port: Port, value: u8) {
        self.counts.port_writes += 1;
        self.advance_ns(PORT_ACCESS_NS);
        self.port_write(port, value);
    }

    fn write_port16(&mut self, port: Port, value: u16) {
        self.counts.port_writes += 1;
        self.advance_ns(PORT_ACCESS_NS);
        if port == Port::VBE_DISPI_INDEX || port == Port::VBE_DISPI_DATA {
            self.register_writes += 1;
            self.registers.write_dispi(port, value);
        } else {
            let [low, high] = value.to_le_bytes();
            self.port_write(port, low);
            if let Some(data_port) = port.data() {
                self.port_write(data_port, high);
            }
        }
    }

    fn read_port8(&mut self, port: Port) -> u8 {
        self.counts.port_reads += 1;
        self.advance_ns(PORT_ACCESS_NS);
        if port == self.registers.input_status_1_port() {
            self.input_status_1()
        } else {
            self.registers.read_port(port)
        }
    }

    fn read_port16(&mut self, port: Port) -> u16 {
        if port == Port::VBE_DISPI_INDEX || port == Port::VBE_DISPI_DATA {
            self.counts.port_reads += 1;
            self.advance_ns(PORT_ACCESS_NS);
            self.registers.read_dispi_port(port)
        } else {
            let low = self.read_port8(port);
            let high = port.data().map_or(0xFF, |next| self.read_port8(next));
            u16::from_le_bytes([low, high])
        }
    }

    fn write_vram8(&mut self, offset: u16, value: u8) {
        self.counts.vram_writes += 1;
        self.advance_ns(VRAM_ACCESS_NS);
        self.vram_write(offset, value);
    }

    fn read_vram8(&mut self, offset: u16) -> u8 {
        self.counts.vram_reads += 1;
        self.advance_ns(VRAM_ACCESS_NS);
        self.memory.read(&self.registers, offset)
    }

    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        let end = (u32::from(offset) + u32::from(count)).min(CPU_WINDOW_BYTES);
        let bytes = u64::from(end.saturating_sub(u32::from(offset)));
        self.counts.vram_writes += bytes;
        self.advance_ns(bytes * VRAM_ACCESS_NS);
        for address in u32::from(offset)..end {
            // Below CPU_WINDOW_BYTES, so it fits.
            self.vram_write(address as u16, value);
        }
    }
    /// A real VGA shows what was written within a frame; the model lets one
    /// pass, so a start address written since the last retrace is latched.
    /// Without it a screen drawn with no flip after it (the fault panel's
    /// text mode, set while page 1 or the report's page 2 was shown) would
    /// still scan out from the old page's address.
    fn flush(&mut self) {
        self.let_a_frame_pass();
    }
    /// The simulated clock, which times the retraces a wait looks for.
    fn now_micros(&mut self) -> Option<u64> {
        Some(self.now_ns / NANOS_PER_MICRO)
    }
    /// The reads one after another, as [`poll_by_reads`] makes them, except
    /// that the reads of Input Status 1 that must give the bits just read
    /// are taken in one step: the bits hold until the beam's next edge
    /// (`status_until_ns`), and the vertical retrace bit until a line where
    /// the retrace starts or ends, so the reads before then are counted and
    /// their microseconds pass at once. A wait for the retrace, thousands of
    /// reads, is a few steps. It ends with the count, the clock, the frames
    /// latched and the answer that the reads one by one would give
    /// (`poll_tests`).
    fn poll_port8(&mut self, port: Port, mask: u8, value: u8, limit_micros: u64) -> bool {
        // The waited microseconds below are the reads made.
        const _: () = assert!(PORT_ACCESS_NS == NANOS_PER_MICRO);
        if port != self.registers.input_status_1_port() {
            return poll_by_reads(self, port, mask, value, limit_micros);
        }
        let start = self.now_ns / NANOS_PER_MICRO;
        loop {
            if self.read_port8(port) & mask == value {
                return true;
            }
            // A read takes PORT_ACCESS_NS, a microsecond, so the reads so
            // far are the microseconds waited, as poll_by_reads counts them.
            let waited = self.now_ns / NANOS_PER_MICRO - start;
            if waited >= limit_micros {
                return false;
            }
            // The next reads fall at now + k µs, k = 1, 2, ...; those before
            // `until` read these bits again under `mask`: the next edge of
            // the beam, or where the vertical retrace bit may next change
            // if that bit is all the wait looks at (or it is stuck, and
            // then no read will ever differ).
            let until = if mask & !status::VERTICAL_RETRACE == 0 {
                match self.retrace_stuck {
                    None => self.timing.retrace_bit_until(self.now_ns),
                    Some(_) => u64::MAX,
                }
            } else {
                self.status_until_ns
            };
            let same = until.saturating_sub(self.now_ns + 1) / PORT_ACCESS_NS;
            let skipped = same.min(limit_micros - waited);
            if skipped > 0 {
                self.counts.port_reads += skipped;
                self.advance_ns(skipped * PORT_ACCESS_NS);
                if waited + skipped >= limit_micros {
                    return false;
                }
            }
        }
    }
}

#[cfg(test)]
mod power_on_tests {
    use super::*;
    extern crate std;
    use std::boxed::Box;
    use std::format;

    /// Every field, compared: `power_on` must give exactly what `new` does.
    fn assert_same_state(a: &SoftVga, b: &SoftVga) {
        assert_eq!(format!("{:?}", a.registers), format!("{:?}", b.registers));
        assert_eq!(a.memory.planes, b.memory.planes);
        assert_eq!(a.memory.latches, b.memory.latches);
        assert_eq!(a.memory.writes, b.memory.writes);
        assert_eq!(a.memory.block_written, b.memory.block_written);
        assert_eq!(a.timing, b.timing);
        assert_eq!(
            (a.now_ns, a.displayed_start, a.frame_count, a.retrace_stuck),
            (b.now_ns, b.displayed_start, b.frame_count, b.retrace_stuck)
        );
        assert_eq!(
            (a.register_writes, a.colour_writes, a.counts),
            (b.register_writes, b.colour_writes, b.counts)
        );
        assert_eq!(format!("{:?}", a.guard), format!("{:?}", b.guard));
    }

    #[test]
    fn power_on_gives_what_new_gives_from_unpowered_and_from_a_used_model() {
        let new = Box::new(SoftVga::new());
        let mut vga = Box::new(SoftVga::unpowered());
        vga.power_on();
        assert_same_state(&vga, &new);

        // Used: registers, memory, clock, counts and guard all changed.
        crate::ModeX::new(&mut *vga).set_mode();
        vga.write_vram8(0x10, 0xAB);
        vga.advance_ns(1_000_000);
        vga.set_retrace_stuck(Some(true));
        vga.power_on();
        assert_same_state(&vga, &new);
    }
}
