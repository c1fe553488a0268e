//! The screen on UEFI boots and on machines without a legacy VGA: Mode X runs
//! on the software VGA, and each page flip presents its picture, scaled, into
//! the framebuffer the bootloader handed over (UEFI GOP's, or the VESA linear
//! mode of the BIOS stage), writing only what changed since the last one.
//!
//! The fault handler shows its panel here too. It must not depend on anything
//! the fault may have broken: no allocation (there is no heap), no lock the
//! interrupted code may hold. So everything the panel needs — the software
//! VGA, the presenter and the framebuffer — lives in statics taken once at
//! start-up, and the handler gets them through `FAULT_DISPLAY`, an atomic
//! pointer it takes with a swap: the first fault takes it, a fault inside the
//! handler finds it empty and reports on serial only. The interrupted code
//! still holds references to the same memory, but it never runs again (the
//! handler halts), and the panel reprograms the whole model from scratch, so
//! a half-done register write or present does not matter.

use crate::{serial_println, time};
use bootloader_api::info::{FrameBuffer, FrameBufferInfo, PixelFormat};
use clock::pacing::FRAME_MICROS;
use core::sync::atomic::{AtomicPtr, Ordering};
use modex::present::{
    FirmwareFormat, FirmwareFramebuffer, FramebufferLayout, PackedFormat, PixelOrder, Placement,
    Presenter,
};
use modex::soft::SoftVga;
use modex::{ModeX, SCREEN_HEIGHT, SCREEN_WIDTH};
use spin::{Mutex, MutexGuard};

/// The software VGA standing in for the missing one, powered on at compile
/// time: at ~300 KiB it must never pass through the stack.
static SOFT_VGA: Mutex<SoftVga> = Mutex::new(SoftVga::new());

/// The last presented picture, the new one and what the last four presents
/// changed, ~880 KiB of zeros (.bss).
static PRESENTER: Mutex<Presenter> = Mutex::new(Presenter::new());

/// The display, once made; the fault handler's way to it (see the module
/// comment). Null before start-up and after a fault took it.
static FAULT_DISPLAY: AtomicPtr<Display> = AtomicPtr::new(core::ptr::null_mut());

/// A report of present costs every this many presents (about ten seconds).
const COST_REPORT_PRESENTS: u64 = 600;

/// The bootloader's framebuffer as the portable presenter sees it
/// ([`FirmwareFramebuffer::layout`] decides; this only converts and logs).
/// A framebuffer that cannot be drawn into safely gets a layout with no
/// pixels: the demo runs on, and serial says why the screen stays as it is.
pub fn layout_of(info: &FrameBufferInfo) -> FramebufferLayout {
    let format = match info.pixel_format {
        PixelFormat::Rgb => FirmwareFormat::Rgb,
        PixelFormat::Bgr => FirmwareFormat::Bgr,
        PixelFormat::U8 => FirmwareFormat::Grey,
        PixelFormat::Unknown {
            red_position,
            green_position,
            blue_position,
        } => FirmwareFormat::BitOffsets {
            red: red_position,
            green: green_position,
            blue: blue_position,
        },
        _ => FirmwareFormat::Other,
    };
    let framebuffer = FirmwareFramebuffer {
        byte_len: info.byte_len,
        width: info.width,
        height: info.height,
        stride: info.stride,
        bytes_per_pixel: info.bytes_per_pixel,
        format,
    };
    match framebuffer.layout() {
        Ok(choice) => {
            if choice.grey_instead {
                serial_println!(
                    "display: pixel format {:?} with {} bytes/pixel not understood; showing grey",
                    info.pixel_format,
                    info.bytes_per_pixel
                );
            }
            choice.layout
        }
        Err(refusal) => {
            serial_println!(
                "display: the framebuffer is refused, nothing is drawn on it: {}",
                refusal
            );
            FramebufferLayout::NOTHING
        }
    }
}

/// The software VGA alone, once, when there is no framebuffer to present it
/// into: the demo runs on it unseen.
pub fn soft_vga_alone() -> &'static mut SoftVga {
    MutexGuard::leak(SOFT_VGA.try_lock().expect("the software VGA is taken once"))
}

/// Takes over the framebuffer and the software VGA, once: returns the model
/// for the mirror to drive and the display it presents to.
pub fn take_over(
    framebuffer: &'static mut FrameBuffer,
    physical_memory_offset: u64,
) -> (&'static mut SoftVga, &'static mut Display) {
    static DISPLAY: Mutex<Option<Display>> = Mutex::new(None);
    let soft = MutexGuard::leak(SOFT_VGA.try_lock().expect("the software VGA is taken once"));
    let presenter = MutexGuard::leak(PRESENTER.try_lock().expect("the presenter is taken once"));
    let slot = MutexGuard::leak(DISPLAY.try_lock().expect("the display is made once"));
    let soft: *mut SoftVga = soft;
    // Both the mirror's reference and the fault handler's pointer derive from
    // this one raw pointer.
    let display: *mut Display = slot.insert(Display::new(
        framebuffer,
        physical_memory_offset,
        presenter,
        soft,
    ));
    FAULT_DISPLAY.store(display, Ordering::Release);
    // SAFETY: both point into leaked statics, never freed or moved; the only
    // other user is the fault handler, after which nothing else runs.
    unsafe { (&mut *soft, &mut *display) }
}

/// The framebuffer, and what it takes to present the software VGA into it.
pub struct Display {
    pixels: &'static mut [u8],
    layout: FramebufferLayout,
    presenter: &'static mut Presenter,
    /// The software VGA, for the fault handler; the mirror drives it otherwise.
    soft: *mut SoftVga,
    next_frame_micros: Option<u64>,
    cost: PresentCost,
}

// SAFETY: the raw pointer is to the leaked static software VGA, which lives
// for the whole run; the kernel has one core, and the display is used by the
// main loop and, after a fault, by the fault handler alone.
unsafe impl Send for Display {}

/// Present costs since the last report.
#[derive(Default)]
struct PresentCost {
    presents: u64,
    micros: u64,
    bytes: u64,
}

impl Display {
    /// Says on serial how the picture will sit on the framebuffer (the QEMU
    /// tests read that line), and maps it write-combining.
    fn new(
        framebuffer: &'static mut FrameBuffer,
        physical_memory_offset: u64,
        presenter: &'static mut Presenter,
        soft: *mut SoftVga,
    ) -> Self {
        let info = framebuffer.info();
        let layout = layout_of(&info);
        let placement = Placement::fit(
            (SCREEN_WIDTH as usize, SCREEN_HEIGHT as usize),
            (layout.width, layout.height),
        );
        serial_println!(
            "display: framebuffer {}x{} stride {} {} {} bytes/pixel, scale {}",
            layout.width,
            layout.height,
            layout.stride,
            order_name(layout.order),
            layout.bytes_per_pixel,
            placement.scale
        );
        let pixels = framebuffer.buffer_mut();
        let write_combining = crate::pat::map_write_combining(pixels, physical_memory_offset);
        crate::facts::record(|facts| {
            facts.display = demo::facts::Display::Framebuffer {
                width: layout.width as u32,
                height: layout.height as u32,
                bytes_per_pixel: layout.bytes_per_pixel as u8,
                scale: placement.scale as u32,
                write_combining: Some(write_combining),
            }
        });
        Display {
            pixels,
            layout,
            presenter,
            soft,
            next_frame_micros: None,
            cost: PresentCost::default(),
        }
    }

    /// Presents what changed in the model's picture, then waits for the next
    /// refresh by the clock, as a flip on a real VGA waits for retrace.
    pub fn present(&mut self, soft: &SoftVga) {
        let started = time::micros();
        let report = self.presenter.present(soft, &self.layout, self.pixels);
        self.count(time::micros() - started, report.bytes_written);
        self.wait_for_next_frame();
    }

    /// Present costs on serial now and then: the kernel's own figure for
    /// `docs/performance.md` (time includes the scan-out and the diff).
    fn count(&mut self, micros: u64, bytes: usize) {
        let cost = &mut self.cost;
        cost.presents += 1;
        cost.micros += micros;
        cost.bytes += bytes as u64;
        if cost.presents == COST_REPORT_PRESENTS {
            serial_println!(
                "present: {} presents, mean {} us and {} bytes written each",
                cost.presents,
                cost.micros / cost.presents,
                cost.bytes / cost.presents
            );
            *cost = PresentCost::default();
        }
    }

    fn wait_for_next_frame(&mut self) {
        let now = time::micros();
        let due = match self.next_frame_micros {
            // Late (drawing took longer than a frame): start a new cadence.
            Some(due) if due > now => due,
            _ => now,
        };
        crate::idle::until(due);
        self.next_frame_micros = Some(due + FRAME_MICROS);
    }
}

/// For the fault handler: shows the panel on the framebuffer, once, if the
/// framebuffer display exists and no earlier fault took it. No waiting, no
/// lock, no allocation.
pub fn show_fault_panel(
    lines: &[&str; demo::screens::REPORT_LINES],
    log: &[&str],
    qr_text: &[u8],
) -> bool {
    let display = FAULT_DISPLAY.swap(core::ptr::null_mut(), Ordering::AcqRel);
    if display.is_null() {
        return false;
    }
    // SAFETY: the pointer was made from the leaked static display and the swap
    // gave it to this handler alone; the code it interrupted never resumes.
    let display = unsafe { &mut *display };
    // SAFETY: as for the display: the leaked static model, and nothing else
    // runs after a fault.
    let soft = unsafe { &mut *display.soft };
    demo::screens::fault_panel(&mut ModeX::new(&mut *soft), lines, log, qr_text);
    display
        .presenter
        .present(soft, &display.layout, display.pixels);
    true
}

fn order_name(order: PixelOrder) -> &'static str {
    match order {
        PixelOrder::Rgb => "rgb",
        PixelOrder::Bgr => "bgr",
        PixelOrder::Grey => "grey",
        PixelOrder::Packed(format) if format == PackedFormat::RGB565 => "rgb565",
        PixelOrder::Packed(format) if format == PackedFormat::RGB555 => "rgb555",
        PixelOrder::Packed(_) => "packed",
    }
}
