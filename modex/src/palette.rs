//! The standard VGA BIOS palettes, in 6-bit DAC units (0..=63), built from
//! their structure rather than typed out; the tests pin them to the values the
//! IBM VGA BIOS (and SeaBIOS, QEMU's VGA BIOS) loads.

/// One DAC entry: red, green, blue, 6 bits each.
pub type Rgb6 = [u8; 3];

/// The palette the BIOS loads for mode 13h, which Mode X keeps:
///
/// * 0-15: the 16 EGA/CGA colours;
/// * 16-31: a grey ramp;
/// * 32-247: nine blocks of a 24-step hue circle, at three saturations for
///   each of three intensities;
/// * 248-255: black.
pub const DEFAULT_PALETTE: [Rgb6; 256] = default_palette();

/// The 64-colour EGA palette the BIOS loads for the 16-colour text modes: bits
/// 0-2 of the index are blue, green and red at 2/3 intensity, bits 3-5 the same
/// at 1/3.
pub const EGA_PALETTE: [Rgb6; 64] = ega_palette();

/// The text-mode colours 0-15 as the Attribute Controller maps them into the
/// EGA palette: brown (6) is 0x14, the bright colours are 0x38-0x3F.
pub const EGA_TEXT_ATTRIBUTES: [u8; 16] = [
    0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x14, 0x07, 0x38, 0x39, 0x3A, 0x3B, 0x3C, 0x3D, 0x3E, 0x3F,
];

const TWO_THIRDS: u8 = 0x2A;
const ONE_THIRD: u8 = 0x15;

const GREY_RAMP: [u8; 16] = [
    0x00, 0x05, 0x08, 0x0B, 0x0E, 0x11, 0x14, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2D, 0x32, 0x38, 0x3F,
];

/// The five channel levels of each hue block, from the floor (the
/// desaturating component) to the peak (the intensity).
const HUE_BLOCK_LEVELS: [[u8; 5]; 9] = [
    [0x00, 0x10, 0x1F, 0x2F, 0x3F], // high intensity, high saturation
    [0x1F, 0x27, 0x2F, 0x37, 0x3F], // high intensity, medium saturation
    [0x2D, 0x31, 0x36, 0x3A, 0x3F], // high intensity, low saturation
    [0x00, 0x07, 0x0E, 0x15, 0x1C], // medium intensity, ...
    [0x0E, 0x11, 0x15, 0x18, 0x1C],
    [0x14, 0x16, 0x18, 0x1A, 0x1C],
    [0x00, 0x04, 0x08, 0x0C, 0x10], // low intensity, ...
    [0x08, 0x0A, 0x0C, 0x0E, 0x10],
    [0x0B, 0x0C, 0x0D, 0x0F, 0x10],
];

/// The hue circle as level numbers per channel: blue, through magenta, red,
/// yellow, green and cyan, back towards blue, one channel moving per step.
const HUE_STEPS: usize = 24;
const HUE_RED: [u8; HUE_STEPS] = [
    0, 1, 2, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 3, 2, 1, 0, 0, 0, 0, 0, 0, 0, 0,
];
const HUE_GREEN: [u8; HUE_STEPS] = [
    0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 3, 2, 1,
];
const HUE_BLUE: [u8; HUE_STEPS] = [
    4, 4, 4, 4, 4, 3, 2, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 4, 4, 4,
];

const fn ega_palette() -> [Rgb6; 64] {
    let mut palette = [[0; 3]; 64];
    let mut index = 0;
    while index < palette.len() {
        let bits = index as u8;
        palette[index] = [
            ega_channel(bits, 0x04, 0x20),
            ega_channel(bits, 0x02, 0x10),
            ega_channel(bits, 0x01, 0x08),
        ];
        index += 1;
    }
    palette
}

const fn ega_channel(bits: u8, two_thirds_bit: u8, one_third_bit: u8) -> u8 {
    let strong = if bits & two_thirds_bit != 0 {
        TWO_THIRDS
    } else {
        0
    };
    let weak = if bits & one_third_bit != 0 {
        ONE_THIRD
    } else {
        0
    };
    strong + weak
}

const fn default_palette() -> [Rgb6; 256] {
    let mut palette = [[0; 3]; 256];
    // The 16 CGA colours: EGA entries 0-7 and their bright versions 0x38-0x3F,
    // with brown (6) taken from 0x14 as the text-mode attributes map it.
    let ega = ega_palette();
    let mut index = 0;
    while index < EGA_TEXT_ATTRIBUTES.len() {
        palette[index] = ega[EGA_TEXT_ATTRIBUTES[index] as usize];
        index += 1;
    }
    let mut grey = 0;
    while grey < GREY_RAMP.len() {
        let level = GREY_RAMP[grey];
        palette[16 + grey] = [level; 3];
        grey += 1;
    }
    let mut block = 0;
    while block < HUE_BLOCK_LEVELS.len() {
        let levels = HUE_BLOCK_LEVELS[block];
        let mut step = 0;
        while step < HUE_STEPS {
            palette[32 + block * HUE_STEPS + step] = [
                levels[HUE_RED[step] as usize],
                levels[HUE_GREEN[step] as usize],
                levels[HUE_BLUE[step] as usize],
            ];
            step += 1;
        }
        block += 1;
    }
    // 248-255 stay black.
    palette
}
