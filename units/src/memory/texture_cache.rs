//! The texture cache of the thesis's §6.5 (Owens 2002, Fig 6.11): a read-only,
//! direct-mapped cache between the memory system and the SRF that serves the words of
//! streams marked cacheable (the texture gathers).
//!
//! * **Shape** (`[texture_cache]` in the machine description): `words` of data (16 K in the
//!   thesis) in lines of `line_words` (2 in the thesis, "forced by Imagine's memory
//!   system"), one line per set.
//! * **Hits** are handed to the address generators at up to `hit_words_per_cycle` words per
//!   core cycle, shared by all of them (the thesis's memory-to-SRF bandwidth ×n: ×1, ×4,
//!   ×32), one cycle after the lookup; they use no DRAM port.
//! * **Misses** go to DRAM like any reference, and the generator also fetches the rest of
//!   the line (fills, ahead of its next references) so that the whole line arrives. A
//!   reference to a word already on its way waits for it (counted a hit, as it costs no
//!   DRAM access): texture gathers ask for a bilinear pair's second word right after the
//!   first, before the line is back. Each word read for a cacheable stream is written into
//!   its line when its reply comes, if the set still holds that line.
//! * **Read-only**: the stream program marks only buffers no instruction stores to; a store
//!   reference to a cached line still invalidates it, so a mistaken mark cannot return
//!   stale data once the store has issued.
//!
//! Words are valid one by one within a line (a line being filled is usable word by word).
//! Probes: `hits`, `misses` (counts, low 32 bits) and `waiting`.

use imagine_hdl::{Scope, SignalId, SignalKind, Trace, bits_for};
use serde::Serialize;

use crate::desc::TextureCacheDesc;

/// Counters of the texture cache.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TextureCacheStats {
    /// References of cacheable streams served from the cache.
    pub hits: u64,
    /// References of cacheable streams that went to DRAM.
    pub misses: u64,
    /// Extra words read from DRAM to complete lines.
    pub fill_words: u64,
    /// Lines invalidated by stores.
    pub invalidations: u64,
}

impl TextureCacheStats {
    /// Hits over references (0 with none).
    pub fn hit_rate(&self) -> f64 {
        let refs = self.hits + self.misses;
        if refs == 0 {
            0.0
        } else {
            self.hits as f64 / refs as f64
        }
    }
}

/// What the cache holds for a word.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Probe {
    Hit(u32),
    /// Its line is being filled and the word is on its way: wait for it.
    Pending,
    /// Not in the cache: fetch it (and the rest of its line).
    Miss,
}

/// A reference waiting for a word on its way: delivered when the word arrives.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Waiter {
    pub ag: usize,
    pub slot: usize,
    pub word: u64,
}

#[derive(Debug)]
pub struct TextureCache {
    line_words: u64,
    sets: u64,
    /// The line number each set holds, plus one (0: none).
    tags: Vec<u64>,
    /// One bit per word of the set's line: the word has arrived.
    valid: Vec<u64>,
    /// One bit per word of the set's line: the word has been asked of DRAM.
    pending: Vec<u64>,
    data: Vec<u32>,
    waiters: Vec<Waiter>,
    hit_words_per_cycle: usize,
    /// Hits handed out this cycle.
    hits_this_cycle: usize,
    stats: TextureCacheStats,
    ids: [SignalId; 3],
}

impl TextureCache {
    pub fn new(scope: &mut Scope<'_>, d: &TextureCacheDesc) -> TextureCache {
        let sets = d.words / d.line_words;
        let count = bits_for(u32::MAX as u64);
        TextureCache {
            line_words: d.line_words as u64,
            sets: sets as u64,
            tags: vec![0; sets],
            valid: vec![0; sets],
            pending: vec![0; sets],
            data: vec![0; d.words],
            waiters: Vec::new(),
            hit_words_per_cycle: d.hit_words_per_cycle,
            hits_this_cycle: 0,
            stats: TextureCacheStats::default(),
            ids: [
                scope.signal("hits", count, SignalKind::Reg),
                scope.signal("misses", count, SignalKind::Reg),
                scope.signal("waiting", 16, SignalKind::Reg),
            ],
        }
    }

    pub fn line_words(&self) -> u64 {
        self.line_words
    }

    pub fn hit_words_per_cycle(&self) -> usize {
        self.hit_words_per_cycle
    }

    pub fn stats(&self) -> &TextureCacheStats {
        &self.stats
    }

    /// References waiting for words on their way.
    pub fn waiting(&self) -> usize {
        self.waiters.len()
    }

    /// Set and word-in-line of DRAM word `word`, and its line's tag.
    fn place(&self, word: u64) -> (usize, usize, u64) {
        let line = word / self.line_words;
        (
            (line % self.sets) as usize,
            (word % self.line_words) as usize,
            line + 1,
        )
    }

    /// What the cache holds for `word` (no side effect).
    pub fn probe(&self, word: u64) -> Probe {
        let (set, k, tag) = self.place(word);
        if self.tags[set] != tag {
            Probe::Miss
        } else if self.valid[set] >> k & 1 == 1 {
            Probe::Hit(self.data[set * self.line_words as usize + k])
        } else if self.pending[set] >> k & 1 == 1 {
            Probe::Pending
        } else {
            Probe::Miss
        }
    }

    /// Takes a word of this cycle's hit bandwidth for a reference that found its word
    /// (or found it on its way), counting a hit; false when it is used up.
    pub fn claim_hit(&mut self) -> bool {
        if self.hits_this_cycle == self.hit_words_per_cycle {
            return false;
        }
        self.hits_this_cycle += 1;
        self.stats.hits += 1;
        true
    }

    /// Records that reorder slot `slot` of address generator `ag` waits for `word`.
    pub fn wait(&mut self, waiter: Waiter) {
        self.waiters.push(waiter);
    }

    /// A miss on `word`: (re)allocates its line and marks `fetched` (the words of the line
    /// about to be read, `word` among them) as on their way.
    pub fn miss(&mut self, word: u64, fetched: impl Iterator<Item = u64>) {
        self.stats.misses += 1;
        let (set, _, tag) = self.place(word);
        if self.tags[set] != tag {
            self.tags[set] = tag;
            self.valid[set] = 0;
            self.pending[set] = 0;
        }
        for w in fetched {
            self.pending[set] |= 1 << (w % self.line_words);
            self.stats.fill_words += (w != word) as u64;
        }
    }

    /// A word of a cacheable stream read from DRAM: writes it into its line if the set
    /// still holds that line, and hands it to the references waiting for it (appended to
    /// `deliver`).
    pub fn fill(&mut self, word: u64, value: u32, deliver: &mut Vec<(Waiter, u32)>) {
        let (set, k, tag) = self.place(word);
        if self.tags[set] == tag {
            self.valid[set] |= 1 << k;
            self.pending[set] &= !(1 << k);
            self.data[set * self.line_words as usize + k] = value;
        }
        self.waiters.retain(|w| {
            let found = w.word == word;
            if found {
                deliver.push((*w, value));
            }
            !found
        });
    }

    /// A store to `word`: drops its line if cached.
    pub fn invalidate(&mut self, word: u64) {
        let (set, _, tag) = self.place(word);
        if self.tags[set] == tag {
            self.tags[set] = 0;
            self.valid[set] = 0;
            self.pending[set] = 0;
            self.stats.invalidations += 1;
        }
    }

    /// The clock edge: the hit port is free again.
    pub fn commit(&mut self) {
        self.hits_this_cycle = 0;
    }

    pub fn trace(&self, t: &mut Trace) {
        t.value(self.ids[0], self.stats.hits & 0xFFFF_FFFF);
        t.value(self.ids[1], self.stats.misses & 0xFFFF_FFFF);
        t.value(self.ids[2], self.waiters.len().min(0xFFFF) as u64);
    }
}

#[cfg(test)]
mod tests {
    use imagine_hdl::{ClockDomain, Design};

    use super::*;

    fn cache(words: usize, hit_words_per_cycle: usize) -> TextureCache {
        let mut design = Design::new("top", vec![ClockDomain::mhz("core", 500)]).unwrap();
        TextureCache::new(
            &mut design.scope(),
            &TextureCacheDesc {
                words,
                line_words: 2,
                hit_words_per_cycle,
            },
        )
    }

    #[test]
    fn a_miss_marks_its_line_on_the_way_and_its_words_hit_once_arrived() {
        let mut c = cache(16, 4);
        assert_eq!(c.probe(6), Probe::Miss);
        c.miss(6, [6, 7].into_iter());
        assert_eq!(c.probe(7), Probe::Pending, "word 7 comes with the line");
        c.wait(Waiter {
            ag: 1,
            slot: 3,
            word: 7,
        });
        let mut deliver = Vec::new();
        c.fill(6, 60, &mut deliver);
        assert!(deliver.is_empty());
        assert_eq!(c.probe(6), Probe::Hit(60));
        c.fill(7, 70, &mut deliver);
        assert_eq!(
            deliver,
            [(
                Waiter {
                    ag: 1,
                    slot: 3,
                    word: 7
                },
                70
            )]
        );
        assert_eq!(c.probe(7), Probe::Hit(70));
        assert_eq!(c.waiting(), 0);
    }

    #[test]
    fn a_conflicting_line_replaces_the_set_and_a_store_invalidates() {
        let mut c = cache(16, 4);
        let mut deliver = Vec::new();
        c.miss(2, [2, 3].into_iter());
        c.fill(2, 20, &mut deliver);
        c.fill(3, 30, &mut deliver);
        // 16 words in 2-word lines: 8 sets; word 18 is in line 9, set 1, as word 2 is.
        c.miss(18, [18].into_iter());
        assert_eq!(c.probe(3), Probe::Miss, "the set now holds line 9");
        c.fill(3, 30, &mut deliver);
        assert_eq!(
            c.probe(3),
            Probe::Miss,
            "a late word of a replaced line is not kept"
        );
        c.fill(18, 180, &mut deliver);
        assert_eq!(c.probe(18), Probe::Hit(180));
        c.invalidate(19);
        assert_eq!(c.probe(18), Probe::Miss);
        assert_eq!(c.stats().invalidations, 1);
        assert_eq!(c.stats().misses, 2);
    }

    #[test]
    fn hits_beyond_the_bandwidth_wait_for_the_next_cycle() {
        let mut c = cache(16, 2);
        assert!(c.claim_hit());
        assert!(c.claim_hit());
        assert!(!c.claim_hit());
        c.commit();
        assert!(c.claim_hit());
        assert_eq!(c.stats().hits, 3);
    }
}
