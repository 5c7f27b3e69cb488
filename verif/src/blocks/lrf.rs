//! Testbench of the local register files (`units::lrf`): every LRF of a cluster, as the
//! machine description names and sizes them, one word per cluster per access.
//!
//! Reference: each file is a table of rows with at most one pending write, which lands at
//! the edge in the clusters its mask selects; a read sees the rows as of the last edge. A
//! second read or write in one cycle, or an entry outside the file, must be refused
//! without changing anything.

use imagine_units::desc::MachineDesc;
use imagine_units::lrf::Lrf;

use super::{BlockClock, Config, Coverage, Outcome, Rng, Scoreboard, Waves, design};

const BINS: &[&str] = &[
    "read",
    "write all clusters",
    "masked write",
    "write masked off everywhere",
    "same-cycle read and write of one entry",
    "read of the entry written last cycle",
    "first entry",
    "last entry",
    "large file",
    "read port conflict",
    "write port conflict",
    "entry outside the file",
];

/// The reference model of one file.
struct RefFile {
    entries: usize,
    rows: Vec<Vec<u32>>,
    pending: Option<(usize, Vec<u32>, Vec<bool>)>,
    last_written: Option<usize>,
    words_read: u64,
    words_written: u64,
}

impl RefFile {
    fn edge(&mut self, lanes: usize) {
        self.last_written = None;
        if let Some((entry, values, mask)) = self.pending.take() {
            for c in 0..lanes {
                if mask[c] {
                    self.rows[entry][c] = values[c];
                    self.words_written += 1;
                }
            }
            self.last_written = Some(entry);
        }
    }
}

/// The testbench's state a write needs besides the file.
struct Ctx<'a> {
    rng: &'a mut Rng,
    sb: &'a mut Scoreboard,
    cov: &'a mut Coverage,
    cycle: u64,
    large: usize,
}

/// Writes random words to `entry` of `lrf`, under a random mask half the time.
fn write(lrf: &mut Lrf, model: &mut RefFile, entry: usize, x: &mut Ctx<'_>) {
    let lanes = model.rows[0].len();
    x.sb.transaction();
    let values = x.rng.lane_words(lanes);
    let mask = x.rng.chance(50).then(|| x.rng.mask(lanes));
    let got = lrf.write(entry as u16, &values, mask.as_deref());
    x.sb.check(
        x.cycle,
        || format!("{} write of entry {entry}", lrf.path()),
        true,
        got.is_ok(),
    );
    x.cov.hit_if(mask.is_none(), "write all clusters");
    x.cov.hit_if(mask.is_some(), "masked write");
    x.cov.hit_if(
        mask.as_ref().is_some_and(|m| m.iter().all(|&b| !b)),
        "write masked off everywhere",
    );
    x.cov.hit_if(model.entries == x.large, "large file");
    model.pending = Some((entry, values, mask.unwrap_or_else(|| vec![true; lanes])));
}

pub fn run(desc: &MachineDesc, config: &Config) -> Outcome {
    let lanes = desc.cluster.count;
    let mut rng = Rng::new(config.seed);
    let mut sb = Scoreboard::default();
    let mut cov = Coverage::new(BINS);
    let mut d = design();
    let names = desc.lrf_names();
    let mut files: Vec<(Lrf, RefFile)> = names
        .iter()
        .map(|name| {
            let entries = desc.lrf_entries(name);
            let lrf = Lrf::new(&mut d.scope(), name, entries, lanes);
            let reference = RefFile {
                entries,
                rows: vec![vec![0; lanes]; entries],
                pending: None,
                last_written: None,
                words_read: 0,
                words_written: 0,
            };
            (lrf, reference)
        })
        .collect();
    let large = desc.lrf.large_entries;
    let mut waves = Waves::new(d.probes(), desc, BlockClock::Core, config);
    let mut cycle = 0u64;
    while sb.transactions < config.transactions {
        for (lrf, model) in &mut files {
            if !rng.chance(40) {
                continue;
            }
            let entries = model.entries;
            let pick_entry = |rng: &mut Rng, model: &RefFile| match rng.below(8) {
                0 => 0,
                1 => entries - 1,
                2 | 3 => model.last_written.unwrap_or(0),
                _ => rng.index(entries),
            };
            let read_entry = rng.chance(70).then(|| pick_entry(&mut rng, model));
            let write_entry = rng.chance(60).then(|| match read_entry {
                Some(r) if rng.chance(30) => r,
                _ => pick_entry(&mut rng, model),
            });
            let write_first = rng.chance(50);
            if write_first && let Some(e) = write_entry {
                write(
                    lrf,
                    model,
                    e,
                    &mut Ctx {
                        rng: &mut rng,
                        sb: &mut sb,
                        cov: &mut cov,
                        cycle,
                        large,
                    },
                );
            }
            if let Some(e) = read_entry {
                sb.transaction();
                let got = lrf
                    .read(e as u16)
                    .map(<[u32]>::to_vec)
                    .map_err(|e| e.to_string());
                sb.check(
                    cycle,
                    || format!("{} read of entry {e}", lrf.path()),
                    Ok(model.rows[e].clone()),
                    got,
                );
                model.words_read += lanes as u64;
                cov.hit("read");
                cov.hit_if(e == 0, "first entry");
                cov.hit_if(e == entries - 1, "last entry");
                cov.hit_if(
                    model.last_written == Some(e),
                    "read of the entry written last cycle",
                );
                cov.hit_if(
                    write_entry == Some(e),
                    "same-cycle read and write of one entry",
                );
            }
            if !write_first && let Some(e) = write_entry {
                write(
                    lrf,
                    model,
                    e,
                    &mut Ctx {
                        rng: &mut rng,
                        sb: &mut sb,
                        cov: &mut cov,
                        cycle,
                        large,
                    },
                );
            }
            // The port contracts: a second access, or an entry past the end, is refused.
            if rng.chance(8) {
                sb.transaction();
                let outside = rng.chance(30);
                let entry = if outside {
                    entries + rng.index(4)
                } else {
                    rng.index(entries)
                } as u16;
                let (port, refused) = if rng.chance(50) {
                    let busy = read_entry.is_some();
                    ("read", (busy || outside, lrf.read(entry).is_err()))
                } else {
                    let busy = write_entry.is_some();
                    (
                        "write",
                        (
                            busy || outside,
                            lrf.write(entry, &vec![0; lanes], None).is_err(),
                        ),
                    )
                };
                let (expected, got) = refused;
                if !expected {
                    // A legal access: the reference takes it too.
                    if port == "read" {
                        model.words_read += lanes as u64;
                    } else {
                        model.pending = Some((entry as usize, vec![0; lanes], vec![true; lanes]));
                    }
                }
                sb.check(
                    cycle,
                    || format!("{} {port} of entry {entry} refused", lrf.path()),
                    expected,
                    got,
                );
                if expected {
                    cov.hit_if(outside, "entry outside the file");
                    cov.hit_if(!outside && port == "read", "read port conflict");
                    cov.hit_if(!outside && port == "write", "write port conflict");
                }
            }
        }
        for (lrf, model) in &mut files {
            lrf.commit();
            model.edge(lanes);
        }
        waves.cycle(cycle, |t| files.iter().for_each(|(lrf, _)| lrf.trace(t)));
        cycle += 1;
    }
    for (lrf, model) in &files {
        sb.check(
            cycle,
            || format!("{} words moved (read, written)", lrf.path()),
            (model.words_read, model.words_written),
            lrf.words_moved(),
        );
    }
    Outcome {
        scoreboard: sb,
        coverage: cov,
        waves: waves.finish(None),
    }
}
