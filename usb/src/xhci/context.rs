//! Device, input and endpoint contexts. A controller with CSZ set in
//! HCCPARAMS1 uses 64-byte contexts (of which the first 32 bytes mean the
//! same as in a 32-byte one), so every offset goes through the layout.

use crate::Memory;
use xhci::context::{EndpointHandler, SlotHandler};

/// The context size the controller asks for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ContextLayout {
    /// Bytes per context: 32, or 64 when CSZ is set.
    pub context_bytes: u64,
}

/// Endpoint types in an endpoint context.
pub mod endpoint_type {
    /// Control, bidirectional.
    pub const CONTROL: u32 = 4;
    /// Interrupt IN.
    pub const INTERRUPT_IN: u32 = 7;
}

/// Device speeds, as PORTSC and the slot context give them.
pub mod speed {
    /// 12 Mb/s.
    pub const FULL: u32 = 1;
    /// 1.5 Mb/s.
    pub const LOW: u32 = 2;
    /// 480 Mb/s.
    pub const HIGH: u32 = 3;
    /// 5 Gb/s.
    pub const SUPER: u32 = 4;
}

/// What goes in a slot context.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SlotContext {
    /// The hubs' ports below the root port, four bits a tier.
    pub route_string: u32,
    /// The device's speed.
    pub speed: u32,
    /// The device is a hub.
    pub hub: bool,
    /// The last valid endpoint context index.
    pub context_entries: u32,
    /// The root hub port (1-based) the device hangs from.
    pub root_port: u8,
    /// For a hub: its number of ports.
    pub hub_ports: u8,
    /// For a low- or full-speed device behind a high-speed hub: that hub's
    /// slot and port (its transaction translator).
    pub tt_hub_slot: u8,
    /// See `tt_hub_slot`.
    pub tt_port: u8,
}

/// What goes in an endpoint context.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EndpointContext {
    /// See [`endpoint_type`].
    pub kind: u32,
    /// Largest packet.
    pub max_packet: u16,
    /// Service interval, as 2^interval x 125 us.
    pub interval: u8,
    /// The transfer ring's dequeue pointer, cycle state in bit 0.
    pub dequeue: u64,
    /// Average TRB length (8 for control, the report size for interrupt).
    pub average_trb_length: u16,
}

impl ContextLayout {
    /// The layout for HCCPARAMS1's CSZ bit.
    pub fn new(csz: bool) -> ContextLayout {
        ContextLayout {
            context_bytes: if csz { 64 } else { 32 },
        }
    }

    /// Bytes of a device context (slot plus 31 endpoints).
    pub fn device_context_bytes(&self) -> u64 {
        32 * self.context_bytes
    }

    /// Bytes of an input context (input control, slot, 31 endpoints).
    pub fn input_context_bytes(&self) -> u64 {
        33 * self.context_bytes
    }

    /// Where the input context at `input` keeps its slot context.
    pub fn input_slot(&self, input: u64) -> u64 {
        input + self.context_bytes
    }

    /// Where the input context at `input` keeps endpoint `dci`'s context
    /// (device context index: 1 is EP0, 2n+1 endpoint n IN).
    pub fn input_endpoint(&self, input: u64, dci: u8) -> u64 {
        input + (1 + u64::from(dci)) * self.context_bytes
    }

    /// Where the output device context at `device` keeps context `dci`
    /// (0 is the slot).
    pub fn output_context(&self, device: u64, dci: u8) -> u64 {
        device + u64::from(dci) * self.context_bytes
    }

    /// Clears the input context and sets its add flags.
    pub fn start_input(&self, memory: &mut impl Memory, input: u64, add_flags: u32) {
        for offset in (0..self.input_context_bytes()).step_by(4) {
            memory.mem_write(input + offset, 0);
        }
        memory.mem_write(input + 4, add_flags);
    }

    /// Writes a slot context into an input context. The fields are laid
    /// out by the `xhci` crate's context types; only the first 32 bytes of a
    /// 64-byte context mean anything, and `start_input` zeroed the rest.
    pub fn write_slot(&self, memory: &mut impl Memory, input: u64, slot: &SlotContext) {
        let mut context = xhci::context::Slot32Byte::new_32byte();
        // Every value is masked to its field: the crate's setters panic on
        // one that does not fit.
        context.set_route_string(slot.route_string & 0xF_FFFF);
        context.set_speed((slot.speed & 0xF) as u8);
        if slot.hub {
            context.set_hub();
        }
        context.set_context_entries((slot.context_entries & 0x1F) as u8);
        context.set_root_hub_port_number(slot.root_port);
        context.set_number_of_ports(slot.hub_ports);
        context.set_parent_hub_slot_id(slot.tt_hub_slot);
        context.set_parent_port_number(slot.tt_port);
        write_words(memory, self.input_slot(input), context.as_ref());
    }

    /// Writes endpoint `dci`'s context into an input context (laid out by
    /// the `xhci` crate, as the slot).
    pub fn write_endpoint(
        &self,
        memory: &mut impl Memory,
        input: u64,
        dci: u8,
        endpoint: &EndpointContext,
    ) {
        use xhci::context::EndpointType;
        /// Three tries before an error stops the endpoint.
        const ERROR_COUNT: u8 = 3;
        let mut context = xhci::context::Endpoint32Byte::new_32byte();
        context.set_endpoint_type(match endpoint.kind {
            endpoint_type::CONTROL => EndpointType::Control,
            endpoint_type::INTERRUPT_IN => EndpointType::InterruptIn,
            _ => EndpointType::NotValid,
        });
        context.set_interval(endpoint.interval);
        context.set_error_count(ERROR_COUNT);
        context.set_max_packet_size(endpoint.max_packet);
        // The crate wants the pointer 64-byte aligned (rings here are pages);
        // a dequeue pointer of 0 is Evaluate Context's "not evaluated".
        context.set_tr_dequeue_pointer(endpoint.dequeue & !0x3F);
        if endpoint.dequeue & 1 != 0 {
            context.set_dequeue_cycle_state();
        }
        context.set_average_trb_length(endpoint.average_trb_length);
        if endpoint.kind != endpoint_type::CONTROL {
            context.set_max_endpoint_service_time_interval_payload_low(endpoint.max_packet);
        }
        write_words(memory, self.input_endpoint(input, dci), context.as_ref());
    }

    /// The slot state (0 disabled, 1 default, 2 addressed, 3 configured) in
    /// the output device context.
    pub fn slot_state(&self, memory: &mut impl Memory, device: u64) -> u32 {
        memory.mem_read(self.output_context(device, 0) + 12) >> 27
    }
}

fn write_words(memory: &mut impl Memory, at: u64, words: &[u32]) {
    for (index, &word) in words.iter().enumerate() {
        memory.mem_write(at + 4 * index as u64, word);
    }
}

/// The xHCI interval for an interrupt endpoint's `bInterval` at `speed`:
/// full and low speed count frames (ms), faster ones give 2^(n-1) microframes.
pub fn interrupt_interval(speed_id: u32, b_interval: u8) -> u8 {
    match speed_id {
        speed::FULL | speed::LOW => {
            // The largest 2^n x 125 us not above bInterval ms, n in 3..=10.
            let microframes = u32::from(b_interval.max(1)) * 8;
            (31 - microframes.leading_zeros()).clamp(3, 10) as u8
        }
        _ => b_interval.clamp(1, 16) - 1,
    }
}

#[cfg(test)]
mod tests;
