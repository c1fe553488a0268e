//! EHCI's DMA data structures (EHCI 1.0 chapter 3): where each lives in the
//! driver's one DMA region, and how their words are built. Queue heads
//! (QH) and queue element transfer descriptors (qTD) are laid out with room
//! for the 64-bit layout (appendix B) whether or not the controller uses
//! it; the high dwords are written only when it does.

use crate::host::{Speed, TransactionTranslator};

/// Devices (each an endpoint-0 queue head with three qTDs) the driver keeps.
pub const MAX_DEVICES: usize = 32;
/// Interrupt-in pipes (each a queue head with one qTD) the driver keeps.
pub const MAX_PIPES: usize = 32;
/// Entries in the periodic frame list (USBCMD frame list size 00b).
pub const FRAME_LIST_ENTRIES: usize = 1024;

/// A link pointer's Terminate bit: nothing follows.
pub const LINK_TERMINATE: u32 = 1 << 0;
/// A link pointer's Typ field for a queue head (01b at bits 2:1).
pub const LINK_TYPE_QH: u32 = 1 << 1;

// Queue head, byte offsets (EHCI 3.6).
/// QH dword 0: the horizontal link pointer.
pub const QH_HORIZONTAL: u64 = 0x00;
/// QH dword 1: endpoint characteristics.
pub const QH_CHARACTERISTICS: u64 = 0x04;
/// QH dword 2: endpoint capabilities.
pub const QH_CAPABILITIES: u64 = 0x08;
/// The transfer overlay (after dword 3, the controller's current qTD
/// pointer): the next qTD pointer.
pub const QH_OVERLAY_NEXT: u64 = 0x10;
/// The transfer overlay's alternate next qTD pointer.
pub const QH_OVERLAY_ALTERNATE: u64 = 0x14;
/// The transfer overlay's token.
pub const QH_OVERLAY_TOKEN: u64 = 0x18;

// qTD, byte offsets (EHCI 3.5).
/// The next qTD pointer.
pub const QTD_NEXT: u64 = 0x00;
/// The alternate next qTD pointer (taken on a short packet).
pub const QTD_ALTERNATE: u64 = 0x04;
/// The token.
pub const QTD_TOKEN: u64 = 0x08;
/// The five buffer pointers.
pub const QTD_BUFFERS: u64 = 0x0C;
/// The five high dwords of the buffer pointers (64-bit layout).
pub const QTD_BUFFERS_HIGH: u64 = 0x20;

// qTD token bits (EHCI 3.5.3).
/// Status: the controller owns the qTD.
pub const TOKEN_ACTIVE: u32 = 1 << 7;
/// Status: a serious error (or a STALL) halted the endpoint.
pub const TOKEN_HALTED: u32 = 1 << 6;
/// Status: overrun or underrun of the controller's memory access.
pub const TOKEN_DATA_BUFFER: u32 = 1 << 5;
/// Status: the device sent more than asked for.
pub const TOKEN_BABBLE: u32 = 1 << 4;
/// Status: no valid response (timeout, CRC, bad PID).
pub const TOKEN_TRANSACTION_ERROR: u32 = 1 << 3;
/// Status: a split transaction's complete-split came too late.
pub const TOKEN_MISSED_MICRO_FRAME: u32 = 1 << 2;
/// Every status bit that says something went wrong.
pub const TOKEN_ERRORS: u32 =
    TOKEN_DATA_BUFFER | TOKEN_BABBLE | TOKEN_TRANSACTION_ERROR | TOKEN_MISSED_MICRO_FRAME;
/// PID code OUT (bits 9:8).
pub const PID_OUT: u32 = 0 << 8;
/// PID code IN.
pub const PID_IN: u32 = 1 << 8;
/// PID code SETUP.
pub const PID_SETUP: u32 = 2 << 8;
/// The error counter (bits 11:10).
pub const TOKEN_CERR: u32 = 3 << 10;
/// Three tries, as Linux.
const TOKEN_CERR_3: u32 = 3 << 10;
/// Interrupt on complete: USBSTS.USBINT when the qTD retires.
const TOKEN_IOC: u32 = 1 << 15;
const TOKEN_TOTAL_SHIFT: u32 = 16;
/// Total Bytes to Transfer is 15 bits.
pub const TOKEN_TOTAL_MASK: u32 = 0x7FFF;
/// The data toggle.
pub const TOKEN_TOGGLE: u32 = 1 << 31;

// QH endpoint characteristics (EHCI 3.6.2).
const EPS_FULL: u32 = 0 << 12;
const EPS_LOW: u32 = 1 << 12;
const EPS_HIGH: u32 = 2 << 12;
/// Data toggle control: the toggle comes from each qTD (control endpoints).
const DATA_TOGGLE_CONTROL: u32 = 1 << 14;
/// Head of reclamation list.
pub const HEAD_OF_RECLAMATION: u32 = 1 << 15;
/// The device address field (bits 6:0).
pub const DEVICE_ADDRESS_MASK: u32 = 0x7F;
const MAX_PACKET_SHIFT: u32 = 16;
/// The maximum packet length field (bits 26:16).
pub const MAX_PACKET_MASK: u32 = 0x7FF << MAX_PACKET_SHIFT;
/// Control endpoint flag: a full- or low-speed control endpoint.
const CONTROL_ENDPOINT: u32 = 1 << 27;
/// NAK count reload for high-speed asynchronous endpoints (Linux's
/// EHCI_TUNE_RL_HS); 0 for periodic and split endpoints, as the spec asks.
const NAK_RELOAD_HIGH_SPEED: u32 = 4 << 28;

// QH endpoint capabilities (EHCI 3.6.2).
const HUB_ADDRESS_SHIFT: u32 = 16;
const PORT_NUMBER_SHIFT: u32 = 23;
/// High-bandwidth pipe multiplier: one transaction per micro-frame.
const MULT_ONE: u32 = 1 << 30;

/// Where everything lives in the DMA region (offsets from its page-aligned
/// base). Device slots are 1.5 KiB, so some data buffers straddle a page
/// boundary and are reached through two buffer pointers.
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    base: u64,
}

const FRAME_LIST: u64 = 0x0000;
const ASYNC_HEAD: u64 = 0x1000;
const PIPES: u64 = 0x1080;
const PIPE_BYTES: u64 = 0x100;
const DEVICES: u64 = PIPES + PIPE_BYTES * MAX_PIPES as u64;
const DEVICE_BYTES: u64 = 0x600;
/// A qTD's room: 52 bytes in the 64-bit layout, rounded to a 32-byte boundary.
const QTD_ROOM: u64 = 0x40;
/// The bytes of the DMA region the driver uses.
pub const DMA_BYTES_USED: u64 = DEVICES + DEVICE_BYTES * MAX_DEVICES as u64;

/// The three qTDs of a control transfer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// The SETUP packet.
    Setup = 0,
    /// The data stage, if any.
    Data = 1,
    /// The status stage.
    Status = 2,
}

impl Layout {
    /// The layout over a region starting at `base` (page aligned).
    pub const fn new(base: u64) -> Layout {
        Layout { base }
    }

    /// The periodic frame list (4 KiB aligned).
    pub const fn frame_list(&self) -> u64 {
        self.base + FRAME_LIST
    }

    /// The asynchronous schedule's reclamation head queue head.
    pub const fn async_head(&self) -> u64 {
        self.base + ASYNC_HEAD
    }

    /// Pipe `index`'s queue head.
    pub const fn pipe_qh(&self, index: usize) -> u64 {
        self.base + PIPES + PIPE_BYTES * index as u64
    }

    /// Pipe `index`'s qTD.
    pub const fn pipe_qtd(&self, index: usize) -> u64 {
        self.pipe_qh(index) + 0x80
    }

    /// Pipe `index`'s report buffer (64 bytes).
    pub const fn pipe_buffer(&self, index: usize) -> u64 {
        self.pipe_qh(index) + 0xC0
    }

    /// Device `index`'s endpoint-0 queue head.
    pub const fn device_qh(&self, index: usize) -> u64 {
        self.base + DEVICES + DEVICE_BYTES * index as u64
    }

    /// Device `index`'s qTD for `stage`.
    pub const fn device_qtd(&self, index: usize, stage: Stage) -> u64 {
        self.device_qh(index) + 0x80 + QTD_ROOM * stage as u64
    }

    /// Device `index`'s 8-byte SETUP buffer.
    pub const fn device_setup(&self, index: usize) -> u64 {
        self.device_qh(index) + 0x140
    }

    /// Device `index`'s data stage buffer (MAX_CONTROL_DATA bytes).
    pub const fn device_data(&self, index: usize) -> u64 {
        self.device_qh(index) + 0x160
    }
}

/// A horizontal link (or frame list entry) to the queue head at `qh`.
pub fn qh_link(qh: u64) -> u32 {
    qh as u32 | LINK_TYPE_QH
}

/// QH dword 1 for endpoint `endpoint` of the device at `address`.
/// `control`: endpoint 0 (its toggle from each qTD, and for a full- or
/// low-speed device the Control Endpoint flag).
pub fn characteristics(
    address: u8,
    endpoint: u8,
    speed: Speed,
    max_packet: u16,
    control: bool,
) -> u32 {
    let eps = match speed {
        Speed::Full => EPS_FULL,
        Speed::Low => EPS_LOW,
        // SuperSpeed never reaches EHCI (`device_new` refuses it).
        Speed::High | Speed::Super => EPS_HIGH,
    };
    let mut word = u32::from(address) & DEVICE_ADDRESS_MASK
        | (u32::from(endpoint) & 0xF) << 8
        | eps
        | (u32::from(max_packet) << MAX_PACKET_SHIFT) & MAX_PACKET_MASK;
    if control {
        word |= DATA_TOGGLE_CONTROL;
        if speed == Speed::High {
            word |= NAK_RELOAD_HIGH_SPEED;
        } else {
            word |= CONTROL_ENDPOINT;
        }
    }
    word
}

/// QH dword 2: the micro-frame masks (periodic only; 0 for the async
/// schedule), and for a device behind a transaction translator its hub's
/// address and port.
pub fn capabilities(translator: Option<TransactionTranslator>, s_mask: u8, c_mask: u8) -> u32 {
    let mut word = MULT_ONE | u32::from(s_mask) | u32::from(c_mask) << 8;
    if let Some(tt) = translator {
        word |= (u32::from(tt.hub_address) & 0x7F) << HUB_ADDRESS_SHIFT
            | (u32::from(tt.hub_port) & 0x7F) << PORT_NUMBER_SHIFT;
    }
    word
}

/// An active qTD token: `pid`, `bytes` to move, the data toggle, three
/// tries, and an interrupt on completion if `ioc`.
pub fn token(pid: u32, bytes: u16, toggle: bool, ioc: bool) -> u32 {
    let mut word = TOKEN_ACTIVE
        | pid
        | TOKEN_CERR_3
        | (u32::from(bytes) & TOKEN_TOTAL_MASK) << TOKEN_TOTAL_SHIFT;
    if toggle {
        word |= TOKEN_TOGGLE;
    }
    if ioc {
        word |= TOKEN_IOC;
    }
    word
}

/// The bytes a token has still to move.
pub fn token_remaining(token: u32) -> u32 {
    token >> TOKEN_TOTAL_SHIFT & TOKEN_TOTAL_MASK
}

/// The five buffer pointers for `bytes` at `address`: the first with the
/// offset in its page, then each following page (EHCI 3.5.4); pages not
/// reached are 0. A buffer needs at most five pages (callers keep it
/// below 16 KiB).
pub fn buffer_pointers(address: u64, bytes: usize) -> [u32; 5] {
    let mut pointers = [0u32; 5];
    pointers[0] = address as u32;
    let first_page = address & !0xFFF;
    let last_page = (address + bytes.max(1) as u64 - 1) & !0xFFF;
    for (page, pointer) in pointers.iter_mut().enumerate().skip(1) {
        let page_address = first_page + 0x1000 * page as u64;
        if page_address <= last_page {
            *pointer = page_address as u32;
        }
    }
    pointers
}

#[cfg(test)]
mod tests;
