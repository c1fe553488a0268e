//! What the page says of the picture's pixel under the mouse: Mode X keeps
//! pixel (x, y) in plane `x % 4`, at byte `y * 80 + x / 4` past the start
//! address the CRTC latched (the shown page's base), and the byte is a DAC
//! index whose 6-bit colour the scan-out widens to 8 bits.

use modex::soft::{dac_6_to_8, SoftVga};
use modex::{Page, BYTES_PER_LINE, PAGE_BYTES, SCREEN_HEIGHT, SCREEN_WIDTH};

/// Everything the readout says of one pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PixelInfo {
    /// Column, 0 to 319.
    pub x: u16,
    /// Line, 0 to 239.
    pub y: u16,
    /// The plane that holds it: `x % 4`.
    pub plane: u8,
    /// Its byte in the plane: `start + y * 80 + x / 4`.
    pub offset: u16,
    /// The page whose bytes hold it (`None` if the start address is not a
    /// page's and the byte is past the last).
    pub page: Option<u8>,
    /// The byte: the DAC index.
    pub colour: u8,
    /// The DAC's entry for it, 6 bits a component.
    pub dac: [u8; 3],
    /// As the scan-out shows it, 8 bits a component.
    pub rgb: [u8; 3],
}

/// The pixel at (x, y) of the picture the VGA shows, if (x, y) is on it.
pub fn pixel_info(vga: &SoftVga, x: u16, y: u16) -> Option<PixelInfo> {
    if i32::from(x) >= SCREEN_WIDTH || i32::from(y) >= SCREEN_HEIGHT {
        return None;
    }
    let plane = (x % 4) as u8;
    // The CRTC counts in a 16-bit address space: it wraps, as the inspector's
    // plane images do.
    let offset = vga
        .displayed_start()
        .wrapping_add(y * BYTES_PER_LINE)
        .wrapping_add(x / 4);
    let page = Page::ALL
        .into_iter()
        .find(|page| (page.base()..page.base() + PAGE_BYTES).contains(&offset))
        .map(Page::index);
    let colour = vga.plane(usize::from(plane))[usize::from(offset)];
    let dac = vga.dac_entry(colour);
    Some(PixelInfo {
        x,
        y,
        plane,
        offset,
        page,
        colour,
        dac,
        rgb: dac.map(dac_6_to_8),
    })
}

/// The readout, one line: "x 13, y 7: plane 1, offset 0x0233 (563) on
/// page 0, colour 15, DAC 63 63 63 = #FFFFFF". Empty off the picture.
pub fn hover_text(vga: &SoftVga, x: u16, y: u16) -> String {
    let Some(info) = pixel_info(vga, x, y) else {
        return String::new();
    };
    let page = match info.page {
        Some(page) => format!("page {page}"),
        None => "no page".to_string(),
    };
    let [r, g, b] = info.dac;
    let [r8, g8, b8] = info.rgb;
    format!(
        "x {}, y {}: plane {}, offset 0x{:04X} ({}) on {page}, colour {}, DAC {r} {g} {b} = #{r8:02X}{g8:02X}{b8:02X}",
        info.x, info.y, info.plane, info.offset, info.offset, info.colour
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::machine::Machine;

    /// A small deterministic generator: the same "random" pixels every run.
    fn pixels(count: usize) -> Vec<(u16, u16)> {
        let mut state: u32 = 0x2545_F491;
        (0..count)
            .map(|_| {
                state ^= state << 13;
                state ^= state >> 17;
                state ^= state << 5;
                ((state % 320) as u16, ((state >> 16) % 240) as u16)
            })
            .collect()
    }

    #[test]
    fn the_readout_is_the_scan_out_and_the_planes_for_random_pixels() {
        crate::with_big_stack(|| {
            let mut machine = Machine::new();
            machine.tap(keyboard::keys::scancode_for_name("m").unwrap());
            for _ in 0..5 {
                machine.frame();
            }
            let vga = machine.vga();
            let picture_indices = machine.scanout_indices();
            let picture = machine.scanout_rgb();
            let start = usize::from(vga.displayed_start());
            let mut colours = std::collections::BTreeSet::new();
            for (x, y) in pixels(200) {
                let info = pixel_info(vga, x, y).unwrap();
                let pixel = usize::from(y) * 320 + usize::from(x);
                // What the monitor shows...
                assert_eq!(info.colour, picture_indices[pixel], "({x}, {y})");
                assert_eq!(info.rgb, picture[pixel], "({x}, {y})");
                // ...and where Mode X keeps it.
                let offset = start + usize::from(y) * 80 + usize::from(x) / 4;
                assert_eq!(usize::from(info.offset), offset);
                assert_eq!(info.plane, (x % 4) as u8);
                assert_eq!(vga.plane(usize::from(x % 4))[offset], info.colour);
                assert_eq!(info.page.map(usize::from), Some(offset / 19200));
                let text = hover_text(vga, x, y);
                assert!(text.starts_with(&format!("x {x}, y {y}: plane {}", x % 4)));
                assert!(
                    text.contains(&format!("offset 0x{offset:04X} ({offset})")),
                    "{text}"
                );
                colours.insert(info.colour);
            }
            assert!(colours.len() > 2, "the pixels cross the cubes: {colours:?}");
        });
    }

    #[test]
    fn the_readout_names_page_one_after_a_flip_and_nothing_off_the_picture() {
        crate::with_big_stack(|| {
            let mut machine = Machine::new();
            machine.frame();
            let vga = machine.vga();
            let page = vga.displayed_start() / PAGE_BYTES;
            let text = hover_text(vga, 319, 239);
            let offset = vga.displayed_start() + 239 * 80 + 79;
            assert!(
                text.contains(&format!("offset 0x{offset:04X} ({offset}) on page {page},")),
                "{text}"
            );
            assert_eq!(hover_text(vga, 320, 0), "");
            assert_eq!(hover_text(vga, 0, 240), "");
        });
    }
}
