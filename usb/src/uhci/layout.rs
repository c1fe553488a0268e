//! UHCI's register and descriptor bits (UHCI 1.1 chapters 2 and 3), and
//! where the driver keeps its frame list, queue heads, transfer descriptors
//! and buffers inside its one DMA region: fixed slices per device and per
//! pipe, so that a slot freed is a slot whose memory is used again.

use crate::host::{MAX_CONTROL_DATA, MAX_REPORT};

// I/O registers, as offsets from the controller's I/O base (BAR4).
/// USBCMD: run/stop, resets, configure flag, max packet.
pub const USBCMD: u32 = 0x00;
/// USBSTS: interrupt causes (write 1 to clear) and HCHalted.
pub const USBSTS: u32 = 0x02;
/// USBINTR: which causes raise the interrupt line.
pub const USBINTR: u32 = 0x04;
/// FRNUM: the frame number (11 bits; the low 10 index the frame list).
pub const FRNUM: u32 = 0x06;
/// FRBASEADD: the frame list's physical address (32 bits, 4 KiB aligned).
pub const FRBASEADD: u32 = 0x08;
/// PORTSC1; port n (0-based) is at `PORTSC1 + 2 * n`.
pub const PORTSC1: u32 = 0x10;
/// The I/O region is 32 bytes: at most 8 port registers fit.
pub const MAX_PORT_REGISTERS: u8 = 8;

// USBCMD bits.
/// Run/Stop.
pub const CMD_RUN: u16 = 1 << 0;
/// Host controller reset (the controller clears it when done).
pub const CMD_HOST_RESET: u16 = 1 << 1;
/// Global reset: USB reset on every port, held by software.
pub const CMD_GLOBAL_RESET: u16 = 1 << 2;
/// Configure Flag: a semaphore for software ("configured").
pub const CMD_CONFIGURE: u16 = 1 << 6;
/// Max packet 64 bytes for full-speed bandwidth reclamation.
pub const CMD_MAX_PACKET_64: u16 = 1 << 7;

// USBSTS bits, all but HCHalted write-1-to-clear.
/// A TD with IOC completed, or a short packet with SPD.
pub const STS_INTERRUPT: u16 = 1 << 0;
/// A transaction ended in an error (stall, babble, errors counted out).
pub const STS_ERROR_INTERRUPT: u16 = 1 << 1;
/// Resume detected.
pub const STS_RESUME_DETECT: u16 = 1 << 2;
/// Host system error (PCI): the controller halts.
pub const STS_HOST_SYSTEM_ERROR: u16 = 1 << 3;
/// Host controller process error (a bad schedule): it halts.
pub const STS_PROCESS_ERROR: u16 = 1 << 4;
/// The controller is halted (read only).
pub const STS_HALTED: u16 = 1 << 5;
/// Every write-1-to-clear cause.
pub const STS_CAUSES: u16 = STS_INTERRUPT
    | STS_ERROR_INTERRUPT
    | STS_RESUME_DETECT
    | STS_HOST_SYSTEM_ERROR
    | STS_PROCESS_ERROR;

// PORTSC bits.
/// Current connect status (read only).
pub const PORT_CONNECTED: u16 = 1 << 0;
/// Connect status change (write 1 to clear).
pub const PORT_CONNECT_CHANGE: u16 = 1 << 1;
/// Port enabled.
pub const PORT_ENABLED: u16 = 1 << 2;
/// Port enable change (write 1 to clear).
pub const PORT_ENABLE_CHANGE: u16 = 1 << 3;
/// Reserved, reads as 1: how Linux counts the ports.
pub const PORT_ALWAYS_ONE: u16 = 1 << 7;
/// Low-speed device attached (read only).
pub const PORT_LOW_SPEED: u16 = 1 << 8;
/// Port reset, held by software.
pub const PORT_RESET: u16 = 1 << 9;
/// Over-current change on some controllers (write 1 to clear).
pub const PORT_OVER_CURRENT_CHANGE: u16 = 1 << 11;
/// The write-1-to-clear bits: never written back as read.
pub const PORT_WRITE_CLEAR: u16 =
    PORT_CONNECT_CHANGE | PORT_ENABLE_CHANGE | PORT_OVER_CURRENT_CHANGE;
/// Reserved bits that must be written as 0.
pub const PORT_WRITE_ZERO: u16 = 0xE000;

// The PCI configuration register LEGSUP (the low 16 bits of the dword at
// 0xC0): the BIOS's keyboard emulation through SMI traps.
/// Its configuration space offset.
pub const LEGACY_OFFSET: u8 = 0xC0;
/// The trap status bits (write 1 to clear): Linux's USBLEGSUP_RWC.
pub const LEGACY_STATUS_CLEAR: u16 = 0x8F00;
/// The SMI enables: the four port 60h/64h traps, SMI on USB
/// interrupt, A20 pass-through, SMI at the end of pass-through.
pub const LEGACY_SMI_ENABLES: u16 = 0x00BF;
/// PIRQ enable: the controller's interrupt routed to the PIC.
pub const LEGACY_PIRQ_ENABLE: u16 = 0x2000;

// Link pointer bits (frame list entries, QH and TD links).
/// Terminate: nothing follows.
pub const LINK_TERMINATE: u32 = 1 << 0;
/// The pointer names a queue head (else a TD).
pub const LINK_QUEUE_HEAD: u32 = 1 << 1;
/// TD links only: depth first (go on with this queue's next TD).
pub const LINK_DEPTH_FIRST: u32 = 1 << 2;

// TD control and status (dword 1) bits.
/// Short packet detect: a short IN stops the queue.
pub const TD_SHORT_PACKET_DETECT: u32 = 1 << 29;
/// Error counter of 3 (bits 28:27): three strikes, then retired.
pub const TD_THREE_ERRORS: u32 = 3 << 27;
/// Low-speed device (the controller sends PRE first through hubs).
pub const TD_LOW_SPEED: u32 = 1 << 26;
/// Interrupt on completion.
pub const TD_INTERRUPT_ON_COMPLETE: u32 = 1 << 24;
/// Active: the controller owns it.
pub const TD_ACTIVE: u32 = 1 << 23;
/// Stalled (also set with babble and errors counted out).
pub const TD_STALLED: u32 = 1 << 22;
/// Data buffer error (overrun or underrun).
pub const TD_DATA_BUFFER_ERROR: u32 = 1 << 21;
/// Babble.
pub const TD_BABBLE: u32 = 1 << 20;
/// CRC error or time-out.
pub const TD_CRC_TIMEOUT: u32 = 1 << 18;
/// Bit stuff error.
pub const TD_BITSTUFF: u32 = 1 << 17;
/// Actual length, n - 1 encoded (0x7FF: nothing).
pub const TD_ACTUAL_LENGTH: u32 = 0x7FF;

/// The td_token's PIDs.
pub const PID_SETUP: u32 = 0x2D;
/// IN.
pub const PID_IN: u32 = 0x69;
/// OUT.
pub const PID_OUT: u32 = 0xE1;

/// The td_token (dword 2): length `bytes` (n - 1 encoded, 0x7FF for 0),
/// toggle, endpoint, address and PID.
pub const fn td_token(pid: u32, address: u8, endpoint: u8, toggle: bool, bytes: usize) -> u32 {
    let length = (bytes as u32).wrapping_sub(1) & 0x7FF;
    length << 21
        | (toggle as u32) << 19
        | (endpoint as u32 & 0xF) << 15
        | (address as u32 & 0x7F) << 8
        | pid
}

/// The bytes an inactive TD moved, from its ActLen (n - 1 encoded).
pub const fn td_actual_length(status: u32) -> usize {
    ((status + 1) & TD_ACTUAL_LENGTH) as usize
}

/// Frames in the frame list.
pub const FRAMES: u32 = 1024;
/// Devices a controller keeps at once.
pub const MAX_DEVICES: usize = 32;
/// Interrupt-in pipes a controller keeps at once.
pub const MAX_PIPES: usize = 32;
/// TDs a control transfer can need: SETUP, a data TD per 8-byte packet of
/// the longest data stage, status.
pub const MAX_CONTROL_TDS: usize = MAX_CONTROL_DATA / 8 + 2;
/// Interrupt periods the schedule has a queue for: 1, 2, 4, ... 32 frames.
pub const PERIODS: usize = 6;
/// Skeleton queue heads: one per period, then the control queue's head.
pub const SKELETONS: usize = PERIODS + 1;
/// The control skeleton's index.
pub const CONTROL_SKELETON: usize = PERIODS;

const QH_BYTES: u32 = 16;
const TD_BYTES: u32 = 16;
/// A device's buffer: the SETUP packet, then the data stage.
const DEVICE_BUFFER_BYTES: u32 = 8 + MAX_CONTROL_DATA as u32;
const PIPE_BUFFER_BYTES: u32 = MAX_REPORT as u32;

const FRAME_LIST_OFFSET: u32 = 0;
const SKELETON_OFFSET: u32 = FRAME_LIST_OFFSET + FRAMES * 4;
const DEVICE_QH_OFFSET: u32 = SKELETON_OFFSET + SKELETONS as u32 * QH_BYTES;
const PIPE_QH_OFFSET: u32 = DEVICE_QH_OFFSET + MAX_DEVICES as u32 * QH_BYTES;
const PIPE_TD_OFFSET: u32 = PIPE_QH_OFFSET + MAX_PIPES as u32 * QH_BYTES;
const PIPE_BUFFER_OFFSET: u32 = PIPE_TD_OFFSET + MAX_PIPES as u32 * TD_BYTES;
const DEVICE_TD_OFFSET: u32 = PIPE_BUFFER_OFFSET + MAX_PIPES as u32 * PIPE_BUFFER_BYTES;
const DEVICE_BUFFER_OFFSET: u32 =
    DEVICE_TD_OFFSET + (MAX_DEVICES * MAX_CONTROL_TDS) as u32 * TD_BYTES;
/// DMA bytes the driver uses, from a 4 KiB aligned start.
pub const DMA_BYTES_NEEDED: u32 = DEVICE_BUFFER_OFFSET + MAX_DEVICES as u32 * DEVICE_BUFFER_BYTES;

// Half of the 256 KiB the kernel gives each controller is plenty.
const _: () = assert!(DMA_BYTES_NEEDED <= 128 * 1024);

/// Where everything is, by physical address (all below 4 GiB).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// The frame list's address (4 KiB aligned); everything follows it.
    pub base: u32,
}

impl Layout {
    /// The layout inside [dma_base, dma_base + dma_bytes), if it fits below
    /// 4 GiB (UHCI pointers are 32 bits).
    pub fn new(dma_base: u64, dma_bytes: u64) -> Option<Layout> {
        let end = dma_base.checked_add(dma_bytes)?;
        let base = dma_base.checked_add(4095)? & !4095;
        let needed_end = base.checked_add(u64::from(DMA_BYTES_NEEDED))?;
        if needed_end > end || needed_end > 1 << 32 {
            return None;
        }
        Some(Layout { base: base as u32 })
    }

    /// The frame list.
    pub fn frame_list(&self) -> u32 {
        self.base + FRAME_LIST_OFFSET
    }

    /// Skeleton queue head `index` (0..PERIODS: period 2^index; then control).
    pub fn skeleton(&self, index: usize) -> u32 {
        self.base + SKELETON_OFFSET + index as u32 * QH_BYTES
    }

    /// Device `slot`'s control queue head.
    pub fn device_qh(&self, slot: usize) -> u32 {
        self.base + DEVICE_QH_OFFSET + slot as u32 * QH_BYTES
    }

    /// Device `slot`'s control TD `index`.
    pub fn device_td(&self, slot: usize, index: usize) -> u32 {
        self.base + DEVICE_TD_OFFSET + (slot * MAX_CONTROL_TDS + index) as u32 * TD_BYTES
    }

    /// Device `slot`'s buffer: the SETUP packet, the data stage at +8.
    pub fn device_buffer(&self, slot: usize) -> u32 {
        self.base + DEVICE_BUFFER_OFFSET + slot as u32 * DEVICE_BUFFER_BYTES
    }

    /// Pipe `slot`'s queue head.
    pub fn pipe_qh(&self, slot: usize) -> u32 {
        self.base + PIPE_QH_OFFSET + slot as u32 * QH_BYTES
    }

    /// Pipe `slot`'s one TD.
    pub fn pipe_td(&self, slot: usize) -> u32 {
        self.base + PIPE_TD_OFFSET + slot as u32 * TD_BYTES
    }

    /// Pipe `slot`'s report buffer.
    pub fn pipe_buffer(&self, slot: usize) -> u32 {
        self.base + PIPE_BUFFER_OFFSET + slot as u32 * PIPE_BUFFER_BYTES
    }
}

/// The skeleton a frame's list entry points to: period-2^k queues are
/// spread so that each frame visits one of them and then the period-1
/// queue (Linux's `uhci_frame_skel_link`): odd frames take period 2,
/// frames 2 mod 4 period 4, ..., frames 16 mod 32 period 32; frames 0 mod
/// 32 go straight to period 1.
pub fn frame_skeleton(frame: u32) -> usize {
    let trailing = (frame | FRAMES).trailing_zeros() as usize;
    if trailing + 1 < PERIODS {
        trailing + 1
    } else {
        0
    }
}

/// The skeleton index for a pipe polled every `interval` frames: the
/// largest power of two not above it, at most 32 (0 is taken as 1).
pub fn period_index(interval: u8) -> usize {
    let interval = interval.max(1);
    (7 - interval.leading_zeros() as usize).min(PERIODS - 1)
}

#[cfg(test)]
mod tests;
