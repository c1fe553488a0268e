//! The fault panel on the host's software VGA: 80x25 text in 8-dot cells, the
//! report's lines across the top, the log on the left and a QR code of the
//! report on the right that decodes to exactly the text it was given, however
//! long the lines and full the log.

use demo::screens::{
    fault_panel, fault_qr_text, CODE_COLUMN, LOWER_TEXT_COLUMNS, PANEL_LOG_LINES,
    PANEL_QR_TEXT_BYTES, REPORT_LINES,
};
use modex::soft::SoftVga;
use modex::{ModeX, TEXT_COLUMNS, TEXT_ROWS};

const WIDTH: usize = 640;
const HEIGHT: usize = 400;

fn panel(lines: &[&str; REPORT_LINES], log: &[&str], qr_text: &[u8]) -> Box<SoftVga> {
    let mut soft = Box::new(SoftVga::new());
    ModeX::new(&mut *soft).set_mode();
    fault_panel(&mut ModeX::new(&mut *soft), lines, log, qr_text);
    soft
}

/// The panel's picture, grey levels.
fn picture(soft: &SoftVga) -> Vec<u8> {
    let mut rgb = vec![[0u8; 3]; 720 * 400];
    assert_eq!(
        soft.scanout_rgb(&mut rgb),
        (WIDTH, HEIGHT),
        "not 640x400 text"
    );
    rgb[..WIDTH * HEIGHT]
        .iter()
        .map(|[r, g, b]| ((u32::from(*r) + u32::from(*g) + u32::from(*b)) / 3) as u8)
        .collect()
}

/// Every QR code in the picture, decoded (scaled up 2x, as a camera sees
/// large squares).
fn decode(grey: &[u8]) -> Vec<String> {
    let mut image = rqrr::PreparedImage::prepare_from_greyscale(WIDTH * 2, HEIGHT * 2, |x, y| {
        grey[(y / 2) * WIDTH + x / 2]
    });
    image
        .detect_grids()
        .iter()
        .map(|grid| grid.decode().expect("the code decodes").1)
        .collect()
}

/// Characters and attributes of the text screen, from planes 0 and 1.
fn cells(soft: &SoftVga) -> Vec<(u8, u8)> {
    let cells = usize::from(TEXT_COLUMNS) * usize::from(TEXT_ROWS);
    (0..cells)
        .map(|cell| (soft.plane(0)[cell], soft.plane(1)[cell]))
        .collect()
}

fn long_report() -> ([String; REPORT_LINES], Vec<String>, Vec<String>) {
    let lines = [
        format!("PANIC: {}", "m".repeat(300)),
        format!("  at {}:1:2", "dir/".repeat(60)),
        "  error code=0xffffffffffffffff".to_owned(),
        "  address=0xffffffffffffffff".to_owned(),
    ];
    let facts = vec![
        "modex-cube 0.1.0 commit 0123456789abcdef0123456789abcdef01234567".to_owned(),
        format!("cpu: GenuineIntel, {}", "X".repeat(48)),
        "firmware: UEFI".to_owned(),
        format!("display: {}", "d".repeat(200)),
    ];
    let log = (0..300)
        .map(|n| format!("line {n}: {}", "z".repeat(n % 130)))
        .collect();
    (lines, facts, log)
}

#[test]
fn long_lines_and_a_full_log_stay_in_their_areas_and_the_code_decodes() {
    let (lines, facts, log) = long_report();
    let lines_text: [&str; REPORT_LINES] = std::array::from_fn(|i| lines[i].as_str());
    let facts: Vec<&str> = facts.iter().map(String::as_str).collect();
    let log: Vec<&str> = log.iter().map(String::as_str).collect();
    let mut text = [0u8; PANEL_QR_TEXT_BYTES];
    let len = fault_qr_text(&lines_text, &facts, &log, &mut text);
    let text = &text[..len];
    assert!(len > 300 && len <= PANEL_QR_TEXT_BYTES, "{len} bytes");
    let soft = panel(&lines_text, &log, text);
    // The code holds exactly the text: no text landed on it.
    assert_eq!(
        decode(&picture(&soft)),
        [String::from_utf8(text.to_vec()).unwrap()]
    );
    // Left of the code, text stops a column short of it; the code's cells are
    // all black-on-white blocks; the last log line is shown, cut.
    let cells = cells(&soft);
    let columns = usize::from(TEXT_COLUMNS);
    for row in 5..usize::from(TEXT_ROWS) {
        for column in 0..columns {
            let (character, attribute) = cells[row * columns + column];
            if column >= usize::from(CODE_COLUMN) {
                assert_eq!(attribute, 0xF0, "row {row} column {column}");
            } else if column > LOWER_TEXT_COLUMNS {
                assert_eq!(
                    (character, attribute),
                    (b' ', 0x0F),
                    "row {row} column {column}"
                );
            }
        }
    }
    let last_row = &cells[24 * columns + 1..24 * columns + 1 + LOWER_TEXT_COLUMNS];
    let shown: String = last_row.iter().map(|&(c, _)| char::from(c)).collect();
    assert!(log[299].starts_with(shown.as_str()), "{shown:?}");
    assert_eq!(PANEL_LOG_LINES, 16);
}

#[test]
fn the_qr_text_is_the_report_then_facts_then_the_newest_log_lines() {
    let lines = ["EXCEPTION: page fault", "  rip=0x1", "", "  address=0x2"];
    let facts = ["modex-cube 0.1.0", "", "firmware: BIOS"];
    let log = ["old", "middle", "new"];
    let mut out = [0u8; PANEL_QR_TEXT_BYTES];
    let len = fault_qr_text(&lines, &facts, &log, &mut out);
    assert_eq!(
        std::str::from_utf8(&out[..len]).unwrap(),
        "EXCEPTION: page fault\n  rip=0x1\n  address=0x2\nmodex-cube 0.1.0\nfirmware: BIOS\nold\nmiddle\nnew"
    );
    // Room for the report and the newest log line only.
    let mut small = [0u8; 56];
    let len = fault_qr_text(&lines, &[], &log, &mut small);
    assert_eq!(
        std::str::from_utf8(&small[..len]).unwrap(),
        "EXCEPTION: page fault\n  rip=0x1\n  address=0x2\nmiddle\nnew"
    );
}

#[test]
fn the_largest_text_fits_the_largest_code() {
    let big = "Q".repeat(PANEL_QR_TEXT_BYTES);
    let soft = panel(&["", "", "", ""], &[], big.as_bytes());
    assert_eq!(decode(&picture(&soft)), [big]);
}
