//! The screen on machines without a legacy VGA (UEFI-only PCs, QEMU's
//! `bochs-display`): Mode X runs on the software VGA, and each page flip
//! copies its picture, scaled, into the framebuffer the bootloader handed over
//! (UEFI GOP's, or the VESA linear mode of the BIOS stage).

use crate::{clock, serial_println};
use bootloader_api::info::{FrameBuffer, FrameBufferInfo, PixelFormat};
use machine::pacing::FRAME_MICROS;
use modex::present::{self, FramebufferLayout, PixelOrder, Placement};
use modex::soft::SoftVga;
use modex::{PAGE_PIXELS, SCREEN_HEIGHT, SCREEN_WIDTH};
use spin::{Mutex, MutexGuard};

/// The software VGA standing in for the missing one, powered on at compile
/// time: at ~260 KiB it must never pass through the stack.
static SOFT_VGA: Mutex<SoftVga> = Mutex::new(SoftVga::new());

/// The model's picture as DAC indices, scanned out before each copy: 75 KiB
/// of zeros, so it costs nothing in the image (.bss).
static SCANOUT: Mutex<[u8; PAGE_PIXELS]> = Mutex::new([0; PAGE_PIXELS]);

/// The software VGA. It can be taken once: from then on it is the machine's
/// display adapter.
pub fn soft_vga() -> &'static mut SoftVga {
    MutexGuard::leak(
        SOFT_VGA
            .try_lock()
            .expect("the software VGA is taken only once"),
    )
}

/// The bootloader's framebuffer as the portable presenter sees it. Pixel
/// formats the bootloader could not name are shown in grey, which is at
/// least a recognisable picture in any 8-bit-per-component layout.
pub fn layout_of(info: &FrameBufferInfo) -> FramebufferLayout {
    let colour_fits = info.bytes_per_pixel >= 3;
    let order = match info.pixel_format {
        PixelFormat::Rgb if colour_fits => PixelOrder::Rgb,
        PixelFormat::Bgr if colour_fits => PixelOrder::Bgr,
        PixelFormat::U8 => PixelOrder::Grey,
        other => {
            serial_println!(
                "display: pixel format {:?} with {} bytes/pixel not supported; showing grey",
                other,
                info.bytes_per_pixel
            );
            PixelOrder::Grey
        }
    };
    FramebufferLayout {
        width: info.width,
        height: info.height,
        stride: info.stride,
        bytes_per_pixel: info.bytes_per_pixel,
        order,
    }
}

/// The framebuffer, and what it takes to copy the software VGA's picture into it.
pub struct Display {
    pixels: &'static mut [u8],
    layout: FramebufferLayout,
    scanout: MutexGuard<'static, [u8; PAGE_PIXELS]>,
    next_frame_micros: Option<u64>,
}

impl Display {
    /// Takes over the framebuffer and says on serial how the picture will sit
    /// on it (the QEMU tests read that line).
    pub fn new(framebuffer: &'static mut FrameBuffer) -> Self {
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
        Display {
            pixels: framebuffer.buffer_mut(),
            layout,
            scanout: SCANOUT
                .try_lock()
                .expect("the framebuffer display is made only once"),
            next_frame_micros: None,
        }
    }

    /// Copies the model's picture to the framebuffer, then waits for the next
    /// refresh by the clock, as a flip on a real VGA waits for retrace.
    pub fn present(&mut self, soft: &SoftVga) {
        present::present(soft, &mut *self.scanout, &self.layout, self.pixels);
        self.wait_for_next_frame();
    }

    fn wait_for_next_frame(&mut self) {
        let now = clock::micros();
        let due = match self.next_frame_micros {
            // Late (drawing took longer than a frame): start a new cadence.
            Some(due) if due > now => due,
            _ => now,
        };
        while clock::micros() < due {
            // The PIT interrupts every millisecond.
            x86_64::instructions::hlt();
        }
        self.next_frame_micros = Some(due + FRAME_MICROS);
    }
}

fn order_name(order: PixelOrder) -> &'static str {
    match order {
        PixelOrder::Rgb => "rgb",
        PixelOrder::Bgr => "bgr",
        PixelOrder::Grey => "grey",
    }
}
