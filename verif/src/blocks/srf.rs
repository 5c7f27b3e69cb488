//! Testbench of the stream register file (`units::srf`): several input and output streams
//! bound at once to random stream buffers, read and written each cycle by the clusters
//! (unconditional accesses of whole rows within the per-cycle bandwidth, conditional ones
//! of any size) and by the memory system's port, at random rates so that buffers fill,
//! starve and compete for the SRF port; outputs flushed when written; sizes and widths
//! from the machine.
//!
//! Reference: the SRF array as the host loads it; an input stream delivers the words of
//! its region in order, an output stream leaves the words written to it, in order, in its
//! region once flushed. Contracts: each port transfer moves 1..=`words_per_cycle` words
//! for a bound stream buffer; no buffer ever offers more than its capacity; an access
//! past what is available, past the room, or not a whole row is refused and changes
//! nothing; every stream finishes (and every flush drains) in bounded time.

use imagine_units::desc::MachineDesc;
use imagine_units::srf::Srf;

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "cluster read",
    "conditional read",
    "memory-port read",
    "cluster write",
    "conditional write",
    "memory-port write",
    "read of every available word",
    "cluster accesses at the bandwidth limit",
    "input buffer full",
    "output buffer full",
    "port transfer of a full line",
    "port transfer of a partial line",
    "flush of a partial line",
    "read refused: more than available",
    "write refused: more than the room",
    "read refused: not a whole row",
];

/// One bound stream in the reference.
struct Stream {
    sb: usize,
    input: bool,
    start: usize,
    /// Input: the words it must deliver; output: the words to write.
    words: Vec<u32>,
    /// Words delivered (input) or written (output).
    done: usize,
    flushed: bool,
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let lanes = desc.cluster.count;
    let bins: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| lanes > 1 || *b != "read refused: not a whole row")
        .collect();
    let mut cov = Coverage::new(&bins);
    let mut d = design();
    let mut srf = Srf::new(&mut d.scope().child("srf"), desc);
    let block = srf.block_words();
    let line = srf.words_per_cycle();
    let cap = srf.sb_capacity();
    let (uncond_limit, cond_limit) = srf.cluster_words_left();
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions && sb.mismatches == 0 {
        // Bind up to four streams on distinct stream buffers, in disjoint regions.
        let count = 1 + rng.index(4);
        let mut sbs: Vec<usize> = (0..srf.stream_buffers()).collect();
        let mut streams = Vec::new();
        for k in 0..count {
            let s = sbs.swap_remove(rng.index(sbs.len()));
            let input = rng.chance(50);
            let len = 1 + rng.index(6 * line.max(lanes));
            let start = k * (6 * line.max(lanes)).div_ceil(block) * block;
            cov.hit_if(
                !input && !len.is_multiple_of(line),
                "flush of a partial line",
            );
            let words: Vec<u32> = (0..len).map(|_| rng.corner_word()).collect();
            let bound = if input {
                srf.load(start, &words)
                    .and_then(|_| srf.bind_input(s, start, len))
            } else {
                srf.bind_output(s, start, len)
            };
            if let Err(e) = bound {
                sb.assert(cycle, false, || format!("binding sb{s}: {e}"));
                return Outcome {
                    scoreboard: sb,
                    coverage: cov,
                    waves: waves.finish(None),
                };
            }
            streams.push(Stream {
                sb: s,
                input,
                start,
                words,
                done: 0,
                flushed: false,
            });
        }
        let rate = rng.pick(&[90, 50, 15]);
        let limit = cycle + 200 + 20 * 6 * line.max(lanes) as u64;
        loop {
            let busy = streams.iter().any(|s| {
                if s.input {
                    s.done < s.words.len()
                } else {
                    !srf.flushed(s.sb) || !s.flushed
                }
            });
            if !busy {
                break;
            }
            if cycle > limit {
                sb.assert(cycle, false, || {
                    "every stream finishes in bounded time".into()
                });
                break;
            }
            let mut ctx = Cycle {
                rng: &mut rng,
                sb: &mut sb,
                cov: &mut cov,
                cycle,
                lanes,
                cap,
                rate,
                uncond: uncond_limit,
                cond: cond_limit,
            };
            for s in streams.iter_mut() {
                ctx.access(&mut srf, s);
            }
            let at_limit = ctx.uncond == 0;
            cov.hit_if(at_limit, "cluster accesses at the bandwidth limit");
            srf.eval();
            if let Some(g) = srf.grant() {
                let bound = streams.iter().any(|s| s.sb == g.sb);
                sb.assert(cycle, bound && (1..=line).contains(&g.words), || {
                    format!("port transfer {g:?} for a bound buffer, at most {line} words")
                });
                cov.hit_if(g.words == line, "port transfer of a full line");
                cov.hit_if(g.words < line, "port transfer of a partial line");
            }
            srf.commit();
            waves.cycle(cycle, |t| srf.trace(t));
            cycle += 1;
        }
        for s in &streams {
            let unbound = srf.unbind(s.sb).map_err(|e| e.to_string());
            sb.check(cycle, || format!("unbind sb{}", s.sb), Ok(()), unbound);
            if !s.input {
                let got = srf
                    .read_back(s.start, s.words.len())
                    .map_err(|e| e.to_string());
                sb.check(
                    cycle,
                    || format!("output stream of sb{} in the SRF", s.sb),
                    Ok(s.words.clone()),
                    got,
                );
            }
        }
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}

/// What the accesses of one cycle share: stimulus, checking, and the clusters' bandwidth
/// left this cycle.
struct Cycle<'a> {
    rng: &'a mut Rng,
    sb: &'a mut Scoreboard,
    cov: &'a mut Coverage,
    cycle: u64,
    lanes: usize,
    cap: usize,
    rate: u64,
    uncond: usize,
    cond: usize,
}

impl Cycle<'_> {
    /// One cycle's access to stream `s`, if the dice say so, checked against the reference.
    fn access(&mut self, srf: &mut Srf, s: &mut Stream) {
        let Cycle {
            rng,
            sb,
            cov,
            cycle,
            lanes,
            cap,
            rate,
            uncond,
            cond,
        } = self;
        let (cycle, lanes, cap, rate) = (*cycle, *lanes, *cap, *rate);
        let left = s.words.len() - s.done;
        if s.input {
            let available = srf.available(s.sb);
            sb.assert(cycle, available <= cap && available <= left, || {
                format!("sb{} offers at most its capacity and what is left", s.sb)
            });
            cov.hit_if(available == cap, "input buffer full");
            if left == 0 || !rng.chance(rate) {
                return;
            }
            if rng.chance(5) {
                sb.transaction();
                let refused = srf.read(s.sb, available + lanes).is_err();
                sb.assert(cycle, refused, || {
                    format!("sb{}: read past available refused", s.sb)
                });
                cov.hit("read refused: more than available");
                if lanes > 1 && available > 1 {
                    let refused = srf.read(s.sb, 1).is_err();
                    sb.assert(cycle, refused, || {
                        format!("sb{}: partial row refused", s.sb)
                    });
                    cov.hit("read refused: not a whole row");
                }
                return;
            }
            let (n, how) = match rng.below(4) {
                0 | 1 => ((available.min(*uncond) / lanes) * lanes, 0),
                2 => (available.min(*cond).min(1 + rng.index(lanes)), 1),
                _ => (available.min(1 + rng.index(8)), 2),
            };
            if n == 0 {
                return;
            }
            sb.transaction();
            let got = match how {
                0 => {
                    *uncond -= n;
                    cov.hit("cluster read");
                    srf.read(s.sb, n).map(<[u32]>::to_vec)
                }
                1 => {
                    *cond -= n;
                    cov.hit("conditional read");
                    srf.read_conditional(s.sb, n).map(<[u32]>::to_vec)
                }
                _ => {
                    cov.hit("memory-port read");
                    srf.memory_read(s.sb, n).map(<[u32]>::to_vec)
                }
            };
            cov.hit_if(n == available, "read of every available word");
            let expected = s.words[s.done..s.done + n].to_vec();
            sb.check(
                cycle,
                || format!("words sb{} delivers from word {}", s.sb, s.done),
                Ok(expected),
                got.map_err(|e| e.to_string()),
            );
            s.done += n;
        } else {
            let space = srf.space(s.sb);
            cov.hit_if(space == 0 && !s.flushed, "output buffer full");
            if s.flushed || !rng.chance(rate) {
                return;
            }
            if left == 0 {
                sb.transaction();
                let ok = srf.flush(s.sb).is_ok();
                sb.assert(cycle, ok, || format!("flush sb{}", s.sb));
                s.flushed = true;
                return;
            }
            if rng.chance(5) {
                sb.transaction();
                let refused = srf.write(s.sb, &vec![0; space + lanes]).is_err();
                sb.assert(cycle, refused, || {
                    format!("sb{}: write past the room refused", s.sb)
                });
                cov.hit("write refused: more than the room");
                return;
            }
            let (n, how) = match rng.below(4) {
                0 | 1 => ((space.min(*uncond).min(left) / lanes) * lanes, 0),
                2 => (space.min(*cond).min(left).min(1 + rng.index(lanes)), 1),
                _ => (space.min(left).min(1 + rng.index(8)), 2),
            };
            if n == 0 {
                return;
            }
            sb.transaction();
            let words = &s.words[s.done..s.done + n];
            let ok = match how {
                0 => {
                    *uncond -= n;
                    cov.hit("cluster write");
                    srf.write(s.sb, words)
                }
                1 => {
                    *cond -= n;
                    cov.hit("conditional write");
                    srf.write_conditional(s.sb, words)
                }
                _ => {
                    cov.hit("memory-port write");
                    srf.memory_write(s.sb, words)
                }
            };
            sb.check(
                cycle,
                || format!("write of {n} words to sb{}", s.sb),
                Ok(()),
                ok.map_err(|e| e.to_string()),
            );
            s.done += n;
        }
    }
}
