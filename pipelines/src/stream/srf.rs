//! The SRF allocator: places the streams of a stream program by lifetime.
//!
//! A pipeline declares its batch schedule as a list of named phases (in the order the host
//! queues them) and each stream with its record layout, its size and the phases it is live
//! in — from the phase that writes it to the last that reads it. Streams live in disjoint
//! phase ranges may share words; streams carried from one batch to the next (or from one
//! frame phase to the rest of the frame) are live in every phase. Sharing is always safe to
//! the scoreboard (it orders every access to the same words by queue order); the lifetimes
//! are what make it correct, as for a register allocator.
//!
//! Placement is first fit, largest stream first, on the SRF's block boundaries (the
//! address generators and stream buffers move whole blocks). *Elastic* streams (those
//! whose size is "what is left", such as a rasterizer's fragments) then share equally the
//! words above every fixed stream live while they are. A stream that does not fit is named
//! in the error, with what was asked and what was left.

use std::fmt;

use imagine_units::desc::MachineDesc;
use imagine_units::machine::StreamBinding;
use serde::Serialize;

/// How a stream's records lie in the SRF.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct Layout {
    /// Words per record.
    pub record_words: usize,
    /// Cluster rows (record `i` of a row of `C` in cluster `i mod C`, stored word by word,
    /// as kernels read multi-word records) rather than one record after another.
    pub cluster_rows: bool,
}

impl Layout {
    /// Records of `words` words in cluster rows (the layout kernels read).
    pub const fn records(words: usize) -> Layout {
        Layout {
            record_words: words,
            cluster_rows: true,
        }
    }

    /// One-word elements (counts, indices, conditional outputs).
    pub const fn words() -> Layout {
        Layout::records(1)
    }

    /// Records one after another, as the host interface writes them.
    pub const fn packed(words: usize) -> Layout {
        Layout {
            record_words: words,
            cluster_rows: false,
        }
    }
}

/// A stream of a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StreamId(usize);

/// The phases a stream is live in, by name (inclusive).
#[derive(Clone, Copy, Debug)]
pub enum Lifetime {
    /// Every phase: carried across batches, or held for the whole program.
    Always,
    /// From the first phase to the second.
    Phases(&'static str, &'static str),
}

/// The fewest rows of one word per cluster that fill whole SRF blocks: a stream that
/// begins inside another (a kernel's parameters after another kernel's) starts on a block.
pub fn block_rows(desc: &MachineDesc) -> usize {
    let (c, block) = (desc.cluster.count.max(1), desc.srf.block_words.max(1));
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    block / gcd(c, block)
}

/// Shorthand for [`Lifetime::Phases`].
pub fn live(from: &'static str, to: &'static str) -> Lifetime {
    Lifetime::Phases(from, to)
}

#[derive(Clone, Debug)]
struct Decl {
    name: String,
    layout: Layout,
    /// Records, or `None` for an elastic stream.
    records: Option<usize>,
    live: (usize, usize),
}

/// A stream program's streams before placement.
pub struct SrfPlanner {
    phases: Vec<&'static str>,
    decls: Vec<Decl>,
    block: usize,
    words: usize,
    clusters: usize,
    error: Option<PlanError>,
}

/// Streams that do not fit, or a declaration that makes no sense.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlanError(pub String);

impl fmt::Display for PlanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for PlanError {}

impl SrfPlanner {
    /// A plan for `desc`'s SRF with the batch schedule `phases`.
    pub fn new(desc: &MachineDesc, phases: &[&'static str]) -> SrfPlanner {
        SrfPlanner {
            phases: phases.to_vec(),
            decls: Vec::new(),
            block: desc.srf.block_words.max(1),
            words: desc.srf.words,
            clusters: desc.cluster.count,
            error: None,
        }
    }

    fn phase(&mut self, name: &str) -> usize {
        match self.phases.iter().position(|p| *p == name) {
            Some(i) => i,
            None => {
                self.error.get_or_insert(PlanError(format!(
                    "no phase `{name}` in the schedule {:?}",
                    self.phases
                )));
                0
            }
        }
    }

    fn declare(
        &mut self,
        name: &str,
        layout: Layout,
        records: Option<usize>,
        live: Lifetime,
    ) -> StreamId {
        let live = match live {
            Lifetime::Always => (0, self.phases.len().saturating_sub(1)),
            Lifetime::Phases(a, b) => (self.phase(a), self.phase(b)),
        };
        if live.0 > live.1 {
            self.error.get_or_insert(PlanError(format!(
                "stream `{name}` ends (phase {}) before it begins (phase {})",
                self.phases[live.1], self.phases[live.0]
            )));
        }
        if let Some(r) = records
            && layout.cluster_rows
            && layout.record_words > 1
            && !r.is_multiple_of(self.clusters)
        {
            self.error.get_or_insert(PlanError(format!(
                "stream `{name}`: {r} records are not whole rows of {} clusters",
                self.clusters
            )));
        }
        self.decls.push(Decl {
            name: name.into(),
            layout,
            records,
            live,
        });
        StreamId(self.decls.len() - 1)
    }

    /// A stream of `records` records.
    pub fn stream(
        &mut self,
        name: &str,
        layout: Layout,
        records: usize,
        live: Lifetime,
    ) -> StreamId {
        self.declare(name, layout, Some(records), live)
    }

    /// `copies` streams of the same shape (buffers that alternate between batches or
    /// chunks), named `name[i]`.
    pub fn buffers<const N: usize>(
        &mut self,
        name: &str,
        layout: Layout,
        records: usize,
        live: Lifetime,
    ) -> [StreamId; N] {
        std::array::from_fn(|i| self.stream(&format!("{name}[{i}]"), layout, records, live))
    }

    /// An elastic stream: the elastic streams share what the fixed streams leave, each
    /// room for as many records as the others.
    pub fn elastic(&mut self, name: &str, layout: Layout, live: Lifetime) -> StreamId {
        self.declare(name, layout, None, live)
    }

    fn overlaps(a: (usize, usize), b: (usize, usize)) -> bool {
        a.0 <= b.1 && b.0 <= a.1
    }

    /// Places every stream, or names the first that does not fit.
    pub fn place(self) -> Result<SrfPlan, PlanError> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let round = |w: usize| w.div_ceil(self.block) * self.block;
        let mut placed: Vec<Option<(usize, usize)>> = vec![None; self.decls.len()];
        let mut order: Vec<usize> = (0..self.decls.len())
            .filter(|&i| self.decls[i].records.is_some())
            .collect();
        // Largest first, then by declaration: deterministic, and big streams get the low
        // words they would otherwise fragment.
        let size = |i: usize| {
            let d = &self.decls[i];
            round(d.records.unwrap_or(0) * d.layout.record_words)
        };
        order.sort_by_key(|&i| (std::cmp::Reverse(size(i)), i));
        for &i in &order {
            let d = &self.decls[i];
            let words = size(i);
            let mut busy: Vec<(usize, usize)> = placed
                .iter()
                .enumerate()
                .filter_map(|(j, p)| p.filter(|_| Self::overlaps(self.decls[j].live, d.live)))
                .collect();
            busy.sort();
            let mut at = 0;
            for (start, len) in busy {
                if at + words <= start {
                    break;
                }
                at = at.max(start + len);
            }
            if at + words > self.words {
                let live_words: usize = placed.iter().flatten().map(|p| p.1).sum();
                return Err(PlanError(format!(
                    "stream `{}` ({} records of {} words = {words} words) does not fit in the \
                     SRF ({} words; {live_words} words already placed)",
                    d.name,
                    d.records.unwrap_or(0),
                    d.layout.record_words,
                    self.words
                )));
            }
            placed[i] = Some((at, words));
        }
        // Elastic streams: the words above every fixed stream live with any of them, shared
        // for equal records, in whole blocks and whole cluster rows.
        let elastic: Vec<usize> = (0..self.decls.len())
            .filter(|&i| self.decls[i].records.is_none())
            .collect();
        if !elastic.is_empty() {
            let floor = placed
                .iter()
                .enumerate()
                .filter_map(|(j, p)| {
                    let d = &self.decls[j];
                    p.filter(|_| {
                        elastic
                            .iter()
                            .any(|&e| Self::overlaps(self.decls[e].live, d.live))
                    })
                })
                .map(|(s, l)| s + l)
                .max()
                .unwrap_or(0);
            let left = self.words.saturating_sub(floor);
            // Equal records: each stream's share in proportion to its record's words.
            let record_words: usize = elastic
                .iter()
                .map(|&i| self.decls[i].layout.record_words)
                .sum();
            let per_word = left / record_words.max(1);
            let mut at = floor;
            for &i in &elastic {
                let d = &self.decls[i];
                let share = per_word * d.layout.record_words / self.block * self.block;
                let row = d.layout.record_words * self.clusters;
                let words = share / row * row;
                if words == 0 {
                    return Err(PlanError(format!(
                        "stream `{}` gets no room: the fixed streams leave {left} of the SRF's \
                         {} words for {} elastic streams",
                        d.name,
                        self.words,
                        elastic.len()
                    )));
                }
                placed[i] = Some((at, words));
                at += share;
            }
        }
        let streams = self
            .decls
            .into_iter()
            .zip(placed)
            .map(|(d, p)| {
                let (start, words) = p.expect("every stream placed");
                Placed {
                    records: d.records.unwrap_or(words / d.layout.record_words),
                    name: d.name,
                    start,
                    words,
                    layout: d.layout,
                    elastic: d.records.is_none(),
                    live: d.live,
                }
            })
            .collect();
        Ok(SrfPlan {
            streams,
            phases: self.phases,
            srf_words: self.words,
        })
    }
}

/// A placed stream.
#[derive(Clone, Debug, Serialize)]
pub struct Placed {
    pub name: String,
    pub start: usize,
    /// Words it takes (whole blocks).
    pub words: usize,
    /// Records it holds: as declared, or as many as an elastic stream's words hold.
    pub records: usize,
    pub layout: Layout,
    pub elastic: bool,
    #[serde(skip)]
    live: (usize, usize),
}

/// Where every stream is.
#[derive(Clone, Debug)]
pub struct SrfPlan {
    streams: Vec<Placed>,
    phases: Vec<&'static str>,
    srf_words: usize,
}

/// One row of the plan as reported (`--stats`, `imagine scene show`).
#[derive(Clone, Debug, Serialize)]
pub struct PlanRow {
    pub stream: String,
    pub start: usize,
    pub words: usize,
    pub record_words: usize,
    pub live_from: String,
    pub live_to: String,
    pub elastic: bool,
}

impl SrfPlan {
    pub fn get(&self, s: StreamId) -> &Placed {
        &self.streams[s.0]
    }

    /// Records the stream can hold.
    pub fn capacity(&self, s: StreamId) -> usize {
        self.get(s).records
    }

    /// A kernel's or memory operation's view of `records` records from record `first`.
    /// Panics past the stream's capacity: a pipeline that asks for more than it planned
    /// is a bug in the pipeline, which checks its counts against [`SrfPlan::capacity`].
    pub fn slice(&self, s: StreamId, first: usize, records: usize) -> StreamBinding {
        let p = self.get(s);
        assert!(
            first + records <= self.capacity(s),
            "stream `{}`: records {first}..{} past its {} (a pipeline bug)",
            p.name,
            first + records,
            self.capacity(s)
        );
        StreamBinding {
            start: p.start + first * p.layout.record_words,
            words: records * p.layout.record_words,
        }
    }

    /// The first `words` words, whatever the record size (a stream planned for the largest
    /// of several record sizes, used with a smaller one).
    pub fn words(&self, s: StreamId, words: usize) -> StreamBinding {
        self.word_range(s, 0, words)
    }

    /// Words `first..first + words` of the stream, whatever its record size (two kernels
    /// writing one stream's two parts, say).
    pub fn word_range(&self, s: StreamId, first: usize, words: usize) -> StreamBinding {
        let p = self.get(s);
        assert!(
            first + words <= p.words,
            "stream `{}`: words {first}..{} past its {} (a pipeline bug)",
            p.name,
            first + words,
            p.words
        );
        StreamBinding {
            start: p.start + first,
            words,
        }
    }

    /// The first `records` records.
    pub fn first(&self, s: StreamId, records: usize) -> StreamBinding {
        self.slice(s, 0, records)
    }

    /// The whole stream.
    pub fn whole(&self, s: StreamId) -> StreamBinding {
        self.first(s, self.capacity(s))
    }

    /// Words in use at the busiest phase.
    pub fn peak_words(&self) -> usize {
        (0..self.phases.len())
            .map(|ph| {
                self.streams
                    .iter()
                    .filter(|p| p.live.0 <= ph && ph <= p.live.1)
                    .map(|p| p.words)
                    .sum::<usize>()
            })
            .max()
            .unwrap_or(0)
            .min(self.srf_words)
    }

    pub fn rows(&self) -> Vec<PlanRow> {
        let mut rows: Vec<PlanRow> = self
            .streams
            .iter()
            .map(|p| PlanRow {
                stream: p.name.clone(),
                start: p.start,
                words: p.words,
                record_words: p.layout.record_words,
                live_from: self.phases[p.live.0].into(),
                live_to: self.phases[p.live.1].into(),
                elastic: p.elastic,
            })
            .collect();
        rows.sort_by_key(|r| (r.start, r.stream.clone()));
        rows
    }

    /// The plan as a table.
    pub fn table(&self) -> String {
        let mut out = format!(
            "{:<18} {:>7} {:>7} {:>6}  live\n",
            "stream", "start", "words", "w/rec"
        );
        for r in self.rows() {
            out += &format!(
                "{:<18} {:>7} {:>7} {:>6}  {}{}\n",
                r.stream,
                r.start,
                r.words,
                r.record_words,
                if r.live_from == self.phases[0] && r.live_to == *self.phases.last().unwrap_or(&"")
                {
                    "always".to_string()
                } else {
                    format!("{}..{}", r.live_from, r.live_to)
                },
                if r.elastic { " (elastic)" } else { "" }
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc() -> MachineDesc {
        MachineDesc::resolve("gold8").unwrap()
    }

    #[test]
    fn streams_in_disjoint_phases_share_words_and_overlapping_ones_do_not() {
        let d = desc();
        let mut p = SrfPlanner::new(&d, &["a", "b", "c"]);
        let x = p.stream("x", Layout::records(4), 64, live("a", "a"));
        let y = p.stream("y", Layout::records(4), 64, live("b", "c"));
        let z = p.stream("z", Layout::words(), 256, live("a", "b"));
        let plan = p.place().unwrap();
        let range = |s| {
            let q = plan.get(s);
            q.start..q.start + q.words
        };
        assert_eq!(
            range(x).start,
            range(y).start,
            "x and y never live together"
        );
        let (rz, rx) = (range(z), range(x));
        assert!(rz.end <= rx.start || rx.end <= rz.start, "z overlaps x");
        for s in [x, y, z] {
            assert!(plan.get(s).start.is_multiple_of(d.srf.block_words));
        }
    }

    #[test]
    fn a_stream_that_does_not_fit_is_named() {
        let d = desc();
        let mut p = SrfPlanner::new(&d, &["a"]);
        p.stream("small", Layout::words(), 1024, Lifetime::Always);
        p.stream("huge", Layout::records(8), d.srf.words, Lifetime::Always);
        let e = p.place().unwrap_err().to_string();
        assert!(e.contains("`huge`"), "{e}");
    }

    #[test]
    fn elastic_streams_share_what_is_left_above_their_neighbours() {
        let d = desc();
        let mut p = SrfPlanner::new(&d, &["a", "b"]);
        let fixed = p.stream("fixed", Layout::words(), 4096, live("b", "b"));
        let early = p.stream("early", Layout::words(), 8192, live("a", "a"));
        let e: [StreamId; 2] =
            [0, 1].map(|i| p.elastic(&format!("e{i}"), Layout::words(), live("b", "b")));
        let plan = p.place().unwrap();
        let floor = plan.get(fixed).start + plan.get(fixed).words;
        assert!(plan.get(e[0]).start >= floor && plan.get(e[1]).start >= floor);
        assert!(plan.get(e[1]).start + plan.get(e[1]).words <= d.srf.words);
        assert!(plan.capacity(e[0]) >= (d.srf.words - floor) / 2 - d.srf.block_words);
        // `early` is not live with the elastic streams: they may use its words.
        assert!(plan.get(early).words > 0);
        assert!(plan.table().contains("(elastic)"));
    }

    #[test]
    fn unknown_phases_are_errors() {
        let d = desc();
        let mut p = SrfPlanner::new(&d, &["a"]);
        p.stream("x", Layout::words(), 8, live("a", "nope"));
        assert!(p.place().unwrap_err().to_string().contains("`nope`"));
    }
}
