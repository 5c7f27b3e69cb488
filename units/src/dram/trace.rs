//! DRAM request traces in DRAMsim3's text format, and the microbenchmarks of Rixner et al.
//! (ISCA 2000, §5.1) as trace generators.
//!
//! One request per line: `<hex byte address> READ|WRITE <DRAM cycle>`, e.g.
//! `0x1f40 READ 12`, with cycles that never decrease. Blank lines and lines starting with
//! `#` are skipped. The address may be written with or without `0x`; the command is case
//! insensitive. Limits (checked as the trace is read, naming the line): at most
//! [`MAX_TRACE_REQUESTS`] requests, cycles up to [`MAX_TRACE_CYCLE`], lines up to
//! [`MAX_TRACE_LINE`] bytes of UTF-8 text, addresses inside the memory, and at least one
//! request. [`write_trace`] writes the same format, so a trace recorded by a run of
//! this model replays in DRAMsim3 and back.

use std::fmt;
use std::io::{self, BufRead, Read, Write};

use super::DramParams;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TraceKind {
    Read,
    Write,
}

/// One request of a trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TraceRequest {
    pub byte_addr: u64,
    pub kind: TraceKind,
    /// The DRAM cycle at which the request is presented to the memory system.
    pub cycle: u64,
}

/// A trace that cannot be used, naming the line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TraceError {
    /// 1-based line number (0: not about one line).
    pub line: usize,
    pub message: String,
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line > 0 {
            write!(f, "line {}: {}", self.line, self.message)
        } else {
            f.write_str(&self.message)
        }
    }
}

impl std::error::Error for TraceError {}

pub use crate::limits::{MAX_TRACE_CYCLE, MAX_TRACE_LINE, MAX_TRACE_REQUESTS};

/// Parses a trace; every address must lie inside the memory `p` describes.
pub fn parse_trace(text: &str, p: &DramParams) -> Result<Vec<TraceRequest>, TraceError> {
    read_trace(text.as_bytes(), p)
}

/// Reads and parses a trace line by line (see [`parse_trace`]), within the limits above:
/// a line that is not UTF-8 text, too long, or malformed is an error naming it, and so is
/// a trace with no requests at all (an empty file is a mistake, not a measurement).
pub fn read_trace(r: impl BufRead, p: &DramParams) -> Result<Vec<TraceRequest>, TraceError> {
    read_at_most(r, p, MAX_TRACE_REQUESTS)
}

/// [`read_trace`] with another request limit (tests use a small one).
fn read_at_most(
    mut r: impl BufRead,
    p: &DramParams,
    max: usize,
) -> Result<Vec<TraceRequest>, TraceError> {
    let mut out = Vec::new();
    let mut last = 0u64;
    let mut buf = Vec::new();
    for line in 1.. {
        let err = |message: String| TraceError { line, message };
        buf.clear();
        (&mut r)
            .take(MAX_TRACE_LINE as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| err(format!("cannot read: {e}")))?;
        if buf.is_empty() {
            break;
        }
        if buf.last() == Some(&b'\n') {
            buf.pop();
        } else if buf.len() > MAX_TRACE_LINE {
            return Err(err(format!(
                "longer than {MAX_TRACE_LINE} bytes (is this a trace?)"
            )));
        }
        let Ok(text) = std::str::from_utf8(&buf) else {
            return Err(err(
                "not UTF-8 text (a binary file?): expected `<hex address> READ|WRITE <cycle>`"
                    .into(),
            ));
        };
        let Some(req) = parse_line(text, p, last).map_err(err)? else {
            continue;
        };
        if out.len() == max {
            return Err(err(format!(
                "more than {max} requests, the most a trace may hold"
            )));
        }
        last = req.cycle;
        out.push(req);
    }
    if out.is_empty() {
        return Err(TraceError {
            line: 0,
            message: "no requests: the trace is empty or holds only blank lines and comments"
                .into(),
        });
    }
    Ok(out)
}

/// A field or line as a message shows it: control characters escaped, long ones cut.
fn shown(s: &str) -> String {
    const MAX: usize = 40;
    let mut out: String = s.chars().take(MAX).flat_map(char::escape_debug).collect();
    if s.chars().nth(MAX).is_some() {
        out.push('…');
    }
    out
}

/// One line: `None` for a blank line or a comment. `last` is the previous request's cycle.
fn parse_line(raw: &str, p: &DramParams, last: u64) -> Result<Option<TraceRequest>, String> {
    let l = raw.trim();
    if l.is_empty() || l.starts_with('#') {
        return Ok(None);
    }
    let fields: Vec<&str> = l.split_whitespace().collect();
    if fields.len() != 3 {
        return Err(format!(
            "`{}`: expected `<hex address> READ|WRITE <cycle>` (3 fields), found {}",
            shown(l),
            fields.len()
        ));
    }
    let hex = fields[0]
        .strip_prefix("0x")
        .or_else(|| fields[0].strip_prefix("0X"))
        .unwrap_or(fields[0]);
    let out_of_range = || {
        format!(
            "address {} is out of range: the memory has {} bytes (up to {:#x})",
            shown(fields[0]),
            p.capacity_bytes(),
            p.capacity_bytes() - 1
        )
    };
    // Digits only: `from_str_radix` would also take a sign.
    if hex.is_empty() || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!(
            "`{}` is not a hexadecimal address",
            shown(fields[0])
        ));
    }
    let byte_addr = u64::from_str_radix(hex, 16).map_err(|_| out_of_range())?;
    if byte_addr >= p.capacity_bytes() {
        return Err(out_of_range());
    }
    let kind = match fields[1].to_ascii_uppercase().as_str() {
        "READ" => TraceKind::Read,
        "WRITE" => TraceKind::Write,
        _ => {
            return Err(format!(
                "`{}` is not a request type (READ or WRITE)",
                shown(fields[1])
            ));
        }
    };
    let c = fields[2];
    if c.is_empty() || !c.bytes().all(|b| b.is_ascii_digit()) {
        let why = if c.starts_with('-') {
            ": cycles are not negative"
        } else {
            ""
        };
        return Err(format!("`{}` is not a cycle number{why}", shown(c)));
    }
    let cycle = c
        .parse::<u64>()
        .ok()
        .filter(|&v| v <= MAX_TRACE_CYCLE)
        .ok_or_else(|| {
            format!(
                "cycle {} is past the latest a trace may name, {MAX_TRACE_CYCLE} (2^44)",
                shown(c)
            )
        })?;
    if cycle < last {
        return Err(format!(
            "cycle {cycle} is before the previous request's cycle {last} (cycles must not decrease)"
        ));
    }
    Ok(Some(TraceRequest {
        byte_addr,
        kind,
        cycle,
    }))
}

/// Writes requests in the DRAMsim3 text format.
pub fn write_trace(w: &mut dyn Write, reqs: &[TraceRequest]) -> io::Result<()> {
    for r in reqs {
        let op = match r.kind {
            TraceKind::Read => "READ",
            TraceKind::Write => "WRITE",
        };
        writeln!(w, "{:#x} {op} {}", r.byte_addr, r.cycle)?;
    }
    Ok(())
}

/// The microbenchmarks (after Rixner et al. ISCA 2000, Table 3).
pub const BENCHES: [(&str, &str); 6] = [
    (
        "unit-load",
        "unit-stride reads of consecutive words, all presented at cycle 0",
    ),
    (
        "unit",
        "a unit-stride read stream and a unit-stride write stream to other banks, interleaved",
    ),
    (
        "unit-conflict",
        "a unit-stride read stream and a write stream to other rows of the same banks, interleaved",
    ),
    (
        "constrained-random",
        "random reads (2/3) and writes (1/3) within two rows of every bank",
    ),
    (
        "random",
        "random reads (2/3) and writes (1/3) anywhere in memory, all presented at cycle 0",
    ),
    (
        "random-reads",
        "random reads anywhere in memory, one presented per cycle (a moderate load)",
    ),
];

/// A small deterministic generator (64-bit LCG, high bits).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 16
    }
}

/// The `n` requests of microbenchmark `name` on memory `p`, or `None` for an unknown name.
pub fn bench(name: &str, n: usize, p: &DramParams) -> Option<Vec<TraceRequest>> {
    let word = 4u64;
    // Bytes from one row of a bank to the next row of the same bank, and to the same row
    // of the next bank (see the address mapping in the module `dram`).
    let bank_stride = (p.columns * p.channels) as u64 * word;
    let row_stride = bank_stride * p.banks as u64;
    let cap = p.capacity_bytes();
    let mut rng = Lcg(0x1234_5678_9ABC_DEF0 ^ n as u64);
    let read = |a: u64, c: u64| TraceRequest {
        byte_addr: a % cap,
        kind: TraceKind::Read,
        cycle: c,
    };
    let write = |a: u64, c: u64| TraceRequest {
        byte_addr: a % cap,
        kind: TraceKind::Write,
        cycle: c,
    };
    let reqs = match name {
        "unit-load" => (0..n as u64).map(|i| read(i * word, 0)).collect(),
        "unit" | "unit-conflict" => {
            let other = if name == "unit" {
                // Two banks over: the streams never share a bank at the same time.
                2 * bank_stride + 16 * row_stride
            } else {
                // The same bank, another row.
                16 * row_stride
            };
            (0..n as u64)
                .map(|i| {
                    let k = i / 2;
                    if i % 2 == 0 {
                        read(k * word, 0)
                    } else {
                        write(other + k * word, 0)
                    }
                })
                .collect()
        }
        "constrained-random" | "random" => {
            let range = if name == "random" {
                cap
            } else {
                2 * row_stride
            };
            (0..n)
                .map(|_| {
                    let a = (rng.next() % (range / word)) * word;
                    if rng.next() % 3 == 2 {
                        write(a, 0)
                    } else {
                        read(a, 0)
                    }
                })
                .collect()
        }
        "random-reads" => (0..n as u64)
            .map(|i| read((rng.next() % (cap / word)) * word, i))
            .collect(),
        _ => return None,
    };
    Some(reqs)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::desc::MachineDesc;

    #[test]
    fn a_trace_past_the_request_limit_is_refused_at_the_first_request_too_many() {
        let p = DramParams::of(&MachineDesc::gold8());
        let text = "# three requests\n0x0 READ 0\n\n0x4 READ 1\n0x8 WRITE 1\n";
        assert_eq!(read_at_most(text.as_bytes(), &p, 3).unwrap().len(), 3);
        let e = read_at_most(text.as_bytes(), &p, 2).unwrap_err();
        assert_eq!(e.line, 5);
        assert!(e.message.contains("more than 2 requests"), "{e}");
    }

    #[test]
    fn limits_and_garbage_are_errors_naming_the_line() {
        let p = DramParams::of(&MachineDesc::gold8());
        let max = MAX_TRACE_CYCLE.to_string();
        let past = (MAX_TRACE_CYCLE + 1).to_string();
        let ok = format!("0x0 READ {max}\n");
        assert_eq!(parse_trace(&ok, &p).unwrap()[0].cycle, MAX_TRACE_CYCLE);
        let long = format!("# {}\n", "x".repeat(MAX_TRACE_LINE));
        for (bad, line, what) in [
            (
                format!("0x0 READ 1\n0x4 READ {past}\n"),
                2,
                "past the latest",
            ),
            (
                "0x0 READ 99999999999999999999999\n".into(),
                1,
                "past the latest",
            ),
            ("0x0 READ -1\n".into(), 1, "not negative"),
            ("0x0 READ +1\n".into(), 1, "not a cycle number"),
            ("0x0 READ 1e3\n".into(), 1, "not a cycle number"),
            ("+1f READ 1\n".into(), 1, "hexadecimal"),
            ("0x READ 1\n".into(), 1, "hexadecimal"),
            ("0x10000000000000000 READ 1\n".into(), 1, "out of range"),
            ("0x0 READ 1 2\n".into(), 1, "3 fields"),
            ("0x0 read 1\n0x0 LOAD 1\n".into(), 2, "READ or WRITE"),
            (long, 1, "longer than 4096 bytes"),
            ("\0\u{1}\n".into(), 1, "`\\0\\u{1}`"),
        ] {
            let e = parse_trace(&bad, &p).unwrap_err();
            assert_eq!(e.line, line, "{bad:?}: {e}");
            assert!(e.to_string().contains(what), "{bad:?}: {e}");
        }
        let e = read_trace(&b"0x0 READ 1\n0x4 \xff\xfe 2\n"[..], &p).unwrap_err();
        assert_eq!(e.line, 2);
        assert!(e.message.contains("not UTF-8"), "{e}");
        // A line of exactly the longest length is fine.
        let edge = format!("#{}\n0x0 READ 0\n", "x".repeat(MAX_TRACE_LINE - 1));
        assert_eq!(parse_trace(&edge, &p).unwrap().len(), 1);
        for empty in ["", "\n\n", "# nothing\n"] {
            let e = parse_trace(empty, &p).unwrap_err();
            assert!(e.message.contains("no requests"), "{empty:?}: {e}");
        }
    }
}
