//! OHCI's data structures in DMA memory (chapter 4): where each lives in the
//! driver's region (fixed pools, reused), and how an endpoint descriptor
//! (ED) and a general transfer descriptor (TD) are encoded.

use super::registers::{HCCA_BYTES, HCCA_INTERRUPT_ENTRIES};

/// Devices the driver keeps (each has a control ED, its TDs and buffers).
pub const MAX_DEVICES: usize = 32;
/// Interrupt-in pipes the driver keeps.
pub const MAX_PIPES: usize = 32;
/// TDs in each device's control ring: SETUP, data, status and the dummy
/// tail the next transfer starts in.
pub const CONTROL_TDS: usize = 4;
/// TDs in each pipe's ring: the one in flight and the dummy tail.
pub const PIPE_TDS: usize = 2;
/// Bytes of each device's control data buffer.
pub const CONTROL_DATA_BYTES: u64 = crate::host::MAX_CONTROL_DATA as u64;
/// Bytes of each pipe's report buffer.
pub const REPORT_BYTES: u64 = crate::host::MAX_REPORT as u64;
/// Longest polling interval, in frames: the HCCA's interrupt table has an
/// entry per frame, mod 32.
pub const MAX_INTERVAL: u8 = HCCA_INTERRUPT_ENTRIES as u8;
/// Static EDs of the interrupt tree: 32 + 16 + 8 + 4 + 2 + 1.
pub const TREE_NODES: usize = 63;

const ED_BYTES: u64 = 16;
const TD_BYTES: u64 = 16;
const SETUP_BYTES: u64 = 8;

/// Where everything lives in the DMA region. Every address is below
/// 4 GiB (checked when the layout is made).
#[derive(Clone, Copy, Debug)]
pub struct Layout {
    /// The Host Controller Communication Area (256-byte aligned).
    pub hcca: u64,
    tree: u64,
    control_eds: u64,
    pipe_eds: u64,
    control_tds: u64,
    pipe_tds: u64,
    setups: u64,
    control_data: u64,
    reports: u64,
    /// One past the last byte used.
    pub end: u64,
}

impl Layout {
    /// The layout from `base` up (rounded up to the HCCA's alignment).
    /// The control data buffers come first, each aligned to its 1 KiB, so
    /// that no buffer crosses a 4 KiB page (nothing relies on a
    /// controller's page crossing, which some got wrong); report buffers
    /// and SETUP buffers are aligned to their sizes for the same reason.
    pub fn new(base: u64) -> Layout {
        let hcca = base.next_multiple_of(HCCA_BYTES);
        let control_data = (hcca + HCCA_BYTES).next_multiple_of(CONTROL_DATA_BYTES);
        let reports = control_data + MAX_DEVICES as u64 * CONTROL_DATA_BYTES;
        let tree = reports + MAX_PIPES as u64 * REPORT_BYTES;
        let control_eds = tree + TREE_NODES as u64 * ED_BYTES;
        let pipe_eds = control_eds + MAX_DEVICES as u64 * ED_BYTES;
        let control_tds = pipe_eds + MAX_PIPES as u64 * ED_BYTES;
        let pipe_tds = control_tds + (MAX_DEVICES * CONTROL_TDS) as u64 * TD_BYTES;
        let setups = pipe_tds + (MAX_PIPES * PIPE_TDS) as u64 * TD_BYTES;
        let end = setups + MAX_DEVICES as u64 * SETUP_BYTES;
        Layout {
            hcca,
            tree,
            control_eds,
            pipe_eds,
            control_tds,
            pipe_tds,
            setups,
            control_data,
            reports,
            end,
        }
    }

    /// The static ED of the interrupt tree at `index` (see [`tree_node`]).
    pub fn tree_ed(&self, index: usize) -> u64 {
        self.tree + index as u64 * ED_BYTES
    }

    /// Device `device`'s control ED.
    pub fn control_ed(&self, device: usize) -> u64 {
        self.control_eds + device as u64 * ED_BYTES
    }

    /// Pipe `pipe`'s ED.
    pub fn pipe_ed(&self, pipe: usize) -> u64 {
        self.pipe_eds + pipe as u64 * ED_BYTES
    }

    /// TD `slot` (mod [`CONTROL_TDS`]) of device `device`'s control ring.
    pub fn control_td(&self, device: usize, slot: usize) -> u64 {
        self.control_tds + (device * CONTROL_TDS + slot % CONTROL_TDS) as u64 * TD_BYTES
    }

    /// TD `slot` (mod [`PIPE_TDS`]) of pipe `pipe`'s ring.
    pub fn pipe_td(&self, pipe: usize, slot: usize) -> u64 {
        self.pipe_tds + (pipe * PIPE_TDS + slot % PIPE_TDS) as u64 * TD_BYTES
    }

    /// Whether `address` is one of the TDs of either pool.
    pub fn is_td(&self, address: u64) -> bool {
        address >= self.control_tds && address < self.setups && address.is_multiple_of(TD_BYTES)
    }

    /// Device `device`'s 8-byte SETUP buffer.
    pub fn setup(&self, device: usize) -> u64 {
        self.setups + device as u64 * SETUP_BYTES
    }

    /// Device `device`'s control data buffer.
    pub fn control_data(&self, device: usize) -> u64 {
        self.control_data + device as u64 * CONTROL_DATA_BYTES
    }

    /// Pipe `pipe`'s report buffer.
    pub fn report(&self, pipe: usize) -> u64 {
        self.reports + pipe as u64 * REPORT_BYTES
    }
}

/// The index of the interrupt tree's static ED for polling every
/// `interval` frames (1, 2, 4, 8, 16 or 32) on branch `branch` (below
/// `interval`): it is visited in the frames whose number mod `interval`
/// is `branch`. The 32 nodes of interval 32 come first; the one node of
/// interval 1 is last.
pub fn tree_node(interval: u8, branch: usize) -> usize {
    let first = match interval {
        32 => 0,
        16 => 32,
        8 => 48,
        4 => 56,
        2 => 60,
        _ => 62,
    };
    first + branch % usize::from(interval.max(1))
}

/// The static ED a tree node's ED links to: the node of half the
/// interval on the same branch, or none after the interval-1 node.
pub fn tree_parent(interval: u8, branch: usize) -> Option<usize> {
    if interval <= 1 {
        None
    } else {
        let half = interval / 2;
        Some(tree_node(half, branch % usize::from(half)))
    }
}

/// ED dword 0 (4.2.1): FunctionAddress, EndpointNumber, Direction,
/// Speed, sKip, Format, MaximumPacketSize.
pub mod ed {
    /// Direction from the TD (control endpoints).
    pub const DIRECTION_FROM_TD: u32 = 0 << 11;
    /// Direction IN.
    pub const DIRECTION_IN: u32 = 2 << 11;
    /// S: a low-speed endpoint.
    pub const LOW_SPEED: u32 = 1 << 13;
    /// K: the controller skips this ED.
    pub const SKIP: u32 = 1 << 14;
    /// HeadP bit 0: halted (the controller stopped on an error).
    pub const HALTED: u32 = 1 << 0;
    /// HeadP bit 1: the data toggle carry.
    pub const TOGGLE_CARRY: u32 = 1 << 1;
    /// The pointer bits of TailP, HeadP and NextED.
    pub const POINTER: u32 = !0xF;

    /// Dword 0 for a general-format ED.
    pub fn control(
        address: u8,
        endpoint: u8,
        direction: u32,
        low_speed: bool,
        max_packet: u16,
    ) -> u32 {
        u32::from(address & 0x7F)
            | u32::from(endpoint & 0xF) << 7
            | direction
            | if low_speed { LOW_SPEED } else { 0 }
            | u32::from(max_packet & 0x7FF) << 16
    }
}

/// General TD dword 0 (4.3.1): bufferRounding, Direction/PID,
/// DelayInterrupt, DataToggle, ErrorCount, ConditionCode.
pub mod td {
    /// R: a short packet ends the TD without error.
    pub const BUFFER_ROUNDING: u32 = 1 << 18;
    /// DP SETUP.
    pub const PID_SETUP: u32 = 0 << 19;
    /// DP OUT.
    pub const PID_OUT: u32 = 1 << 19;
    /// DP IN.
    pub const PID_IN: u32 = 2 << 19;
    /// DI 0: the done queue is written back at the end of the frame the
    /// TD retires in (WDH), so the idle poll sees every completion.
    pub const DELAY_INTERRUPT_NONE: u32 = 0 << 21;
    /// T 00: the toggle comes from the ED's toggle carry.
    pub const TOGGLE_FROM_ED: u32 = 0 << 24;
    /// T 10: DATA0, from the TD.
    pub const TOGGLE_DATA0: u32 = 2 << 24;
    /// T 11: DATA1, from the TD.
    pub const TOGGLE_DATA1: u32 = 3 << 24;
    /// CC NotAccessed: the controller has not retired the TD.
    pub const NOT_ACCESSED: u32 = 0xF << 28;

    /// The ConditionCode of dword 0.
    pub fn condition(control: u32) -> u32 {
        control >> 28
    }
}

/// A TD ConditionCode (table 4-7).
pub mod condition {
    /// NoError.
    pub const NO_ERROR: u32 = 0x0;
    /// CRC.
    pub const CRC: u32 = 0x1;
    /// BitStuffing.
    pub const BIT_STUFFING: u32 = 0x2;
    /// DataToggleMismatch.
    pub const DATA_TOGGLE_MISMATCH: u32 = 0x3;
    /// Stall.
    pub const STALL: u32 = 0x4;
    /// DeviceNotResponding.
    pub const DEVICE_NOT_RESPONDING: u32 = 0x5;
    /// PIDCheckFailure.
    pub const PID_CHECK_FAILURE: u32 = 0x6;
    /// UnexpectedPID.
    pub const UNEXPECTED_PID: u32 = 0x7;
    /// DataOverrun: the endpoint sent more than fits.
    pub const DATA_OVERRUN: u32 = 0x8;
    /// DataUnderrun: a short packet without bufferRounding.
    pub const DATA_UNDERRUN: u32 = 0x9;
    /// BufferOverrun: memory too slow for the incoming data.
    pub const BUFFER_OVERRUN: u32 = 0xC;
    /// BufferUnderrun: memory too slow for the outgoing data.
    pub const BUFFER_UNDERRUN: u32 = 0xD;
}

#[cfg(test)]
mod tests;
