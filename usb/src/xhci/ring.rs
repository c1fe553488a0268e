//! xHCI rings in DMA memory: the producer rings the driver fills (the
//! command ring and each endpoint's transfer ring, closed by a Link TRB that
//! toggles the cycle bit) and the event ring the controller fills. A TRB
//! belongs to whoever's cycle state matches its cycle bit, so the driver
//! writes a TRB's control word (with the cycle bit) last.

use crate::Memory;

/// Bytes in one TRB.
pub const TRB_BYTES: u64 = 16;

/// TRB types (xHCI 1.2, table 6-91).
pub mod trb_type {
    /// Normal (transfer).
    pub const NORMAL: u32 = 1;
    /// Setup Stage (control transfer).
    pub const SETUP: u32 = 2;
    /// Data Stage (control transfer).
    pub const DATA: u32 = 3;
    /// Status Stage (control transfer).
    pub const STATUS: u32 = 4;
    /// Link: go on at another address.
    pub const LINK: u32 = 6;
    /// No Op on a transfer ring.
    pub const NO_OP_TRANSFER: u32 = 8;
    /// Enable Slot command.
    pub const ENABLE_SLOT: u32 = 9;
    /// Address Device command.
    pub const ADDRESS_DEVICE: u32 = 11;
    /// Configure Endpoint command.
    pub const CONFIGURE_ENDPOINT: u32 = 12;
    /// Evaluate Context command.
    pub const EVALUATE_CONTEXT: u32 = 13;
    /// No Op command.
    pub const NO_OP_COMMAND: u32 = 23;
    /// Transfer event.
    pub const TRANSFER_EVENT: u32 = 32;
    /// Command Completion event.
    pub const COMMAND_COMPLETION: u32 = 33;
    /// Port Status Change event.
    pub const PORT_STATUS_CHANGE: u32 = 34;
}

/// The control word's cycle bit.
pub const CYCLE: u32 = 1 << 0;
/// Link TRB: toggle the consumer's cycle state when following it.
pub const TOGGLE_CYCLE: u32 = 1 << 1;

/// One TRB's four words.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Trb(pub [u32; 4]);

impl Trb {
    /// A TRB of `kind` with a 64-bit parameter, status word and the other
    /// control bits (the cycle bit is the ring's business).
    pub fn new(kind: u32, parameter: u64, status: u32, control: u32) -> Trb {
        Trb([
            parameter as u32,
            (parameter >> 32) as u32,
            status,
            (kind << 10) | (control & !(0x3F << 10) & !CYCLE),
        ])
    }

    /// The TRB type.
    pub fn kind(&self) -> u32 {
        (self.0[3] >> 10) & 0x3F
    }

    /// The 64-bit parameter (for events: the TRB it reports on).
    pub fn parameter(&self) -> u64 {
        u64::from(self.0[0]) | (u64::from(self.0[1]) << 32)
    }

    /// An event's completion code.
    pub fn completion_code(&self) -> u8 {
        (self.0[2] >> 24) as u8
    }

    /// An event's slot.
    pub fn slot(&self) -> u8 {
        (self.0[3] >> 24) as u8
    }

    /// A transfer event's endpoint (device context index).
    pub fn endpoint(&self) -> u8 {
        ((self.0[3] >> 16) & 0x1F) as u8
    }

    /// A transfer event's residual: bytes asked for but not moved.
    pub fn residual(&self) -> u32 {
        self.0[2] & 0x00FF_FFFF
    }

    /// A port status change event's port (1-based).
    pub fn port(&self) -> u8 {
        (self.0[0] >> 24) as u8
    }
}

fn write_trb(memory: &mut impl Memory, address: u64, trb: &Trb, cycle: bool) {
    memory.mem_write(address, trb.0[0]);
    memory.mem_write(address + 4, trb.0[1]);
    memory.mem_write(address + 8, trb.0[2]);
    // Last: this write hands the TRB to the controller.
    memory.mem_write(address + 12, (trb.0[3] & !CYCLE) | u32::from(cycle));
}

/// A ring the driver produces into: `size` TRBs at `base`, the last a Link
/// back to the start.
#[derive(Clone, Debug)]
pub struct ProducerRing {
    base: u64,
    size: u16,
    enqueue: u16,
    cycle: bool,
}

impl ProducerRing {
    /// A ring over zeroed memory at `base` (16-byte aligned, not crossing a
    /// 64 KiB boundary) holding `size` TRBs, at least 2.
    pub fn new(base: u64, size: u16) -> ProducerRing {
        assert!(size >= 2, "a ring needs a TRB and its Link");
        ProducerRing {
            base,
            size,
            enqueue: 0,
            cycle: true,
        }
    }

    /// Where the ring's memory starts.
    pub fn base(&self) -> u64 {
        self.base
    }

    /// Where the ring starts, with the cycle state the consumer starts with
    /// (for CRCR and endpoint contexts' dequeue pointers).
    pub fn dequeue_pointer(&self) -> u64 {
        self.base | u64::from(self.cycle)
    }

    /// TRBs that can be written before the Link TRB.
    pub fn room_before_link(&self) -> u16 {
        self.size - 1 - self.enqueue
    }

    /// The ring's index of the TRB at `address`, if it is one of its TRBs.
    pub fn index_of(&self, address: u64) -> Option<u16> {
        let offset = address.checked_sub(self.base)?;
        if offset % TRB_BYTES != 0 || offset / TRB_BYTES >= u64::from(self.size - 1) {
            return None;
        }
        Some((offset / TRB_BYTES) as u16)
    }

    /// Where the next TRB will go, with the producer's cycle state: the
    /// dequeue pointer that makes the consumer skip everything queued so
    /// far (for Set TR Dequeue Pointer).
    pub fn enqueue_pointer(&self) -> u64 {
        self.enqueue_address() | u64::from(self.cycle)
    }

    /// Where the next TRB will go.
    pub fn enqueue_address(&self) -> u64 {
        self.base + u64::from(self.enqueue) * TRB_BYTES
    }

    /// Writes `trb` with the producer's cycle bit, following the Link when
    /// the ring's end is reached; returns the TRB's address.
    pub fn push(&mut self, memory: &mut impl Memory, trb: Trb) -> u64 {
        let address = self.enqueue_address();
        write_trb(memory, address, &trb, self.cycle);
        self.enqueue += 1;
        if self.enqueue == self.size - 1 {
            let link = Trb::new(trb_type::LINK, self.base, 0, TOGGLE_CYCLE);
            write_trb(memory, self.enqueue_address(), &link, self.cycle);
            self.enqueue = 0;
            self.cycle = !self.cycle;
        }
        address
    }

    /// Fills the ring with No Op TRBs until the next TRB's address is a
    /// multiple of `bytes` (a power of two, at most the ring's size).
    pub fn align_enqueue(&mut self, memory: &mut impl Memory, bytes: u64) {
        while !self.enqueue_address().is_multiple_of(bytes) {
            self.push(memory, Trb::new(trb_type::NO_OP_TRANSFER, 0, 0, 0));
        }
    }

    /// Makes the next `count` TRBs contiguous (a control transfer must not
    /// be split by the Link), filling the rest of the segment with No Ops.
    pub fn reserve_contiguous(&mut self, memory: &mut impl Memory, count: u16) {
        if self.room_before_link() < count {
            while self.enqueue != 0 {
                self.push(memory, Trb::new(trb_type::NO_OP_TRANSFER, 0, 0, 0));
            }
        }
    }
}

/// The event ring's one segment, consumed by the driver.
#[derive(Clone, Debug)]
pub struct EventRing {
    base: u64,
    size: u16,
    dequeue: u16,
    cycle: bool,
}

impl EventRing {
    /// A ring over zeroed memory at `base` holding `size` TRBs.
    pub fn new(base: u64, size: u16) -> EventRing {
        EventRing {
            base,
            size,
            dequeue: 0,
            cycle: true,
        }
    }

    /// The segment's start (for the ERST entry).
    pub fn base(&self) -> u64 {
        self.base
    }

    /// TRBs in the segment (for the ERST entry).
    pub fn size(&self) -> u16 {
        self.size
    }

    /// Where the next event will be read (for ERDP).
    pub fn dequeue_address(&self) -> u64 {
        self.base + u64::from(self.dequeue) * TRB_BYTES
    }

    /// The next event, if the controller has written one.
    pub fn pop(&mut self, memory: &mut impl Memory) -> Option<Trb> {
        let address = self.dequeue_address();
        let control = memory.mem_read(address + 12);
        if (control & CYCLE != 0) != self.cycle {
            return None;
        }
        let trb = Trb([
            memory.mem_read(address),
            memory.mem_read(address + 4),
            memory.mem_read(address + 8),
            control,
        ]);
        self.dequeue += 1;
        if self.dequeue == self.size {
            self.dequeue = 0;
            self.cycle = !self.cycle;
        }
        Some(trb)
    }
}

#[cfg(test)]
mod tests;
