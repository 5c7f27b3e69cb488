//! Host speed of the SRF model (ignored by default; run with
//! `cargo test --release -p imagine-units --test srf_perf -- --ignored --nocapture`):
//! a kernel reading two streams and writing one, a row each per cycle, with the streams
//! rebound whenever they end, as a machine running back-to-back kernels would.

use std::hint::black_box;
use std::time::Instant;

use imagine_hdl::{Design, default_domains};
use imagine_units::desc::MachineDesc;
use imagine_units::srf::Srf;

#[test]
#[ignore = "timing; run in release"]
fn srf_cycles_per_second() {
    let desc = MachineDesc::gold8();
    let mut design = Design::new("top", default_domains()).unwrap();
    let mut srf = Srf::new(&mut design.scope().child("srf"), &desc);
    let lanes = desc.cluster.count;
    let len = 4096;
    srf.load(0, &vec![1; len]).unwrap();
    srf.load(len, &vec![2; len]).unwrap();
    let bind = |srf: &mut Srf| {
        srf.bind_input(0, 0, len).unwrap();
        srf.bind_input(1, len, len).unwrap();
        srf.bind_output(2, 2 * len, len).unwrap();
    };
    bind(&mut srf);
    let cycles = 20_000_000u64;
    let mut row = vec![0u32; lanes];
    let mut sum = 0u64;
    let t = Instant::now();
    for _ in 0..cycles {
        if srf.available(0) >= lanes && srf.available(1) >= lanes && srf.space(2) >= lanes {
            let a = srf.read(0, lanes).unwrap();
            row.copy_from_slice(a);
            let b = srf.read(1, lanes).unwrap();
            for (r, b) in row.iter_mut().zip(b) {
                *r = r.wrapping_add(*b);
            }
            srf.write(2, &row).unwrap();
        }
        if srf.exhausted(0) && srf.exhausted(1) {
            srf.flush(2).unwrap();
            if srf.flushed(2) {
                sum += srf.output_len(2) as u64;
                for sb in 0..3 {
                    srf.unbind(sb).unwrap();
                }
                bind(&mut srf);
            }
        }
        srf.eval();
        srf.commit();
    }
    let secs = t.elapsed().as_secs_f64();
    black_box(sum);
    println!(
        "SRF: {:.1} M cycles/s ({:.1} ns/cycle), port {:.2} words/cycle, {} words out",
        cycles as f64 / secs / 1e6,
        secs * 1e9 / cycles as f64,
        srf.stats().words_per_cycle(),
        sum
    );
}
