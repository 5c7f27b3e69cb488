//! Scope filters: which signals a waveform holds (`--vcd-scope GLOB`, repeatable).

use glob::{MatchOptions, Pattern};
use imagine_hdl::{ProbeRegistry, SignalId, SignalKind};

/// A set of glob patterns over dot-separated signal paths.
///
/// **Matching rule.** A signal is selected when any pattern matches its full path *or* one of
/// its enclosing scopes, i.e. any dot-boundary prefix of the path. For
/// `top.mac.s2.pp_lo` the candidates are `top`, `top.mac`, `top.mac.s2` and
/// `top.mac.s2.pp_lo`. Consequently:
///
/// * `top.mac` and `top.mac.*` both select everything under `top.mac` (but not `top.macro`);
/// * `*.s2.*` selects the stage-2 signals of any module, `*.valid` every `valid` signal;
/// * `top.mac.s?` selects stages `s1`…`s9`, `top.sink.[cl]*` sink signals beginning c or l.
///
/// Patterns use [`glob::Pattern`] syntax: `*` matches any run of characters **including
/// dots** (so `top.*` is everything under `top`), `?` one character, `[…]`/`[!…]` a class;
/// `**` is accepted and means the same as `*`. Matching is case-sensitive. Clock signals
/// ([`SignalKind::Clock`]) are always selected, so every dump has its time reference.
/// An empty filter (no patterns) selects every signal.
#[derive(Clone, Debug, Default)]
pub struct ScopeFilter {
    patterns: Vec<(String, Pattern)>,
}

const OPTIONS: MatchOptions = MatchOptions {
    case_sensitive: true,
    require_literal_separator: false,
    require_literal_leading_dot: false,
};

impl ScopeFilter {
    /// Compiles the patterns; an invalid glob is an error naming it.
    pub fn new<S: AsRef<str>>(patterns: &[S]) -> Result<Self, String> {
        let patterns = patterns
            .iter()
            .map(|p| {
                let p = p.as_ref();
                let src = p.trim();
                if src.is_empty() {
                    return Err("empty --vcd-scope pattern".to_string());
                }
                // glob's `**` is a path-component wildcard; over dotted names `*` already
                // crosses levels, so `**` is simply a `*`.
                let mut g = src.to_string();
                while g.contains("**") {
                    g = g.replace("**", "*");
                }
                Pattern::new(&g)
                    .map(|c| (src.to_string(), c))
                    .map_err(|e| format!("--vcd-scope pattern `{src}` is not a valid glob: {e}"))
            })
            .collect::<Result<_, _>>()?;
        Ok(ScopeFilter { patterns })
    }

    /// The patterns as given.
    pub fn patterns(&self) -> impl Iterator<Item = &str> {
        self.patterns.iter().map(|(s, _)| s.as_str())
    }

    /// Whether there are no patterns (everything is selected).
    pub fn is_empty(&self) -> bool {
        self.patterns.is_empty()
    }

    /// Whether pattern `p` matches `path` or one of its enclosing scopes.
    fn pattern_matches(p: &Pattern, path: &str) -> bool {
        path.match_indices('.')
            .map(|(i, _)| &path[..i])
            .chain(std::iter::once(path))
            .any(|candidate| p.matches_with(candidate, OPTIONS))
    }

    /// Whether a signal at `path` (not a clock) is selected.
    pub fn matches_path(&self, path: &str) -> bool {
        self.is_empty()
            || self
                .patterns
                .iter()
                .any(|(_, p)| Self::pattern_matches(p, path))
    }

    /// Whether a signal of `kind` at `path` is selected (clocks always are).
    pub fn matches(&self, path: &str, kind: SignalKind) -> bool {
        kind == SignalKind::Clock || self.matches_path(path)
    }

    /// The selected signals of `probes`, in registration order.
    pub fn select(&self, probes: &ProbeRegistry) -> Vec<SignalId> {
        probes
            .signals()
            .iter()
            .enumerate()
            .filter(|(_, s)| self.matches(&s.path, s.kind))
            .map(|(i, _)| SignalId(i as u32))
            .collect()
    }

    /// The patterns that select no signal of `probes` other than the clocks (which are in
    /// every dump anyway): almost always a typo, worth an error or a warning.
    pub fn unmatched(&self, probes: &ProbeRegistry) -> Vec<String> {
        self.patterns
            .iter()
            .filter(|(_, p)| {
                !probes
                    .signals()
                    .iter()
                    .any(|s| s.kind != SignalKind::Clock && Self::pattern_matches(p, &s.path))
            })
            .map(|(s, _)| s.clone())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn registry() -> ProbeRegistry {
        let mut r = ProbeRegistry::new();
        for (p, k) in [
            ("top.clk_core", SignalKind::Clock),
            ("top.mac.s1.a", SignalKind::Reg),
            ("top.mac.s2.pp_lo", SignalKind::Reg),
            ("top.mac.stalled", SignalKind::Reg),
            ("top.macro.x", SignalKind::Reg),
            ("top.alu.s2.sum", SignalKind::Wire),
            ("top.results.valid", SignalKind::Wire),
        ] {
            r.register(p.into(), 4, k);
        }
        r
    }

    fn names(f: &ScopeFilter, r: &ProbeRegistry) -> Vec<String> {
        f.select(r)
            .into_iter()
            .map(|i| r.get(i).path.clone())
            .collect()
    }

    #[test]
    fn scope_prefixes_and_globs() {
        let r = registry();
        let mac = [
            "top.clk_core",
            "top.mac.s1.a",
            "top.mac.s2.pp_lo",
            "top.mac.stalled",
        ];
        for p in ["top.mac", "top.mac.*", "top.mac.**"] {
            assert_eq!(names(&ScopeFilter::new(&[p]).unwrap(), &r), mac, "{p}");
        }
        // Without the dot, `*` also takes in `top.macro`.
        let star = ScopeFilter::new(&["top.mac**"]).unwrap();
        assert_eq!(
            names(&star, &r)[1..],
            [
                "top.mac.s1.a",
                "top.mac.s2.pp_lo",
                "top.mac.stalled",
                "top.macro.x"
            ]
        );
        let s2 = ScopeFilter::new(&["*.s2.*"]).unwrap();
        assert_eq!(
            names(&s2, &r),
            ["top.clk_core", "top.mac.s2.pp_lo", "top.alu.s2.sum"]
        );
        let two = ScopeFilter::new(&["top.macro", "*.valid"]).unwrap();
        assert_eq!(
            names(&two, &r),
            ["top.clk_core", "top.macro.x", "top.results.valid"]
        );
        assert_eq!(names(&ScopeFilter::default(), &r).len(), r.len());
        assert_eq!(
            names(&ScopeFilter::new(&["top"]).unwrap(), &r).len(),
            r.len()
        );
        // A pattern must match a whole scope name, not a prefix of one.
        assert!(
            !ScopeFilter::new(&["top.ma"])
                .unwrap()
                .matches_path("top.mac.s1.a")
        );
    }

    #[test]
    fn unmatched_patterns_are_reported() {
        let r = registry();
        let f = ScopeFilter::new(&["top.mac", "top.nothing", "*.clk_core", "TOP.MAC"]).unwrap();
        assert_eq!(f.unmatched(&r), ["top.nothing", "*.clk_core", "TOP.MAC"]);
        let e = ScopeFilter::new(&["top.[mac"]).unwrap_err();
        assert!(e.contains("top.[mac"), "{e}");
        assert!(ScopeFilter::new(&[" "]).is_err());
    }
}
