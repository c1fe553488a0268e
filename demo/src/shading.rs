//! Flat shading through the palette. Each of Abrash's face colours (DAC
//! entries 9-15) gets a ramp of 32 levels from black up to that very colour,
//! loaded into DAC entries 16-239; a lit face is drawn in the level its
//! brightness rounds to. Entries 0-15, which Abrash's flat colours and the
//! on-screen display use, are left alone, so lighting can be switched on and
//! off without touching the DAC again.

use engine::{quantize, Light};
use modex::palette::{Rgb6, DEFAULT_PALETTE};

/// Levels per ramp, darkest first.
pub const RAMP_LEVELS: u8 = 32;
/// The DAC entry of the first ramp's first level.
pub const RAMP_FIRST: u8 = 16;
/// The flat colours that have ramps: `FIRST_RAMPED`, `FIRST_RAMPED + 1`, ...
const FIRST_RAMPED: u8 = 9;
const RAMPS: usize = 7;
/// DAC entries the shading ramps take.
pub const RAMP_ENTRIES: usize = RAMPS * RAMP_LEVELS as usize;

/// Where the light starts: above, to the left of and behind the viewer, so it
/// falls on the scene from upper left front, as in Ammeraal and Zhang.
pub fn default_light() -> Light {
    Light::new(
        -core::f64::consts::FRAC_PI_4,
        libm::asin(libm::sqrt(1.0 / 3.0)),
        AMBIENT,
    )
}

/// The share of full brightness a face turned away from the light keeps.
const AMBIENT: f64 = 0.25;

/// The DAC entries from `RAMP_FIRST` on: level k of a ramp is its flat
/// colour scaled by k / 31, rounded.
pub fn ramp_palette() -> [Rgb6; RAMP_ENTRIES] {
    let top = u32::from(RAMP_LEVELS - 1);
    core::array::from_fn(|entry| {
        let ramp = entry / usize::from(RAMP_LEVELS);
        let level = (entry % usize::from(RAMP_LEVELS)) as u32;
        let full = DEFAULT_PALETTE[usize::from(FIRST_RAMPED) + ramp];
        full.map(|component| ((u32::from(component) * level * 2 + top) / (2 * top)) as u8)
    })
}

/// The palette index for a face of flat colour `flat` at `intensity` (0..=1).
/// A colour without a ramp keeps its flat colour.
pub fn shaded_colour(flat: u8, intensity: f64) -> u8 {
    let ramp = flat.wrapping_sub(FIRST_RAMPED);
    if usize::from(ramp) >= RAMPS {
        return flat;
    }
    RAMP_FIRST + ramp * RAMP_LEVELS + quantize(intensity, RAMP_LEVELS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_ramp_climbs_from_black_to_its_flat_colour() {
        let ramps = ramp_palette();
        for flat in FIRST_RAMPED..FIRST_RAMPED + RAMPS as u8 {
            let dark = usize::from(shaded_colour(flat, 0.0) - RAMP_FIRST);
            let bright = usize::from(shaded_colour(flat, 1.0) - RAMP_FIRST);
            assert_eq!(ramps[dark], [0, 0, 0]);
            assert_eq!(ramps[bright], DEFAULT_PALETTE[usize::from(flat)]);
            for pair in ramps[dark..=bright].windows(2) {
                assert!(pair[0].iter().zip(&pair[1]).all(|(a, b)| a <= b));
            }
        }
    }

    #[test]
    fn the_ramps_fill_entries_16_to_239_and_no_others() {
        assert_eq!(shaded_colour(9, 0.0), 16);
        assert_eq!(shaded_colour(15, 1.0), 239);
        assert_eq!(usize::from(RAMP_FIRST) + RAMP_ENTRIES, 240);
        for flat in [0, 1, 8, 16, 200, 255] {
            assert_eq!(shaded_colour(flat, 0.7), flat);
        }
    }

    #[test]
    fn a_ramp_level_is_the_flat_colour_scaled_and_rounded() {
        // Bright red is (63, 21, 21); level 10 of 31: 20.32, 6.77, 6.77.
        let ramps = ramp_palette();
        let red_level_10 = usize::from(shaded_colour(12, 10.0 / 31.0) - RAMP_FIRST);
        assert_eq!(DEFAULT_PALETTE[12], [63, 21, 21]);
        assert_eq!(ramps[red_level_10], [20, 7, 7]);
    }

    #[test]
    fn the_default_light_shines_from_upper_left_front() {
        let s = libm::sqrt(1.0 / 3.0);
        let towards = default_light().towards_light();
        assert!((towards - engine::Vec3::new(-s, s, s)).length() < 1e-12);
    }
}
