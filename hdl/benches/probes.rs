//! Cost of probing: the demo design with no tracer attached, against the same design with
//! a tracer that discards everything. Run once as is and once with
//! `--no-default-features` (probes compiled out) to compare "tracer off" against
//! "probes compiled out":
//!
//! ```text
//! cargo bench -p imagine-hdl --bench probes
//! cargo bench -p imagine-hdl --bench probes --no-default-features
//! ```

use std::hint::black_box;
use std::io;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use imagine_hdl::demo::{self, DemoConfig, DemoReport};
use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, Tracer, default_domains};

const CYCLES: u64 = 100_000;

struct Discard;
impl Tracer for Discard {
    fn start(&mut self, _: &ProbeRegistry, _: &[ClockDomain]) -> io::Result<()> {
        Ok(())
    }
    fn time(&mut self, t: u64, _: u64) {
        black_box(t);
    }
    fn change(&mut self, id: SignalId, v: &[u64]) {
        black_box((id, v));
    }
    fn finish(&mut self) -> io::Result<()> {
        Ok(())
    }
}

fn run(tracer: bool) -> DemoReport {
    let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
    if tracer {
        sim.attach(Box::new(Discard)).unwrap();
    }
    sim.run_core_cycles(CYCLES, |_| {}).unwrap();
    DemoReport::of(&sim)
}

fn probes(c: &mut Criterion) {
    let mut g = c.benchmark_group("demo_100k_core_cycles");
    g.throughput(Throughput::Elements(CYCLES));
    g.sample_size(20);
    let label = if cfg!(feature = "probes") {
        "tracer_off"
    } else {
        "probes_compiled_out"
    };
    g.bench_function(label, |b| b.iter(|| black_box(run(false))));
    if cfg!(feature = "probes") {
        g.bench_function("tracer_discarding", |b| b.iter(|| black_box(run(true))));
    }
    g.finish();
}

criterion_group!(benches, probes);
criterion_main!(benches);
