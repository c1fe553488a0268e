//! Where a frame stops fitting a refresh: the search the kernel's `bench`
//! runs over a scene that grows (`demo::grid`), measuring as few sizes as
//! it can, and as few large ones: a large size costs the bench the most
//! time. Sizes double from a start, but once two have been measured the
//! next is no larger than where the line through the last two meets the
//! budget, a 32nd beyond it, so the first miss lands just past the answer
//! rather than up to twice it. The gap between the last fit and the first
//! miss is then closed the same way, the line's guess kept a 32nd of the
//! fit inside the gap (so that a good guess leaves a small gap on one side
//! or the other), until the gap is within a 32nd of the fit (or one).
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
/// measurements, and for a cost that grows about linearly, two or three
/// after the first miss.
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
    let mut before: Option<Trial> = None;
    // Growing until a miss or the limit.
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
        let doubled = (count * 2).min(limit);
        count = match before.and_then(|before| crossing(before, result, budget)) {
            Some(guess) => (guess + guess / 32).clamp(count + 1, doubled),
            None => doubled,
        };
        before = Some(result);
    }
    // Closing the gap between the last fit and the first miss.
    while let (Some(fit), Some(miss)) = (found.fits, found.misses) {
        let gap = miss.count - fit.count;
        let tolerance = (fit.count / 32).max(1);
        if gap <= tolerance {
            break;
        }
        let (low, high) = (fit.count + tolerance, miss.count - tolerance);
        let next = match crossing(fit, miss, budget) {
            Some(guess) if low <= high => guess.clamp(low, high),
            _ => fit.count + gap / 2,
        };
        let result = trial(next);
        if result.micros > budget {
            found.misses = Some(result);
        } else {
            found.fits = Some(result);
        }
    }
    found
}

/// Where the line through two trials reaches `budget`: the size whose cost
/// it predicts to be the budget (rounded down), if the cost grew between
/// them.
fn crossing(a: Trial, b: Trial, budget: u64) -> Option<usize> {
    let (a, b) = if a.count <= b.count { (a, b) } else { (b, a) };
    let (sizes, costs) = (b.count - a.count, b.micros.checked_sub(a.micros)?);
    if sizes == 0 || costs == 0 {
        return None;
    }
    // Sizes and costs are far below 2^32, so the products fit.
    let beyond_a = (budget as i128 - a.micros as i128) * sizes as i128 / costs as i128;
    usize::try_from(a.count as i128 + beyond_a).ok()
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

    /// A large size costs the bench the most: the first miss lands a little
    /// past the answer, not at twice the last fit, and the gap closes in
    /// two trials.
    #[test]
    fn the_first_miss_lands_near_the_answer_not_at_twice_it() {
        let mut tried = Vec::new();
        // 100 + 14 n <= 16_747: n <= 1189.
        let mut cost = linear(14);
        let found = largest_that_fits(16, 2048, 16_747, |count| {
            tried.push(count);
            cost(count)
        });
        let (fit, miss) = (found.fits.unwrap(), found.misses.unwrap());
        assert!(fit.count <= 1189 && miss.count > 1189, "{found:?}");
        assert!(miss.count - fit.count <= fit.count / 32, "{found:?}");
        assert!(tried.iter().all(|&n| n <= 1189 + 1189 / 16), "{tried:?}");
        assert_eq!(tried.len(), 9, "{tried:?}");
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
