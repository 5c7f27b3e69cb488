//! Cost of writing a VCD: the demo design for 100k core cycles with a [`VcdWriter`]
//! writing every signal to a sink and to a file, against the same run with no tracer.
//!
//! ```text
//! cargo bench -p imagine-waves --bench vcd
//! ```

use std::io;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use imagine_hdl::demo::{self, DemoConfig};
use imagine_hdl::{ClockDomain, ProbeRegistry, SignalId, Tracer, default_domains};
use imagine_waves::{VcdOptions, VcdWriter, parse_window};
use vcd::{IdCode, Value};

/// For comparison: a tracer writing every change through the `vcd` crate's
/// `change_scalar`/`change_vector` (one `Value` per bit), which [`VcdWriter`] does not use.
struct CrateWriter {
    w: vcd::Writer<io::BufWriter<io::Sink>>,
    widths: Vec<u32>,
}

impl Tracer for CrateWriter {
    fn start(&mut self, probes: &ProbeRegistry, _: &[ClockDomain]) -> io::Result<()> {
        self.w.add_module("top")?;
        for (i, s) in probes.signals().iter().enumerate() {
            self.w.add_wire(s.width, &format!("s{i}"))?;
            self.widths.push(s.width);
        }
        self.w.upscope()?;
        self.w.enddefinitions()
    }
    fn time(&mut self, t: u64, _: u64) {
        self.w.timestamp(t).unwrap();
    }
    fn change(&mut self, id: SignalId, v: &[u64]) {
        let code = IdCode::from(id.0);
        let width = self.widths[id.0 as usize];
        if width == 1 {
            self.w.change_scalar(code, v[0] & 1 != 0).unwrap();
        } else {
            let bits = (0..width)
                .rev()
                .map(|i| Value::from(v[i as usize / 64] >> (i % 64) & 1 != 0));
            self.w.change_vector(code, bits).unwrap();
        }
    }
    fn finish(&mut self) -> io::Result<()> {
        self.w.flush()
    }
}

const CYCLES: u64 = 100_000;

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("demo_100k");
    g.throughput(Throughput::Elements(CYCLES));
    g.sample_size(10);
    g.bench_function("no_tracer", |b| {
        b.iter(|| {
            let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
            sim.run_core_cycles(CYCLES, |_| {}).unwrap();
        })
    });
    g.bench_function("vcd_to_sink", |b| {
        b.iter(|| {
            let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
            let w = VcdWriter::new(io::sink(), &VcdOptions::default()).unwrap();
            sim.attach(Box::new(w)).unwrap();
            sim.run_core_cycles(CYCLES, |_| {}).unwrap();
            sim.finish().unwrap();
        })
    });
    g.bench_function("vcd_crate_change_vector_to_sink", |b| {
        b.iter(|| {
            let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
            let w = CrateWriter {
                w: vcd::Writer::new(io::BufWriter::with_capacity(1 << 16, io::sink())),
                widths: Vec::new(),
            };
            sim.attach(Box::new(w)).unwrap();
            sim.run_core_cycles(CYCLES, |_| {}).unwrap();
            sim.finish().unwrap();
        })
    });
    let path = std::env::temp_dir().join(format!("imagine-waves-bench-{}.vcd", std::process::id()));
    g.bench_function("vcd_to_file", |b| {
        b.iter(|| {
            let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
            let w = VcdWriter::create(&path, &VcdOptions::default()).unwrap();
            sim.attach(Box::new(w)).unwrap();
            sim.run_core_cycles(CYCLES, |_| {}).unwrap();
            sim.finish().unwrap();
        })
    });
    // A window at the end: the cost of following changes without writing them.
    g.bench_function("vcd_window_last_100", |b| {
        b.iter(|| {
            let mut sim = demo::build(default_domains(), DemoConfig::default()).unwrap();
            let opts = VcdOptions {
                window: parse_window(&format!("{}:", CYCLES - 100)).unwrap(),
                scopes: vec![],
                max_bytes: None,
            };
            let w = VcdWriter::new(io::sink(), &opts).unwrap();
            sim.attach(Box::new(w)).unwrap();
            sim.run_core_cycles(CYCLES, |_| {}).unwrap();
            sim.finish().unwrap();
        })
    });
    g.finish();
    let _ = std::fs::remove_file(&path);
    let _ = std::fs::remove_file(path.with_extension("gtkw"));
}

criterion_group!(benches, bench);
criterion_main!(benches);
