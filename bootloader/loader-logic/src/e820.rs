//! The BIOS memory-map walk (INT 15h, EAX=E820h) as firmware really answers
//! it. Each call gives one entry and a continuation value (EBX) for the next.
//! The list ends when the continuation comes back 0, or (Ralf Brown's
//! Interrupt List allows it, and some BIOSes do it) when a call returns with
//! the carry flag set after the last entry. Entries past the caller's table
//! are counted and dropped, and the walk is bounded in calls, so that a
//! BIOS whose continuation never returns to 0 cannot hold the loader.

/// One call's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer<T> {
    /// The call succeeded (carry clear, EAX = 'SMAP'): an entry (None for an
    /// empty one, of zero length, which is skipped) and the continuation.
    Entry {
        /// The entry, if it is not empty.
        entry: Option<T>,
        /// EBX: 0 after the last entry.
        next: u32,
    },
    /// Carry set: the end of the list (or, on the first call, no E820).
    Carry,
    /// EAX is not 'SMAP': the BIOS does not know the function (on the first
    /// call), or the list ends.
    NotSmap,
}

/// How the walk ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ending {
    /// The continuation came back 0.
    LastEntry,
    /// A call returned with the carry flag set.
    Carry,
    /// A call returned without the 'SMAP' signature.
    NotSmap,
    /// The bound on calls was reached.
    CallLimit,
}

/// What the walk found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Walk {
    /// Entries stored at the start of the table.
    pub stored: usize,
    /// Entries that did not fit in the table and were dropped.
    pub dropped: usize,
    /// How it ended.
    pub ending: Ending,
}

/// Walks the list: `call(continuation)` makes one INT 15h call. Entries go
/// into `table` in order; at most `max_calls` calls are made.
pub fn walk<T>(table: &mut [T], max_calls: usize, mut call: impl FnMut(u32) -> Answer<T>) -> Walk {
    let mut walk = Walk {
        stored: 0,
        dropped: 0,
        ending: Ending::CallLimit,
    };
    let mut continuation = 0;
    for _ in 0..max_calls {
        match call(continuation) {
            Answer::Carry => {
                walk.ending = Ending::Carry;
                return walk;
            }
            Answer::NotSmap => {
                walk.ending = Ending::NotSmap;
                return walk;
            }
            Answer::Entry { entry, next } => {
                if let Some(entry) = entry {
                    match table.get_mut(walk.stored) {
                        Some(slot) => {
                            *slot = entry;
                            walk.stored += 1;
                        }
                        None => walk.dropped += 1,
                    }
                }
                if next == 0 {
                    walk.ending = Ending::LastEntry;
                    return walk;
                }
                continuation = next;
            }
        }
    }
    walk
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A BIOS with `entries` entries whose continuation values are 1, 2, ...
    /// and which ends its list with `last_next` as the last continuation
    /// (0: the EBX=0 ending), then answers `after`.
    fn bios(
        entries: &[u32],
        last_next: u32,
        after: Answer<u32>,
    ) -> impl FnMut(u32) -> Answer<u32> + '_ {
        move |continuation| {
            let index = continuation as usize;
            match entries.get(index) {
                Some(&entry) => Answer::Entry {
                    entry: Some(entry),
                    next: if index + 1 == entries.len() {
                        last_next
                    } else {
                        continuation + 1
                    },
                },
                None => after,
            }
        }
    }

    #[test]
    fn the_list_ends_on_a_zero_continuation() {
        let mut table = [0; 8];
        let walk = walk(&mut table, 100, bios(&[10, 20, 30], 0, Answer::Carry));
        assert_eq!(
            walk,
            Walk {
                stored: 3,
                dropped: 0,
                ending: Ending::LastEntry
            }
        );
        assert_eq!(table[..3], [10, 20, 30]);
    }

    #[test]
    fn the_list_ends_on_carry_with_what_it_has() {
        // The last entry's continuation is not 0; the next call sets CF.
        let mut table = [0; 8];
        let walk = walk(&mut table, 100, bios(&[10, 20, 30], 3, Answer::Carry));
        assert_eq!(
            walk,
            Walk {
                stored: 3,
                dropped: 0,
                ending: Ending::Carry
            }
        );
        assert_eq!(table[..3], [10, 20, 30]);
    }

    #[test]
    fn carry_on_the_first_call_finds_nothing() {
        let mut table = [0; 8];
        let walk = walk(&mut table, 100, |_| Answer::Carry);
        assert_eq!((walk.stored, walk.ending), (0, Ending::Carry));
        let walk = super::walk(&mut table, 100, |_| Answer::NotSmap);
        assert_eq!((walk.stored, walk.ending), (0, Ending::NotSmap));
    }

    #[test]
    fn entries_past_the_table_are_counted_and_dropped() {
        let entries: [u32; 7] = [1, 2, 3, 4, 5, 6, 7];
        let mut table = [0; 4];
        let walk = walk(&mut table, 100, bios(&entries, 0, Answer::Carry));
        assert_eq!(
            walk,
            Walk {
                stored: 4,
                dropped: 3,
                ending: Ending::LastEntry
            }
        );
        assert_eq!(table, [1, 2, 3, 4]);
    }

    #[test]
    fn empty_entries_are_skipped() {
        let mut table = [0; 4];
        let mut calls = 0;
        let walk = walk(&mut table, 100, |continuation| {
            calls += 1;
            Answer::Entry {
                entry: (continuation != 1).then_some(continuation),
                next: (continuation + 1) % 3,
            }
        });
        assert_eq!(calls, 3);
        assert_eq!((walk.stored, walk.ending), (2, Ending::LastEntry));
        assert_eq!(table[..2], [0, 2]);
    }

    #[test]
    fn a_continuation_that_never_ends_is_bounded() {
        let mut table = [0; 4];
        let mut calls = 0;
        let walk = walk(&mut table, 50, |_| {
            calls += 1;
            Answer::Entry {
                entry: Some(1),
                next: 7,
            }
        });
        assert_eq!(calls, 50);
        assert_eq!(
            walk,
            Walk {
                stored: 4,
                dropped: 46,
                ending: Ending::CallLimit
            }
        );
    }
}
