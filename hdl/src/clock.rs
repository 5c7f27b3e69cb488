//! Clock domains with exact rational frequency ratios.
//!
//! Each domain has an integer frequency in hertz, so the ratio of any two domains is an
//! exact rational number (500 MHz : 167 MHz = 500 : 167). Edges are ordered by exact
//! integer cross-multiplication, never by rounded periods, so over any run the number of
//! edges of each domain is exact. Simulated time is reported in picoseconds (rounded down);
//! the ordering of edges does not depend on that rounding.
//!
//! The scheduler walks half-periods so that falling edges can be shown in waveforms: the
//! rising edge `k` of a domain with frequency `f` is at `k / f` seconds, its falling edge at
//! `(k + ½) / f`. Edges of several domains that fall at exactly the same instant are
//! reported together as one [`Edge`].

use std::fmt;

/// Index of a clock domain within a design (0 is the core clock by convention).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct DomainId(pub u8);

/// A set of clock domains, as a bit mask.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DomainSet(pub u64);

impl DomainSet {
    pub fn contains(self, d: DomainId) -> bool {
        self.0 & (1 << d.0) != 0
    }
    pub fn is_empty(self) -> bool {
        self.0 == 0
    }
    pub fn insert(&mut self, d: DomainId) {
        self.0 |= 1 << d.0;
    }
}

/// A named clock with an integer frequency.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ClockDomain {
    pub name: String,
    pub freq_hz: u64,
}

impl ClockDomain {
    pub fn new(name: &str, freq_hz: u64) -> Self {
        ClockDomain {
            name: name.to_string(),
            freq_hz,
        }
    }
    pub fn mhz(name: &str, mhz: u64) -> Self {
        Self::new(name, mhz * 1_000_000)
    }
}

/// The defaults of ARCHITECTURE §4: core 500 MHz, SDRAM 167 MHz.
pub fn default_domains() -> Vec<ClockDomain> {
    vec![ClockDomain::mhz("core", 500), ClockDomain::mhz("dram", 167)]
}

/// An impossible clock description.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ClockError {
    NoDomains,
    TooManyDomains(usize),
    ZeroFrequency(String),
    DuplicateName(String),
}

impl fmt::Display for ClockError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClockError::NoDomains => write!(f, "a design needs at least one clock domain"),
            ClockError::TooManyDomains(n) => {
                write!(f, "{n} clock domains; at most 64 are supported")
            }
            ClockError::ZeroFrequency(n) => write!(f, "clock domain `{n}` has frequency 0 Hz"),
            ClockError::DuplicateName(n) => write!(f, "clock domain `{n}` is declared twice"),
        }
    }
}

impl std::error::Error for ClockError {}

/// One step of simulated time: the domains whose clocks rise and fall at `time_ps`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Edge {
    pub time_ps: u64,
    pub rising: DomainSet,
    pub falling: DomainSet,
}

const PS_PER_S: u128 = 1_000_000_000_000;

/// The edge scheduler for a set of clock domains.
#[derive(Clone, Debug)]
pub struct Clocks {
    domains: Vec<ClockDomain>,
    /// Per domain, the index of its next half-period edge (even: rising, odd: falling).
    next_half: Vec<u64>,
    /// Per domain, the time of that edge in picoseconds (rounded down) and the remainder
    /// of the division that gives it, kept by adding one half-period at a time (a 128-bit
    /// division per edge cost more than the rest of the scheduler).
    next_ps: Vec<u64>,
    next_ps_rem: Vec<u64>,
    /// Per domain, `PS_PER_S / 2f` as quotient and remainder.
    half_period_ps: Vec<(u64, u64)>,
    /// Per domain, the number of rising edges so far.
    cycles: Vec<u64>,
    time_ps: u64,
}

impl Clocks {
    pub fn new(domains: Vec<ClockDomain>) -> Result<Self, ClockError> {
        if domains.is_empty() {
            return Err(ClockError::NoDomains);
        }
        if domains.len() > 64 {
            return Err(ClockError::TooManyDomains(domains.len()));
        }
        for (i, d) in domains.iter().enumerate() {
            if d.freq_hz == 0 {
                return Err(ClockError::ZeroFrequency(d.name.clone()));
            }
            if domains[..i].iter().any(|o| o.name == d.name) {
                return Err(ClockError::DuplicateName(d.name.clone()));
            }
        }
        let n = domains.len();
        let mut clocks = Clocks {
            domains,
            next_half: vec![0; n],
            next_ps: vec![0; n],
            next_ps_rem: vec![0; n],
            half_period_ps: Vec::new(),
            cycles: vec![0; n],
            time_ps: 0,
        };
        clocks.half_period_ps = (0..n).map(|d| clocks.half_edge(d, 1)).collect();
        Ok(clocks)
    }

    pub fn domains(&self) -> &[ClockDomain] {
        &self.domains
    }

    /// Looks a domain up by name.
    pub fn find(&self, name: &str) -> Option<DomainId> {
        self.domains
            .iter()
            .position(|d| d.name == name)
            .map(|i| DomainId(i as u8))
    }

    /// The exact ratio `freq(a) : freq(b)` in lowest terms.
    pub fn ratio(&self, a: DomainId, b: DomainId) -> (u64, u64) {
        let (fa, fb) = (
            self.domains[a.0 as usize].freq_hz,
            self.domains[b.0 as usize].freq_hz,
        );
        let g = gcd(fa, fb);
        (fa / g, fb / g)
    }

    /// Rising edges of domain `d` so far.
    pub fn cycles(&self, d: DomainId) -> u64 {
        self.cycles[d.0 as usize]
    }

    /// Time of the most recent edge, in picoseconds.
    pub fn time_ps(&self) -> u64 {
        self.time_ps
    }

    /// Time of half-period edge `half` of domain `d`, in picoseconds, rounded down.
    fn half_edge_ps(&self, d: usize, half: u64) -> u64 {
        self.half_edge(d, half).0
    }

    /// [`half_edge_ps`](Self::half_edge_ps) and the remainder of its division.
    fn half_edge(&self, d: usize, half: u64) -> (u64, u64) {
        let denom = 2 * self.domains[d].freq_hz as u128;
        let num = half as u128 * PS_PER_S;
        ((num / denom) as u64, (num % denom) as u64)
    }

    /// Sets domain `d`'s next half-period edge to `half`.
    fn set_half(&mut self, d: usize, half: u64) {
        self.next_half[d] = half;
        (self.next_ps[d], self.next_ps_rem[d]) = self.half_edge(d, half);
    }

    /// Moves domain `d`'s next edge on by one half-period: `next_ps` grows by
    /// `PS_PER_S / 2f`, exactly, carrying the remainder.
    #[inline]
    fn step_half(&mut self, d: usize) {
        let denom = 2 * self.domains[d].freq_hz;
        let (q, r) = self.half_period_ps[d];
        self.next_half[d] += 1;
        self.next_ps[d] += q;
        self.next_ps_rem[d] += r;
        if self.next_ps_rem[d] >= denom {
            self.next_ps_rem[d] -= denom;
            self.next_ps[d] += 1;
        }
    }

    /// Advances to the next instant at which any clock has an edge.
    pub fn next_edge(&mut self) -> Edge {
        // Edge time of domain i is next_half[i] / (2 f_i); compare a/fa < b/fb as a·fb < b·fa.
        let mut first = 0;
        for i in 1..self.domains.len() {
            if self.earlier(i, first) {
                first = i;
            }
        }
        let mut edge = Edge {
            time_ps: self.next_ps[first],
            rising: DomainSet::default(),
            falling: DomainSet::default(),
        };
        // Decide every domain against the same instant before advancing any of them.
        let mut fired = 0u64;
        for i in 0..self.domains.len() {
            if i == first || self.simultaneous(i, first) {
                fired |= 1 << i;
            }
        }
        for i in 0..self.domains.len() {
            if fired & (1 << i) != 0 {
                let d = DomainId(i as u8);
                if self.next_half[i].is_multiple_of(2) {
                    edge.rising.insert(d);
                    self.cycles[i] += 1;
                } else {
                    edge.falling.insert(d);
                }
                self.step_half(i);
            }
        }
        self.time_ps = edge.time_ps;
        edge
    }

    /// Skips every pending falling edge, so the next [`next_edge`](Self::next_edge) is a
    /// rising one. Without a waveform to draw, falling edges change nothing.
    pub fn skip_falling_edges(&mut self) {
        for d in 0..self.next_half.len() {
            if self.next_half[d] & 1 == 1 {
                self.step_half(d);
            }
        }
    }

    /// Advances a single-domain clock by `n` rising edges at once, leaving it exactly as
    /// `n` calls of [`skip_falling_edges`](Self::skip_falling_edges) then
    /// [`next_edge`](Self::next_edge) would (same edge count, half-period index and time).
    /// With several domains this returns `false` and changes nothing (use
    /// [`skip_to`](Self::skip_to)); so it does if the edge count would overflow.
    pub fn skip_rising_edges(&mut self, n: u64) -> bool {
        if self.domains.len() != 1 {
            return false;
        }
        if n == 0 {
            return true;
        }
        match self.cycles[0].checked_add(n) {
            Some(target) => self.skip_to(DomainId(0), target),
            None => false,
        }
    }

    /// The rising edges every domain has had once domain `d` has had `cycles` of them, as
    /// stepping without falling edges leaves them (see [`skip_to`](Self::skip_to)); `None`
    /// unless `cycles` is ahead of `d`'s count, or if a count would overflow.
    pub fn cycles_at(&self, d: DomainId, cycles: u64) -> Option<Vec<u64>> {
        self.target(d, cycles)
            .map(|t| t.into_iter().map(|(c, _)| c).collect())
    }

    /// Advances every domain at once to rising edge number `cycles` of domain `d` (counted
    /// from 1), leaving edge counts, half-period indices and time exactly as repeated
    /// [`skip_falling_edges`](Self::skip_falling_edges) then [`next_edge`](Self::next_edge)
    /// leave them once `d` has had `cycles` rising edges. Returns `false`, changing nothing,
    /// unless `cycles` is ahead of `d`'s count (or if a count would overflow).
    ///
    /// That state does not depend on where the clocks were: at the instant `T` of `d`'s
    /// edge every domain has had exactly the rising edges at or before `T`; a domain with
    /// an edge at `T` sits on the falling edge after it, every other domain on its next
    /// rising edge (the step that reached `T` skipped their falling edges first).
    pub fn skip_to(&mut self, d: DomainId, cycles: u64) -> bool {
        let Some(target) = self.target(d, cycles) else {
            return false;
        };
        for (i, (c, at_t)) in target.into_iter().enumerate() {
            self.cycles[i] = c;
            self.set_half(i, 2 * c - at_t as u64);
        }
        self.time_ps = self.half_edge_ps(d.0 as usize, 2 * (cycles - 1));
        true
    }

    /// Per domain, the rising edges up to and including the instant of `d`'s edge
    /// `cycles − 1` (0-based), and whether it has an edge at that very instant.
    fn target(&self, d: DomainId, cycles: u64) -> Option<Vec<(u64, bool)>> {
        let d = d.0 as usize;
        if cycles <= self.cycles[d] || cycles > u64::MAX / 2 {
            return None;
        }
        // Edge r of d is at r / f_d; edge k of domain i is at or before it iff
        // k · f_d <= r · f_i, exactly, in integers.
        let r = (cycles - 1) as u128;
        let fd = self.domains[d].freq_hz as u128;
        self.domains
            .iter()
            .map(|dom| {
                let num = r * dom.freq_hz as u128;
                let c = u64::try_from(num / fd + 1)
                    .ok()
                    .filter(|&c| c <= u64::MAX / 2)?;
                Some((c, num.is_multiple_of(fd)))
            })
            .collect()
    }

    fn cross(&self, i: usize, j: usize) -> (u128, u128) {
        (
            self.next_half[i] as u128 * self.domains[j].freq_hz as u128,
            self.next_half[j] as u128 * self.domains[i].freq_hz as u128,
        )
    }
    fn earlier(&self, i: usize, j: usize) -> bool {
        let (a, b) = self.cross(i, j);
        a < b
    }
    fn simultaneous(&self, i: usize, j: usize) -> bool {
        let (a, b) = self.cross(i, j);
        a == b
    }
}

fn gcd(mut a: u64, mut b: u64) -> u64 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dram_edges_over_a_million_core_cycles_are_exact() {
        let mut clocks = Clocks::new(default_domains()).unwrap();
        let (core, dram) = (DomainId(0), DomainId(1));
        assert_eq!(clocks.ratio(core, dram), (500, 167));
        let n: u64 = 1_000_000;
        while clocks.cycles(core) < n {
            clocks.next_edge();
        }
        // Core edge k is at k/500e6 s; the last core edge is k = n-1. DRAM edges at j/167e6 s
        // with j/167 <= (n-1)/500 number floor((n-1)·167/500) + 1.
        let expected = (n - 1) * 167 / 500 + 1;
        assert_eq!(expected, 334_000);
        assert_eq!(clocks.cycles(dram), expected);
        assert_eq!(clocks.time_ps(), (n - 1) * 2000);
    }

    #[test]
    fn coincident_edges_fire_together_and_time_is_monotonic() {
        // 4:3 ratio: edges coincide every 3 fast / ... cycles.
        let mut clocks =
            Clocks::new(vec![ClockDomain::new("a", 400), ClockDomain::new("b", 300)]).unwrap();
        let first = clocks.next_edge();
        assert!(first.rising.contains(DomainId(0)) && first.rising.contains(DomainId(1)));
        assert_eq!(first.time_ps, 0);
        let mut last = 0;
        let mut both = 0;
        for _ in 0..10_000 {
            let e = clocks.next_edge();
            assert!(e.time_ps >= last);
            last = e.time_ps;
            if e.rising.contains(DomainId(0)) && e.rising.contains(DomainId(1)) {
                both += 1;
            }
        }
        assert!(both > 0);
        // Rising edges per domain stay in the exact 4:3 ratio (within one edge).
        let (a, b) = (clocks.cycles(DomainId(0)), clocks.cycles(DomainId(1)));
        assert!((a * 3).abs_diff(b * 4) <= 4, "{a} {b}");
    }

    #[test]
    fn edge_times_kept_by_addition_equal_the_exact_division() {
        let mut clocks = Clocks::new(vec![
            ClockDomain::mhz("core", 500),
            ClockDomain::mhz("dram", 167),
            ClockDomain::new("odd", 333_333_337),
        ])
        .unwrap();
        for k in 0..200_000 {
            if k % 3 == 0 {
                clocks.skip_falling_edges();
            }
            let e = clocks.next_edge();
            for d in 0..3 {
                assert_eq!(
                    clocks.next_ps[d],
                    clocks.half_edge_ps(d, clocks.next_half[d]),
                    "domain {d} after edge {k}"
                );
            }
            let first = (0..3)
                .filter(|&d| {
                    e.rising.contains(DomainId(d as u8)) || e.falling.contains(DomainId(d as u8))
                })
                .map(|d| clocks.half_edge_ps(d, clocks.next_half[d] - 1))
                .collect::<Vec<_>>();
            assert!(first.iter().all(|&t| t == e.time_ps), "edge {k}");
        }
    }

    #[test]
    fn falling_edges_are_mid_period() {
        let mut clocks = Clocks::new(vec![ClockDomain::mhz("core", 500)]).unwrap();
        let r = clocks.next_edge();
        let f = clocks.next_edge();
        let r2 = clocks.next_edge();
        assert!(!r.rising.is_empty() && r.falling.is_empty());
        assert!(!f.falling.is_empty() && f.rising.is_empty());
        assert_eq!((r.time_ps, f.time_ps, r2.time_ps), (0, 1000, 2000));
    }

    #[test]
    fn skipping_falling_edges_keeps_rising_edges_exact() {
        let mut all = Clocks::new(default_domains()).unwrap();
        let mut rising_only = Clocks::new(default_domains()).unwrap();
        let mut expected = Vec::new();
        while expected.len() < 5000 {
            let e = all.next_edge();
            if !e.rising.is_empty() {
                expected.push((e.time_ps, e.rising));
            }
        }
        for &(t, rising) in &expected {
            rising_only.skip_falling_edges();
            let e = rising_only.next_edge();
            assert_eq!((e.time_ps, e.rising), (t, rising));
            assert!(e.falling.is_empty());
        }
    }

    #[test]
    fn skipping_rising_edges_equals_stepping() {
        for n in [0u64, 1, 2, 7, 2604, 100_003] {
            let mut stepped = Clocks::new(vec![ClockDomain::mhz("dram", 167)]).unwrap();
            // Start mid-run, after a rising edge (the index on a falling edge).
            for _ in 0..3 {
                stepped.skip_falling_edges();
                stepped.next_edge();
            }
            let mut skipped = stepped.clone();
            for _ in 0..n {
                stepped.skip_falling_edges();
                stepped.next_edge();
            }
            assert!(skipped.skip_rising_edges(n));
            assert_eq!(
                (
                    skipped.next_half.clone(),
                    skipped.cycles.clone(),
                    skipped.time_ps
                ),
                (
                    stepped.next_half.clone(),
                    stepped.cycles.clone(),
                    stepped.time_ps
                ),
                "n = {n}"
            );
            // And the next edge after the skip is the same one.
            assert_eq!(skipped.next_edge(), stepped.next_edge());
        }
        let mut two = Clocks::new(default_domains()).unwrap();
        assert!(!two.skip_rising_edges(5));
        assert_eq!(two.cycles(DomainId(0)), 0);
        let mut one = Clocks::new(vec![ClockDomain::mhz("dram", 1)]).unwrap();
        assert!(!one.skip_rising_edges(u64::MAX));
        assert_eq!(one.cycles(DomainId(0)), 0);
    }

    /// Steps as the simulator does without a tracer until domain `d` has `cycles` rising
    /// edges.
    fn step_to(c: &mut Clocks, d: DomainId, cycles: u64) {
        while c.cycles(d) < cycles {
            c.skip_falling_edges();
            c.next_edge();
        }
    }

    #[test]
    fn skipping_to_an_edge_of_one_domain_equals_stepping_every_domain() {
        let sets = [
            default_domains(),
            vec![ClockDomain::new("a", 400), ClockDomain::new("b", 300)],
            vec![
                ClockDomain::mhz("core", 500),
                ClockDomain::mhz("dram", 167),
                ClockDomain::mhz("io", 333),
            ],
            vec![ClockDomain::mhz("slow", 7), ClockDomain::mhz("fast", 1000)],
            vec![ClockDomain::mhz("dram", 167)],
        ];
        let mut checked = 0;
        for domains in sets {
            let n = domains.len();
            for d in (0..n).map(|i| DomainId(i as u8)) {
                // Start points: fresh, after edges of every phase, and after falling edges
                // too (a tracer was attached until then).
                for start in [0usize, 1, 2, 3, 5, 8, 13] {
                    for with_falling in [false, true] {
                        let mut from = Clocks::new(domains.clone()).unwrap();
                        for _ in 0..start {
                            if !with_falling {
                                from.skip_falling_edges();
                            }
                            from.next_edge();
                        }
                        for ahead in [1u64, 2, 3, 7, 167, 500, 1001, 30_011] {
                            let target = from.cycles(d) + ahead;
                            let mut stepped = from.clone();
                            step_to(&mut stepped, d, target);
                            let mut skipped = from.clone();
                            let counts = skipped.cycles_at(d, target).unwrap();
                            assert!(skipped.skip_to(d, target));
                            let state =
                                |c: &Clocks| (c.next_half.clone(), c.cycles.clone(), c.time_ps);
                            assert_eq!(
                                state(&skipped),
                                state(&stepped),
                                "{domains:?} d {d:?} start {start} {with_falling} ahead {ahead}"
                            );
                            assert_eq!(counts, stepped.cycles);
                            // The edges after the skip are the same ones.
                            for _ in 0..2 * n + 3 {
                                skipped.skip_falling_edges();
                                stepped.skip_falling_edges();
                                assert_eq!(skipped.next_edge(), stepped.next_edge());
                            }
                            checked += 1;
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 10 * 7 * 2 * 8);
        // Never backwards or in place, and no overflow.
        let mut c = Clocks::new(default_domains()).unwrap();
        step_to(&mut c, DomainId(0), 10);
        let before = (c.next_half.clone(), c.cycles.clone(), c.time_ps);
        assert!(!c.skip_to(DomainId(0), 10) && !c.skip_to(DomainId(0), 3));
        assert!(!c.skip_to(DomainId(1), u64::MAX) && c.cycles_at(DomainId(0), 9).is_none());
        assert_eq!((c.next_half.clone(), c.cycles.clone(), c.time_ps), before);
    }

    #[test]
    fn impossible_clocks_are_rejected() {
        assert_eq!(Clocks::new(vec![]).unwrap_err(), ClockError::NoDomains);
        let e = Clocks::new(vec![ClockDomain::new("x", 0)]).unwrap_err();
        assert!(e.to_string().contains("`x`"));
        let e = Clocks::new(vec![ClockDomain::new("x", 1), ClockDomain::new("x", 2)]).unwrap_err();
        assert_eq!(e, ClockError::DuplicateName("x".into()));
    }
}
