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

use std::cmp::Ordering;
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

/// Where one domain is in time.
#[derive(Clone, Debug)]
struct DomainTime {
    freq_hz: u64,
    /// The index of its next half-period edge (even: rising, odd: falling).
    next_half: u64,
    /// The time of that edge in picoseconds (rounded down) and the remainder of the
    /// division that gives it, kept by adding one half-period at a time (a 128-bit division
    /// per edge cost more than the rest of the scheduler).
    next_ps: u64,
    next_ps_rem: u64,
    /// `PS_PER_S / 2f` as quotient and remainder.
    half_period_ps: (u64, u64),
    /// The number of rising edges so far.
    cycles: u64,
}

impl DomainTime {
    fn new(freq_hz: u64) -> Self {
        let mut t = DomainTime {
            freq_hz,
            next_half: 0,
            next_ps: 0,
            next_ps_rem: 0,
            half_period_ps: (0, 0),
            cycles: 0,
        };
        t.half_period_ps = t.half_edge(1);
        t
    }

    /// Time of half-period edge `half` in picoseconds, rounded down, and the remainder of
    /// its division.
    fn half_edge(&self, half: u64) -> (u64, u64) {
        let denom = 2 * self.freq_hz as u128;
        let num = half as u128 * PS_PER_S;
        ((num / denom) as u64, (num % denom) as u64)
    }

    /// Sets the next half-period edge to `half`.
    fn set_half(&mut self, half: u64) {
        self.next_half = half;
        (self.next_ps, self.next_ps_rem) = self.half_edge(half);
    }

    /// Moves the next edge on by one half-period: `next_ps` grows by `PS_PER_S / 2f`,
    /// exactly, carrying the remainder.
    #[inline]
    fn step_half(&mut self) {
        let denom = 2 * self.freq_hz;
        let (q, r) = self.half_period_ps;
        self.next_half += 1;
        self.next_ps += q;
        self.next_ps_rem += r;
        if self.next_ps_rem >= denom {
            self.next_ps_rem -= denom;
            self.next_ps += 1;
        }
    }

    /// How this domain's next edge compares in time with `other`'s: `a / 2fa` against
    /// `b / 2fb` as `a·fb` against `b·fa`, exactly.
    #[inline]
    fn compare(&self, other: &DomainTime) -> Ordering {
        // (Edges a picosecond or more apart are ordered by their times rounded down: the
        // earlier rounds down lower. Only within the same picosecond are they multiplied.)
        if self.next_ps != other.next_ps {
            return self.next_ps.cmp(&other.next_ps);
        }
        let a = self.next_half as u128 * other.freq_hz as u128;
        let b = other.next_half as u128 * self.freq_hz as u128;
        a.cmp(&b)
    }
}

/// The edge scheduler for a set of clock domains.
#[derive(Clone, Debug)]
pub struct Clocks {
    domains: Vec<ClockDomain>,
    /// Per domain, in the order of `domains`: where it is in time (apart from the names,
    /// so that stepping touches only these records).
    times: Vec<DomainTime>,
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
        let times = domains.iter().map(|d| DomainTime::new(d.freq_hz)).collect();
        Ok(Clocks {
            domains,
            times,
            time_ps: 0,
        })
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
        self.times[d.0 as usize].cycles
    }

    /// Time of the most recent edge, in picoseconds.
    pub fn time_ps(&self) -> u64 {
        self.time_ps
    }

    /// Advances to the next instant at which any clock has an edge.
    pub fn next_edge(&mut self) -> Edge {
        // One pass finds the earliest edge and every domain with an edge at the same
        // instant, decided before any domain advances.
        let times = &mut self.times[..];
        let mut first = 0;
        let mut fired = 1u64;
        for (i, t) in times.iter().enumerate().skip(1) {
            match t.compare(&times[first]) {
                Ordering::Less => (first, fired) = (i, 1 << i),
                Ordering::Equal => fired |= 1 << i,
                Ordering::Greater => {}
            }
        }
        let mut edge = Edge {
            time_ps: times[first].next_ps,
            rising: DomainSet::default(),
            falling: DomainSet::default(),
        };
        while fired != 0 {
            let i = fired.trailing_zeros() as usize;
            fired &= fired - 1;
            let t = &mut times[i];
            if t.next_half.is_multiple_of(2) {
                edge.rising.insert(DomainId(i as u8));
                t.cycles += 1;
            } else {
                edge.falling.insert(DomainId(i as u8));
            }
            t.step_half();
        }
        self.time_ps = edge.time_ps;
        edge
    }

    /// The next rising edge of a domain in `wanted` (a bit per domain, at least one of
    /// them a domain of these clocks), skipping every falling edge and the rising edges of
    /// the other domains before it: the clocks end exactly as repeating
    /// [`skip_falling_edges`](Self::skip_falling_edges) then [`next_edge`](Self::next_edge)
    /// until an edge has a rising domain in `wanted` leaves them, and the edge is the last
    /// of those. In one pass: the skipped edges of an unwanted domain only count, in any
    /// order.
    #[inline]
    pub fn next_rising_edge(&mut self, wanted: DomainSet) -> Edge {
        // The falling edges skipped as `skip_falling_edges` does, written out here: calling
        // it (inlined) left the whole SPHERE render 1.09× slower in 5 alternating pairs.
        let times = &mut self.times[..];
        for t in times.iter_mut() {
            if t.next_half & 1 == 1 {
                t.step_half();
            }
        }
        // The earliest rising edge of a wanted domain, and the domains that rise with it.
        let mut first = usize::MAX;
        let mut fired = 0u64;
        let mut rest = wanted.0;
        while rest != 0 {
            let i = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            if i >= times.len() {
                break;
            }
            let order = if first == usize::MAX {
                Ordering::Less
            } else {
                times[i].compare(&times[first])
            };
            match order {
                Ordering::Less => (first, fired) = (i, 1 << i),
                Ordering::Equal => fired |= 1 << i,
                Ordering::Greater => {}
            }
        }
        assert!(first != usize::MAX, "no wanted domain among the clocks");
        // Every other domain's rising edges up to that instant: those before it pass (a
        // rising and the skipped falling edge each), one at it fires with it.
        for i in 0..times.len() {
            if wanted.0 >> i & 1 == 1 {
                continue;
            }
            loop {
                match times[i].compare(&times[first]) {
                    Ordering::Less => {
                        let t = &mut times[i];
                        t.cycles += 1;
                        t.step_half();
                        t.step_half();
                    }
                    Ordering::Equal => {
                        fired |= 1 << i;
                        break;
                    }
                    Ordering::Greater => break,
                }
            }
        }
        let edge = Edge {
            time_ps: times[first].next_ps,
            rising: DomainSet(fired),
            falling: DomainSet::default(),
        };
        while fired != 0 {
            let i = fired.trailing_zeros() as usize;
            fired &= fired - 1;
            times[i].cycles += 1;
            times[i].step_half();
        }
        self.time_ps = edge.time_ps;
        edge
    }

    /// Skips every pending falling edge, so the next [`next_edge`](Self::next_edge) is a
    /// rising one. Without a waveform to draw, falling edges change nothing.
    pub fn skip_falling_edges(&mut self) {
        for t in &mut self.times {
            if t.next_half & 1 == 1 {
                t.step_half();
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
        match self.times[0].cycles.checked_add(n) {
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
        for (t, (c, at_t)) in self.times.iter_mut().zip(target) {
            t.cycles = c;
            t.set_half(2 * c - at_t as u64);
        }
        self.time_ps = self.times[d.0 as usize].half_edge(2 * (cycles - 1)).0;
        true
    }

    /// Per domain, the rising edges up to and including the instant of `d`'s edge
    /// `cycles − 1` (0-based), and whether it has an edge at that very instant.
    fn target(&self, d: DomainId, cycles: u64) -> Option<Vec<(u64, bool)>> {
        let d = d.0 as usize;
        if cycles <= self.times[d].cycles || cycles > u64::MAX / 2 {
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

    /// Every domain's half-period index and rising-edge count, and the time.
    fn state(c: &Clocks) -> (Vec<u64>, Vec<u64>, u64) {
        let halves = c.times.iter().map(|t| t.next_half).collect();
        let cycles = c.times.iter().map(|t| t.cycles).collect();
        (halves, cycles, c.time_ps)
    }

    #[test]
    fn edges_are_ordered_as_the_exact_ratio_orders_them() {
        // Pairs whose edges coincide, fall within a picosecond of each other, or neither.
        let pairs = [
            (500_000_000, 167_000_000),
            (500_000_000, 250_000_000),
            (333_333_333, 999_999_999),
            (1_000_000_000_000, 999_999_999_999),
            (3, 7),
        ];
        for (fa, fb) in pairs {
            let (mut a, mut b) = (DomainTime::new(fa), DomainTime::new(fb));
            for step in 0..200_000u64 {
                let exact = (u128::from(a.next_half) * u128::from(fb))
                    .cmp(&(u128::from(b.next_half) * u128::from(fa)));
                assert_eq!(a.compare(&b), exact, "{fa} Hz against {fb} Hz, step {step}");
                assert_eq!(b.compare(&a), exact.reverse());
                if step % 3 == 0 {
                    a.step_half();
                } else {
                    b.step_half();
                }
            }
        }
    }

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
    fn a_wanted_rising_edge_in_one_pass_is_the_edge_stepping_would_reach() {
        let sets: [&[u64]; 4] = [
            &[500_000_000, 167_000_000],
            &[400, 300],
            &[500_000_000, 167_000_000, 133_000_000],
            &[7, 3, 7, 20],
        ];
        for freqs in sets {
            let domains: Vec<ClockDomain> = freqs
                .iter()
                .enumerate()
                .map(|(i, &f)| ClockDomain::new(&format!("d{i}"), f))
                .collect();
            let all = (1u64 << freqs.len()) - 1;
            for wanted in 1..=all {
                let (mut fast, mut stepped) = (
                    Clocks::new(domains.clone()).unwrap(),
                    Clocks::new(domains.clone()).unwrap(),
                );
                for k in 0..3_000 {
                    // Now and then a falling edge is left pending, as a tracer's run leaves it.
                    if k % 97 == 5 {
                        fast.next_edge();
                        stepped.next_edge();
                    }
                    // Bits past the last domain are ignored, as the simulator's mask has them.
                    let edge = fast.next_rising_edge(DomainSet(wanted | !all));
                    let expected = loop {
                        stepped.skip_falling_edges();
                        let e = stepped.next_edge();
                        if e.rising.0 & wanted != 0 {
                            break e;
                        }
                    };
                    assert_eq!(edge, expected, "{freqs:?}, wanted {wanted:#b}, edge {k}");
                    assert_eq!(state(&fast), state(&stepped), "{freqs:?}, edge {k}");
                }
            }
        }
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
                let t = &clocks.times[d];
                assert_eq!(
                    t.next_ps,
                    t.half_edge(t.next_half).0,
                    "domain {d} after edge {k}"
                );
            }
            let first = (0..3)
                .filter(|&d| {
                    e.rising.contains(DomainId(d as u8)) || e.falling.contains(DomainId(d as u8))
                })
                .map(|d| {
                    let t = &clocks.times[d];
                    t.half_edge(t.next_half - 1).0
                })
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
            assert_eq!(state(&skipped), state(&stepped), "n = {n}");
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
                            assert_eq!(
                                state(&skipped),
                                state(&stepped),
                                "{domains:?} d {d:?} start {start} {with_falling} ahead {ahead}"
                            );
                            assert_eq!(counts, state(&stepped).1);
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
        let before = state(&c);
        assert!(!c.skip_to(DomainId(0), 10) && !c.skip_to(DomainId(0), 3));
        assert!(!c.skip_to(DomainId(1), u64::MAX) && c.cycles_at(DomainId(0), 9).is_none());
        assert_eq!(state(&c), before);
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
