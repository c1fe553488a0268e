//! HID report descriptors (HID 1.11 section 6.2.2), read only as far as a
//! keyboard needs: where in which report the modifier bits, the key arrays
//! and the key bitmaps (N-key rollover) lie. A keyboard that ignores
//! SET_PROTOCOL(boot), numbers its reports, or sends a bitmap is decoded
//! through what its descriptor says instead of being taken for a boot
//! keyboard.
//!
//! Nothing here trusts the device: every item's data must lie inside the
//! descriptor, sizes and counts are bounded, collections and Push/Pop must
//! nest and close, and a report is decoded only if it carries every byte its
//! fields need. A descriptor that breaks a rule is a [`HidError`]; a report
//! that cannot be read is [`Decoded::Unreadable`], never keys.

/// The Keyboard/Keypad usage page.
pub const PAGE_KEYBOARD: u16 = 0x07;
/// The most bytes of report descriptor this driver reads.
pub const MAX_DESCRIPTOR_BYTES: usize = 1024;
/// The longest keyboard report decoded (a full-speed interrupt packet).
pub const MAX_REPORT_BYTES: usize = 64;
/// The largest Report Size a field may have, in bits.
const MAX_FIELD_BITS: u32 = 32;
/// The most bits any one report may claim (a report past this is absurd).
const MAX_REPORT_BITS: u32 = 8 * 4096;
/// Collections nested deeper than this are refused.
const MAX_NESTING: usize = 16;
/// Push without Pop deeper than this is refused.
const MAX_PUSHES: usize = 4;
/// Keyboard fields kept: modifier bits, arrays and bitmap runs.
const MAX_FIELDS: usize = 16;
/// Report IDs whose input reports are tracked.
const MAX_REPORT_IDS: usize = 16;
/// Usages listed one by one (Usage items) before a main item.
const MAX_LISTED_USAGES: usize = 16;

/// What a report descriptor failed on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum HidError {
    /// An item's data runs past the end of the descriptor, at this offset.
    Truncated(usize),
    /// Collections nested deeper than the driver allows.
    TooDeep,
    /// An End Collection with no collection open, at this offset.
    UnbalancedEnd(usize),
    /// The descriptor ended inside this many open collections.
    Unclosed(usize),
    /// Push nested too deep, or Pop with nothing pushed, at this offset.
    BadPushPop(usize),
    /// Report ID 0 (reserved), or a report ID past 255.
    BadReportId(u32),
    /// A Report Size past 32 bits.
    BadReportSize(u32),
    /// A report that claims more bits than any device sends.
    ReportTooLong {
        /// The report's ID (0: reports are not numbered).
        report_id: u8,
        /// The bits it claims.
        bits: u32,
    },
    /// Usage Minimum above Usage Maximum, or Logical Minimum above Maximum.
    BadRange(usize),
    /// More keyboard fields, or report IDs, than the driver keeps.
    TooManyFields,
}

impl core::fmt::Display for HidError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            HidError::Truncated(at) => write!(f, "item at byte {at} runs past the end"),
            HidError::TooDeep => write!(f, "collections nested past {MAX_NESTING}"),
            HidError::UnbalancedEnd(at) => write!(f, "End Collection at byte {at} closes nothing"),
            HidError::Unclosed(open) => write!(f, "{open} collections never closed"),
            HidError::BadPushPop(at) => write!(f, "Push/Pop at byte {at} unbalanced"),
            HidError::BadReportId(id) => write!(f, "report ID {id} is impossible"),
            HidError::BadReportSize(bits) => write!(f, "report size {bits} bits is impossible"),
            HidError::ReportTooLong { report_id, bits } => {
                write!(f, "report {report_id} claims {bits} bits")
            }
            HidError::BadRange(at) => write!(f, "range at byte {at} runs backwards"),
            HidError::TooManyFields => write!(f, "more keyboard fields than are kept"),
        }
    }
}

/// How a field's values say which keys are down.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FieldKind {
    /// One bit a key: bit `i` set means usage `first_usage + i` is down
    /// (modifier bytes and N-key rollover bitmaps).
    Bitmap {
        /// The usage of the first bit.
        first_usage: u16,
    },
    /// Each element holds the index of a key that is down (the boot
    /// report's six key bytes).
    Array {
        /// Bits an element.
        size: u8,
        /// The usage of logical value `logical_min`.
        usage_min: u16,
        /// The smallest value that names a key.
        logical_min: i32,
        /// The largest value that names a key.
        logical_max: i32,
    },
}

/// A run of keyboard bits or elements in one report.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Field {
    /// The report it is in (0: reports are not numbered).
    pub report_id: u8,
    /// Its first bit, counted after the report ID byte.
    pub bit_offset: u32,
    /// Bits (bitmaps) or elements (arrays).
    pub count: u16,
    /// What the bits mean.
    pub kind: FieldKind,
}

/// Where a keyboard's keys lie in its input reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeyboardLayout {
    /// Reports start with a report ID byte.
    pub numbered: bool,
    fields: [Option<Field>; MAX_FIELDS],
    /// Input report lengths in bits (after the ID byte), by report ID.
    report_bits: [(u8, u32); MAX_REPORT_IDS],
    report_ids: usize,
}

/// The usages held down, one bit each (usages past 0xFF cannot be keys
/// with a PS/2 code).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct KeySet(pub [u32; 8]);

impl KeySet {
    /// Marks `usage` as down.
    pub fn insert(&mut self, usage: u8) {
        self.0[usize::from(usage / 32)] |= 1 << (usage % 32);
    }
    /// Whether `usage` is down.
    pub fn contains(&self, usage: u8) -> bool {
        self.0[usize::from(usage / 32)] & (1 << (usage % 32)) != 0
    }
    /// Both sets' keys.
    pub fn union(&self, other: &KeySet) -> KeySet {
        let mut both = *self;
        for (word, other) in both.0.iter_mut().zip(other.0) {
            *word |= other;
        }
        both
    }
}

/// What one report said.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decoded {
    /// The keys this report's fields say are down (only those the report
    /// carries: the caller merges reports of different IDs).
    Keys {
        /// The report's ID (0: not numbered).
        report_id: u8,
        /// Keys down.
        keys: KeySet,
    },
    /// Too many keys down (ErrorRollOver in an array): the keys are unknown,
    /// so nothing should change.
    Rollover,
    /// A report that carries no keys (another report ID: consumer keys, a
    /// mouse in the same interface).
    NotKeys,
    /// Too short for its fields, or an unknown report ID: dropped.
    Unreadable,
}

/// The parser's global state (HID 1.11 6.2.2.7), pushed and popped whole.
#[derive(Clone, Copy, Debug, Default)]
struct Globals {
    usage_page: u16,
    logical_min: i32,
    logical_max: i32,
    report_size: u32,
    report_count: u32,
    report_id: u8,
}

/// The parser's local state (6.2.2.8), cleared after every main item.
#[derive(Clone, Copy, Debug, Default)]
struct Locals {
    /// Usages listed one by one, each with its page (0: the global page).
    listed: [(u16, u16); MAX_LISTED_USAGES],
    listed_count: usize,
    /// Usage Minimum and Maximum, with their pages when given extended.
    minimum: Option<(u16, u16)>,
    maximum: Option<(u16, u16)>,
}

fn unsigned(data: &[u8]) -> u32 {
    data.iter()
        .rev()
        .fold(0u32, |value, &byte| value << 8 | u32::from(byte))
}

fn signed(data: &[u8]) -> i32 {
    match *data {
        [] => 0,
        [a] => i32::from(a as i8),
        [a, b] => i32::from(i16::from_le_bytes([a, b])),
        _ => unsigned(data) as i32,
    }
}

/// A usage item's (page, id): four bytes carry their own page.
fn usage(data: &[u8], page: u16) -> (u16, u16) {
    let value = unsigned(data);
    if data.len() == 4 {
        ((value >> 16) as u16, value as u16)
    } else {
        (page, value as u16)
    }
}

impl KeyboardLayout {
    fn empty() -> Self {
        KeyboardLayout {
            numbered: false,
            fields: [None; MAX_FIELDS],
            report_bits: [(0, 0); MAX_REPORT_IDS],
            report_ids: 0,
        }
    }

    /// The keyboard fields found.
    pub fn fields(&self) -> impl Iterator<Item = &Field> {
        self.fields.iter().flatten()
    }

    /// Whether any input report carries keys.
    pub fn has_keys(&self) -> bool {
        self.fields().next().is_some()
    }

    /// The longest input report that carries keys, in bytes with its ID byte.
    pub fn longest_key_report(&self) -> usize {
        self.fields()
            .filter_map(|f| self.report_bytes(f.report_id))
            .max()
            .unwrap_or(0)
    }

    /// How long the input report whose first byte is `first_byte` is, in
    /// bytes with its ID byte: its report's length, or, for a report ID
    /// the descriptor does not name, the longest input report's.
    pub fn report_length(&self, first_byte: u8) -> usize {
        let report_id = if self.numbered { first_byte } else { 0 };
        self.report_bytes(report_id).unwrap_or_else(|| {
            self.report_bits[..self.report_ids]
                .iter()
                .filter_map(|&(id, _)| self.report_bytes(id))
                .max()
                .unwrap_or(0)
        })
    }

    /// An input report's length in bytes, with its ID byte.
    fn report_bytes(&self, report_id: u8) -> Option<usize> {
        self.report_bits[..self.report_ids]
            .iter()
            .find(|&&(id, _)| id == report_id)
            .map(|&(_, bits)| bits.div_ceil(8) as usize + usize::from(self.numbered))
    }

    /// Adds `bits` to the input report `report_id`; gives the field's offset.
    fn claim(&mut self, report_id: u8, bits: u32) -> Result<u32, HidError> {
        let index = match self.report_bits[..self.report_ids]
            .iter()
            .position(|&(id, _)| id == report_id)
        {
            Some(index) => index,
            None if self.report_ids < MAX_REPORT_IDS => {
                self.report_bits[self.report_ids] = (report_id, 0);
                self.report_ids += 1;
                self.report_ids - 1
            }
            None => return Err(HidError::TooManyFields),
        };
        let offset = self.report_bits[index].1;
        let end = offset.saturating_add(bits);
        if end > MAX_REPORT_BITS {
            return Err(HidError::ReportTooLong {
                report_id,
                bits: end,
            });
        }
        self.report_bits[index].1 = end;
        Ok(offset)
    }

    fn add(&mut self, field: Field) -> Result<(), HidError> {
        // A bitmap run that goes on where the last one ended is one field.
        if let (
            Some(Some(last)),
            FieldKind::Bitmap {
                first_usage: next_usage,
            },
        ) = (self.fields.iter().rev().find(|f| f.is_some()), field.kind)
        {
            if let FieldKind::Bitmap { first_usage } = last.kind {
                if last.report_id == field.report_id
                    && last.bit_offset + u32::from(last.count) == field.bit_offset
                    && u32::from(first_usage) + u32::from(last.count) == u32::from(next_usage)
                {
                    let slot = self
                        .fields
                        .iter_mut()
                        .rev()
                        .flatten()
                        .next()
                        .ok_or(HidError::TooManyFields)?;
                    slot.count = slot.count.saturating_add(field.count);
                    return Ok(());
                }
            }
        }
        let slot = self
            .fields
            .iter_mut()
            .find(|f| f.is_none())
            .ok_or(HidError::TooManyFields)?;
        *slot = Some(field);
        Ok(())
    }

    /// Records an Input item's keyboard fields (`flags`: bit 0 constant,
    /// bit 1 variable).
    fn input(
        &mut self,
        globals: &Globals,
        locals: &Locals,
        flags: u32,
        at: usize,
    ) -> Result<(), HidError> {
        let bits = globals.report_size.saturating_mul(globals.report_count);
        let offset = self.claim(globals.report_id, bits)?;
        if flags & 1 != 0 || globals.report_count == 0 || globals.report_size == 0 {
            return Ok(()); // padding
        }
        let page_of = |page: u16| if page == 0 { globals.usage_page } else { page };
        let count = globals.report_count.min(u32::from(u16::MAX)) as u16;
        if flags & 0b10 != 0 {
            // Variable: one usage a field, from the range or the list.
            if globals.report_size != 1 {
                return Ok(()); // keys are single bits
            }
            if let (Some(minimum), Some(maximum)) = (locals.minimum, locals.maximum) {
                if page_of(minimum.0) != PAGE_KEYBOARD || page_of(maximum.0) != PAGE_KEYBOARD {
                    return Ok(());
                }
                let usages = u32::from(maximum.1)
                    .checked_sub(u32::from(minimum.1))
                    .ok_or(HidError::BadRange(at))?
                    + 1;
                return self.add(Field {
                    report_id: globals.report_id,
                    bit_offset: offset,
                    count: count.min(usages.min(u32::from(u16::MAX)) as u16),
                    kind: FieldKind::Bitmap {
                        first_usage: minimum.1,
                    },
                });
            }
            // Usages listed: bit i is the i-th usage (the last one stands
            // for the rest, HID 1.11 6.2.2.8).
            for bit in 0..count {
                let Some(last) = locals.listed_count.checked_sub(1) else {
                    break;
                };
                let (page, id) = locals.listed[usize::from(bit).min(last)];
                if page_of(page) == PAGE_KEYBOARD {
                    self.add(Field {
                        report_id: globals.report_id,
                        bit_offset: offset + u32::from(bit),
                        count: 1,
                        kind: FieldKind::Bitmap { first_usage: id },
                    })?;
                }
            }
            return Ok(());
        }
        // Array: values index the usage range.
        let (Some(minimum), Some(_)) = (locals.minimum, locals.maximum) else {
            return Ok(());
        };
        if page_of(minimum.0) != PAGE_KEYBOARD || globals.report_size > 16 {
            return Ok(());
        }
        if globals.logical_min > globals.logical_max {
            return Err(HidError::BadRange(at));
        }
        self.add(Field {
            report_id: globals.report_id,
            bit_offset: offset,
            count,
            kind: FieldKind::Array {
                size: globals.report_size as u8,
                usage_min: minimum.1,
                logical_min: globals.logical_min,
                logical_max: globals.logical_max,
            },
        })
    }

    /// Reads the keys out of one input report, as many bytes as arrived.
    pub fn decode(&self, report: &[u8]) -> Decoded {
        let (report_id, body) = if self.numbered {
            match report.split_first() {
                Some((&id, body)) => (id, body),
                None => return Decoded::Unreadable,
            }
        } else {
            (0, report)
        };
        let Some(needed) = self.report_bytes(report_id) else {
            return Decoded::Unreadable;
        };
        if report.len() < needed {
            return Decoded::Unreadable;
        }
        let mut keys = KeySet::default();
        let mut carried = false;
        for field in self.fields().filter(|f| f.report_id == report_id) {
            carried = true;
            match field.kind {
                FieldKind::Bitmap { first_usage } => {
                    for bit in 0..u32::from(field.count) {
                        let usage = u32::from(first_usage) + bit;
                        if usage <= 0xFF && read_bits(body, field.bit_offset + bit, 1) != 0 {
                            keys.insert(usage as u8);
                        }
                    }
                }
                FieldKind::Array {
                    size,
                    usage_min,
                    logical_min,
                    logical_max,
                } => {
                    for element in 0..u32::from(field.count) {
                        let at = field.bit_offset + element * u32::from(size);
                        let raw = read_bits(body, at, u32::from(size));
                        // Signed when the logical range is.
                        let value = if logical_min < 0 && size < 32 && raw >> (size - 1) & 1 != 0 {
                            raw as i32 - (1 << size)
                        } else {
                            raw as i32
                        };
                        if value < logical_min || value > logical_max {
                            continue; // no key in this element
                        }
                        let usage =
                            i64::from(usage_min) + i64::from(value) - i64::from(logical_min);
                        match usage {
                            0 => {}
                            1..=3 => return Decoded::Rollover,
                            4..=0xFF => keys.insert(usage as u8),
                            _ => {}
                        }
                    }
                }
            }
        }
        if carried {
            Decoded::Keys { report_id, keys }
        } else {
            Decoded::NotKeys
        }
    }
}

/// `bits` bits (at most 32) from bit `at` of `bytes`, little-endian as HID
/// packs them; bits past the end read as 0 (the caller checked the length).
fn read_bits(bytes: &[u8], at: u32, bits: u32) -> u32 {
    let mut value = 0u32;
    for bit in 0..bits {
        let position = at + bit;
        let byte = bytes.get((position / 8) as usize).copied().unwrap_or(0);
        value |= u32::from(byte >> (position % 8) & 1) << bit;
    }
    value
}

/// Reads a report descriptor: where the keyboard fields of its input
/// reports lie. A descriptor that breaks a rule is refused whole.
pub fn parse(descriptor: &[u8]) -> Result<KeyboardLayout, HidError> {
    let descriptor = &descriptor[..descriptor.len().min(MAX_DESCRIPTOR_BYTES)];
    let mut layout = KeyboardLayout::empty();
    let mut globals = Globals::default();
    let mut stack = [Globals::default(); MAX_PUSHES];
    let mut pushed = 0;
    let mut locals = Locals::default();
    let mut depth = 0usize;
    let mut at = 0usize;
    while at < descriptor.len() {
        let prefix = descriptor[at];
        if prefix == 0xFE {
            // A long item: its data size is the next byte; nothing of ours.
            let size = usize::from(*descriptor.get(at + 1).ok_or(HidError::Truncated(at))?);
            let end = at + 3 + size;
            if end > descriptor.len() {
                return Err(HidError::Truncated(at));
            }
            at = end;
            continue;
        }
        let size = match prefix & 3 {
            3 => 4,
            n => usize::from(n),
        };
        let data = descriptor
            .get(at + 1..at + 1 + size)
            .ok_or(HidError::Truncated(at))?;
        let value = unsigned(data);
        match (prefix >> 2) & 3 {
            // Main items.
            0 => {
                match prefix >> 4 {
                    0x8 => layout.input(&globals, &locals, value, at)?,
                    0xA => {
                        depth += 1;
                        if depth > MAX_NESTING {
                            return Err(HidError::TooDeep);
                        }
                    }
                    0xC => {
                        depth = depth.checked_sub(1).ok_or(HidError::UnbalancedEnd(at))?;
                    }
                    _ => {} // Output and Feature reports carry no keys
                }
                locals = Locals::default();
            }
            // Global items.
            1 => match prefix >> 4 {
                0x0 => globals.usage_page = value as u16,
                0x1 => globals.logical_min = signed(data),
                0x2 => {
                    // A maximum that only makes sense unsigned (0xFF in one
                    // byte with a minimum of 0) is read unsigned, as Linux does.
                    globals.logical_max = if globals.logical_min >= 0 {
                        value as i32
                    } else {
                        signed(data)
                    }
                }
                0x7 => {
                    if value > MAX_FIELD_BITS {
                        return Err(HidError::BadReportSize(value));
                    }
                    globals.report_size = value;
                }
                0x8 => {
                    if value == 0 || value > 0xFF {
                        return Err(HidError::BadReportId(value));
                    }
                    globals.report_id = value as u8;
                    layout.numbered = true;
                }
                0x9 => globals.report_count = value,
                0xA => {
                    if pushed == MAX_PUSHES {
                        return Err(HidError::BadPushPop(at));
                    }
                    stack[pushed] = globals;
                    pushed += 1;
                }
                0xB => {
                    pushed = pushed.checked_sub(1).ok_or(HidError::BadPushPop(at))?;
                    globals = stack[pushed];
                }
                _ => {} // physical extents and units mean nothing to keys
            },
            // Local items.
            2 => match prefix >> 4 {
                0x0 => {
                    if locals.listed_count < MAX_LISTED_USAGES {
                        locals.listed[locals.listed_count] = usage(data, 0);
                        locals.listed_count += 1;
                    }
                }
                0x1 => locals.minimum = Some(usage(data, 0)),
                0x2 => {
                    let maximum = usage(data, 0);
                    if locals.minimum.is_some_and(|m| m.1 > maximum.1) {
                        return Err(HidError::BadRange(at));
                    }
                    locals.maximum = Some(maximum);
                }
                _ => {}
            },
            _ => {} // reserved item type: skipped by its size
        }
        at += 1 + size;
    }
    if depth != 0 {
        return Err(HidError::Unclosed(depth));
    }
    if layout.numbered
        && layout.report_bits[..layout.report_ids]
            .iter()
            .any(|&(id, _)| id == 0)
    {
        // Some input items came before the first Report ID: reports both
        // numbered and not cannot be told apart.
        return Err(HidError::BadReportId(0));
    }
    if layout.longest_key_report() > MAX_REPORT_BYTES {
        let (report_id, bits) = layout
            .fields()
            .map(|f| f.report_id)
            .filter_map(|id| {
                layout.report_bits[..layout.report_ids]
                    .iter()
                    .find(|&&(i, _)| i == id)
            })
            .copied()
            .max_by_key(|&(_, bits)| bits)
            .unwrap_or((0, 0));
        return Err(HidError::ReportTooLong { report_id, bits });
    }
    Ok(layout)
}

#[cfg(test)]
pub(crate) mod tests;
