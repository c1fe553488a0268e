use super::*;
use crate::test_memory::Words;

#[test]
fn the_producer_links_back_and_toggles_its_cycle() {
    let mut memory = Words::default();
    let mut ring = ProducerRing::new(0x1000, 4);
    assert_eq!(ring.dequeue_pointer(), 0x1001);
    for expected in [0x1000, 0x1010, 0x1020] {
        let trb = Trb::new(trb_type::NORMAL, 0xAB, 8, 0);
        assert_eq!(ring.push(&mut memory, trb), expected);
        assert_eq!(memory.mem_read(expected + 12) & CYCLE, 1);
    }
    // The Link at index 3, owned with cycle 1, pointing home, toggling.
    let link = memory.mem_read(0x1030 + 12);
    assert_eq!((link >> 10) & 0x3F, trb_type::LINK);
    assert_eq!(link & (CYCLE | TOGGLE_CYCLE), CYCLE | TOGGLE_CYCLE);
    assert_eq!(memory.mem_read(0x1030), 0x1000);
    // The second lap writes cycle 0.
    assert_eq!(ring.push(&mut memory, Trb::new(1, 0, 0, 0)), 0x1000);
    assert_eq!(memory.mem_read(0x1000 + 12) & CYCLE, 0);
    assert_eq!(ring.index_of(0x1010), Some(1));
    assert_eq!(ring.index_of(0x1030), None, "the Link is no transfer");
    assert_eq!(ring.index_of(0x1008), None);
    assert_eq!(ring.index_of(0xFF0), None);
}

#[test]
fn a_control_transfer_is_never_split_by_the_link() {
    let mut memory = Words::default();
    let mut ring = ProducerRing::new(0, 8);
    for _ in 0..5 {
        ring.push(&mut memory, Trb::new(1, 0, 0, 0));
    }
    assert_eq!(ring.room_before_link(), 2);
    ring.reserve_contiguous(&mut memory, 3);
    assert_eq!(ring.enqueue_address(), 0, "No Ops filled the segment");
    assert_eq!(
        (memory.mem_read(5 * 16 + 12) >> 10) & 0x3F,
        trb_type::NO_OP_TRANSFER
    );
    ring.reserve_contiguous(&mut memory, 3);
    assert_eq!(ring.enqueue_address(), 0, "room enough: nothing written");
}

#[test]
fn the_event_ring_wraps_and_follows_the_cycle_bit() {
    let mut memory = Words::default();
    let mut ring = EventRing::new(0x2000, 3);
    assert_eq!(ring.pop(&mut memory), None, "zeroed memory holds no event");
    // The controller's first lap: cycle 1.
    for i in 0..3u64 {
        memory.mem_write(0x2000 + i * 16, i as u32);
        memory.mem_write(0x2000 + i * 16 + 12, (33 << 10) | 1);
    }
    for i in 0..3u32 {
        assert_eq!(ring.pop(&mut memory).map(|t| t.0[0]), Some(i));
    }
    assert_eq!(ring.dequeue_address(), 0x2000);
    // The old lap's TRBs (cycle 1) are not new events on the second lap.
    assert_eq!(ring.pop(&mut memory), None);
    memory.mem_write(0x2000, 7);
    memory.mem_write(0x2000 + 12, 33 << 10);
    assert_eq!(ring.pop(&mut memory).map(|t| t.0[0]), Some(7));
    assert_eq!(ring.pop(&mut memory), None);
}
