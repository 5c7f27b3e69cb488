//! DRAM request traces in DRAMsim3's text format, and the microbenchmarks of Rixner et al.
//! (ISCA 2000, §5.1) as trace generators.
//!
//! One request per line: `<hex byte address> READ|WRITE <DRAM cycle>`, e.g.
//! `0x1f40 READ 12`, with cycles that never decrease. Blank lines and lines starting with
//! `#` are skipped. The address may be written with or without `0x`; the command is case
//! insensitive. [`write_trace`] writes the same format, so a trace recorded by a run of
//! this model replays in DRAMsim3 and back.

use std::fmt;
use std::io::{self, Write};

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

/// Parses a trace; every address must lie inside the memory `p` describes.
pub fn parse_trace(text: &str, p: &DramParams) -> Result<Vec<TraceRequest>, TraceError> {
    let mut out = Vec::new();
    let mut last = 0u64;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let err = |message: String| TraceError { line, message };
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = l.split_whitespace().collect();
        if fields.len() != 3 {
            return Err(err(format!(
                "`{l}`: expected `<hex address> READ|WRITE <cycle>` (3 fields), found {}",
                fields.len()
            )));
        }
        let hex = fields[0]
            .strip_prefix("0x")
            .or_else(|| fields[0].strip_prefix("0X"))
            .unwrap_or(fields[0]);
        let byte_addr = u64::from_str_radix(hex, 16)
            .map_err(|_| err(format!("`{}` is not a hexadecimal address", fields[0])))?;
        let kind = match fields[1].to_ascii_uppercase().as_str() {
            "READ" => TraceKind::Read,
            "WRITE" => TraceKind::Write,
            other => {
                return Err(err(format!(
                    "`{other}` is not a request type (READ or WRITE)"
                )));
            }
        };
        let cycle: u64 = fields[2]
            .parse()
            .map_err(|_| err(format!("`{}` is not a cycle number", fields[2])))?;
        if cycle < last {
            return Err(err(format!(
                "cycle {cycle} is before the previous request's cycle {last} (cycles must not decrease)"
            )));
        }
        if byte_addr >= p.capacity_bytes() {
            return Err(err(format!(
                "address {:#x} is out of range: the memory has {} bytes (up to {:#x})",
                byte_addr,
                p.capacity_bytes(),
                p.capacity_bytes() - 1
            )));
        }
        last = cycle;
        out.push(TraceRequest {
            byte_addr,
            kind,
            cycle,
        });
    }
    Ok(out)
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
