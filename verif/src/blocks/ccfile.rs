//! Testbench of the condition-code file (`units::ccfile`): the machine's codes, one bit per
//! cluster each, written by compares under a cluster mask and read by `select`, conditional
//! streams and loop tests.
//!
//! Reference: a table of bits per code and cluster; a write sets bit 0 of each selected
//! cluster's word at the edge (other bits of the word do not matter); a read, and the
//! "set in every cluster" test of a condition loop, see the table as of the last edge. One
//! write per code per cycle; a second write of the same code, or a code outside the file,
//! must be refused without changing anything.

use imagine_units::ccfile::CcFile;
use imagine_units::desc::MachineDesc;

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "read",
    "write to every cluster",
    "masked write",
    "write masked off everywhere",
    "word with bit 0 clear and other bits set",
    "several codes written in one cycle",
    "read of a code written this cycle (old value)",
    "read of the code written last cycle",
    "set in every cluster",
    "clear in exactly one cluster",
    "first code",
    "last code",
    "second write of a code refused",
    "code outside the file refused",
];

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let codes = desc.cluster.condition_codes;
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let bins: Vec<&str> = BINS
        .iter()
        .copied()
        .filter(|b| lanes > 1 || *b != "masked write")
        .collect();
    let mut cov = Coverage::new(&bins);
    let mut d = design();
    let mut cc = CcFile::new(&mut d.scope().child("cc"), codes, lanes);
    let mut table = vec![vec![false; lanes]; codes];
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut written_last: Vec<usize> = Vec::new();
    let mut cycle = 0u64;
    while sb.transactions < config.transactions {
        let pick = |rng: &mut Rng, recent: &[usize]| match rng.below(6) {
            0 => 0,
            1 => codes - 1,
            2 if !recent.is_empty() => recent[rng.index(recent.len())],
            _ => rng.index(codes),
        };
        // Writes: up to three codes this cycle.
        let mut pending: Vec<(usize, Vec<bool>)> = Vec::new();
        for _ in 0..rng.below(4) {
            let code = pick(&mut rng, &written_last);
            if pending.iter().any(|(c, _)| *c == code) {
                continue;
            }
            sb.transaction();
            let values: Vec<u32> = (0..lanes)
                .map(|_| match rng.below(4) {
                    0 => 0xFFFF_FFFE,
                    1 => 1,
                    2 => 0,
                    _ => rng.word(),
                })
                .collect();
            let mask = if rng.chance(50) {
                vec![true; lanes]
            } else {
                rng.mask(lanes)
            };
            let ok = cc
                .write(code as u16, &values, &mask)
                .map_err(|e| e.to_string());
            sb.check(cycle, || format!("write of code {code}"), Ok(()), ok);
            let mut row = table[code].clone();
            for c in 0..lanes {
                if mask[c] {
                    row[c] = values[c] & 1 != 0;
                }
            }
            cov.hit_if(mask.iter().all(|&m| m), "write to every cluster");
            cov.hit_if(
                mask.iter().any(|&m| m) && !mask.iter().all(|&m| m),
                "masked write",
            );
            cov.hit_if(mask.iter().all(|&m| !m), "write masked off everywhere");
            cov.hit_if(
                values
                    .iter()
                    .zip(&mask)
                    .any(|(&v, &m)| m && v & 1 == 0 && v != 0),
                "word with bit 0 clear and other bits set",
            );
            pending.push((code, row));
        }
        cov.hit_if(pending.len() > 1, "several codes written in one cycle");
        // The write port's contracts.
        if rng.chance(10) {
            sb.transaction();
            let (code, what) = match pending.first() {
                Some((c, _)) if rng.chance(50) => (*c, "second write of a code refused"),
                _ => (codes + rng.index(4), "code outside the file refused"),
            };
            let refused = cc
                .write(code as u16, &vec![1; lanes], &vec![true; lanes])
                .is_err();
            sb.check(
                cycle,
                || format!("write of code {code}: {what}"),
                true,
                refused,
            );
            cov.hit(what);
            let refused = cc.read(code as u16).is_err();
            if code >= codes {
                sb.check(
                    cycle,
                    || format!("read of code {code} refused"),
                    true,
                    refused,
                );
            }
        }
        // Reads: they see the table as of the last edge.
        for _ in 0..1 + rng.below(3) {
            sb.transaction();
            let code = pick(&mut rng, &written_last);
            let got = cc
                .read(code as u16)
                .map(<[bool]>::to_vec)
                .map_err(|e| e.to_string());
            sb.check(
                cycle,
                || format!("read of code {code}"),
                Ok(table[code].clone()),
                got,
            );
            let every = table[code].iter().all(|&b| b);
            let all = cc.all(code as u16).map_err(|e| e.to_string());
            sb.check(
                cycle,
                || format!("code {code} set in every cluster"),
                Ok(every),
                all,
            );
            cov.hit("read");
            cov.hit_if(every, "set in every cluster");
            cov.hit_if(
                table[code].iter().filter(|&&b| !b).count() == 1,
                "clear in exactly one cluster",
            );
            cov.hit_if(code == 0, "first code");
            cov.hit_if(code == codes - 1, "last code");
            cov.hit_if(
                pending.iter().any(|(c, _)| *c == code),
                "read of a code written this cycle (old value)",
            );
            cov.hit_if(
                written_last.contains(&code),
                "read of the code written last cycle",
            );
        }
        cc.commit();
        written_last.clear();
        for (code, row) in pending {
            table[code] = row;
            written_last.push(code);
        }
        waves.cycle(cycle, |t| cc.trace(t));
        cycle += 1;
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
