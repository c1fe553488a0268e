//! The demo as the kernel runs it, on the software VGA: scan codes in, one
//! retrace period (a frame of the 60 Hz display) per [`Machine::frame`].
//!
//! The app's clock is the model's simulated clock, not the host's, so the
//! statistics (frame rate, frame time) read as they would on a VGA whose
//! every port access costs ISA time, and a run is the same on any host.

use std::cell::Cell;
use std::rc::Rc;

use demo::app::App;
use demo::frame::Renderer;
use modex::regs::{Crtc, Graphics, IndexedPair, Port, Sequencer};
use modex::soft::SoftVga;
use modex::{ModeX, VgaBus, PAGE_BYTES, SCREEN_HEIGHT, SCREEN_WIDTH};

use crate::inspector::{frame_cost, FrameCost};
use crate::keys::Scancode;
use crate::oplog::{BusOp, LoggedOp, OpLog};

/// Pixels in the Mode X picture.
pub const PICTURE_PIXELS: usize = (SCREEN_WIDTH * SCREEN_HEIGHT) as usize;
/// How far the model's clock moves at a time while it waits, idle, for the
/// next vertical retrace: fine enough that the wait ends within 1 % of a frame.
const IDLE_STEP_NS: u64 = 10_000;
const NANOS_PER_MICRO: u64 = 1_000;
const PLANE_COUNT: usize = 4;
/// A page's bytes in each plane.
const PAGE_BYTES_USIZE: usize = PAGE_BYTES as usize;

/// The software VGA with the model's time in microseconds beside it, kept up
/// to date after every bus operation for the app's clock to read while the
/// driver holds the bus; and, while a frame is recorded, its operations.
struct ClockedVga {
    soft: Box<SoftVga>,
    micros: Rc<Cell<u64>>,
    log: OpLog,
    /// Registers whose value the program's writes do not change
    /// ([`Machine::hold`]).
    held: Vec<HeldRegister>,
}

/// A register a program writes by port: Misc Output, or one of an
/// index/data pair's (its index). The register lab holds its edits so.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HeldRegister {
    /// Miscellaneous Output.
    MiscOutput,
    /// Register `index` of the pair.
    Pair(IndexedPair, u8),
}

/// One byte-wide port access of [`Machine::access_ports`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PortAccess {
    /// An OUT of the byte.
    Write(Port, u8),
    /// An IN, its value dropped (Input Status 1's read resets the
    /// Attribute Controller's flip-flop).
    Read(Port),
}

/// The value register `index` of `pair` holds in `soft` (0 past the group).
fn pair_value(soft: &SoftVga, pair: IndexedPair, index: u8) -> u8 {
    match pair {
        IndexedPair::Sequencer => Sequencer::from_index(index).map(|r| soft.sequencer(r)),
        IndexedPair::Graphics => Graphics::from_index(index).map(|r| soft.graphics(r)),
        IndexedPair::Crtc => Crtc::from_index(index).map(|r| soft.crtc(r)),
    }
    .unwrap_or(0)
}

/// The pair whose data port `port` is.
fn pair_of_data_port(port: Port) -> Option<IndexedPair> {
    [
        IndexedPair::Sequencer,
        IndexedPair::Graphics,
        IndexedPair::Crtc,
    ]
    .into_iter()
    .find(|pair| pair.data_port() == port)
}

impl ClockedVga {
    /// The byte a program's 8-bit write of `value` to `port` becomes: a
    /// held register's own value again, so the write costs what it costs
    /// and changes nothing.
    fn held_byte(&self, port: Port, value: u8) -> u8 {
        if self.held.is_empty() {
            return value;
        }
        let held = if port == Port::MISC_OUTPUT_WRITE {
            self.held
                .contains(&HeldRegister::MiscOutput)
                .then(|| self.soft.misc_output())
        } else {
            pair_of_data_port(port).and_then(|pair| {
                let index = self.soft.pair_index(pair);
                self.held
                    .contains(&HeldRegister::Pair(pair, index))
                    .then(|| pair_value(&self.soft, pair, index))
            })
        };
        held.unwrap_or(value)
    }

    /// The word a program's 16-bit write of `value` to `port` becomes: an
    /// index port's data byte is the held register's own value.
    fn held_word(&self, port: Port, value: u16) -> u16 {
        if self.held.is_empty() {
            return value;
        }
        let [index, _] = value.to_le_bytes();
        let pair = [
            IndexedPair::Sequencer,
            IndexedPair::Graphics,
            IndexedPair::Crtc,
        ]
        .into_iter()
        .find(|pair| pair.index_port() == port);
        match pair {
            Some(pair) if self.held.contains(&HeldRegister::Pair(pair, index)) => {
                u16::from_le_bytes([index, pair_value(&self.soft, pair, index)])
            }
            _ => value,
        }
    }

    fn tick(&self) {
        self.micros.set(self.soft.now_ns() / NANOS_PER_MICRO);
    }

    /// Does `op` on the software VGA (through `action`), logs it, and ticks.
    fn operate<T>(
        &mut self,
        op: impl FnOnce(T) -> BusOp,
        action: impl FnOnce(&mut SoftVga) -> T,
    ) -> T
    where
        T: Copy,
    {
        let start_ns = self.soft.now_ns();
        let result = action(&mut self.soft);
        self.log.note(op(result), start_ns);
        self.tick();
        result
    }
}

impl VgaBus for ClockedVga {
    fn write_port8(&mut self, port: Port, value: u8) {
        let value = self.held_byte(port, value);
        self.operate(
            |()| BusOp::WritePort8 { port, value },
            |soft| soft.write_port8(port, value),
        );
    }
    fn write_port16(&mut self, port: Port, value: u16) {
        let value = self.held_word(port, value);
        self.operate(
            |()| BusOp::WritePort16 { port, value },
            |soft| soft.write_port16(port, value),
        );
    }
    fn read_port8(&mut self, port: Port) -> u8 {
        self.operate(
            |value| BusOp::ReadPort8 { port, value },
            |soft| soft.read_port8(port),
        )
    }
    fn read_port16(&mut self, port: Port) -> u16 {
        self.operate(
            |value| BusOp::ReadPort16 { port, value },
            |soft| soft.read_port16(port),
        )
    }
    fn write_vram8(&mut self, offset: u16, value: u8) {
        self.operate(
            |()| BusOp::WriteVram8 { offset, value },
            |soft| soft.write_vram8(offset, value),
        );
    }
    fn read_vram8(&mut self, offset: u16) -> u8 {
        self.operate(
            |value| BusOp::ReadVram8 { offset, value },
            |soft| soft.read_vram8(offset),
        )
    }
    fn fill_vram(&mut self, offset: u16, count: u16, value: u8) {
        self.operate(
            |()| BusOp::FillVram {
                offset,
                count,
                value,
            },
            |soft| soft.fill_vram(offset, count, value),
        );
    }
    fn flush(&mut self) {
        self.operate(|()| BusOp::Flush, |soft| soft.flush());
    }
    fn now_micros(&mut self) -> Option<u64> {
        self.soft.now_micros()
    }
    /// A frame being recorded logs each read, as `poll_by_reads` makes
    /// them; any other lets the software VGA take its stretches of equal
    /// reads at once, and the clock is read once at the end: nothing reads
    /// it in between.
    fn poll_port8(&mut self, port: Port, mask: u8, value: u8, limit_micros: u64) -> bool {
        if self.log.recording() {
            return modex::poll_by_reads(self, port, mask, value, limit_micros);
        }
        let done = self.soft.poll_port8(port, mask, value, limit_micros);
        self.tick();
        done
    }
    fn enter(&mut self, function: &'static str) {
        self.log.enter(function);
    }
    fn leave(&mut self) {
        self.log.leave();
    }
}

/// The demo on a software VGA in Mode X.
pub struct Machine {
    /// One driver for the whole run, as on the kernel, so its register cache
    /// saves the same port writes there and here.
    vga: ModeX<ClockedVga>,
    /// The renderer boxed: its page images and the page update's room for
    /// writes are about 600 KiB, too much to build and move on a test
    /// thread's stack.
    app: App<Box<Renderer>>,
    micros: Rc<Cell<u64>>,
    frames: u64,
    /// The page the frame draws into, each plane's bytes before the frame,
    /// for the lower bound.
    page_before: Box<[[u8; PAGE_BYTES_USIZE]; PLANE_COUNT]>,
    last_cost: FrameCost,
}

impl Default for Machine {
    fn default() -> Self {
        Self::new()
    }
}

impl Machine {
    /// Sets Mode X and draws the first frame, as the kernel does at boot
    /// before it reads any key.
    pub fn new() -> Self {
        let mut machine = Self::with_mode_set(OpLog::default());
        machine.frame();
        machine
    }

    /// As [`Machine::new`], with the bus operations of the mode set and the
    /// first frame, from a VGA as the BIOS leaves it (`SoftVga::new`).
    pub fn new_logged() -> (Self, Vec<LoggedOp>) {
        let mut log = OpLog::default();
        log.start();
        let mut machine = Self::with_mode_set(log);
        machine.frame();
        let log = machine.vga.bus_mut().log.take();
        (machine, log)
    }

    /// The machine with Mode X set (through a bus keeping `log`), no frame run.
    fn with_mode_set(log: OpLog) -> Self {
        let micros = Rc::new(Cell::new(0));
        let bus = ClockedVga {
            soft: Box::new(SoftVga::new()),
            micros: Rc::clone(&micros),
            log,
            held: Vec::new(),
        };
        let mut vga = ModeX::new(bus);
        vga.set_mode();
        Machine {
            vga,
            app: App::with_renderer(Box::new(Renderer::new())),
            micros,
            frames: 0,
            page_before: Box::new([[0; PAGE_BYTES_USIZE]; PLANE_COUNT]),
            last_cost: FrameCost::default(),
        }
    }

    /// Scan-code bytes, decoded as the kernel decodes its keyboard's.
    pub fn feed(&mut self, bytes: &[u8]) {
        for &byte in bytes {
            self.app.feed_scancode(byte);
        }
    }

    /// A key pressed and released.
    pub fn tap(&mut self, key: Scancode) {
        self.feed(&crate::keys::tap(key));
    }

    /// One frame: the app draws and flips if anything moved (the flip waits
    /// for vertical retrace on the model's clock), otherwise the model's clock
    /// runs to the next retrace. Returns what the frame cost on the bus.
    pub fn frame(&mut self) -> FrameCost {
        let soft = &self.vga.bus().soft;
        let retraces_before = soft.frame_count();
        let counts_before = soft.counts();
        // The renderer draws into the page not shown and then shows it: that
        // page's bytes are all the lower bound needs from before the frame
        // (a quarter of a copy of every plane).
        let drawn_page = self.app.shown_page().other();
        let drawn_base = usize::from(drawn_page.base());
        for (plane, copy) in self.page_before.iter_mut().enumerate() {
            copy.copy_from_slice(&soft.plane(plane)[drawn_base..][..PAGE_BYTES_USIZE]);
        }
        let micros = Rc::clone(&self.micros);
        let drawn = self
            .app
            .step(&mut self.vga, &move || micros.get())
            .is_some();
        if self.app.report_to_draw().is_some() {
            self.show_report();
            // No log to scroll.
            self.app.report_drawn(0);
        }
        // A flip has waited for the retrace already; an idle frame waits here.
        self.idle_until_retrace(retraces_before);
        let soft = &self.vga.bus().soft;
        // A drawn frame is the page the flip just put on screen: its bytes
        // in each plane, before the frame and now. A flip that showed the
        // page shown before (the demo's page again after the report's)
        // drew nothing into it: the renderer never draws into the page on
        // screen, so its bytes before are its bytes now.
        let shown = self.app.shown_page();
        let shown_base = usize::from(shown.base());
        let page_bytes = if drawn { PAGE_BYTES_USIZE } else { 0 };
        let new_planes: [&[u8]; 4] =
            std::array::from_fn(|plane| &soft.plane(plane)[shown_base..][..page_bytes]);
        let old_planes: [&[u8]; 4] = if shown == drawn_page {
            std::array::from_fn(|plane| &self.page_before[plane][..page_bytes])
        } else {
            new_planes
        };
        self.frames += 1;
        self.last_cost = frame_cost(counts_before, soft.counts(), old_planes, new_planes);
        self.last_cost
    }

    /// One frame as [`Machine::frame`] runs it, with every bus operation it
    /// made, in order, each with the `modex` functions that issued it.
    pub fn frame_logged(&mut self) -> (FrameCost, Vec<LoggedOp>) {
        self.vga.bus_mut().log.start();
        let cost = self.frame();
        (cost, self.vga.bus_mut().log.take())
    }

    /// The report screen (I): the simulator has no machine to report on and
    /// no kernel log, so it says so; the layout is the kernel's.
    fn show_report(&mut self) {
        let facts = [
            "modex-cube simulator: no machine to report on.",
            "On the machine this screen shows the build, the",
            "firmware, CPU, display adapter and path, keyboard,",
            "clock, counters and the kernel's log, and a QR code.",
        ];
        let report = demo::report::Report {
            facts: &facts,
            log: &[],
            position: demo::report::LogPosition::default(),
        };
        let mut image = Box::new([0u8; modex::PAGE_PIXELS]);
        demo::report::show(&mut self.vga, &mut image, &report);
    }

    /// Lets the model's clock run, with no bus activity, until a vertical
    /// retrace after the `retraces_before`-th starts (a flip waits for one).
    fn idle_until_retrace(&mut self, retraces_before: u64) {
        let bus = self.vga.bus_mut();
        while bus.soft.frame_count() == retraces_before {
            bus.soft.advance_ns(IDLE_STEP_NS);
        }
        bus.tick();
    }

    /// Makes `accesses` on the VGA's ports, in order, as another program on
    /// the machine would (a register tweaker): through the bus, behind the
    /// driver's back, so the driver then forgets what it cached. Held
    /// registers take these writes; then a frame passes, so that the VGA
    /// shows them (a start address is latched at a retrace).
    pub fn access_ports(&mut self, accesses: &[PortAccess]) {
        let bus = self.vga.bus_mut();
        for &access in accesses {
            match access {
                PortAccess::Write(port, value) => bus.operate(
                    |()| BusOp::WritePort8 { port, value },
                    |soft| soft.write_port8(port, value),
                ),
                PortAccess::Read(port) => {
                    bus.operate(
                        |value| BusOp::ReadPort8 { port, value },
                        |soft| soft.read_port8(port),
                    );
                }
            }
        }
        bus.flush();
        self.vga.invalidate_caches();
    }

    /// From now on the program's writes leave `held` as they are (each
    /// write still costs its time, writing the register's own value): the
    /// register lab's edits stay while the demo runs. Empty: none held.
    pub fn hold(&mut self, held: &[HeldRegister]) {
        let bus = self.vga.bus_mut();
        bus.held.clear();
        bus.held.extend_from_slice(held);
    }

    /// The software VGA.
    pub fn vga(&self) -> &SoftVga {
        &self.vga.bus().soft
    }

    /// The demo.
    pub fn app(&self) -> &App<Box<Renderer>> {
        &self.app
    }

    /// Frames run so far, the first (drawn at start) included.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// What the last frame cost on the bus.
    pub fn last_cost(&self) -> FrameCost {
        self.last_cost
    }

    /// The picture on screen as DAC indices, row by row.
    pub fn scanout_indices(&self) -> Vec<u8> {
        let mut pixels = vec![0; PICTURE_PIXELS];
        let size = self.vga().scanout_indices(&mut pixels);
        assert_eq!(size, (320, 240), "the software VGA is not showing Mode X");
        pixels
    }

    /// The picture on screen as 8-bit RGB, row by row.
    pub fn scanout_rgb(&self) -> Vec<[u8; 3]> {
        let mut pixels = vec![[0; 3]; PICTURE_PIXELS];
        let size = self.vga().scanout_rgb(&mut pixels);
        assert_eq!(size, (320, 240), "the software VGA is not showing Mode X");
        pixels
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::keys::scancode_for_name;

    fn key(name: &str) -> Scancode {
        scancode_for_name(name).unwrap()
    }

    #[test]
    fn every_frame_is_one_retrace_period_of_the_model() {
        let mut machine = Machine::new();
        machine.tap(key("r")); // still: the frames after the next are idle
        for _ in 0..5 {
            let before = machine.vga().frame_count();
            machine.frame();
            assert_eq!(machine.vga().frame_count(), before + 1);
        }
        assert_eq!(
            machine.last_cost().vram_writes,
            0,
            "idle frames draw nothing"
        );
    }

    #[test]
    fn the_statistics_measure_the_model_clock() {
        let mut machine = Machine::new();
        machine.tap(key("s"));
        for _ in 0..150 {
            machine.frame();
        }
        let stats = machine.app().stats();
        // A spinning cube is drawn and flipped every retrace: Mode X's 527
        // lines of 800 dots at 25.175 MHz make 59.7 per second.
        let frame_ns = machine.vga().timing().frame_ns();
        let tenths = 10 * 1_000_000_000 / frame_ns;
        assert_eq!(tenths, 597);
        assert_eq!(stats.frames_per_second_tenths, Some(tenths as u32));
        let frame_micros = u32::try_from(frame_ns / 1000).unwrap();
        assert!(stats.frame_micros > 0 && stats.frame_micros < frame_micros);
    }

    /// Runs `test` with 16 MiB of stack: a frame of the demo takes about
    /// 2 MiB in a test build, all a test thread has, and these tests hold a
    /// second machine or a copy of the VGA besides.
    fn on_big_stack(test: impl FnOnce() + Send + 'static) {
        let thread = std::thread::Builder::new().stack_size(16 << 20).spawn(test);
        if let Err(panic) = thread.expect("a test thread starts").join() {
            std::panic::resume_unwind(panic);
        }
    }

    /// Everything a picture or the inspector shows of a software VGA.
    fn visible_state(vga: &SoftVga) -> (Vec<u8>, u16, Vec<modex::Rgb6>, u8) {
        let planes = (0..PLANE_COUNT)
            .flat_map(|p| vga.plane(p).to_vec())
            .collect();
        let dac = (0..=255).map(|i| vga.dac_entry(i)).collect();
        let map_mask = vga.sequencer(modex::regs::Sequencer::MapMask);
        (planes, vga.displayed_start(), dac, map_mask)
    }

    #[test]
    fn a_logged_frame_replayed_on_a_copy_gives_the_same_vga() {
        on_big_stack(|| {
            let mut machine = Machine::new();
            machine.tap(key("m")); // several cubes: many Map Masks a frame
            machine.frame();
            for _ in 0..3 {
                let mut copy = Box::new(machine.vga().clone());
                let (_, log) = machine.frame_logged();
                assert!(log.len() > 10, "{} entries", log.len());
                for entry in &log {
                    entry.replay(&mut copy);
                }
                assert!(visible_state(&copy) == visible_state(machine.vga()));
            }
            // Not recording: no log kept.
            machine.frame();
            assert!(machine.vga.bus_mut().log.take().is_empty());
        });
    }

    #[test]
    fn the_mode_set_is_logged_from_the_vga_the_bios_leaves() {
        on_big_stack(|| {
            let (machine, log) = Machine::new_logged();
            let first = log.first().expect("the mode set is logged");
            assert_eq!(first.callers.names(), ["ModeX::set_mode", "ModeX::program"]);
            let mut copy = Box::new(SoftVga::new());
            for entry in &log {
                entry.replay(&mut copy);
            }
            assert!(visible_state(&copy) == visible_state(machine.vga()));
            assert!(visible_state(Machine::new().vga()) == visible_state(machine.vga()));
        });
    }

    #[test]
    fn each_logged_operation_names_the_modex_function_that_issued_it() {
        let mut machine = Machine::new();
        let (_, log) = machine.frame_logged();
        let map_mask = log
            .iter()
            .find(|entry| {
                matches!(entry.op, BusOp::WritePort16 { port, value }
                    if port == Port::SEQUENCER_INDEX && value & 0xFF == 2)
            })
            .expect("a frame sets the Map Mask");
        assert_eq!(map_mask.callers.innermost(), Some("ModeX::update_page"));
        let status = log
            .iter()
            .find(|entry| matches!(entry.op, BusOp::ReadPort8 { port, .. } if port == Port::INPUT_STATUS_1))
            .expect("a flip waits for retrace");
        assert_eq!(status.callers.names(), ["ModeX::show_page"]);
        assert!(status.repeat > 1, "a wait is one entry with a count");
    }

    /// The lower bound from the copy of the drawn page alone is the one a
    /// copy of all video memory before each frame gives, through the crowd,
    /// the report screen (I) and back, and idle frames.
    #[test]
    fn the_lower_bound_needs_only_the_drawn_page_before_the_frame() {
        on_big_stack(|| {
            let mut machine = Machine::new();
            let script = [
                (1, "m"),
                (6, "i"),
                (9, "i"),
                (12, "x"),
                (16, "r"),
                (20, "s"),
            ];
            let mut bounded = 0;
            for frame in 0..24 {
                for (_, name) in script.iter().filter(|(at, _)| *at == frame) {
                    machine.tap(key(name));
                }
                let before: Vec<Vec<u8>> = (0..PLANE_COUNT)
                    .map(|plane| machine.vga().plane(plane).to_vec())
                    .collect();
                let cost = machine.frame();
                let base = usize::from(machine.app().shown_page().base());
                let page = |plane: &[u8]| plane[base..][..PAGE_BYTES_USIZE].to_vec();
                let old: Vec<Vec<u8>> = before.iter().map(|plane| page(plane)).collect();
                let new: Vec<Vec<u8>> = (0..PLANE_COUNT)
                    .map(|plane| page(machine.vga().plane(plane)))
                    .collect();
                let old: [&[u8]; 4] = std::array::from_fn(|plane| old[plane].as_slice());
                let new: [&[u8]; 4] = std::array::from_fn(|plane| new[plane].as_slice());
                let full = crate::inspector::lower_bound_in_planes(old, new);
                assert_eq!(cost.lower_bound, full, "frame {frame}");
                bounded += u32::from(full > 0);
            }
            assert!(bounded > 10, "{bounded} frames changed the picture");
        });
    }

    #[test]
    fn keys_reach_the_demo_through_the_kernels_decoder() {
        let mut machine = Machine::new();
        for name in ["r", "left", "kp_4", "v", "f1"] {
            machine.tap(key(name));
        }
        // V is the simulator's: no command on the machine.
        assert_eq!(machine.app().commands(), 4);
        assert!(!machine.app().paused());
    }
}
