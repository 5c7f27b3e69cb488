//! The pending-reference buffer of one channel's memory access scheduler (Rixner, Dally,
//! Kapasi, Mattson and Owens, "Memory Access Scheduling", ISCA 2000, §3): the references
//! waiting for DRAM operations, in arrival order, with the comparators the arbiters read.
//!
//! Each entry holds a reference's load/store bit, bank, row, column, write data and tag.
//! Beside the entries the buffer keeps, as [`AgeMask`]s over the entries, what the arbiters
//! select on:
//!
//! * per bank, the entries addressing it;
//! * the stores;
//! * the entries that hit their bank's open row (as the scheduler sees the banks: it tells
//!   the buffer when it opens and closes a row);
//! * the entries an older pending reference to the same burst holds back (reordering must
//!   never change what a load sees or what a location finally holds).
//!
//! Hardware compares every entry with every other in parallel. The model keeps the masks
//! up to date as entries arrive, leave and rows open and close, so that an arbiter's choice
//! is a few mask operations and "the oldest" is the lowest set bit, rather than a walk over
//! the entries (with a walk over the older ones per entry for the same-burst rule).
//!
//! Positions: an arriving entry takes the position after the last one taken, so position
//! order is age order; an entry that leaves leaves a hole. When the positions run out the
//! entries are packed to the front in order (every [`POSITIONS`] − capacity arrivals at
//! most). An entry's *age rank* (the `decision_entry` probe) is the number of older entries.

use std::ops::{BitAnd, BitOr, BitOrAssign, Not};

use super::Tag;

/// A reference waiting in the pending-reference buffer.
#[derive(Clone, Copy, Debug)]
pub struct Entry {
    pub write: bool,
    pub bank: u8,
    pub row: u16,
    pub column: u16,
    /// Burst-aligned byte address (for same-location ordering).
    pub burst_addr: u64,
    pub data: [u32; 8],
    pub tag: Tag,
    /// DRAM cycle it entered the buffer.
    pub arrival: u64,
}

/// 64-bit words of an [`AgeMask`].
const WORDS: usize = 4;
/// Positions of the buffer: room for the 256 entries a machine description may ask for
/// (`memory.pending_references`).
pub const POSITIONS: usize = WORDS * 64;

/// A set of entries of the buffer by position: bit `k` is the entry at position `k`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AgeMask([u64; WORDS]);

impl AgeMask {
    pub const EMPTY: AgeMask = AgeMask([0; WORDS]);
    pub const ALL: AgeMask = AgeMask([u64::MAX; WORDS]);

    #[inline]
    pub fn is_empty(self) -> bool {
        self.0.iter().fold(0, |a, &w| a | w) == 0
    }

    #[inline]
    pub fn contains(self, position: usize) -> bool {
        self.0[position / 64] >> (position % 64) & 1 != 0
    }

    #[inline]
    fn insert(&mut self, position: usize) {
        self.0[position / 64] |= 1 << (position % 64);
    }

    #[inline]
    fn remove(&mut self, position: usize) {
        self.0[position / 64] &= !(1 << (position % 64));
    }

    /// The oldest entry of the set.
    #[inline]
    pub fn first(self) -> Option<usize> {
        self.0
            .iter()
            .position(|&w| w != 0)
            .map(|k| k * 64 + self.0[k].trailing_zeros() as usize)
    }

    /// How many entries of the set are older than position `position`.
    fn count_before(self, position: usize) -> usize {
        let (w, bit) = (position / 64, position % 64);
        let whole: u32 = self.0[..w].iter().map(|x| x.count_ones()).sum();
        (whole + (self.0[w] & ((1 << bit) - 1)).count_ones()) as usize
    }

    /// The positions in the set, oldest first.
    pub fn positions(self) -> Positions {
        Positions {
            words: self.0,
            word: 0,
        }
    }
}

/// The positions of an [`AgeMask`], oldest first.
pub struct Positions {
    words: [u64; WORDS],
    word: usize,
}

impl Iterator for Positions {
    type Item = usize;

    #[inline]
    fn next(&mut self) -> Option<usize> {
        while self.word < WORDS {
            let w = self.words[self.word];
            if w != 0 {
                self.words[self.word] = w & (w - 1);
                return Some(self.word * 64 + w.trailing_zeros() as usize);
            }
            self.word += 1;
        }
        None
    }
}

impl BitAnd for AgeMask {
    type Output = AgeMask;
    #[inline]
    fn bitand(self, o: AgeMask) -> AgeMask {
        AgeMask(std::array::from_fn(|k| self.0[k] & o.0[k]))
    }
}

impl BitOr for AgeMask {
    type Output = AgeMask;
    #[inline]
    fn bitor(self, o: AgeMask) -> AgeMask {
        AgeMask(std::array::from_fn(|k| self.0[k] | o.0[k]))
    }
}

impl BitOrAssign for AgeMask {
    #[inline]
    fn bitor_assign(&mut self, o: AgeMask) {
        *self = *self | o;
    }
}

impl Not for AgeMask {
    type Output = AgeMask;
    #[inline]
    fn not(self) -> AgeMask {
        AgeMask(self.0.map(|w| !w))
    }
}

/// Buckets of the same-burst filter (a power of two).
const BURST_BUCKETS: usize = 256;

/// The bucket of a burst address in the same-burst filter (Fibonacci hashing: the
/// channel's bursts differ in their high bits as much as in their low ones).
fn burst_bucket(burst_addr: u64) -> usize {
    (burst_addr.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> (64 - BURST_BUCKETS.trailing_zeros()))
        as usize
}

/// The entries addressing one bank.
#[derive(Clone, Copy, Debug, Default)]
pub struct BankRefs {
    pub refs: AgeMask,
    /// How many entries address the bank, and how many of those hit its open row.
    len: u16,
    hits: u16,
}

impl BankRefs {
    /// Whether some entry addresses the bank.
    #[inline]
    pub fn wanted(&self) -> bool {
        self.len > 0
    }

    /// Whether some entry hits the bank's open row.
    #[inline]
    pub fn hit(&self) -> bool {
        self.hits > 0
    }
}

#[derive(Clone, Debug)]
pub struct PendingBuffer {
    capacity: usize,
    /// The entries by position.
    entries: Vec<Entry>,
    /// The position the next arriving entry takes.
    next_position: usize,
    pending: AgeMask,
    len: usize,
    banks: Vec<BankRefs>,
    writes: AgeMask,
    hits: AgeMask,
    held: AgeMask,
    /// Pending entries per bucket of burst addresses: an arriving entry whose bucket is
    /// empty needs no search for an older entry to its burst.
    same_burst: [u16; BURST_BUCKETS],
}

impl PendingBuffer {
    /// A buffer of `capacity` entries (at most [`POSITIONS`]) for a channel of `banks`
    /// banks.
    pub fn new(capacity: usize, banks: usize) -> Self {
        assert!(
            (1..=POSITIONS).contains(&capacity),
            "{capacity} pending references"
        );
        let empty = Entry {
            write: false,
            bank: 0,
            row: 0,
            column: 0,
            burst_addr: 0,
            data: [0; 8],
            tag: Tag::default(),
            arrival: 0,
        };
        PendingBuffer {
            capacity,
            entries: vec![empty; POSITIONS],
            next_position: 0,
            pending: AgeMask::EMPTY,
            len: 0,
            banks: vec![BankRefs::default(); banks],
            writes: AgeMask::EMPTY,
            hits: AgeMask::EMPTY,
            held: AgeMask::EMPTY,
            same_burst: [0; BURST_BUCKETS],
        }
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline]
    pub fn is_full(&self) -> bool {
        self.len == self.capacity
    }

    /// The entry at `position`.
    #[inline]
    pub fn entry(&self, position: usize) -> &Entry {
        &self.entries[position]
    }

    /// The position of the oldest entry.
    #[inline]
    pub fn oldest(&self) -> Option<usize> {
        self.pending.first()
    }

    /// The age rank of the entry at `position`: how many pending entries are older.
    pub fn rank(&self, position: usize) -> usize {
        self.pending.count_before(position)
    }

    /// The entries addressing each bank.
    #[inline]
    pub fn banks(&self) -> &[BankRefs] {
        &self.banks
    }

    /// The stores.
    #[inline]
    pub fn writes(&self) -> AgeMask {
        self.writes
    }

    /// The entries hitting their bank's open row.
    #[inline]
    pub fn hits(&self) -> AgeMask {
        self.hits
    }

    /// The entries an older entry to the same burst holds back.
    #[inline]
    pub fn held(&self) -> AgeMask {
        self.held
    }

    /// Takes in a reference as the youngest entry; `open_row` is the row open in its bank.
    #[inline]
    pub fn push(&mut self, e: Entry, open_row: Option<u16>) {
        debug_assert!(!self.is_full());
        if self.next_position == POSITIONS {
            self.pack();
        }
        let position = self.next_position;
        self.next_position += 1;
        let bucket = &mut self.same_burst[burst_bucket(e.burst_addr)];
        if *bucket > 0
            && self
                .pending
                .positions()
                .any(|p| self.entries[p].burst_addr == e.burst_addr)
        {
            self.held.insert(position);
        }
        *bucket += 1;
        self.len += 1;
        self.pending.insert(position);
        let bank = &mut self.banks[e.bank as usize];
        bank.refs.insert(position);
        bank.len += 1;
        if e.write {
            self.writes.insert(position);
        }
        if open_row == Some(e.row) {
            self.hits.insert(position);
            bank.hits += 1;
        }
        self.entries[position] = e;
    }

    /// Takes out the entry at `position` (its column access issued).
    #[inline]
    pub fn remove(&mut self, position: usize) {
        let e = &self.entries[position];
        let was_held = self.held.contains(position);
        let bank = &mut self.banks[e.bank as usize];
        self.len -= 1;
        self.pending.remove(position);
        bank.refs.remove(position);
        bank.len -= 1;
        if self.hits.contains(position) {
            bank.hits -= 1;
        }
        self.writes.remove(position);
        self.hits.remove(position);
        self.held.remove(position);
        let bucket = &mut self.same_burst[burst_bucket(e.burst_addr)];
        *bucket -= 1;
        // The oldest entry to a burst is never held back; the next oldest to the burst of
        // one that leaves becomes the oldest (unless an older one is still there).
        if !was_held && *bucket > 0 {
            let burst_addr = e.burst_addr;
            let next = self
                .held
                .positions()
                .find(|&p| self.entries[p].burst_addr == burst_addr);
            if let Some(p) = next {
                self.held.remove(p);
            }
        }
    }

    /// The scheduler opened `row` in bank `b`.
    pub fn opened(&mut self, b: usize, row: u16) {
        let bank = &mut self.banks[b];
        for p in bank.refs.positions() {
            if self.entries[p].row == row {
                self.hits.insert(p);
                bank.hits += 1;
            }
        }
    }

    /// The scheduler closed bank `b`'s row.
    pub fn closed(&mut self, b: usize) {
        let bank = &mut self.banks[b];
        self.hits = self.hits & !bank.refs;
        bank.hits = 0;
    }

    /// Moves the pending entries to the front, in order, with their bits (each entry moves
    /// to a position no later than its own, so in place).
    fn pack(&mut self) {
        let (pending, writes, hits, held) = (self.pending, self.writes, self.hits, self.held);
        self.banks.iter_mut().for_each(|b| b.refs = AgeMask::EMPTY);
        self.pending = AgeMask::EMPTY;
        self.writes = AgeMask::EMPTY;
        self.hits = AgeMask::EMPTY;
        self.held = AgeMask::EMPTY;
        for (new, old) in pending.positions().enumerate() {
            let e = self.entries[old];
            self.entries[new] = e;
            self.pending.insert(new);
            self.banks[e.bank as usize].refs.insert(new);
            for (from, to) in [
                (writes, &mut self.writes),
                (hits, &mut self.hits),
                (held, &mut self.held),
            ] {
                if from.contains(old) {
                    to.insert(new);
                }
            }
        }
        self.next_position = self.len;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask(positions: &[usize]) -> AgeMask {
        let mut m = AgeMask::EMPTY;
        positions.iter().for_each(|&p| m.insert(p));
        m
    }

    #[test]
    fn masks_count_and_list_across_words() {
        let m = mask(&[0, 5, 63, 64, 100, 191, 192, 255]);
        assert_eq!(
            m.positions().collect::<Vec<_>>(),
            [0, 5, 63, 64, 100, 191, 192, 255]
        );
        assert_eq!(m.count_before(0), 0);
        assert_eq!(m.count_before(64), 3);
        assert_eq!(m.count_before(192), 6);
        assert_eq!(m.count_before(255), 7);
        assert_eq!((m & mask(&[100, 7])).first(), Some(100));
        assert_eq!(AgeMask::EMPTY.first(), None);
        assert!(!m.is_empty() && AgeMask::EMPTY.is_empty());
    }

    fn entry(bank: u8, row: u16, burst_addr: u64) -> Entry {
        Entry {
            write: false,
            bank,
            row,
            column: 0,
            burst_addr,
            data: [0; 8],
            tag: Tag::default(),
            arrival: 0,
        }
    }

    #[test]
    fn only_the_oldest_entry_to_a_burst_goes_unheld() {
        let mut b = PendingBuffer::new(8, 4);
        for (bank, addr) in [(0, 7), (1, 9), (0, 7), (0, 7), (1, 9)] {
            b.push(entry(bank, 3, addr), None);
        }
        assert_eq!(b.held(), mask(&[2, 3, 4]));
        b.remove(1);
        assert_eq!(b.held(), mask(&[2, 3]));
        // A held entry leaving (as a scheduler ignoring the rule would) frees nobody.
        b.remove(3);
        assert_eq!(b.held(), mask(&[2]));
        b.remove(0);
        assert_eq!(b.held(), AgeMask::EMPTY);
        assert_eq!(b.len(), 2);
        assert_eq!(b.banks()[0].refs, mask(&[2]));
        assert_eq!(b.banks()[1].refs, mask(&[4]));
        assert_eq!(b.rank(4), 1);
    }

    #[test]
    fn hits_follow_the_rows_opened_and_closed() {
        let mut b = PendingBuffer::new(4, 2);
        b.push(entry(0, 3, 1), Some(3));
        b.push(entry(0, 4, 2), Some(3));
        b.push(entry(1, 4, 3), None);
        assert_eq!(b.hits(), mask(&[0]));
        b.closed(0);
        b.opened(1, 4);
        assert_eq!(b.hits(), mask(&[2]));
        b.opened(0, 4);
        assert_eq!(b.hits(), mask(&[1, 2]));
        b.remove(0);
        assert_eq!(b.hits(), mask(&[1, 2]));
        assert!(!b.is_full());
    }

    #[test]
    fn packing_keeps_the_order_and_the_bits() {
        let mut b = PendingBuffer::new(3, 2);
        for k in 0..POSITIONS as u64 + 5 {
            if b.is_full() {
                b.remove(b.oldest().unwrap());
            }
            let mut e = entry((k % 2) as u8, (k % 3) as u16, k % 4);
            e.write = k % 5 == 0;
            e.tag.seq = k as u32;
            b.push(e, Some(1));
        }
        let kept: Vec<_> = b.pending.positions().collect();
        assert_eq!(kept, [4, 5, 6], "packed five arrivals ago");
        let seqs: Vec<_> = kept.iter().map(|&p| b.entry(p).tag.seq).collect();
        let n = POSITIONS as u32 + 5;
        assert_eq!(seqs, [n - 3, n - 2, n - 1]);
        for &p in &kept {
            let e = b.entry(p);
            assert!(b.banks()[e.bank as usize].refs.contains(p));
            assert_eq!(b.writes().contains(p), e.write);
            assert_eq!(b.hits().contains(p), e.row == 1);
        }
        assert_eq!(b.held(), AgeMask::EMPTY);
        assert_eq!(b.rank(6), 2);
    }
}
