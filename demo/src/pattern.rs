//! The Mode X test pattern: every palette colour, a one-pixel white frame at
//! the screen's edge, and filled rectangles at every left alignment (x mod 4)
//! and widths 1 to 12, so a driver mistake in the ragged edges shows at once.
//! Each page gets a marker of its own, so a flip is visible.

use modex::{ModeX, Page, VgaBus, SCREEN_HEIGHT, SCREEN_WIDTH};

const WHITE: u8 = 15;
const SWATCH_COLUMNS: i32 = 32;
const SWATCH_WIDTH: i32 = SCREEN_WIDTH / SWATCH_COLUMNS;
const SWATCH_HEIGHT: i32 = 12;
const SWATCH_TOP: i32 = 4;
const ALIGNMENT_TOP: i32 = 110;
const ALIGNMENT_ROW_HEIGHT: i32 = 14;
const ALIGNMENT_COLUMN_WIDTH: i32 = 26;
const MARKER_TOP: i32 = 180;
const MARKER_SIZE: i32 = 37;

/// Draws the test pattern into `page`: colour swatches, a border and a
/// marker whose place says which page it is.
pub fn draw<B: VgaBus>(vga: &mut ModeX<B>, page: Page) {
    vga.clear_page(page, 0);
    // All 256 palette colours, 32 to a row.
    for colour in 0..=255u8 {
        let (column, row) = (
            i32::from(colour) % SWATCH_COLUMNS,
            i32::from(colour) / SWATCH_COLUMNS,
        );
        let (x, y) = (column * SWATCH_WIDTH, SWATCH_TOP + row * SWATCH_HEIGHT);
        vga.fill_rect(page, x, y, x + SWATCH_WIDTH, y + SWATCH_HEIGHT, colour);
    }
    // Rectangles starting at each x mod 4, 1 to 12 pixels wide.
    for alignment in 0..4 {
        for width in 1..=12 {
            let x = 4 + (width - 1) * ALIGNMENT_COLUMN_WIDTH + alignment;
            let y = ALIGNMENT_TOP + alignment * ALIGNMENT_ROW_HEIGHT;
            let colour = (32 + alignment * 12 + width) as u8;
            vga.fill_rect(page, x, y, x + width, y + ALIGNMENT_ROW_HEIGHT - 4, colour);
        }
    }
    // A marker whose place says which page this is.
    let marker_x = 20 + 40 * i32::from(page.index());
    vga.fill_rect(
        page,
        marker_x,
        MARKER_TOP,
        marker_x + MARKER_SIZE,
        MARKER_TOP + MARKER_SIZE,
        40 + page.index(),
    );
    // The frame, one pixel wide, on the outermost rows and columns.
    vga.fill_rect(page, 0, 0, SCREEN_WIDTH, 1, WHITE);
    vga.fill_rect(
        page,
        0,
        SCREEN_HEIGHT - 1,
        SCREEN_WIDTH,
        SCREEN_HEIGHT,
        WHITE,
    );
    vga.fill_rect(page, 0, 0, 1, SCREEN_HEIGHT, WHITE);
    vga.fill_rect(
        page,
        SCREEN_WIDTH - 1,
        0,
        SCREEN_WIDTH,
        SCREEN_HEIGHT,
        WHITE,
    );
}
