use super::*;
use crate::test_memory::Words;

#[test]
fn sixty_four_byte_contexts_double_every_offset() {
    let small = ContextLayout::new(false);
    let large = ContextLayout::new(true);
    assert_eq!(small.input_slot(0x1000), 0x1020);
    assert_eq!(large.input_slot(0x1000), 0x1040);
    assert_eq!(small.input_endpoint(0x1000, 1), 0x1040);
    assert_eq!(large.input_endpoint(0x1000, 1), 0x1080);
    assert_eq!(large.input_endpoint(0x1000, 3), 0x1100);
    assert_eq!(large.output_context(0x2000, 3), 0x20C0);
    assert_eq!(large.device_context_bytes(), 2048);
    assert_eq!(large.input_context_bytes(), 2112);
}

#[test]
fn a_slot_and_an_endpoint_context_hold_their_fields() {
    let layout = ContextLayout::new(true);
    let mut memory = Words::default();
    layout.start_input(&mut memory, 0, 0b1001);
    assert_eq!(memory.mem_read(4), 0b1001);
    let slot = SlotContext {
        route_string: 0x3,
        speed: speed::FULL,
        hub: false,
        context_entries: 3,
        root_port: 2,
        hub_ports: 0,
        tt_hub_slot: 5,
        tt_port: 3,
    };
    layout.write_slot(&mut memory, 0, &slot);
    assert_eq!(memory.mem_read(64), 0x3 | 1 << 20 | 3 << 27);
    assert_eq!(memory.mem_read(68), 2 << 16);
    assert_eq!(memory.mem_read(72), 5 | 3 << 8);
    let endpoint = EndpointContext {
        kind: endpoint_type::INTERRUPT_IN,
        max_packet: 8,
        interval: 6,
        dequeue: 0x1234_5001,
        average_trb_length: 8,
    };
    layout.write_endpoint(&mut memory, 0, 3, &endpoint);
    let at = 4 * 64;
    assert_eq!(memory.mem_read(at), 6 << 16);
    assert_eq!(memory.mem_read(at + 4), 3 << 1 | 7 << 3 | 8 << 16);
    assert_eq!(memory.mem_read(at + 8), 0x1234_5001);
    assert_eq!(memory.mem_read(at + 16), 8 | 8 << 16);
}

#[test]
fn intervals_follow_the_speed() {
    assert_eq!(interrupt_interval(speed::FULL, 10), 6); // 8 ms
    assert_eq!(interrupt_interval(speed::LOW, 1), 3); // 1 ms
    assert_eq!(interrupt_interval(speed::FULL, 255), 10);
    assert_eq!(interrupt_interval(speed::FULL, 0), 3);
    assert_eq!(interrupt_interval(speed::HIGH, 4), 3);
    assert_eq!(interrupt_interval(speed::HIGH, 0), 0);
}
