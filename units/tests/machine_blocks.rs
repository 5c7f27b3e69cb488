//! The machine's blocks and sequencer under small programs: loops of every kind, stalls on
//! stream buffers, and every contract the blocks enforce, each error naming its block.

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::asm::assemble;
use imagine_units::runner::{KernelRun, RunError, RunOptions, run_kernel};

fn run(machine: &str, text: &str, inputs: &[Vec<u32>]) -> Result<KernelRun, RunError> {
    let desc = MachineDesc::resolve(machine).unwrap();
    let program = assemble(text, &desc).unwrap_or_else(|e| panic!("{e}\n{text}"));
    run_kernel(
        &desc,
        &program,
        inputs,
        RunOptions {
            max_cycles: 100_000,
            ..RunOptions::default()
        },
    )
}

fn error(machine: &str, text: &str, inputs: &[Vec<u32>]) -> String {
    match run(machine, text, inputs) {
        Ok(r) => panic!("ran without error: {:?}", r.stats),
        Err(e) => e.to_string(),
    }
}

/// Counts passes: every pass adds 1 to a counter and writes it to stream `y`.
const NESTED: &str = "
kernel nested
out y
    imm 0 -> add0.a[0]
    imm 1 -> add0.b[0]
loop count 3:
    nop
loop count 4:
    add0 iadd a[0], b[0] -> add0.a[0], sout.data[0]
    nop
    nop
    sout y, data[0]
end
    nop
end
done
";

#[test]
fn nested_counted_loops_run_every_pass() {
    for m in ["gold8", "gold1"] {
        let r = run(m, NESTED, &[]).unwrap();
        let lanes = MachineDesc::resolve(m).unwrap().cluster.count;
        let expected: Vec<u32> = (1..=12)
            .flat_map(|v| std::iter::repeat_n(v, lanes))
            .collect();
        assert_eq!(r.outputs[0], expected, "{m}");
    }
}

#[test]
fn loop_until_condition_stops_when_every_cluster_agrees() {
    // Each cluster counts up from its own index; the loop ends once every counter >= 5,
    // i.e. after 5 passes (cluster 0 is the last to get there).
    let text = "
kernel until
out y
    imm cid -> add0.a[0]
    imm 1 -> add0.b[0]
    imm 4 -> add1.a[0]
loop until cc[0]:
    add0 iadd a[0], b[0] -> add0.a[0], add1.b[0]
    nop
    nop
    add1 ilt_s a[0], b[0] -> cc[0]
    nop
    nop
    nop
end
    add0 iadd a[0], b[0] -> sout.data[0]
    nop
    nop
    sout y, data[0]
done
";
    let r = run("gold8", text, &[]).unwrap();
    // 5 passes then one more increment after the loop: cluster c holds c + 6.
    assert_eq!(r.outputs[0], (0..8).map(|c| c + 6).collect::<Vec<u32>>());
}

#[test]
fn empty_stream_loop_is_skipped() {
    let text = "
kernel copy
in x
out y
loop stream x:
    sin0 x -> sout.data[0]
    nop
    nop
    nop
    sout y, data[0]
end
    nop
done
";
    let r = run("gold8", text, &[vec![]]).unwrap();
    assert!(r.outputs[0].is_empty());
    let data: Vec<u32> = (0..64).collect();
    let r = run("gold8", text, std::slice::from_ref(&data)).unwrap();
    assert_eq!(r.outputs[0], data);
}

#[test]
fn clusters_stall_when_the_srf_cannot_keep_up() {
    // Four input streams read every cycle want 32 words/cycle; the SRF moves 16.
    let text = "
kernel four
in a
in b
in c
in d
out y
loop stream a:
    sin0 a -> add0.a[0] | sin1 b -> add0.b[0] | sin2 c -> add1.a[0] | sin3 d -> add1.b[0]
    nop
end
    nop
done
";
    let n = 8 * 64;
    let inputs: Vec<Vec<u32>> = (0..4)
        .map(|s| (0..n).map(|i| i * 4 + s).collect())
        .collect();
    let r = run("gold8", text, &inputs).unwrap();
    let s = &r.stats;
    // 64 passes of 2 instructions need 128 cycles at full speed; 2048 words at 16 per cycle
    // need at least 128 cycles of SRF transfer, and the clusters wait for them.
    assert!(s.stall_cycles > 0, "{s:?}");
    assert!(s.cycles >= (4 * n / 16) as u64, "{s:?}");
}

#[test]
fn two_results_in_one_lrf_in_one_cycle_is_a_port_conflict() {
    // iadd (latency 2, issued at 0) and imm (latency 1, issued at 1) both land at 2 in mul0.a.
    let text = "
kernel conflict
out y
    add0 iadd a[0], b[0] -> mul0.a[1]
    imm 5 -> mul0.a[2]
    nop
    nop
    nop
done
";
    let e = error("gold8", text, &[]);
    assert!(
        e.contains("mul0_a") && e.contains("write port conflict"),
        "{e}"
    );
}

#[test]
fn writeback_conflict_on_a_unit_is_an_error() {
    // fadd (latency 4) at 0 and iadd (latency 2) at 2 would leave add0 at the same cycle.
    let text = "
kernel wb
out y
    add0 fadd a[0], b[0] -> add0.a[1]
    nop
    add0 iadd a[0], b[0] -> add0.a[2]
    nop
    nop
    nop
    nop
done
";
    let e = error("gold8", text, &[]);
    assert!(e.contains("add0"), "{e}");
}

#[test]
fn divide_unit_busy_within_its_issue_interval() {
    let text = "
kernel dsq
out y
    dsq0 fdiv a[0], b[0] -> dsq0.a[1]
    nop
    nop
    dsq0 fsqrt a[0] -> dsq0.a[2]
    nop
done
";
    let e = error("gold8", text, &[]);
    assert!(e.contains("dsq0"), "{e}");
    // A fully pipelined divide/sqrt unit (gold8+F) takes it.
    assert!(run("gold8+F", text, &[]).is_ok());
}

#[test]
fn scratchpad_address_out_of_range_names_the_cluster() {
    let text = "
kernel sp
out y
    imm 300 -> sp0.addr[0]
    nop
    sp0 ld 0, addr[0] -> add0.a[0]
    nop
    nop
    nop
done
";
    let e = error("gold8", text, &[]);
    assert!(
        e.contains("cluster0.sp0") && e.contains("address 300"),
        "{e}"
    );
}

#[test]
fn reading_past_the_end_of_a_stream_is_an_error() {
    let text = "
kernel past
in x
out y
    sin0 x -> add0.a[0]
    sin0 x -> add0.a[1]
    nop
done
";
    let e = error("gold8", text, &[(0..8).collect()]);
    assert!(e.contains("`x`") && e.contains("only 0 left"), "{e}");
}

#[test]
fn permutations_route_words_between_clusters() {
    for (perm, source) in [
        ("rotate 3", (|c: u32| (c + 3) % 8) as fn(u32) -> u32),
        ("xor 5", |c| c ^ 5),
        ("bcast 6", |_| 6),
    ] {
        let text = format!(
            "
kernel perm
out y
    imm cid -> comm0.data[0]
    nop
    comm0 data[0], {perm} -> sout.data[0]
    nop
    nop
    sout y, data[0]
done
"
        );
        let r = run("gold8", &text, &[]).unwrap();
        assert_eq!(
            r.outputs[0],
            (0..8).map(source).collect::<Vec<u32>>(),
            "{perm}"
        );
    }
}

#[test]
fn conditional_streams_occupy_the_intercluster_network() {
    let desc = MachineDesc::gold8();
    let text = "
kernel busy
in x
out y
    sin0 x if cc[0] -> add0.a[0] | comm0 data[0], rotate 1 -> add0.b[0]
    nop
done
";
    let e = assemble(text, &desc).unwrap_err().to_string();
    assert!(
        e.contains("comm0") && e.contains("conditional stream"),
        "{e}"
    );
}

#[test]
fn conditional_streams_buffer_in_the_top_of_the_scratchpad() {
    let desc = MachineDesc::gold8();
    // The scratchpad port is theirs in their cycle...
    let busy = "
kernel busy
in x
out y
    sin0 x if cc[0] -> add0.a[0] | sp0 ld 0 -> add0.b[0]
    nop
done
";
    let e = assemble(busy, &desc).unwrap_err().to_string();
    assert!(e.contains("sp0") && e.contains("scratchpad"), "{e}");
    // ...and its top two words are theirs for the whole kernel.
    let top = "
kernel top
in x
out y
    sp0 st 254, data[0]
    nop
    sin0 x if cc[0] -> add0.a[0]
    nop
done
";
    let e = error("gold8", top, &[(0..8).collect()]);
    assert!(
        e.contains("address 254") && e.contains("conditional streams"),
        "{e}"
    );
    // Without conditional streams the whole scratchpad is the kernel's.
    let plain = top.replace("sin0 x if cc[0]", "sin0 x");
    assert!(run("gold8", &plain, &[(0..8).collect()]).is_ok());
}
