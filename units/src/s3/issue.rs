//! The issue unit (Figs 8–10, l.162–184): destination reservation stations (RS), one
//! source-RS file per source slot, candidate buffers with dependence vectors, and the
//! dependence matrix that fills them.
//!
//! Each cycle:
//! 1. **Retire** — every accelerator that finished broadcasts its tag: the tag's
//!    destination RS and the source RS it owns are freed, and its bit is cleared in every
//!    candidate's dependence and conflict vectors. A candidate whose vectors become zero
//!    may issue from the next cycle (l.180–182).
//! 2. **Issue** — if an accelerator is free, one candidate whose vectors are zero goes to
//!    it (the lowest-numbered free accelerator), chosen by the select policy; its
//!    candidate buffer is freed, its RS stay valid until it retires (l.175).
//! 3. **Insert** — if a destination RS, a candidate buffer and the source RS it needs
//!    are free, one primitive enters from fetch; its dependence vector has bit k set when
//!    it must wait for the primitive in destination RS k: RAW (its sources against k's
//!    destination), WAW, or WAR (its destination against k's sources), against **every**
//!    valid RS, issued or waiting (l.171–180).
//!
//! **Dependence-chain breaking** (§4.6, switchable): an opaque Z-buffered (independent)
//! candidate does not take dependence bits toward earlier independent primitives; it takes
//! *conflict* bits toward those among them that are issued, at insert, and whenever an
//! overlapping independent primitive issues later (a broadcast of the issuing region to
//! the candidates). So it waits only for overlapping triangles in flight, never for the
//! chain of earlier unissued ones; toward blended primitives its dependences stay. The
//! paper gives no encoding; this is the natural reading of l.265–267 (spec §1.2), and it
//! keeps the invariant that no two overlapping primitives are ever in flight at once.
//! (The stricter reading the spec mentions, also waiting for overlapping earlier
//! independent primitives that have not issued, would wait for them to issue and then,
//! by conflict, to retire: the basic model again, so it is not offered as a switch.)
//!
//! The retire, issue and insert decisions are made in `eval` from the committed state;
//! `commit` applies them (the next-state logic of the large RS and candidate arrays).
//! Dependence and conflict vectors are `WideWord`s of exactly one bit per destination RS.

use imagine_hdl::bits::{WideWord, bits_for, wide_word};
use imagine_hdl::{
    ContractError, Display, DomainId, FifoRx, Module, PipeRx, PipeTx, Scope, SignalId, SignalKind,
    Trace,
};

use super::raster::Region;
use super::{Job, Prim, Retire, S3Config, Select, hazard};

/// Why the issue stage did not issue in a cycle (or that it did).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cause {
    /// No candidate waits: the issue unit is starved by fetch (or the frame is done).
    Empty = 0,
    Issued = 1,
    /// A candidate is ready but every accelerator is busy.
    NoAccelerator = 2,
    /// No candidate is ready, and every one waits on a dependence.
    Dependence = 3,
    /// No candidate is ready, and some candidate waits only on conflicts (chain
    /// breaking: an overlapping independent triangle is in flight).
    Conflict = 4,
}

pub const CAUSE_NAMES: &[&str] = &[
    "empty",
    "issued",
    "no_accelerator",
    "dependence",
    "conflict",
];

#[derive(Clone, Debug)]
struct Candidate {
    tag: u16,
    /// Insert order, for the oldest-first policy.
    age: u32,
    prim: Prim,
    dep: WideWord,
    conflict: WideWord,
}

/// The decisions of one cycle, applied at commit.
#[derive(Clone, Debug, Default)]
struct Actions {
    retired: Vec<Retire>,
    /// (candidate index, accelerator).
    issued: Option<(usize, usize)>,
    /// (candidate index, destination RS, source RS per slot, candidate).
    inserted: Option<(usize, usize, Vec<Option<usize>>, Candidate)>,
    cause: Option<Cause>,
    /// Fetch held a primitive the window had no room for.
    window_full: bool,
}

pub struct Issue {
    domain: DomainId,
    input: FifoRx<Prim>,
    dispatch: Vec<PipeTx<Job>>,
    retire: Vec<PipeRx<Retire>>,
    select: Select,
    chain_break: bool,
    // Destination RS.
    rs_valid: WideWord,
    rs_issued: WideWord,
    rs_indep: WideWord,
    rs_dest: Vec<Region>,
    rs_prim: Vec<Option<Prim>>,
    // Source RS files: per slot, entries of (owner tag, region).
    src: Vec<Vec<Option<(u16, Region)>>>,
    // Candidate buffers.
    cands: Vec<Option<Candidate>>,
    accel_busy: WideWord,
    lfsr: u32,
    inserted: u32,
    act: Actions,
    last: Actions,
    /// (tag, accelerator) of the last cycle's issue.
    last_issue: Option<(usize, usize)>,
    ids: IssueIds,
}

struct IssueIds {
    rs_valid: SignalId,
    rs_issued: SignalId,
    cand_valid: SignalId,
    accel_busy: SignalId,
    cause: SignalId,
    issued: SignalId,
    issue_tag: SignalId,
    issue_accel: SignalId,
    inserted: SignalId,
    insert_tag: SignalId,
    retired: SignalId,
    lfsr: SignalId,
    /// Per candidate: valid, tag, dependence vector, conflict vector.
    cand: Vec<[SignalId; 4]>,
}

/// A free entry among `valid` bits (the lowest).
fn first_free(valid: &WideWord) -> Option<usize> {
    valid.first_zero()
}

impl Issue {
    pub fn new(
        s: &mut Scope<'_>,
        domain: DomainId,
        cfg: &S3Config,
        input: FifoRx<Prim>,
        dispatch: Vec<PipeTx<Job>>,
        retire: Vec<PipeRx<Retire>>,
    ) -> Self {
        let (n_rs, n_cand, k) = (cfg.dest_rs(), cfg.candidates(), cfg.accelerators);
        let tag_w = bits_for(n_rs as u64 - 1);
        let accel_w = bits_for(k as u64 - 1);
        let n_rs_w = n_rs as u32;
        let ids = IssueIds {
            rs_valid: s.signal("rs_valid", n_rs_w, SignalKind::Reg),
            rs_issued: s.signal("rs_issued", n_rs_w, SignalKind::Reg),
            cand_valid: s.signal("cand_valid", n_cand as u32, SignalKind::Reg),
            accel_busy: s.signal("accel_busy", k as u32, SignalKind::Reg),
            cause: s.signal_shown("cause", 3, SignalKind::Wire, Display::Names(CAUSE_NAMES)),
            issued: s.signal("issued", 1, SignalKind::Wire),
            issue_tag: s.signal("issue_tag", tag_w, SignalKind::Wire),
            issue_accel: s.signal("issue_accel", accel_w, SignalKind::Wire),
            inserted: s.signal("inserted", 1, SignalKind::Wire),
            insert_tag: s.signal("insert_tag", tag_w, SignalKind::Wire),
            retired: s.signal("retired", bits_for(k as u64), SignalKind::Wire),
            lfsr: s.signal("lfsr", 32, SignalKind::Reg),
            cand: (0..n_cand)
                .map(|i| {
                    let mut c = s.child(&format!("cand{i}"));
                    [
                        c.signal("valid", 1, SignalKind::Reg),
                        c.signal("tag", tag_w, SignalKind::Reg),
                        c.signal("dep", n_rs_w, SignalKind::Reg),
                        c.signal("conflict", n_rs_w, SignalKind::Reg),
                    ]
                })
                .collect(),
        };
        s.glance(ids.cause);
        Issue {
            domain,
            input,
            dispatch,
            retire,
            select: cfg.select,
            chain_break: cfg.chain_break,
            rs_valid: wide_word(n_rs),
            rs_issued: wide_word(n_rs),
            rs_indep: wide_word(n_rs),
            rs_dest: vec![
                Region {
                    x0: 0,
                    x1: 0,
                    y0: 0,
                    y1: 0
                };
                n_rs
            ],
            rs_prim: vec![None; n_rs],
            src: vec![vec![None; n_rs]; cfg.source_slots],
            cands: vec![None; n_cand],
            accel_busy: wide_word(k),
            lfsr: cfg.select_seed,
            inserted: 0,
            act: Actions::default(),
            last: Actions::default(),
            last_issue: None,
            ids,
        }
    }

    /// No primitive held (no valid RS) and none waiting in the queue from fetch.
    pub fn is_idle(&self) -> bool {
        self.rs_valid.not_any() && self.input.available() == 0
    }

    /// The last cycle's issue-stage outcome.
    pub fn cause(&self) -> Option<Cause> {
        self.last.cause
    }

    /// Whether fetch held a primitive the window could not take last cycle.
    pub fn window_full(&self) -> bool {
        self.last.window_full
    }

    /// Pairs of issued (in-flight) primitives whose regions are in hazard: the property
    /// the dependence and conflict vectors exist to keep at zero.
    pub fn in_flight_hazards(&self) -> usize {
        let flying: Vec<&Prim> = self
            .rs_issued
            .iter_ones()
            .filter_map(|k| self.rs_prim[k].as_ref())
            .collect();
        let mut n = 0;
        for (i, p) in flying.iter().enumerate() {
            n += flying[..i].iter().filter(|q| p.hazard(q)).count();
        }
        n
    }

    /// The source regions RS `k` owns.
    fn sources_of(&self, k: usize) -> [Option<Region>; 2] {
        let mut s = [None; 2];
        for (slot, file) in self.src.iter().enumerate() {
            s[slot] = file
                .iter()
                .flatten()
                .find(|(t, _)| *t as usize == k)
                .map(|e| e.1);
        }
        s
    }

    fn step_lfsr(x: u32) -> u32 {
        // x^32 + x^22 + x^2 + x + 1, maximal length.
        (x >> 1) ^ if x & 1 != 0 { 0x8020_0003 } else { 0 }
    }
}

impl Module for Issue {
    fn domain(&self) -> DomainId {
        self.domain
    }

    fn eval(&mut self) -> Result<(), ContractError> {
        let mut act = Actions::default();
        // 1. Retire: tags arriving from the accelerators.
        for rx in &mut self.retire {
            while let Some(r) = rx.read() {
                act.retired.push(r);
            }
        }
        // 2. Issue, from the committed vectors.
        let ready: Vec<usize> = (0..self.cands.len())
            .filter(|&i| {
                self.cands[i]
                    .as_ref()
                    .is_some_and(|c| c.dep.not_any() && c.conflict.not_any())
            })
            .collect();
        let free_accel = self.accel_busy.first_zero();
        let any_cand = self.cands.iter().any(Option::is_some);
        act.cause = Some(if let (false, Some(a)) = (ready.is_empty(), free_accel) {
            let pick = match self.select {
                Select::Oldest => *ready
                    .iter()
                    .min_by_key(|&&i| self.cands[i].as_ref().map(|c| c.age))
                    .expect("not empty"),
                Select::Random => ready[self.lfsr as usize % ready.len()],
            };
            let c = self.cands[pick].as_ref().expect("ready");
            self.dispatch[a].write(Job {
                tag: c.tag,
                prim: c.prim,
            })?;
            act.issued = Some((pick, a));
            Cause::Issued
        } else if !ready.is_empty() {
            Cause::NoAccelerator
        } else if !any_cand {
            Cause::Empty
        } else if self.cands.iter().flatten().any(|c| c.dep.not_any()) {
            Cause::Conflict
        } else {
            Cause::Dependence
        });
        // 3. Insert, against the RS as they stand after this cycle's retires and issue.
        if self.input.available() > 0 {
            let rs = first_free(&self.rs_valid);
            let cand = self.cands.iter().position(Option::is_none);
            match (rs, cand) {
                (Some(rs), Some(ci)) => {
                    let p = self.input.pop()?;
                    let retiring = |k: usize| act.retired.iter().any(|r| r.tag as usize == k);
                    let issuing = act
                        .issued
                        .and_then(|(i, _)| self.cands[i].as_ref().map(|c| c.tag as usize));
                    let n_rs = self.rs_valid.len();
                    let mut dep = wide_word(n_rs);
                    let mut conflict = wide_word(n_rs);
                    for k in self.rs_valid.iter_ones() {
                        if retiring(k) {
                            continue;
                        }
                        let ks = self.sources_of(k);
                        if !hazard(&p.dest, &p.sources, &self.rs_dest[k], &ks) {
                            continue;
                        }
                        if self.chain_break && p.independent() && self.rs_indep[k] {
                            let flying = self.rs_issued[k] || issuing == Some(k);
                            conflict.set(k, flying);
                        } else {
                            dep.set(k, true);
                        }
                    }
                    // Each source slot takes a free entry of its file.
                    let mut srcs = Vec::with_capacity(self.src.len());
                    for (slot, file) in self.src.iter().enumerate() {
                        srcs.push(match p.sources[slot] {
                            Some(_) => file.iter().position(Option::is_none),
                            None => None,
                        });
                    }
                    act.inserted = Some((
                        ci,
                        rs,
                        srcs,
                        Candidate {
                            tag: rs as u16,
                            age: self.inserted,
                            prim: p,
                            dep,
                            conflict,
                        },
                    ));
                }
                _ => act.window_full = true,
            }
        }
        self.act = act;
        Ok(())
    }

    fn commit(&mut self) {
        let act = std::mem::take(&mut self.act);
        for r in &act.retired {
            let k = r.tag as usize;
            self.rs_valid.set(k, false);
            self.rs_issued.set(k, false);
            self.rs_indep.set(k, false);
            self.rs_prim[k] = None;
            for file in &mut self.src {
                for e in file.iter_mut() {
                    if e.is_some_and(|(t, _)| t as usize == k) {
                        *e = None;
                    }
                }
            }
            for c in self.cands.iter_mut().flatten() {
                c.dep.set(k, false);
                c.conflict.set(k, false);
            }
            self.accel_busy.set(r.accel as usize, false);
        }
        self.last_issue = None;
        if let Some((ci, a)) = act.issued {
            let c = self.cands[ci].take().expect("issued a valid candidate");
            let k = c.tag as usize;
            self.last_issue = Some((k, a));
            self.rs_issued.set(k, true);
            self.accel_busy.set(a, true);
            if self.chain_break && c.prim.independent() {
                // The conflict broadcast: waiting independent candidates that overlap the
                // issued triangle may not run beside it.
                let (d, s) = (c.prim.dest, c.prim.sources);
                for o in self.cands.iter_mut().flatten() {
                    if o.prim.independent() && hazard(&o.prim.dest, &o.prim.sources, &d, &s) {
                        o.conflict.set(k, true);
                    }
                }
            }
        }
        if let Some((ci, rs, srcs, c)) = act.inserted.clone() {
            self.rs_valid.set(rs, true);
            self.rs_indep.set(rs, c.prim.independent());
            self.rs_dest[rs] = c.prim.dest;
            self.rs_prim[rs] = Some(c.prim);
            for (slot, e) in srcs.iter().enumerate() {
                if let (Some(e), Some(r)) = (e, c.prim.sources[slot]) {
                    self.src[slot][*e] = Some((rs as u16, r));
                }
            }
            self.cands[ci] = Some(c);
            self.inserted = self.inserted.wrapping_add(1);
        }
        self.lfsr = Self::step_lfsr(self.lfsr);
        self.last = act;
    }

    fn trace(&self, t: &mut Trace) {
        let i = &self.ids;
        t.wide(i.rs_valid, self.rs_valid.as_raw_slice());
        t.wide(i.rs_issued, self.rs_issued.as_raw_slice());
        let mut cv = wide_word(self.cands.len());
        for (k, c) in self.cands.iter().enumerate() {
            cv.set(k, c.is_some());
        }
        t.wide(i.cand_valid, cv.as_raw_slice());
        t.wide(i.accel_busy, self.accel_busy.as_raw_slice());
        t.value(i.cause, self.last.cause.map_or(0, |c| c as u64));
        let issued = self.last_issue;
        t.value(i.issued, issued.is_some() as u64);
        t.value(i.issue_accel, issued.map_or(0, |(_, a)| a as u64));
        let itag = self.last.inserted.as_ref().map(|(_, rs, _, _)| *rs);
        t.value(i.inserted, itag.is_some() as u64);
        t.value(i.insert_tag, itag.unwrap_or(0) as u64);
        t.value(i.retired, self.last.retired.len() as u64);
        t.value(i.lfsr, self.lfsr as u64);
        let zero = wide_word(self.rs_valid.len());
        for (c, ids) in self.cands.iter().zip(&i.cand) {
            t.value(ids[0], c.is_some() as u64);
            t.value(ids[1], c.as_ref().map_or(0, |c| c.tag as u64));
            t.wide(ids[2], c.as_ref().map_or(&zero, |c| &c.dep).as_raw_slice());
            t.wide(
                ids[3],
                c.as_ref().map_or(&zero, |c| &c.conflict).as_raw_slice(),
            );
        }
        t.value(i.issue_tag, self.last_issue.map_or(0, |(k, _)| k as u64));
    }
}
