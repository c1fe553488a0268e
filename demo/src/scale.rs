//! Where a frame stops fitting a refresh: the search the kernel's `bench`
//! runs over a scene that grows (`demo::grid`), measuring as few sizes as
//! it can. Sizes double from a start until one misses the budget, then the
//! gap between the last fit and the first miss is halved until it is within
//! a 32nd of the fit (or one).
//!
//! The search assumes that cost grows with size; a measurement that breaks
//! that (host noise under emulation) can only move the answer within the
//! last gap, and every size measured is reported so a reader can see it.

/// One size measured: how many, and its cost (microseconds a frame).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trial {
    /// The scene's size.
    pub count: usize,
    /// Its mean cost per frame.
    pub micros: u64,
}

/// What the search found.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Largest {
    /// The largest size measured that fits the budget, if any did.
    pub fits: Option<Trial>,
    /// The smallest size measured above it that does not, if any did (none
    /// when even `limit` fits).
    pub misses: Option<Trial>,
}

/// Finds the largest size in `start..=limit` whose cost is within `budget`,
/// calling `measure` for each size it tries. At most about 2·log2(limit)
/// measurements.
pub fn largest_that_fits(
    start: usize,
    limit: usize,
    budget: u64,
    mut measure: impl FnMut(usize) -> u64,
) -> Largest {
    let mut trial = |count: usize| Trial {
        count,
        micros: measure(count),
    };
    let mut found = Largest::default();
    let mut count = start.clamp(1, limit.max(1));
    // Doubling until a miss or the limit.
    loop {
        let result = trial(count);
        if result.micros > budget {
            found.misses = Some(result);
            break;
        }
        found.fits = Some(result);
        if count >= limit {
            return found;
        }
        count = (count * 2).min(limit);
    }
    // Halving the gap between the last fit and the first miss.
    while let (Some(fit), Some(miss)) = (found.fits, found.misses) {
        let gap = miss.count - fit.count;
        if gap <= (fit.count / 32).max(1) {
            break;
        }
        let result = trial(fit.count + gap / 2);
        if result.micros > budget {
            found.misses = Some(result);
        } else {
            found.fits = Some(result);
        }
    }
    found
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    fn linear(per_item: u64) -> impl FnMut(usize) -> u64 {
        move |count| 100 + per_item * count as u64
    }

    #[test]
    fn finds_the_largest_size_within_a_32nd() {
        let mut tried = Vec::new();
        // 100 + 50 n <= 16_747: n <= 332.
        let mut cost = linear(50);
        let found = largest_that_fits(16, 1024, 16_747, |count| {
            tried.push(count);
            cost(count)
        });
        let (fit, miss) = (found.fits.unwrap(), found.misses.unwrap());
        assert!(fit.count <= 332 && miss.count > 332, "{found:?}");
        assert!(miss.count - fit.count <= (fit.count / 32).max(1));
        assert!(332 - fit.count <= 332 / 32);
        assert_eq!(&tried[..5], &[16, 32, 64, 128, 256]);
        assert!(tried.len() <= 2 * 10, "{tried:?}");
    }

    #[test]
    fn the_limit_itself_may_fit() {
        let found = largest_that_fits(16, 1000, 16_747, linear(1));
        assert_eq!(found.fits.unwrap().count, 1000);
        assert_eq!(found.misses, None);
    }

    #[test]
    fn even_the_smallest_may_miss() {
        let found = largest_that_fits(16, 1024, 16_747, linear(10_000));
        assert_eq!(found.fits, None);
        assert_eq!(found.misses.unwrap().count, 16);
    }

    #[test]
    fn exact_to_one_at_small_sizes() {
        // 100 + 5000 n <= 16_747: n <= 3.
        let found = largest_that_fits(1, 64, 16_747, linear(5000));
        assert_eq!(found.fits.unwrap().count, 3);
        assert_eq!(found.misses.unwrap().count, 4);
    }

    #[test]
    fn a_noisy_measurement_still_ends() {
        let mut calls = 0u64;
        let found = largest_that_fits(16, 1024, 16_747, |count| {
            calls += 1;
            // Alternating noise around a limit of about 300.
            (count as u64 * 55) ^ (calls % 2 * 4096)
        });
        assert!(found.fits.is_some() || found.misses.is_some());
        assert!(calls <= 30);
    }
}
