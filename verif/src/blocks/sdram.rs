//! Testbench of the SDRAM part of one channel (`units::dram::sdram` and its banks) with the
//! channel's independent timing checker (`units::dram::timing_check`) watching the same
//! command bus. Each cycle drives at most one command: mostly a legal one, biased to the
//! first cycle it becomes legal (every timing rule met exactly at its limit), sometimes an
//! illegal one (a timing rule broken by a cycle or more, or a command the bank's state
//! forbids); geometry and timings from the machine's `[dram]` section.
//!
//! Reference, written from the datasheet rules and the part's documented behaviour:
//! per bank its open row and the cycles of its last ACTIVATE, PRECHARGE, READ and WRITE;
//! the stored words (unwritten words read 0; a column command to an idle bank addresses
//! row 0); a READ in cycle `t` puts its burst's words on the data bus in cycles
//! `t + CL ..`, as stored at `t`; a WRITE stores its words at `t`. For every command the
//! reference names the rules it breaks, and the checker must flag exactly those; the bank
//! states, the data bus and the read words in flight must match every cycle.

use std::collections::{BTreeMap, HashMap, VecDeque};

use imagine_hdl::bits::{u4, u12};
use imagine_units::desc::MachineDesc;
use imagine_units::dram::bank::BankState;
use imagine_units::dram::sdram::Sdram;
use imagine_units::dram::{Command, DramParams, TimingChecker};

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

/// Rules whose limit a legal command can meet exactly.
const LIMIT_RULES: &[&str] = &[
    "tRCD",
    "tRP",
    "tRAS",
    "tRC",
    "tRRD",
    "tWR",
    "read burst",
    "data bus",
    "turnaround",
    "tRFC",
];

/// Rules an illegal command of the stimulus breaks.
const BROKEN_RULES: &[&str] = &[
    "tRCD",
    "tRP",
    "tRAS",
    "tRC",
    "tRRD",
    "tWR",
    "turnaround",
    "tRFC",
    "bank state",
];

const BINS: &[&str] = &[
    "ACTIVATE",
    "READ",
    "WRITE",
    "PRECHARGE",
    "PRECHARGE of an idle bank",
    "REFRESH",
    "row hit (second column access to an open row)",
    "row miss (ACTIVATE of another row than the bank's last)",
    "row reopened (ACTIVATE of the bank's last row)",
    "read after write to the same word",
    "read of a word never written",
    "read of an idle bank (row 0)",
    "back-to-back commands",
    "idle cycle",
    "every bank open",
];

/// How far a command is from one rule: `slack < 0` breaks it, `slack == 0` meets it exactly.
struct Constraint {
    rule: &'static str,
    slack: i64,
}

#[derive(Clone, Default)]
struct RefBank {
    open: Option<u16>,
    /// The row open last (kept across a precharge).
    last_row: Option<u16>,
    /// Column accesses since the ACTIVATE.
    accesses: u32,
    act: Option<u64>,
    pre: Option<u64>,
    read: Option<u64>,
    write: Option<u64>,
}

/// The reference: bank states, command history, stored words, data bus.
pub(super) struct RefSdram {
    p: DramParams,
    banks: Vec<RefBank>,
    last_act: Option<u64>,
    last_read: Option<u64>,
    last_write: Option<u64>,
    last_ref: Option<u64>,
    refreshes: u64,
    missed: u64,
    words: HashMap<(usize, u16, usize), u32>,
    /// Words due on the data bus by cycle.
    bus: BTreeMap<u64, u32>,
}

/// `now - since - min` when `since` happened.
fn slack(now: u64, since: Option<u64>, min: u64) -> Option<i64> {
    since.map(|s| now as i64 - s as i64 - min as i64)
}

impl RefSdram {
    pub(super) fn new(p: &DramParams) -> Self {
        RefSdram {
            p: p.clone(),
            banks: vec![RefBank::default(); p.banks],
            last_act: None,
            last_read: None,
            last_write: None,
            last_ref: None,
            refreshes: 0,
            missed: 0,
            words: HashMap::new(),
            bus: BTreeMap::new(),
        }
    }

    /// Every timing constraint `cmd` in cycle `t` is subject to.
    fn constraints(&self, t: u64, cmd: Command) -> Vec<Constraint> {
        let p = &self.p;
        let bl = p.burst as u64;
        let mut out = Vec::new();
        let mut add = |rule, s: Option<i64>| {
            if let Some(slack) = s {
                out.push(Constraint { rule, slack });
            }
        };
        add("tRFC", slack(t, self.last_ref, p.t_rfc));
        match cmd {
            Command::Activate { bank, .. } => {
                let h = &self.banks[bank.value() as usize];
                add("tRP", slack(t, h.pre, p.t_rp));
                add("tRC", slack(t, h.act, p.t_rc));
                add("tRRD", slack(t, self.last_act, p.t_rrd));
            }
            Command::Read { bank, .. } => {
                let h = &self.banks[bank.value() as usize];
                add("tRCD", slack(t, h.act, p.t_rcd));
                add("data bus", slack(t, self.last_read, bl));
                // Read data at t + CL must come after the last write burst's words.
                add(
                    "data bus",
                    self.last_write.map(|w| (t + p.cl) as i64 - (w + bl) as i64),
                );
            }
            Command::Write { bank, .. } => {
                let h = &self.banks[bank.value() as usize];
                add("tRCD", slack(t, h.act, p.t_rcd));
                add("data bus", slack(t, self.last_write, bl));
                add(
                    "turnaround",
                    slack(t, self.last_read, p.cl + bl + p.turnaround),
                );
            }
            Command::Precharge { bank } => {
                let h = &self.banks[bank.value() as usize];
                if h.open.is_some() {
                    add("tRAS", slack(t, h.act, p.t_ras));
                    add("tWR", slack(t, h.write, bl - 1 + p.t_wr));
                    add("read burst", slack(t, h.read, bl));
                }
            }
            Command::Refresh => {
                for h in &self.banks {
                    add("tRP", slack(t, h.pre, p.t_rp));
                }
            }
        }
        out
    }

    /// The rules `cmd` in cycle `t` breaks, sorted.
    pub(super) fn broken(&self, t: u64, cmd: Command) -> Vec<&'static str> {
        let mut rules: Vec<_> = self
            .constraints(t, cmd)
            .iter()
            .filter(|c| c.slack < 0)
            .map(|c| c.rule)
            .collect();
        match cmd {
            Command::Activate { bank, .. } if self.banks[bank.value() as usize].open.is_some() => {
                rules.push("bank state")
            }
            Command::Read { bank, .. } | Command::Write { bank, .. }
                if self.banks[bank.value() as usize].open.is_none() =>
            {
                rules.push("bank state")
            }
            Command::Refresh => {
                rules.extend(
                    self.banks
                        .iter()
                        .filter(|h| h.open.is_some())
                        .map(|_| "bank state"),
                );
            }
            _ => {}
        }
        rules.sort_unstable();
        rules
    }

    /// Whether the refresh interval is overdue in cycle `t` (counted once per interval).
    pub(super) fn refresh_overdue(&mut self, t: u64) -> bool {
        let overdue = t >= (self.refreshes + self.missed + 2) * self.p.t_refi;
        self.missed += overdue as u64;
        overdue
    }

    /// Executes `cmd` in cycle `t` with write data `data`.
    pub(super) fn apply(&mut self, t: u64, cmd: Command, data: &[u32]) {
        let bl = self.p.burst;
        match cmd {
            Command::Activate { bank, row } => {
                let h = &mut self.banks[bank.value() as usize];
                h.open = Some(row);
                h.last_row = Some(row);
                h.accesses = 0;
                h.act = Some(t);
                self.last_act = Some(t);
            }
            Command::Read { bank, column } => {
                let b = bank.value() as usize;
                let h = &mut self.banks[b];
                let row = h.open.unwrap_or(0);
                h.accesses += 1;
                h.read = Some(t);
                self.last_read = Some(t);
                for k in 0..bl {
                    let w = self.word(b, row, column.value() as usize + k);
                    self.bus.insert(t + self.p.cl + k as u64, w);
                }
            }
            Command::Write { bank, column } => {
                let b = bank.value() as usize;
                let h = &mut self.banks[b];
                let row = h.open.unwrap_or(0);
                h.accesses += 1;
                h.write = Some(t);
                self.last_write = Some(t);
                for (k, &w) in data.iter().enumerate().take(bl) {
                    self.words.insert((b, row, column.value() as usize + k), w);
                }
            }
            Command::Precharge { bank } => {
                let h = &mut self.banks[bank.value() as usize];
                h.open = None;
                h.pre = Some(t);
            }
            Command::Refresh => {
                self.last_ref = Some(t);
                self.refreshes += 1;
            }
        }
    }

    /// The row open in `bank`, if any.
    pub(super) fn open_row(&self, bank: usize) -> Option<u16> {
        self.banks[bank].open
    }

    /// Forgets the read words due on the data bus (for a testbench that models the data
    /// itself).
    pub(super) fn forget_data_bus(&mut self) {
        self.bus.clear();
    }

    fn word(&self, bank: usize, row: u16, column: usize) -> u32 {
        self.words.get(&(bank, row, column)).copied().unwrap_or(0)
    }
}

/// What the stimulus is after for a while.
#[derive(Clone, Copy, PartialEq)]
enum Phase {
    /// Column accesses to open rows.
    RowHits,
    /// Precharges and activates: bank conflicts.
    Conflicts,
    /// Close every bank and refresh.
    Refresh,
}

/// The commands worth considering in cycle `t`.
fn candidates(
    r: &RefSdram,
    rng: &mut Rng,
    written: &VecDeque<(usize, u16, usize)>,
) -> Vec<Command> {
    let p = &r.p;
    let last_column = p.columns - p.burst;
    let mut out = vec![Command::Refresh];
    for (b, h) in r.banks.iter().enumerate() {
        let bank = u4::new(b as u8);
        let row = match rng.below(4) {
            0 => 0,
            1 => (p.rows - 1) as u16,
            2 => h.last_row.unwrap_or(0),
            _ => rng.below(p.rows as u64) as u16,
        };
        out.push(Command::Activate { bank, row });
        out.push(Command::Precharge { bank });
        let open = h.open.unwrap_or(0);
        let recent: Vec<usize> = written
            .iter()
            .filter(|(wb, wr, _)| *wb == b && *wr == open)
            .map(|w| w.2)
            .collect();
        for _ in 0..2 {
            let column = match rng.below(4) {
                0 => 0,
                1 => last_column,
                2 if !recent.is_empty() => recent[rng.index(recent.len())],
                _ => rng.index(p.columns / p.burst) * p.burst,
            };
            let column = u12::new(column as u16);
            out.push(Command::Read { bank, column });
            out.push(Command::Write { bank, column });
        }
    }
    out
}

/// Whether `cmd` suits `phase` (the stimulus prefers those).
fn suits(phase: Phase, cmd: Command) -> bool {
    match phase {
        Phase::RowHits => matches!(cmd, Command::Read { .. } | Command::Write { .. }),
        Phase::Conflicts => matches!(cmd, Command::Activate { .. } | Command::Precharge { .. }),
        Phase::Refresh => matches!(cmd, Command::Precharge { .. } | Command::Refresh),
    }
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let p = DramParams::of(desc);
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let bins: Vec<String> = BINS
        .iter()
        .map(|b| b.to_string())
        .chain(LIMIT_RULES.iter().map(|r| format!("{r} met at its limit")))
        .chain(
            BROKEN_RULES
                .iter()
                .map(|r| format!("{r} broken and flagged")),
        )
        .collect();
    let mut cov = Coverage::new(&bins);
    let mut d = design();
    let mut sdram = Sdram::new(&mut d.scope().child("sdram"), &p);
    let mut checker = TimingChecker::new(0, &p);
    let mut r = RefSdram::new(&p);
    let mut written: VecDeque<(usize, u16, usize)> = VecDeque::new();
    let mut phase = Phase::RowHits;
    let mut last_cmd_cycle = None;
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Dram, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions || !r.bus.is_empty() {
        if cycle.is_multiple_of(48) {
            phase = rng.pick(&[
                Phase::RowHits,
                Phase::RowHits,
                Phase::Conflicts,
                Phase::Refresh,
            ]);
        }
        let driving = sb.transactions < config.transactions;
        let cmd = if driving && rng.chance(80) {
            pick(&r, &mut rng, &written, phase, cycle)
        } else {
            None
        };
        let mut data = Vec::new();
        if let Some(cmd) = cmd {
            sb.transaction();
            cov.hit_if(
                last_cmd_cycle == Some(cycle.wrapping_sub(1)),
                "back-to-back commands",
            );
            last_cmd_cycle = Some(cycle);
            note(&r, &mut cov, cycle, cmd);
            if let Command::Write { bank, column } = cmd {
                data = (0..p.burst).map(|_| rng.corner_word()).collect();
                let b = bank.value() as usize;
                let key = (b, r.banks[b].open.unwrap_or(0), column.value() as usize);
                written.push_back(key);
                if written.len() > 16 {
                    written.pop_front();
                }
            }
        } else {
            cov.hit("idle cycle");
        }
        // The checker must flag exactly the rules the reference says the command breaks.
        let mut expected = cmd.map_or_else(Vec::new, |c| r.broken(cycle, c));
        if r.refresh_overdue(cycle) {
            expected.push("refresh interval");
            expected.sort_unstable();
        }
        let before = checker.violations().len();
        checker.observe(cycle, cmd);
        let mut flagged: Vec<&str> = checker.violations()[before..]
            .iter()
            .map(|v| v.rule)
            .collect();
        flagged.sort_unstable();
        for rule in &flagged {
            if BROKEN_RULES.contains(rule) {
                cov.hit(&format!("{rule} broken and flagged"));
            }
        }
        sb.check(
            cycle,
            || format!("rules the timing checker flags for {cmd:?}"),
            expected,
            flagged,
        );

        let dq = sdram.eval(cmd, &data, cycle);
        if let Some(cmd) = cmd {
            r.apply(cycle, cmd, &data);
        }
        let due = r.bus.remove(&cycle);
        sb.check(cycle, || "word on the data bus".into(), due, dq);
        sdram.commit();
        for (b, h) in r.banks.iter().enumerate() {
            let state = match h.open {
                Some(row) => BankState::Active { row },
                None => BankState::Idle,
            };
            sb.check(
                cycle,
                || format!("bank {b} state after the edge"),
                state,
                sdram.bank(b).state(),
            );
        }
        cov.hit_if(r.banks.iter().all(|h| h.open.is_some()), "every bank open");
        sb.check(
            cycle,
            || "read words in flight".into(),
            r.bus.len(),
            sdram.reads_in_flight(),
        );
        waves.cycle(cycle, |t| sdram.trace(t));
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}

/// The command driven in cycle `t`, if any: a legal one suiting the phase (half the time
/// one that meets a rule exactly at its limit), or now and then an illegal one.
fn pick(
    r: &RefSdram,
    rng: &mut Rng,
    written: &VecDeque<(usize, u16, usize)>,
    phase: Phase,
    t: u64,
) -> Option<Command> {
    let all = candidates(r, rng, written);
    let (legal, illegal): (Vec<Command>, Vec<Command>) =
        all.into_iter().partition(|&c| r.broken(t, c).is_empty());
    if rng.chance(6) {
        // Never overlapping read bursts: the data bus would carry two words at once.
        let illegal: Vec<Command> = illegal
            .into_iter()
            .filter(|&c| {
                !(matches!(c, Command::Read { .. }) && r.broken(t, c).contains(&"data bus"))
            })
            .collect();
        if !illegal.is_empty() {
            return Some(illegal[rng.index(illegal.len())]);
        }
    }
    let suited: Vec<Command> = legal.iter().copied().filter(|&c| suits(phase, c)).collect();
    let pool = if suited.is_empty() || rng.chance(15) {
        legal
    } else {
        suited
    };
    let at_limit: Vec<Command> = pool
        .iter()
        .copied()
        .filter(|&c| r.constraints(t, c).iter().any(|k| k.slack == 0))
        .collect();
    let pool = if !at_limit.is_empty() && rng.chance(50) {
        at_limit
    } else {
        pool
    };
    (!pool.is_empty()).then(|| pool[rng.index(pool.len())])
}

/// Counts the coverage `cmd` in cycle `t` reaches (before the reference executes it).
fn note(r: &RefSdram, cov: &mut Coverage, t: u64, cmd: Command) {
    if r.broken(t, cmd).is_empty() {
        for c in r.constraints(t, cmd) {
            if c.slack == 0 {
                cov.hit(&format!("{} met at its limit", c.rule));
            }
        }
    }
    match cmd {
        Command::Activate { bank, row } => {
            cov.hit("ACTIVATE");
            let h = &r.banks[bank.value() as usize];
            match h.last_row {
                Some(last) if last == row => {
                    cov.hit("row reopened (ACTIVATE of the bank's last row)")
                }
                Some(_) => cov.hit("row miss (ACTIVATE of another row than the bank's last)"),
                None => {}
            }
        }
        Command::Read { bank, column } | Command::Write { bank, column } => {
            let b = bank.value() as usize;
            let h = &r.banks[b];
            cov.hit_if(
                h.open.is_some() && h.accesses > 0,
                "row hit (second column access to an open row)",
            );
            if matches!(cmd, Command::Read { .. }) {
                cov.hit("READ");
                cov.hit_if(h.open.is_none(), "read of an idle bank (row 0)");
                let key = (b, h.open.unwrap_or(0), column.value() as usize);
                if r.words.contains_key(&key) {
                    cov.hit("read after write to the same word");
                } else {
                    cov.hit("read of a word never written");
                }
            } else {
                cov.hit("WRITE");
            }
        }
        Command::Precharge { bank } => {
            cov.hit("PRECHARGE");
            cov.hit_if(
                r.banks[bank.value() as usize].open.is_none(),
                "PRECHARGE of an idle bank",
            );
        }
        Command::Refresh => cov.hit("REFRESH"),
    }
}
