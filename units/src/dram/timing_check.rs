//! An independent timing checker for one channel's command bus.
//!
//! It sees only the commands on the bus, one per cycle, and the datasheet's numbers (the
//! machine description's `[dram]` section); it shares no state or code with the
//! scheduler. Every command is checked against every rule that applies, and each broken
//! rule is recorded as a [`TimingViolation`] naming the cycle, the bank and the rule:
//!
//! | rule | between |
//! |---|---|
//! | `tRCD` | ACTIVATE and READ/WRITE of a bank |
//! | `tRP` | PRECHARGE and ACTIVATE (or REFRESH) of a bank |
//! | `tRAS` | ACTIVATE and PRECHARGE of a bank |
//! | `tRC` | ACTIVATE and ACTIVATE of a bank |
//! | `tRRD` | ACTIVATEs of different banks |
//! | `tWR` | the last write data word and PRECHARGE of the bank |
//! | `read burst` | READ and a PRECHARGE that would cut its burst short |
//! | `data bus` | bursts overlapping on the data bus |
//! | `turnaround` | read data and the next write data without the idle cycles |
//! | `tRFC` | REFRESH and any command |
//! | `bank state` | ACTIVATE of an active bank, READ/WRITE of an idle bank, REFRESH with a bank open |
//! | `refresh interval` | a refresh interval of `refresh_interval` cycles passed without its REFRESH |
//! | `address` | a row or column outside the part |
//!
//! (Source of the rules: the Micron MT48LC4M32B2 datasheet, timing parameters and
//! command truth tables.)

use std::fmt;

use super::{Command, DramParams};

/// A broken timing or protocol rule.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimingViolation {
    /// The command-bus cycle of the offending command.
    pub cycle: u64,
    pub channel: usize,
    pub bank: Option<usize>,
    pub rule: &'static str,
    pub detail: String,
}

impl fmt::Display for TimingViolation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "channel {} ", self.channel)?;
        if let Some(b) = self.bank {
            write!(f, "bank {b} ")?;
        }
        write!(
            f,
            "DRAM cycle {}: {} violated: {}",
            self.cycle, self.rule, self.detail
        )
    }
}

#[derive(Clone, Debug, Default)]
struct BankHistory {
    open: Option<u16>,
    act: Option<u64>,
    pre: Option<u64>,
    read: Option<u64>,
    write: Option<u64>,
}

/// The checker of one channel.
#[derive(Clone, Debug)]
pub struct TimingChecker {
    p: DramParams,
    banks: Vec<BankHistory>,
    last_act: Option<u64>,
    last_read: Option<u64>,
    last_write: Option<u64>,
    last_ref: Option<u64>,
    refreshes: u64,
    /// Refresh intervals already reported as missed.
    missed: u64,
    commands: u64,
    log: ViolationLog,
}

/// The violations found so far.
#[derive(Clone, Debug)]
struct ViolationLog {
    channel: usize,
    violations: Vec<TimingViolation>,
}

impl ViolationLog {
    /// Records a violation; out of line (with the formatting of its detail), so that the
    /// checks stay small.
    #[cold]
    #[inline(never)]
    fn flag(
        &mut self,
        cycle: u64,
        bank: Option<usize>,
        rule: &'static str,
        detail: impl FnOnce() -> String,
    ) {
        self.violations.push(TimingViolation {
            cycle,
            channel: self.channel,
            bank,
            rule,
            detail: detail(),
        });
    }

    /// Requires `now - since >= min` when `since` happened.
    #[inline]
    fn gap(
        &mut self,
        now: u64,
        since: Option<u64>,
        min: u64,
        bank: Option<usize>,
        rule: &'static str,
        what: &str,
    ) {
        if let Some(s) = since
            && now < s + min
        {
            self.too_soon(now, s, min, bank, rule, what);
        }
    }

    /// Flags a [`gap`](Self::gap) too short; out of line, so the check stays small.
    #[cold]
    #[inline(never)]
    fn too_soon(
        &mut self,
        now: u64,
        since: u64,
        min: u64,
        bank: Option<usize>,
        rule: &'static str,
        what: &str,
    ) {
        self.flag(now, bank, rule, || {
            format!(
                "{what}: {} cycles after cycle {since}, need {min}",
                now - since
            )
        });
    }
}

impl TimingChecker {
    pub fn new(channel: usize, p: &DramParams) -> Self {
        TimingChecker {
            banks: vec![BankHistory::default(); p.banks],
            p: p.clone(),
            last_act: None,
            last_read: None,
            last_write: None,
            last_ref: None,
            refreshes: 0,
            missed: 0,
            commands: 0,
            log: ViolationLog {
                channel,
                violations: Vec::new(),
            },
        }
    }

    pub fn violations(&self) -> &[TimingViolation] {
        &self.log.violations
    }

    /// Commands checked so far.
    pub fn commands(&self) -> u64 {
        self.commands
    }

    /// Whether a REFRESH at every due cycle (`k · refresh_interval`) from `cycle` on, and
    /// no other command, breaks no rule, given that `refreshes` have been issued: every
    /// bank closed long enough, the last refresh's tRFC over, none overdue.
    pub fn idle_skippable(&self, cycle: u64, refreshes: u64) -> bool {
        let p = &self.p;
        self.refreshes == refreshes
            && p.t_rfc < p.t_refi
            && cycle < (refreshes + 1) * p.t_refi
            && self.last_ref.is_none_or(|t| t + p.t_rfc <= cycle)
            && self
                .banks
                .iter()
                .all(|h| h.open.is_none() && h.pre.is_none_or(|t| t + p.t_rp <= cycle))
    }

    /// The state of having observed `count` idle cycles' refreshes, the last at
    /// `last_cycle`, and no other command (only when
    /// [`idle_skippable`](Self::idle_skippable)): each was on time and legal, so only the
    /// counts and the last refresh's cycle change.
    pub fn skip_idle(&mut self, count: u64, last_cycle: Option<u64>) {
        self.refreshes += count;
        self.commands += count;
        if let Some(t) = last_cycle {
            self.last_ref = Some(t);
        }
    }

    /// The first cycle in which a refresh is overdue: by the end of interval k+1 the k-th
    /// refresh must be done. (Before it, a cycle without a command breaks no rule.)
    pub fn next_refresh_deadline(&self) -> u64 {
        (self.refreshes + self.missed + 2) * self.p.t_refi
    }

    /// Checks the bus in `cycle`: `cmd` is the command it carries, if any.
    #[inline]
    pub fn observe(&mut self, cycle: u64, cmd: Option<Command>) {
        if cycle >= self.next_refresh_deadline() {
            self.missed += 1;
            let (refreshes, due) = (self.refreshes, cycle / self.p.t_refi);
            self.log.flag(cycle, None, "refresh interval", || {
                format!("{refreshes} refreshes by cycle {cycle}, {due} were due")
            });
        }
        let Some(cmd) = cmd else { return };
        let (p, log) = (&self.p, &mut self.log);
        self.commands += 1;
        let t = cycle;
        let bl = p.burst as u64;
        log.gap(
            t,
            self.last_ref,
            p.t_rfc,
            None,
            "tRFC",
            "command after REFRESH",
        );
        match cmd {
            Command::Activate { bank, row } => {
                let b = bank.value() as usize;
                if (row as usize) >= p.rows {
                    let rows = p.rows;
                    log.flag(t, Some(b), "address", || format!("row {row} of {rows}"));
                }
                let h = &mut self.banks[b];
                if let Some(r) = h.open {
                    log.flag(t, Some(b), "bank state", || {
                        format!("ACTIVATE row {row} while row {r} is open")
                    });
                }
                log.gap(t, h.pre, p.t_rp, Some(b), "tRP", "PRECHARGE to ACTIVATE");
                log.gap(t, h.act, p.t_rc, Some(b), "tRC", "ACTIVATE to ACTIVATE");
                log.gap(
                    t,
                    self.last_act,
                    p.t_rrd,
                    Some(b),
                    "tRRD",
                    "ACTIVATE to ACTIVATE",
                );
                h.open = Some(row);
                h.act = Some(t);
                self.last_act = Some(t);
            }
            Command::Read { bank, column } | Command::Write { bank, column } => {
                let write = matches!(cmd, Command::Write { .. });
                let b = bank.value() as usize;
                let (name, after_activate) = if write {
                    ("WRITE", "ACTIVATE to WRITE")
                } else {
                    ("READ", "ACTIVATE to READ")
                };
                if column.value() as usize + p.burst > p.columns {
                    let columns = p.columns;
                    log.flag(t, Some(b), "address", || {
                        format!("column {column} of {columns}")
                    });
                }
                let h = &mut self.banks[b];
                if h.open.is_none() {
                    log.flag(t, Some(b), "bank state", || {
                        format!("{name} of an idle bank")
                    });
                }
                log.gap(t, h.act, p.t_rcd, Some(b), "tRCD", after_activate);
                if write {
                    log.gap(
                        t,
                        self.last_write,
                        bl,
                        Some(b),
                        "data bus",
                        "write bursts overlap",
                    );
                    // Write data at t must follow the last read data (r + CL .. r + CL + BL)
                    // and the turnaround.
                    log.gap(
                        t,
                        self.last_read,
                        p.cl + bl + p.turnaround,
                        Some(b),
                        "turnaround",
                        "READ to WRITE",
                    );
                    h.write = Some(t);
                    self.last_write = Some(t);
                } else {
                    log.gap(
                        t,
                        self.last_read,
                        bl,
                        Some(b),
                        "data bus",
                        "read bursts overlap",
                    );
                    if let Some(w) = self.last_write
                        && t + p.cl < w + bl
                    {
                        let data_at = t + p.cl;
                        log.flag(t, Some(b), "data bus", || {
                            format!("read data at {data_at} meets write data of cycle {w}")
                        });
                    }
                    h.read = Some(t);
                    self.last_read = Some(t);
                }
            }
            Command::Precharge { bank } => {
                let b = bank.value() as usize;
                let h = &mut self.banks[b];
                if h.open.is_some() {
                    log.gap(t, h.act, p.t_ras, Some(b), "tRAS", "ACTIVATE to PRECHARGE");
                    log.gap(
                        t,
                        h.write,
                        bl - 1 + p.t_wr,
                        Some(b),
                        "tWR",
                        "WRITE to PRECHARGE",
                    );
                    log.gap(t, h.read, bl, Some(b), "read burst", "READ to PRECHARGE");
                }
                h.open = None;
                h.pre = Some(t);
            }
            Command::Refresh => {
                for (b, h) in self.banks.iter().enumerate() {
                    if h.open.is_some() {
                        log.flag(t, Some(b), "bank state", || {
                            "REFRESH with the bank open".into()
                        });
                    }
                    log.gap(t, h.pre, p.t_rp, Some(b), "tRP", "PRECHARGE to REFRESH");
                }
                self.last_ref = Some(t);
                self.refreshes += 1;
            }
        }
    }
}
