//! Load-balanced conditional input of multi-word records, and `load_balance`, a kernel that
//! exercises it.
//!
//! Imagine's conditional streams deliver whole records: each cluster whose condition holds
//! receives the next record, in cluster order, routed over the intercluster switch and
//! buffered in the scratchpad, 2 entries per word of the record (thesis §4.4.1; the
//! scanline rasterizer's `spangen` and `spanrast` take half-triangles and spans this way).
//! The machine's own conditional access is a single word (`read_if`: the next words of the
//! stream, one per selected cluster), so a record read word by word would hand a cluster
//! words of other clusters' records. [`RecordInput`] builds the record access from what
//! the machine has, the way the hardware does it:
//!
//! * The stream is in the cluster-row layout: a row of `C` records holds word `j` of its
//!   records side by side. Two rows are buffered, `A` (which holds the next record to hand
//!   out) and `B` after it: `2·k` words per cluster for `k`-word records, the 2 entries per
//!   word — kept in the LRFs as loop-carried values, or in the scratchpad as on Imagine
//!   (with a third slot for the reads of iterations that bring no row in; `A` and `B`
//!   swap by pointer), which leaves the LRFs to the kernel (`spanrast`'s 13-word records
//!   do not schedule with their rows in the LRFs).
//! * Each iteration the takers are ranked by an exclusive prefix sum of the condition
//!   across the clusters (`log2 C` rotations), and their count broadcast.
//! * The records handed out, `next … next + n − 1`, lie in `A` and `B` and hold each
//!   cluster's buffered record at most once, so every cluster sends one word per record
//!   word (its `A` word if its `A` record is not yet taken, else its `B` word), and taker
//!   `r` receives from cluster `(next + r) mod C` (`Perm::PerCluster`): `k` comms.
//! * When `next` passes `A`, `B` becomes `A` and the next row is read into `B` by `k`
//!   conditional reads whose condition is the same in every cluster (a whole row, or
//!   nothing).
//!
//! The switch carries one word per cluster per cycle, as Imagine's conditional streams do,
//! so a record of `k` words costs `k` comms an iteration. The stream must hold two rows
//! past the last record taken (the reads run ahead by a row). A loop whose decision to take
//! depends on the record it took in the iteration before has the ranking and the routing
//! on its recurrence: `load_balance` taking the record it works on at once was bound at 54
//! cycles an iteration on gold8. Holding the next record ahead puts two iterations between
//! a take and the decision it feeds: bound 32 (its ops 14; `imagine kernel show
//! load_balance`).

use imagine_units::arith::fp32::testgen::SplitMix64;
use imagine_units::desc::MachineDesc;

use super::prefix_sum::{inclusive_scan, scan_steps};
use super::{finish, records_to_stream};
use crate::kernel::{
    Kernel, KernelBuilder, KernelInputs, LoopSpec, MachineRequirementError, Needs, Perm, StreamId,
    Ty, Value,
};

/// The conditional input of records from one stream, or from several streams read in
/// step, record `e` of each one part of record `e` (see the module notes). Made before the
/// loop ([`RecordInput::new`], which reads the first two rows); taken from once per
/// iteration ([`RecordInput::take`]).
pub struct RecordInput {
    /// The stream of each word of a record, in the order a take returns them.
    word_streams: Vec<StreamId>,
    clusters: usize,
    cluster: Value,
    /// The ranking scan's steps (their conditions kept across the loop).
    scan: Vec<(usize, Value)>,
    rows: Rows,
    /// 0 and 1, made before the loop.
    zero: Value,
    one: Value,
}

/// Where the two buffered rows are kept.
enum Rows {
    /// In the LRFs, as loop-carried values (their words before the loop).
    Lrf {
        first: Vec<Value>,
        second: Vec<Value>,
    },
    /// In the scratchpad from word `at`: three slots of a record's words, `A`, `B` and a
    /// slot that takes the reads of an iteration that brings no row in. Which slot is `A`
    /// alternates, so rows are never moved.
    Scratchpad { at: u16 },
}

impl RecordInput {
    /// Before the loop: reads the first two rows of `stream`'s `words`-word records.
    /// Needs a power-of-two cluster count (a record's cluster is its index's low bits).
    pub fn new(
        b: &mut KernelBuilder,
        desc: &MachineDesc,
        kernel: &str,
        stream: StreamId,
        words: usize,
    ) -> Result<RecordInput, MachineRequirementError> {
        RecordInput::in_step(b, desc, kernel, &[(stream, words)], None)
    }

    /// Before the loop: reads the first two rows of every stream, `(stream, words)`, whose
    /// records are taken together: a take returns the words of each in turn. With
    /// `scratchpad_at`, the rows are kept in the scratchpad from that word, as Imagine's
    /// conditional streams keep them (3 words per record word: the rows and a slot for the
    /// reads that bring nothing), else in the LRFs.
    pub fn in_step(
        b: &mut KernelBuilder,
        desc: &MachineDesc,
        kernel: &str,
        streams: &[(StreamId, usize)],
        scratchpad_at: Option<u16>,
    ) -> Result<RecordInput, MachineRequirementError> {
        Needs::new(kernel, desc).power_of_two_clusters(None)?;
        let word_streams: Vec<StreamId> = streams
            .iter()
            .flat_map(|&(s, words)| std::iter::repeat_n(s, words))
            .collect();
        let words = word_streams.len();
        if let Some(at) = scratchpad_at {
            Needs::new(kernel, desc).scratchpad_words(
                usize::from(at) + 3 * words,
                &format!("two buffered rows of {words}-word records and a slot for empty reads"),
                true,
            )?;
        }
        let row = |b: &mut KernelBuilder| -> Vec<Value> {
            word_streams.iter().map(|&s| b.read(s)).collect()
        };
        let first = row(b);
        let second = row(b);
        let rows = match scratchpad_at {
            None => Rows::Lrf { first, second },
            Some(at) => {
                for (slot, row) in [first, second].iter().enumerate() {
                    for (j, &w) in row.iter().enumerate() {
                        b.sp_write(at + (slot * words + j) as u16, None, w);
                    }
                }
                Rows::Scratchpad { at }
            }
        };
        let clusters = desc.cluster.count;
        let cluster = b.cluster_id();
        let scan = scan_steps(b, clusters, cluster);
        let (zero, one) = (b.i32(0), b.i32(1));
        Ok(RecordInput {
            word_streams,
            clusters,
            cluster,
            scan,
            rows,
            zero,
            one,
        })
    }

    /// In the loop, once per iteration: the next records for the clusters where `want`
    /// (a condition) holds, in cluster order; the other clusters get words of no use.
    pub fn take(&self, b: &mut KernelBuilder, want: Value) -> Vec<Value> {
        let c = self.clusters;
        let (zero, one) = (b.i32(0), b.i32(1));
        let row_c = b.i32(c as i32);
        let lane_mask = b.i32(c as i32 - 1);
        let cluster = self.cluster;
        let next = b.carried(zero);
        let base = b.carried(zero);
        // Ranks: an inclusive scan of the takers across the clusters, less one's own.
        let taking = b.select(want, one, zero);
        let partial = inclusive_scan(b, c, &self.scan, taking);
        let rank = b.isub(partial, taking);
        let taken = b.comm(partial, Perm::Broadcast((c - 1) as u16));
        // Taker `r` receives record `next + r` from the cluster that buffers it; a cluster
        // sends its `A` record while that one is not yet taken.
        let source = {
            let e = b.iadd(next, rank);
            b.and(e, lane_mask)
        };
        let done_in_a = b.isub(next, base);
        let sends_a = b.ile(done_in_a, cluster);
        // Past `A`: `B` moves up and the next row comes in (the same choice everywhere).
        let next_after = b.iadd(next, taken);
        let end_of_a = b.iadd(base, row_c);
        let advance = b.ile(end_of_a, next_after);
        let word_streams = &self.word_streams;
        let got = match &self.rows {
            Rows::Lrf { first, second } => {
                let rows: [Vec<Value>; 2] =
                    [first, second].map(|r| r.iter().map(|&w| b.carried(w)).collect());
                let got = rows[0]
                    .iter()
                    .zip(&rows[1])
                    .map(|(&a, &second)| {
                        let sent = b.select(sends_a, a, second);
                        b.comm(sent, Perm::PerCluster(source))
                    })
                    .collect();
                for ((&a, &second), &stream) in rows[0].iter().zip(&rows[1]).zip(word_streams) {
                    let moved = b.select(advance, second, a);
                    b.set_next(a, moved);
                    let fresh = b.read_if(stream, advance, second);
                    b.set_next(second, fresh);
                }
                got
            }
            &Rows::Scratchpad { at } => {
                let k = word_streams.len() as i32;
                let slot_b = b.i32(k);
                let a_at = b.carried(zero);
                let b_at = b.carried(slot_b);
                let send_at = b.select(sends_a, a_at, b_at);
                let got = (0..word_streams.len())
                    .map(|j| {
                        let sent = b.sp_read(at + j as u16, Some(send_at));
                        b.comm(sent, Perm::PerCluster(source))
                    })
                    .collect();
                // The new row goes where `A` was, and becomes `B`.
                let nowhere = b.i32(2 * k);
                let write_at = b.select(advance, a_at, nowhere);
                for (j, &stream) in word_streams.iter().enumerate() {
                    let fresh = b.read_if(stream, advance, zero);
                    b.sp_write(at + j as u16, Some(write_at), fresh);
                }
                let a_after = b.select(advance, b_at, a_at);
                let b_after = b.select(advance, a_at, b_at);
                b.set_next(a_at, a_after);
                b.set_next(b_at, b_after);
                got
            }
        };
        b.set_next(next, next_after);
        let base_after = b.select(advance, end_of_a, base);
        b.set_next(base, base_after);
        got
    }
}

/// What [`RecordInput::take_ahead`] gives an iteration.
pub struct Held {
    /// Whether the cluster starts the record it held this iteration.
    pub switch: Value,
    /// The record held ahead at the start of the iteration (the one started on a switch).
    pub ahead: Vec<Value>,
    /// Whether the cluster takes a record this iteration, and the words it takes.
    pub want: Value,
    pub got: Vec<Value>,
}

impl RecordInput {
    /// In the loop, once per iteration: each cluster works on a record for as many
    /// iterations as `cost` (of its words) says, holding the next one ahead. When it starts
    /// the held record it takes the next, and in the first iteration, which holds none, it
    /// takes one: a take's ranking and routing then reach the decision to take again two
    /// iterations later, not one.
    pub fn take_ahead(
        &self,
        b: &mut KernelBuilder,
        cost: impl FnOnce(&mut KernelBuilder, &[Value]) -> Value,
    ) -> Held {
        let (zero, one) = (self.zero, self.one);
        let words = self.word_streams.len();
        let left = b.carried(one);
        let first = b.carried(one);
        let ahead: Vec<Value> = (0..words).map(|_| b.carried(zero)).collect();
        let switch = b.ieq(left, zero);
        let cost = cost(b, &ahead);
        let current = b.select(switch, cost, left);
        let left_after = b.isub(current, one);
        b.set_next(left, left_after);
        let want = {
            let starts = b.cast(switch, Ty::I32);
            let w = b.or(starts, first);
            b.cast(w, Ty::Cc)
        };
        b.set_next(first, zero);
        let got = self.take(b, want);
        for (&a, &g) in ahead.iter().zip(&got) {
            let kept = b.select(want, g, a);
            b.set_next(a, kept);
        }
        Held {
            switch,
            ahead,
            want,
            got,
        }
    }
}

/// Words of a `load_balance` record: its cost (iterations, at least 1) and two payload
/// words.
pub const RECORD_WORDS: usize = 3;

/// `load_balance`: each cluster works on a record for as many iterations as its first word
/// says, holding the next one ahead: when it starts a record it takes the next by
/// [`RecordInput`]; a record taken is written out with the cluster that took it (`a`, `b`,
/// `taker`, conditional outputs). Inputs: `records` ([`RECORD_WORDS`] each, two rows past
/// the last one the loop can take) and `tickets`, which sets the iterations.
pub fn build(desc: &MachineDesc) -> Result<Kernel, MachineRequirementError> {
    let mut b = KernelBuilder::new("load_balance");
    let records = b.input("records");
    let tickets = b.input("tickets");
    let out_a = b.output("a");
    let out_b = b.output("b");
    let taker = b.output("taker");
    let input = RecordInput::new(&mut b, desc, "load_balance", records, RECORD_WORDS)?;
    let cluster = b.cluster_id();
    b.begin_loop(LoopSpec::OverStream(tickets));
    let _ticket = b.read(tickets);
    // A record's cost is its first word; the next one is held ahead (see `take_ahead`).
    let Held { want, got, .. } = input.take_ahead(&mut b, |b, ahead| b.cast(ahead[0], Ty::I32));
    b.write_if(out_a, want, got[1]);
    b.write_if(out_b, want, got[2]);
    b.write_if(taker, want, cluster);
    b.end_loop();
    Ok(finish(b))
}

/// `rows` iterations over records of random costs 1 to 4 (record `e`'s `a` is `e`), laid
/// out in rows of `C` records, with the two rows the input reads ahead.
pub fn inputs(desc: &MachineDesc, rows: usize, seed: u64) -> KernelInputs {
    let c = desc.cluster.count;
    let mut rng = SplitMix64::new(seed);
    let records: Vec<Vec<u32>> = (0..(rows + 2) * c)
        .map(|e| vec![1 + rng.next_u32() % 4, e as u32, rng.next_u32()])
        .collect();
    KernelInputs {
        streams: vec![
            records_to_stream(&records, c),
            vec![0; rows * c],
            Vec::new(),
            Vec::new(),
            Vec::new(),
        ],
        params: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::interpret;
    use crate::kernels::stream_to_records;

    /// What `load_balance` must write: in the first iteration every cluster takes a record
    /// to hold ahead; afterwards a cluster whose record is used up starts the one it holds
    /// and takes the next; the takers of an iteration take in cluster order.
    fn expected(stream: &[u32], c: usize, iterations: usize) -> [Vec<u32>; 3] {
        let records = stream_to_records(stream, RECORD_WORDS, c);
        let word = |e: usize, j: usize| records[e][j];
        let mut left = vec![1u32; c];
        let mut ahead = vec![0usize; c];
        let mut next = 0;
        let mut out: [Vec<u32>; 3] = Default::default();
        for i in 0..iterations {
            for cluster in 0..c {
                let switch = left[cluster] == 0;
                if switch {
                    left[cluster] = word(ahead[cluster], 0);
                }
                left[cluster] -= 1;
                if switch || i == 0 {
                    ahead[cluster] = next;
                    out[0].push(word(next, 1));
                    out[1].push(word(next, 2));
                    out[2].push(cluster as u32);
                    next += 1;
                }
            }
        }
        out
    }

    #[test]
    fn each_cluster_takes_the_next_record_when_its_own_is_used_up() {
        for desc in [MachineDesc::gold8(), MachineDesc::resolve("gold4").unwrap()] {
            let k = build(&desc).unwrap();
            let c = desc.cluster.count;
            for seed in 0..4 {
                let rows = 5 + 3 * seed as usize;
                let inputs = inputs(&desc, rows, seed);
                let out = interpret(&k, &inputs, &desc).unwrap();
                let want = expected(&inputs.streams[0], c, rows);
                assert_eq!(out[2..5], want, "{} clusters, seed {seed}", c);
                assert!(want[0].len() > rows * c / 4, "records were taken");
            }
        }
    }
}
