//! Cycle windows: which core-clock cycles a waveform covers (`--vcd-window FROM:TO`).

use std::fmt;

/// A range of core-clock cycles, `from` inclusive and `to` exclusive.
///
/// Core cycle `c` is everything from the rising core-clock edge that starts it up to (not
/// including) the next rising core edge: its falling edge and any edge of another domain in
/// between belong to cycle `c`. A window `FROM:TO` therefore dumps cycles
/// `FROM, FROM+1, …, TO-1`, starting at the time of the rising edge of cycle `FROM` and
/// ending at the time of the rising edge of cycle `TO`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct CycleWindow {
    /// First core cycle written (inclusive).
    pub from: u64,
    /// First core cycle no longer written (exclusive); `None` means to the end of the run.
    pub to: Option<u64>,
}

impl CycleWindow {
    /// The whole run.
    pub const ALL: CycleWindow = CycleWindow { from: 0, to: None };

    /// Cycles `from..to`; `None` if the window would be empty (`to <= from`).
    pub fn new(from: u64, to: Option<u64>) -> Option<Self> {
        match to {
            Some(t) if t <= from => None,
            _ => Some(CycleWindow { from, to }),
        }
    }

    /// Whether core cycle `c` is inside the window.
    pub fn contains(&self, c: u64) -> bool {
        c >= self.from && self.to.is_none_or(|t| c < t)
    }

    /// Whether the window is the whole run.
    pub fn is_all(&self) -> bool {
        *self == Self::ALL
    }
}

impl fmt::Display for CycleWindow {
    /// The `FROM:TO` form that [`parse_window`] reads (`FROM:` when open-ended).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.to {
            Some(t) => write!(f, "{}:{t}", self.from),
            None => write!(f, "{}:", self.from),
        }
    }
}

impl std::str::FromStr for CycleWindow {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        parse_window(s)
    }
}

/// Parses a cycle window `FROM:TO` (core cycles, `FROM` inclusive, `TO` exclusive).
///
/// * `FROM:` runs to the end of the simulation; `:TO` starts at cycle 0;
/// * numbers are decimal and may use `_` as a digit separator (`1_000_000:1_000_100`);
/// * an empty window (`TO <= FROM`), a missing colon, a negative or non-numeric bound is an
///   error whose message names the problem.
pub fn parse_window(s: &str) -> Result<CycleWindow, String> {
    let Some((from, to)) = s.trim().split_once(':') else {
        return Err(format!(
            "cycle window `{s}`: expected FROM:TO (core cycles, FROM inclusive, TO exclusive) or FROM:"
        ));
    };
    let from = match from.trim() {
        "" => 0,
        f => parse_cycle(s, "FROM", f)?,
    };
    let to = match to.trim() {
        "" => None,
        t => Some(parse_cycle(s, "TO", t)?),
    };
    CycleWindow::new(from, to).ok_or_else(|| {
        format!(
            "cycle window `{s}` is empty: TO ({}) must be greater than FROM ({from}); TO is exclusive",
            to.unwrap_or_default()
        )
    })
}

fn parse_cycle(whole: &str, which: &str, v: &str) -> Result<u64, String> {
    let digits: String = v.chars().filter(|&c| c != '_').collect();
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) || v.starts_with('_') {
        return Err(format!(
            "cycle window `{whole}`: {which} `{v}` is not a cycle number (a non-negative decimal integer)"
        ));
    }
    digits
        .parse()
        .map_err(|_| format!("cycle window `{whole}`: {which} `{v}` is too large"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forms_that_parse() {
        assert_eq!(
            parse_window("10:20"),
            Ok(CycleWindow::new(10, Some(20)).unwrap())
        );
        assert_eq!(
            parse_window(" 10 : 20 "),
            Ok(CycleWindow::new(10, Some(20)).unwrap())
        );
        assert_eq!(parse_window("5:"), Ok(CycleWindow { from: 5, to: None }));
        assert_eq!(
            parse_window(":7"),
            Ok(CycleWindow {
                from: 0,
                to: Some(7)
            })
        );
        assert_eq!(parse_window(":"), Ok(CycleWindow::ALL));
        assert_eq!(
            parse_window("1_000:2_000"),
            Ok(CycleWindow {
                from: 1000,
                to: Some(2000)
            })
        );
        assert_eq!(parse_window("0:1").unwrap().to_string(), "0:1");
        assert_eq!(parse_window("3:").unwrap().to_string(), "3:");
    }

    #[test]
    fn bad_windows_are_explained() {
        let e = parse_window("20:10").unwrap_err();
        assert!(e.contains("empty") && e.contains("exclusive"), "{e}");
        assert!(parse_window("10:10").unwrap_err().contains("empty"));
        let e = parse_window("100").unwrap_err();
        assert!(e.contains("FROM:TO"), "{e}");
        let e = parse_window("a:10").unwrap_err();
        assert!(e.contains("FROM `a`"), "{e}");
        let e = parse_window("1:-5").unwrap_err();
        assert!(e.contains("TO `-5`"), "{e}");
        assert!(parse_window("1:2:3").unwrap_err().contains("TO"));
        assert!(parse_window("1:0x10").is_err());
        assert!(parse_window("_:1").is_err());
        assert!(
            parse_window("1:99999999999999999999999")
                .unwrap_err()
                .contains("too large")
        );
    }

    #[test]
    fn membership() {
        let w = parse_window("10:12").unwrap();
        assert!(!w.contains(9) && w.contains(10) && w.contains(11) && !w.contains(12));
        assert!(parse_window("10:").unwrap().contains(u64::MAX));
        assert!(CycleWindow::ALL.is_all() && CycleWindow::default().is_all());
    }
}
