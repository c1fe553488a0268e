use crate::dap;
use core::fmt::Write as _; // Patched

#[derive(Clone)]
pub struct DiskAccess {
    pub disk_number: u16,
    pub base_offset: u64,
    pub current_offset: u64,

    /// The offset of the sector read in the last call to read_exact_at.
    pub last_read_exact_at_offset: Option<u64>,
}

impl Read for DiskAccess {
    unsafe fn read_exact_at(&mut self, len: usize, offset: u64) -> &[u8] {
        self.seek(SeekFrom::Start(offset - (offset % 512)));
        let current_sector_offset = usize::try_from(offset % 512).unwrap();

        static mut TMP_BUF: AlignedArrayBuffer<1024> = AlignedArrayBuffer {
            buffer: [0; 512 * 2],
        };
        #[allow(static_mut_refs)]
        let buf = unsafe { &mut TMP_BUF };
        assert!(current_sector_offset + len <= buf.buffer.len());

        // Don't read the sector if we already read the same sector in the last
        // call.
        if self
            .last_read_exact_at_offset
            .is_none_or(|offset| offset != self.current_offset)
        {
            self.last_read_exact_at_offset = Some(self.current_offset);
            self.read_exact_into(buf.buffer.len(), buf);
        }

        &buf.buffer[current_sector_offset..][..len]
    }

    fn read_exact_into(&mut self, len: usize, buf: &mut dyn AlignedBuffer) {
        assert_eq!(len % 512, 0);
        let buf = &mut buf.slice_mut()[..len];

        let end_addr = self.base_offset + self.current_offset + u64::try_from(buf.len()).unwrap();
        let mut start_lba = (self.base_offset + self.current_offset) / 512;
        let end_lba = (end_addr - 1) / 512;

        let mut number_of_sectors = end_lba + 1 - start_lba;
        let mut target_addr = buf.as_ptr_range().start as u32;

        loop {
            // Patched: never more than 32 sectors (the limit is 127), and
            // never across a 64 KiB boundary: the buffers are 512-aligned,
            // so the boundary falls between sectors.
            let to_boundary = (0x1_0000 - (target_addr & 0xffff)) / 512;
            let sectors = u64::min(number_of_sectors, u64::from(to_boundary).min(32)) as u16;
            read_with_retries(self.disk_number, start_lba, sectors, target_addr);

            start_lba += u64::from(sectors);
            number_of_sectors -= u64::from(sectors);
            target_addr += u32::from(sectors) * 512;

            if number_of_sectors == 0 {
                break;
            }
        }

        self.current_offset = end_addr;
    }
}

/// Patched: tries a read up to [`READ_TRIES`] times, with a disk reset
/// between tries, as GRUB and SYSLINUX do (a USB stick behind a BIOS's INT
/// 13h emulation may fail once). Each retry is said; a read that fails every
/// time stops the loader with the LBA and the BIOS's status, on the screen
/// and COM1. It does not reset the machine.
fn read_with_retries(disk_number: u16, lba: u64, sectors: u16, target_addr: u32) {
    let (segment, offset) = crate::bios::far_pointer(target_addr);
    let mut status = 0;
    for attempt in 1..=READ_TRIES {
        // A new packet each try: on failure the BIOS writes the sectors it
        // did move (often 0) into the packet's count.
        let mut dap = dap::DiskAddressPacket::from_lba(lba, sectors, offset, segment);
        match dap.perform_load(disk_number) {
            Ok(()) => return,
            Err(failed) => status = failed,
        }
        if attempt < READ_TRIES {
            let _ = writeln!(
                crate::serial::Both,
                "loader: read retried: LBA {lba:#010x}, BIOS status {status:#04x}"
            );
            dap::reset(disk_number);
        }
    }
    crate::serial::stop(format_args!(
        "loader: cannot read the disk at LBA {lba:#010x} (BIOS status {status:#04x}) after \
         {READ_TRIES} tries; write the stick again or try another USB port"
    ))
}

/// Patched: how often a disk read is tried before the loader gives up.
pub const READ_TRIES: u32 = 3;

impl Seek for DiskAccess {
    fn seek(&mut self, pos: SeekFrom) -> u64 {
        match pos {
            SeekFrom::Start(offset) => {
                assert_eq!(offset % 512, 0);
                self.current_offset = offset;
                self.current_offset
            }
        }
    }
}

pub trait Read {
    unsafe fn read_exact_at(&mut self, len: usize, offset: u64) -> &[u8];
    fn read_exact_into(&mut self, len: usize, buf: &mut dyn AlignedBuffer);
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeekFrom {
    Start(u64),
}

pub trait Seek {
    fn seek(&mut self, pos: SeekFrom) -> u64;
}

/// Patched: 512-aligned (was 2), so that a read split at a 64 KiB boundary
/// splits between sectors.
#[repr(align(512))]
pub struct AlignedArrayBuffer<const LEN: usize> {
    pub buffer: [u8; LEN],
}

pub trait AlignedBuffer {
    fn slice(&self) -> &[u8];
    fn slice_mut(&mut self) -> &mut [u8];
}

impl<const LEN: usize> AlignedBuffer for AlignedArrayBuffer<LEN> {
    fn slice(&self) -> &[u8] {
        &self.buffer[..]
    }
    fn slice_mut(&mut self) -> &mut [u8] {
        &mut self.buffer[..]
    }
}
