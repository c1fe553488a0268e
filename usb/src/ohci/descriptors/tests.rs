use super::*;

#[test]
fn every_tree_node_is_distinct_and_links_to_half_its_interval() {
    let mut seen = [false; TREE_NODES];
    for shift in 0..=5u8 {
        let interval = 1u8 << shift;
        for branch in 0..usize::from(interval) {
            let node = tree_node(interval, branch);
            assert!(!seen[node], "node {node} given twice");
            seen[node] = true;
            match tree_parent(interval, branch) {
                None => assert_eq!(interval, 1),
                Some(parent) => {
                    assert_eq!(
                        parent,
                        tree_node(interval / 2, branch % usize::from(interval / 2))
                    )
                }
            }
        }
    }
    assert!(seen.iter().all(|&s| s));
}

#[test]
fn a_frame_visits_each_interval_once_on_the_branch_of_its_number() {
    // Walk the tree from each interrupt-table entry as the controller
    // does: entry f visits the interval-I node of branch f mod I.
    for frame in 0..32usize {
        let mut node = tree_node(32, frame);
        let mut interval = 32u8;
        loop {
            assert_eq!(node, tree_node(interval, frame % usize::from(interval)));
            match tree_parent(interval, frame % usize::from(interval)) {
                Some(parent) => {
                    node = parent;
                    interval /= 2;
                }
                None => break,
            }
        }
        assert_eq!(interval, 1);
    }
}

#[test]
fn the_layout_keeps_alignment_and_fits_the_kernel_region() {
    let layout = Layout::new(0x10_0010);
    assert_eq!(layout.hcca % 256, 0);
    assert_eq!(layout.tree_ed(0) % 16, 0);
    assert_eq!(layout.control_td(MAX_DEVICES - 1, CONTROL_TDS - 1) % 16, 0);
    assert!(layout.is_td(layout.pipe_td(MAX_PIPES - 1, 1)));
    assert!(!layout.is_td(layout.setup(0)));
    assert!(layout.end - 0x10_0010 <= 256 * 1024);
    let page = |address: u64| address / 4096;
    for device in 0..MAX_DEVICES {
        let data = layout.control_data(device);
        assert_eq!(
            page(data),
            page(data + CONTROL_DATA_BYTES - 1),
            "device {device}"
        );
        assert_eq!(page(layout.setup(device)), page(layout.setup(device) + 7));
    }
    for pipe in 0..MAX_PIPES {
        let report = layout.report(pipe);
        assert_eq!(page(report), page(report + REPORT_BYTES - 1), "pipe {pipe}");
    }
}
