//! The compiler on small kernels: machine output equals the interpreter's, bit for bit.

use imagine_pipelines::compile::compile;
use imagine_pipelines::kernel::{Kernel, KernelBuilder, KernelInputs, LoopSpec, Perm, Ty};
use imagine_pipelines::run::check;
use imagine_units::desc::MachineDesc;

fn machine(name: &str) -> MachineDesc {
    MachineDesc::resolve(name).unwrap()
}

fn scale() -> Kernel {
    let mut b = KernelBuilder::new("scale");
    let (input, output) = (b.input("in"), b.output("out"));
    let k = b.param_f32("k");
    let c = b.f32(1.5);
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_f32(input);
    let y = b.fmul(x, k);
    let z = b.fadd(y, c);
    b.write(output, z);
    b.end_loop();
    b.finish().unwrap()
}

fn floats(n: usize, seed: u32) -> Vec<u32> {
    (0..n as u32)
        .map(|i| ((i.wrapping_mul(2654435761) ^ seed) % 2000) as f32 / 7.0 - 100.0)
        .map(f32::to_bits)
        .collect()
}

/// Inputs for a kernel with one input stream of `n` scattered words and one output.
fn hashed_words(n: u32) -> KernelInputs {
    KernelInputs {
        streams: vec![(0..n).map(|i| i.wrapping_mul(2654435761)).collect(), vec![]],
        params: vec![],
    }
}

fn assert_matches(
    k: &Kernel,
    m: &str,
    inputs: &KernelInputs,
) -> imagine_pipelines::compile::Compiled {
    let desc = machine(m);
    let c = compile(k, &desc).unwrap_or_else(|e| panic!("{e}"));
    let r = check(k, &c, &desc, inputs)
        .unwrap_or_else(|e| panic!("{}: {e}\n{}", k.name, c.report.text()));
    assert!(r.words > 0);
    assert_eq!(r.mismatch, None, "{}\n{}", k.name, c.report.text());
    c
}

#[test]
fn a_scaling_loop_matches_the_interpreter() {
    let k = scale();
    for m in ["gold1", "gold8", "gold32"] {
        let c = machine(m).cluster.count;
        let inputs = KernelInputs {
            streams: vec![floats(c * 40, 7), vec![]],
            params: vec![3.25f32.to_bits()],
        };
        let compiled = assert_matches(&k, m, &inputs);
        assert_eq!(compiled.report.ii, Some(1), "{}", compiled.report.text());
    }
}

#[test]
fn a_carried_running_sum_matches() {
    let mut b = KernelBuilder::new("running");
    let (input, output, total) = (b.input("in"), b.output("out"), b.output("total"));
    let zero = b.i32(0);
    b.begin_loop(LoopSpec::OverStream(input));
    let acc = b.carried(zero);
    let x = b.read_i32(input);
    let s = b.iadd(acc, x);
    b.set_next(acc, s);
    b.write(output, s);
    b.end_loop();
    let t = b.mov(acc);
    b.write(total, t);
    let k = b.finish().unwrap();
    let inputs = KernelInputs {
        streams: vec![(0..64u32).map(|i| i * 3 + 1).collect(), vec![], vec![]],
        params: vec![],
    };
    assert_matches(&k, "gold8", &inputs);
    assert_matches(&k, "gold1", &inputs);
}

/// A value carried unchanged (`set_next(x, x)`) becomes a loop `mov` that reads its own
/// previous result: no distance-0 dependence on itself (a cycle that tripped the
/// scheduler's debug assertion), and it still holds its initial value after the loop.
#[test]
fn a_value_carried_unchanged_matches() {
    let mut b = KernelBuilder::new("unchanged");
    let (input, output, total) = (b.input("in"), b.output("out"), b.output("total"));
    let k = b.param("k", Ty::I32);
    let seven = b.i32(7);
    let init = b.iadd(k, seven);
    b.begin_loop(LoopSpec::OverStream(input));
    let kept = b.carried(init);
    b.set_next(kept, kept);
    let x = b.read_i32(input);
    let s = b.iadd(kept, x);
    b.write(output, s);
    b.end_loop();
    let t = b.mov(kept);
    b.write(total, t);
    let k = b.finish().unwrap();
    let inputs = KernelInputs {
        streams: vec![(0..64u32).map(|i| i * 5 + 2).collect(), vec![], vec![]],
        params: vec![1000],
    };
    assert_matches(&k, "gold8", &inputs);
    assert_matches(&k, "gold1", &inputs);
}

#[test]
fn comm_and_scratchpad_and_conditional_streams_match() {
    let mut b = KernelBuilder::new("mix");
    let (input, output, kept) = (b.input("in"), b.output("out"), b.output("kept"));
    let limit = b.i32(50);
    let id = b.cluster_id();
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_i32(input);
    let left = b.comm(x, Perm::Rotate(1));
    b.sp_write(3, Some(id), left);
    let back = b.sp_read(3, Some(id));
    let y = b.iadd(back, x);
    b.write(output, y);
    let small = b.ilt(x, limit);
    b.write_if(kept, small, x);
    b.end_loop();
    let k = b.finish().unwrap();
    for m in ["gold8", "gold1"] {
        let c = machine(m).cluster.count;
        let inputs = KernelInputs {
            streams: vec![
                (0..c as u32 * 12).map(|i| (i * 37) % 101).collect(),
                vec![],
                vec![],
            ],
            params: vec![],
        };
        assert_matches(&k, m, &inputs);
    }
}

/// A table lookup read by three ops: each reader gets its own scratchpad read, issued just
/// before it, and the results still equal the interpreter's.
#[test]
fn a_table_lookup_with_several_readers_is_read_again_for_each() {
    const ENTRIES: u16 = 16;
    let mut b = KernelBuilder::new("lookup");
    let (table, input, output) = (b.input("table"), b.input("in"), b.output("out"));
    let mask = b.i32(i32::from(ENTRIES) - 1);
    let seven = b.i32(7);
    for entry in 0..ENTRIES {
        let word = b.read_i32(table);
        b.sp_write(entry, None, word);
    }
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_i32(input);
    let index = b.and(x, mask);
    let value = b.sp_read(0, Some(index));
    let product = b.imul(value, x);
    let sum = b.iadd(value, seven);
    let mixed = b.xor(value, x);
    // (Records of eight words: the output slot bounds the interval at 8, which leaves the
    // scratchpad room for the extra reads.)
    let more: Vec<_> = (0..5)
        .map(|i| {
            let k = b.i32(i + 1);
            b.iadd(x, k)
        })
        .collect();
    for y in [product, sum, mixed].into_iter().chain(more) {
        b.write(output, y);
    }
    b.end_loop();
    let k = b.finish().unwrap();
    for m in ["gold1", "gold8", "gold32"] {
        let c = machine(m).cluster.count;
        let words: Vec<u32> = (0..u32::from(ENTRIES))
            .flat_map(|i| std::iter::repeat_n(i.wrapping_mul(2654435761), c))
            .collect();
        let inputs = KernelInputs {
            streams: vec![
                words,
                (0..c as u32 * 20).map(|i| i * 13 + 5).collect(),
                vec![],
            ],
            params: vec![],
        };
        let compiled = assert_matches(&k, m, &inputs);
        assert_eq!(
            compiled.report.loop_ops.scratchpad,
            3,
            "{m}\n{}",
            compiled.report.text()
        );
    }
}

fn compile_error(k: &Kernel) -> imagine_pipelines::compile::CompileError {
    compile(k, &machine("gold8")).expect_err("must not fit")
}

#[test]
fn a_kernel_with_too_many_live_values_names_the_lrf() {
    // 80 parameters, each multiplied in the loop: they would stay in the multipliers'
    // LRFs for the whole loop, and four 16-entry LRFs hold 64.
    let mut b = KernelBuilder::new("crowded");
    let (input, output) = (b.input("in"), b.output("out"));
    let params: Vec<_> = (0..80).map(|i| b.param_f32(&format!("p{i}"))).collect();
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_f32(input);
    let mut acc = x;
    for &p in &params {
        let m = b.fmul(x, p);
        acc = b.fadd(acc, m);
    }
    b.write(output, acc);
    b.end_loop();
    let e = compile_error(&b.finish().unwrap());
    assert_eq!(e.kernel, "crowded");
    assert!(e.resource.starts_with("LRF mul"), "{e}");
    assert!(e.to_string().contains("kernel `crowded`"), "{e}");
}

#[test]
fn a_kernel_too_long_for_the_microcode_store_says_so() {
    let mut b = KernelBuilder::new("long");
    let output = b.output("out");
    let one = b.i32(1);
    let mut x = b.i32(0);
    for _ in 0..1100 {
        x = b.iadd(x, one);
    }
    b.write(output, x);
    let e = compile_error(&b.finish().unwrap());
    assert_eq!(
        (e.kernel.as_str(), e.resource.as_str()),
        ("long", "microcode store")
    );
    assert!(e.message.contains("2048"), "{e}");
}

#[test]
fn a_kernel_with_too_many_streams_says_so() {
    let mut b = KernelBuilder::new("wide");
    let ins: Vec<_> = (0..8).map(|i| b.input(&format!("in{i}"))).collect();
    let output = b.output("out");
    b.begin_loop(LoopSpec::OverStream(ins[0]));
    let mut acc = b.read_i32(ins[0]);
    for &s in &ins[1..] {
        let v = b.read_i32(s);
        acc = b.iadd(acc, v);
    }
    b.write(output, acc);
    b.end_loop();
    let e = compile_error(&b.finish().unwrap());
    assert_eq!(e.resource, "kernel streams", "{e}");
}

/// A loop whose adders are nearly full at its bound and whose input word is read again after
/// a chain of a dozen cycles: near the bound no copies fit, so the body is unrolled into
/// passes that each keep the input in an entry of their own (modulo variable expansion), and the loop
/// leaves after whichever pass ends the last iteration.
#[test]
fn a_value_outliving_the_interval_gets_an_entry_per_pass() {
    let mut b = KernelBuilder::new("outlive");
    let (input, output) = (b.input("in"), b.output("out"));
    let k = b.i32(0x9e37);
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_i32(input);
    let (mut sum, mut mix) = (x, b.read_i32(input));
    for i in 0..5 {
        sum = b.iadd(sum, k);
        if i > 0 {
            mix = b.xor(mix, k);
        }
    }
    let back = b.isub(sum, x);
    let y = b.iadd(back, mix);
    b.write(output, y);
    b.end_loop();
    let k = b.finish().unwrap();
    for m in ["gold1", "gold8"] {
        let c = machine(m).cluster.count;
        // Odd and even iteration counts leave after different passes.
        for rows in 1..=9u32 {
            let compiled = assert_matches(&k, m, &hashed_words(c as u32 * rows * 2));
            let r = &compiled.report;
            assert!(r.ii <= Some(r.res_mii + 1), "{m}\n{}", r.text());
            assert!(r.unroll > 1, "{m}\n{}", r.text());
        }
    }
}

/// A value read through more than two LRFs needs a copy (a result has two destinations).
/// Here every adder slot of the interval is taken, so the copy goes on an idle multiplier
/// (`imul_lo(x, 1)`) and the loop still runs at its bound.
#[test]
fn a_fanned_out_value_in_a_full_loop_is_copied_on_a_multiplier() {
    let mut b = KernelBuilder::new("fanout");
    let (input, output) = (b.input("in"), b.output("out"));
    let (k1, k2, k3) = (b.i32(0x1234), b.i32(0x0f0f), b.i32(77));
    b.begin_loop(LoopSpec::OverStream(input));
    let x = b.read_i32(input);
    let p = b.iadd(x, k1);
    let q = b.xor(x, k2);
    let r = b.isub(x, k3);
    let s = b.iadd(p, q);
    let t = b.isub(s, r);
    let u = b.xor(t, x);
    b.write(output, u);
    b.end_loop();
    let k = b.finish().unwrap();
    for m in ["gold1", "gold8"] {
        let c = machine(m).cluster.count;
        let compiled = assert_matches(&k, m, &hashed_words(c as u32 * 20));
        let r = &compiled.report;
        assert_eq!(r.loop_ops.adder, 6, "{m}\n{}", r.text());
        assert!(r.loop_ops.copies >= 1, "{m}\n{}", r.text());
        assert_eq!(r.ii, Some(r.mii()), "{m}\n{}", r.text());
    }
}
