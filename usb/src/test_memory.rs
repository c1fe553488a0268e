//! DMA memory for the unit tests of the rings and contexts: 32-bit words by
//! address, zero where nothing was written.

use super::Memory;
use std::collections::BTreeMap;

/// Words written so far, by address.
#[derive(Default)]
pub struct Words(BTreeMap<u64, u32>);

impl Memory for Words {
    fn mem_read(&mut self, address: u64) -> u32 {
        self.0.get(&address).copied().unwrap_or(0)
    }
    fn mem_write(&mut self, address: u64, value: u32) {
        self.0.insert(address, value);
    }
}
