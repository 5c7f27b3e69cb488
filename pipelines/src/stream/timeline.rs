//! A run as a timeline (`render --timeline F.json`): the Trace Event format
//! (<https://docs.google.com/document/d/1CvAClvFfyA5R-PhYUmn5OOQtYMH4h6I0nSsKchNAySU>) that
//! Perfetto's UI (ui.perfetto.dev) and Chrome's `chrome://tracing` open, built after the
//! run from the stream controller's records.
//!
//! * one track for the clusters: each kernel call from its issue to its completion, with
//!   its batch, the cycles it ran (start to the end of its output flush), its stalls,
//!   instructions issued, loop passes (iterations plus the software pipeline's fill) and
//!   the compiled loop's II;
//! * one for where the clusters' other cycles went ([`attribution`](super::attribution)):
//!   the waits between kernel calls, by what they waited for (with the kernel calls, the
//!   window once over);
//! * one per address generator (each load, store, gather and scatter with its words,
//!   records, DRAM base and SRF start), one for the host interface (SRF writes and reads) and
//!   one for the microcode loader;
//!   A wait's slice carries what it waited on (`waiting_on_*` cycles: scoreboard, DRAM
//!   bandwidth, bank conflicts, memory latency, the unit at work);
//! * counter tracks over buckets of the window: DRAM bandwidth (each operation's words spread
//!   evenly over its time), DRAM row hits and misses per microsecond (all channels, from
//!   their activity counters: a column access without an activate is a hit), the clusters'
//!   busy share, the scoreboard's occupancy and the SRF words bound to the instructions
//!   running (a kernel's streams, a memory operation's or host transfer's words) during
//!   each bucket.
//!
//! Times are simulated time in microseconds (the format's unit) with nanosecond precision
//! and `displayTimeUnit` `ns`; every slice also carries its core cycles (`from_cycle`,
//! `to_cycle`), ready for `--vcd-window FROM:TO`. The size is bounded: past
//! `max_events` slices, consecutive slices of the same name on a track become one (with
//! `calls`), and `otherData` says so.

use std::ops::Range;

use imagine_units::memory::MemOpKind;
use imagine_units::stream_controller::{InstrRecord, StreamInstr, Unit};
use serde_json::{Value, json};

use super::attribution::{Category, DramActivity, Segment};

/// What a kernel program is called and its compiled loop's initiation interval.
#[derive(Clone, Debug)]
pub struct ProgramInfo {
    pub name: String,
    pub ii: Option<u32>,
}

/// What the timeline is made from.
pub struct TimelineInput<'a> {
    pub records: &'a [InstrRecord],
    pub programs: &'a [ProgramInfo],
    /// The batch of each instruction, by index.
    pub batch_tags: &'a [Option<usize>],
    /// The attribution of `window`'s cycles.
    pub segments: &'a [Segment],
    /// What DRAM did, for the row-hit counter.
    pub dram: &'a DramActivity<'a>,
    pub window: Range<u64>,
    pub core_mhz: f64,
    /// Address generators of the machine.
    pub address_generators: usize,
}

/// Slices kept before consecutive ones of a name are merged.
pub const MAX_EVENTS: usize = 400_000;
/// Buckets of each counter track.
const COUNTER_BUCKETS: u64 = 2_000;

const PID: u32 = 1;
const TID_CLUSTERS: u32 = 1;
const TID_ATTRIBUTION: u32 = 2;
const TID_HOST: u32 = 3;
const TID_MICROCODE: u32 = 4;
const TID_RASTERIZER: u32 = 5;
const TID_AG0: u32 = 10;

/// A slice before it is written.
struct Slice {
    tid: u32,
    name: String,
    cat: &'static str,
    cycles: Range<u64>,
    args: serde_json::Map<String, Value>,
    calls: u64,
}

/// The timeline as Trace Event JSON, with at most `max_events` slices.
pub fn timeline(input: &TimelineInput<'_>, max_events: usize) -> Value {
    let us = |cycle: u64| cycle as f64 / input.core_mhz;
    let w = &input.window;
    let mut slices = Vec::new();
    for (id, r) in input.records.iter().enumerate() {
        let (Some(issued), Some(completed)) = (r.issued, r.completed) else {
            continue;
        };
        if completed <= w.start || issued >= w.end {
            continue;
        }
        let mut args = serde_json::Map::new();
        if let Some(b) = input.batch_tags.get(id).copied().flatten() {
            args.insert("batch".into(), json!(b));
        }
        args.insert("instruction".into(), json!(id));
        let (tid, name, cat) = match (&r.instr, r.unit) {
            (StreamInstr::Kernel { program, .. }, _) => {
                let p = &input.programs[*program];
                if let Some(st) = &r.kernel_stats {
                    args.insert("running_cycles".into(), json!(st.cycles));
                    args.insert("stall_cycles".into(), json!(st.stall_cycles));
                    args.insert("instructions_issued".into(), json!(st.instructions));
                    args.insert("loop_passes".into(), json!(st.loop_passes));
                }
                if let Some(ii) = p.ii {
                    args.insert("ii".into(), json!(ii));
                }
                (TID_CLUSTERS, p.name.clone(), "kernel")
            }
            (StreamInstr::Memory(op), Some(Unit::AddressGenerator(a))) => {
                let indexed = matches!(op.pattern, imagine_units::memory::Pattern::Indexed { .. });
                let name = match (op.kind, indexed) {
                    (MemOpKind::Load, false) => "load",
                    (MemOpKind::Store, false) => "store",
                    (MemOpKind::Load, true) => "gather",
                    (MemOpKind::Store, true) => "scatter",
                };
                args.insert("words".into(), json!(op.words()));
                args.insert("records".into(), json!(op.records));
                args.insert("dram_word".into(), json!(op.base));
                args.insert("srf_start".into(), json!(op.srf_start));
                (TID_AG0 + a as u32, name.to_string(), "memory")
            }
            (StreamInstr::WriteSrf { start, words }, _) => {
                args.insert("words".into(), json!(words.len()));
                args.insert("srf_start".into(), json!(start));
                (TID_HOST, "SRF write".into(), "host")
            }
            (StreamInstr::ReadSrf { start, len }, _) => {
                args.insert("words".into(), json!(len));
                args.insert("srf_start".into(), json!(start));
                (TID_HOST, "SRF read".into(), "host")
            }
            (StreamInstr::LoadMicrocode { program }, _) => {
                args.insert("kernel".into(), json!(input.programs[*program].name));
                (TID_MICROCODE, "microcode load".into(), "microcode")
            }
            (StreamInstr::Rasterize(job), _) => {
                if let Some(res) = &r.raster {
                    args.insert("fragments".into(), json!(res.fragments));
                    args.insert("overflowed".into(), json!(res.overflowed));
                }
                args.insert("triangles".into(), json!(job.inputs[1].words));
                (
                    TID_RASTERIZER,
                    imagine_units::stream_controller::RASTERIZER_KERNEL.into(),
                    "kernel",
                )
            }
            (StreamInstr::Memory(_), _) => continue,
        };
        slices.push(Slice {
            tid,
            name,
            cat,
            cycles: issued.max(w.start)..completed.min(w.end),
            args,
            calls: 1,
        });
    }
    let names: Vec<String> = input.programs.iter().map(|p| p.name.clone()).collect();
    // The kernel calls' slices cover kernels running and their dispatch: the waits fill the
    // rest, so the two cluster tracks together cover the window once.
    for s in input.segments {
        if matches!(s.category, Category::Kernel(_) | Category::KernelDispatch) {
            continue;
        }
        let mut args = serde_json::Map::new();
        for (on, cycles) in s.waiting_on.rows() {
            if cycles > 0 {
                args.insert(
                    format!("waiting_on_{}", on.replace(' ', "_")),
                    json!(cycles),
                );
            }
        }
        slices.push(Slice {
            tid: TID_ATTRIBUTION,
            name: s.category.name(&names),
            cat: "attribution",
            cycles: s.cycles.clone(),
            args,
            calls: 1,
        });
    }
    let before = slices.len();
    let aggregated = slices.len() > max_events;
    if aggregated {
        slices = merge_runs(slices);
    }
    let truncated = slices.len() > max_events;
    slices.truncate(max_events);

    let mut events: Vec<Value> = Vec::new();
    let thread = |tid: u32, name: &str| json!({"ph": "M", "pid": PID, "tid": tid, "name": "thread_name", "args": {"name": name}});
    events
        .push(json!({"ph": "M", "pid": PID, "name": "process_name", "args": {"name": "imagine"}}));
    events.push(thread(TID_CLUSTERS, "clusters: kernel calls"));
    events.push(thread(
        TID_ATTRIBUTION,
        "clusters: waiting (where cycles went)",
    ));
    for a in 0..input.address_generators {
        events.push(thread(
            TID_AG0 + a as u32,
            &format!("address generator {a}"),
        ));
    }
    events.push(thread(TID_HOST, "host interface"));
    events.push(thread(TID_MICROCODE, "microcode loader"));
    events.push(thread(TID_RASTERIZER, "hardware rasterizer"));
    for (i, tid) in [TID_CLUSTERS, TID_ATTRIBUTION]
        .into_iter()
        .chain((0..input.address_generators as u32).map(|a| TID_AG0 + a))
        .chain([TID_HOST, TID_MICROCODE, TID_RASTERIZER])
        .enumerate()
    {
        events.push(json!({"ph": "M", "pid": PID, "tid": tid, "name": "thread_sort_index", "args": {"sort_index": i}}));
    }
    for s in slices {
        let mut args = s.args;
        args.insert("from_cycle".into(), json!(s.cycles.start));
        args.insert("to_cycle".into(), json!(s.cycles.end));
        if s.calls > 1 {
            args.insert("calls".into(), json!(s.calls));
        }
        events.push(json!({
            "ph": "X", "pid": PID, "tid": s.tid, "name": s.name, "cat": s.cat,
            "ts": us(s.cycles.start), "dur": us(s.cycles.end - s.cycles.start), "args": args,
        }));
    }
    counters(input, &mut events);
    json!({
        "traceEvents": events,
        "displayTimeUnit": "ns",
        "otherData": {
            "core_mhz": input.core_mhz,
            "window_cycles": [w.start, w.end],
            "slices": before,
            "aggregated": aggregated,
            "truncated": truncated,
            "note": if aggregated {
                "more slices than the limit: consecutive slices of one name on a track are merged (args.calls)"
            } else {
                "every stream instruction of the window is a slice"
            },
        },
    })
}

/// Consecutive slices of one name on a track merged into one.
fn merge_runs(mut slices: Vec<Slice>) -> Vec<Slice> {
    slices.sort_by_key(|s| (s.tid, s.cycles.start));
    let mut out: Vec<Slice> = Vec::new();
    for s in slices {
        match out.last_mut() {
            Some(last) if last.tid == s.tid && last.name == s.name => {
                last.cycles.end = last.cycles.end.max(s.cycles.end);
                last.calls += s.calls;
                last.args.retain(|k, _| k == "batch");
            }
            _ => out.push(s),
        }
    }
    out
}

/// Counter tracks: DRAM bandwidth, row hits and misses, the clusters' busy share, the
/// scoreboard occupancy and
/// the SRF words bound to running instructions, one value per bucket of the window.
fn counters(input: &TimelineInput<'_>, events: &mut Vec<Value>) {
    let w = &input.window;
    let span = w.end.saturating_sub(w.start);
    if span == 0 {
        return;
    }
    let bucket = span.div_ceil(COUNTER_BUCKETS).max(1);
    let n = span.div_ceil(bucket) as usize;
    let index = |c: u64| ((c.clamp(w.start, w.end - 1) - w.start) / bucket) as usize;
    // Calls `add(bucket, cycles)` for the cycles of `from..to` (clipped to the window) in
    // each bucket they cover.
    let per_bucket = |from: u64, to: u64, add: &mut dyn FnMut(usize, u64)| {
        let (mut t, to) = (from.max(w.start), to.min(w.end));
        while t < to {
            let end = (w.start + (index(t) as u64 + 1) * bucket).min(to);
            add(index(t), end - t);
            t = end;
        }
    };
    // Words moved per bucket, each operation's words spread evenly over its span.
    let mut words = vec![0f64; n];
    // Differences by bucket: an amount counts in every bucket from `from`'s to `to`'s.
    let mut occupancy = vec![0i64; n + 1];
    let mut srf_bound = vec![0i64; n + 1];
    let count_over = |diff: &mut [i64], from: u64, to: u64, amount: i64| {
        if to > w.start && from < w.end {
            diff[index(from.max(w.start))] += amount;
            if to < w.end {
                diff[index(to) + 1] -= amount;
            }
        }
    };
    for r in input.records {
        if let (StreamInstr::Memory(op), Some(i), Some(c)) = (&r.instr, r.issued, r.completed) {
            let per_cycle = op.words() as f64 / (c - i).max(1) as f64;
            per_bucket(i, c, &mut |b, cycles| words[b] += per_cycle * cycles as f64);
        }
        if let (Some(e), Some(c)) = (r.entered, r.completed) {
            count_over(&mut occupancy, e, c, 1);
        }
        let bound = match &r.instr {
            StreamInstr::Kernel { bindings, .. } => bindings.iter().map(|b| b.words).sum(),
            StreamInstr::Memory(op) => op.words(),
            StreamInstr::WriteSrf { words, .. } => words.len(),
            StreamInstr::ReadSrf { len, .. } => *len,
            StreamInstr::LoadMicrocode { .. } => 0,
            StreamInstr::Rasterize(job) => {
                job.inputs.iter().chain(&job.outputs).map(|b| b.words).sum()
            }
        };
        if let (Some(i), Some(c)) = (r.issued, r.completed) {
            count_over(&mut srf_bound, i, c, bound as i64);
        }
    }
    let mut busy = vec![0u64; n];
    for s in input.segments {
        if matches!(s.category, Category::Kernel(_)) {
            per_bucket(s.cycles.start, s.cycles.end, &mut |b, cycles| {
                busy[b] += cycles
            });
        }
    }
    let seconds_per_bucket = bucket as f64 / (input.core_mhz * 1e6);
    let (mut live, mut bound) = (0i64, 0i64);
    for b in 0..n {
        let ts = (w.start + b as u64 * bucket) as f64 / input.core_mhz;
        live += occupancy[b];
        bound += srf_bound[b];
        let from = w.start + b as u64 * bucket;
        let cycles = bucket.min(w.end - from);
        let (columns, activates) = input.dram.accesses(&(from..from + cycles));
        let per_us = input.core_mhz / cycles as f64;
        events.push(
            json!({"ph": "C", "pid": PID, "name": "DRAM row hits and misses per µs",
            "ts": ts, "args": {"row hits": (columns - activates).max(0.0) * per_us,
            "row misses": activates.min(columns) * per_us}}),
        );
        events.push(json!({"ph": "C", "pid": PID, "name": "DRAM GB/s", "ts": ts,
            "args": {"GB/s": 4.0 * words[b] / seconds_per_bucket / 1e9}}));
        events.push(
            json!({"ph": "C", "pid": PID, "name": "clusters running a kernel %", "ts": ts,
            "args": {"%": 100.0 * busy[b] as f64 / cycles as f64}}),
        );
        events.push(
            json!({"ph": "C", "pid": PID, "name": "scoreboard instructions", "ts": ts,
            "args": {"instructions": live}}),
        );
        events.push(json!({"ph": "C", "pid": PID, "ts": ts,
            "name": "SRF words bound to running instructions", "args": {"words": bound}}));
    }
}
