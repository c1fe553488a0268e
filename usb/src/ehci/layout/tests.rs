use super::*;

#[test]
fn buffers_within_a_page_use_one_pointer() {
    assert_eq!(buffer_pointers(0x12_3400, 1024), [0x12_3400, 0, 0, 0, 0]);
    assert_eq!(buffer_pointers(0x12_3C00, 1024), [0x12_3C00, 0, 0, 0, 0]);
}

#[test]
fn buffers_across_a_page_use_the_next_page_too() {
    assert_eq!(
        buffer_pointers(0x12_3E00, 1024),
        [0x12_3E00, 0x12_4000, 0, 0, 0]
    );
}

#[test]
fn slots_are_aligned_and_inside_the_region() {
    let layout = Layout::new(0x10_0000);
    for i in 0..MAX_DEVICES {
        assert_eq!(layout.device_qh(i) % 32, 0);
        assert_eq!(layout.device_qtd(i, Stage::Status) % 32, 0);
        assert!(layout.device_data(i) + 1024 <= layout.device_qh(i) + DEVICE_BYTES);
    }
    for i in 0..MAX_PIPES {
        assert_eq!(layout.pipe_qh(i) % 32, 0);
        assert_eq!(layout.pipe_qtd(i) % 32, 0);
        assert!(layout.pipe_buffer(i) + 64 <= layout.pipe_qh(i) + PIPE_BYTES);
    }
    assert!(layout.pipe_qh(0) >= layout.async_head() + 0x60);
    assert_eq!(
        layout.device_qh(MAX_DEVICES - 1) + DEVICE_BYTES,
        0x10_0000 + DMA_BYTES_USED
    );
    // Some data buffers straddle a page, so the second pointer is used.
    assert!((0..MAX_DEVICES).any(|i| {
        let data = layout.device_data(i);
        data & !0xFFF != (data + 1023) & !0xFFF
    }));
}
