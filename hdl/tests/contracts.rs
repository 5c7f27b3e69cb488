//! Contract violations of pipes, FIFOs and crossings are detected and name the module
//! path, the signal and the cycle.

use imagine_hdl::*;

/// A test module whose behaviour per cycle is a closure over its cycle number.
struct Probe<F: FnMut(u64) -> Result<(), ContractError>> {
    domain: DomainId,
    cycle: u64,
    f: F,
}

impl<F: FnMut(u64) -> Result<(), ContractError> + 'static> Module for Probe<F> {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        (self.f)(self.cycle)
    }
    fn commit(&mut self) {
        self.cycle += 1;
    }
}

fn probe<F: FnMut(u64) -> Result<(), ContractError> + 'static>(domain: DomainId, f: F) -> Probe<F> {
    Probe {
        domain,
        cycle: 0,
        f,
    }
}

fn core_only() -> Design {
    Design::new("top", vec![ClockDomain::mhz("core", 500)]).unwrap()
}

fn run(design: Design, cycles: u64) -> Result<(), ContractError> {
    Sim::new(design).run_core_cycles(cycles, |_| {})
}

#[test]
fn over_bandwidth_write_names_pipe_and_cycle() {
    let mut d = core_only();
    let core = DomainId(0);
    let (mut tx, mut rx) = d
        .scope()
        .child("producer")
        .pipe::<u32>("bus", core, 2, 1)
        .unwrap();
    d.add(probe(core, move |c| {
        tx.write(1)?;
        if c == 5 {
            tx.write(2)?;
        }
        Ok(())
    }));
    d.add(probe(core, move |_| {
        rx.read();
        Ok(())
    }));
    let e = run(d, 20).unwrap_err();
    assert_eq!(e.module, "top.producer");
    assert_eq!(e.signal, "bus");
    assert_eq!(e.cycle, Some(5));
    assert_eq!(
        e.violation,
        Violation::OverBandwidth {
            written: 2,
            bandwidth: 1
        }
    );
    let msg = e.to_string();
    assert!(
        msg.contains("top.producer") && msg.contains("bus") && msg.contains("core cycle 5"),
        "{msg}"
    );
}

#[test]
fn a_value_nobody_reads_is_an_error_at_its_arrival() {
    let mut d = core_only();
    let core = DomainId(0);
    let (mut tx, mut rx) = d.scope().pipe::<u32>("bus", core, 3, 2).unwrap();
    d.add(probe(core, move |c| {
        if c == 10 {
            tx.write(7)?;
            tx.write(8)?;
        }
        Ok(())
    }));
    d.add(probe(core, move |c| {
        // Reads one of the two values that arrive at cycle 13.
        if c == 13 {
            assert_eq!(rx.available(), 2);
            assert_eq!(rx.read(), Some(7));
        } else {
            assert_eq!(rx.read(), None, "value visible at cycle {c}");
        }
        Ok(())
    }));
    let e = run(d, 30).unwrap_err();
    assert_eq!(e.violation, Violation::Unread { lost: 1 });
    assert_eq!(e.cycle, Some(13));
    assert_eq!((e.module.as_str(), e.signal.as_str()), ("top", "bus"));
}

#[test]
fn pipe_latency_is_exact() {
    for latency in 1..5u64 {
        let mut d = core_only();
        let core = DomainId(0);
        let (mut tx, mut rx) = d
            .scope()
            .pipe::<u64>("p", core, latency as usize, 1)
            .unwrap();
        d.add(probe(core, move |c| tx.write(c)));
        d.add(probe(core, move |c| {
            let got = rx.read();
            let expected = c.checked_sub(latency);
            assert_eq!(got, expected, "latency {latency} cycle {c}");
            Ok(())
        }));
        run(d, 20).unwrap();
    }
}

#[test]
fn zero_latency_and_zero_capacity_are_rejected() {
    let mut d = core_only();
    let e = d
        .scope()
        .child("x")
        .pipe::<u8>("p", DomainId(0), 0, 1)
        .err()
        .unwrap();
    assert!(
        e.to_string().contains("top.x.p") && e.to_string().contains("latency"),
        "{e}"
    );
    let e = d.scope().fifo::<u8>("f", DomainId(0), 0, 1).err().unwrap();
    assert!(e.to_string().contains("capacity"), "{e}");
    let e = d
        .scope()
        .async_fifo::<u8>("a", (DomainId(0), DomainId(0)), 4, 0)
        .err()
        .unwrap();
    assert!(e.to_string().contains("sync_stages"), "{e}");
    assert!(matches!(
        d.domain("nope"),
        Err(DesignError::UnknownDomain(_))
    ));
}

#[test]
fn fifo_overflow_and_underflow_are_errors() {
    let mut d = core_only();
    let core = DomainId(0);
    let (mut tx, _rx) = d.scope().fifo::<u8>("q", core, 3, 1).unwrap();
    d.add(probe(core, move |_| tx.push(1)));
    let e = run(d, 10).unwrap_err();
    assert_eq!(e.violation, Violation::Overflow { capacity: 3 });
    assert_eq!(e.cycle, Some(3));

    let mut d = core_only();
    let (_tx, mut rx) = d.scope().fifo::<u8>("q", core, 3, 1).unwrap();
    d.add(probe(core, move |_| rx.pop().map(|_| ())));
    let e = run(d, 10).unwrap_err();
    assert_eq!((&e.violation, e.cycle), (&Violation::Underflow, Some(0)));
}

#[test]
fn fifo_pushes_are_visible_next_cycle_and_keep_order() {
    let mut d = core_only();
    let core = DomainId(0);
    let (mut tx, mut rx) = d.scope().fifo::<u64>("q", core, 4, 2).unwrap();
    d.add(probe(core, move |c| {
        if c < 10 {
            tx.push(2 * c)?;
            tx.push(2 * c + 1)?;
        }
        Ok(())
    }));
    let mut expect = 0;
    d.add(probe(core, move |c| {
        if c == 0 {
            assert_eq!(rx.available(), 0);
        }
        while rx.available() > 0 {
            assert_eq!(rx.pop()?, expect);
            expect += 1;
        }
        Ok(())
    }));
    run(d, 15).unwrap();
}

#[test]
fn crossing_delivers_everything_in_order_and_respects_synchroniser_delay() {
    let mut d = Design::new("top", default_domains()).unwrap();
    let (core, dram) = (DomainId(0), DomainId(1));
    let (mut tx, mut rx) = d
        .scope()
        .async_fifo::<u64>("x", (core, dram), 4, 2)
        .unwrap();
    let mut next = 0u64;
    d.add(probe(core, move |_| {
        if tx.can_push() {
            tx.push(next)?;
            next += 1;
        }
        Ok(())
    }));
    let mut expect = 0u64;
    let mut first_seen = None;
    d.add(probe(dram, move |c| {
        if rx.can_pop() {
            first_seen.get_or_insert(c);
            // A value pushed at the first core edge crosses 2 synchroniser stages.
            assert!(first_seen.unwrap() >= 2);
            assert_eq!(rx.pop()?, expect);
            expect += 1;
        }
        Ok(())
    }));
    run(d, 3000).unwrap();
}

#[test]
fn crossing_overflow_is_an_error() {
    let mut d = Design::new("top", default_domains()).unwrap();
    let (core, dram) = (DomainId(0), DomainId(1));
    let (mut tx, _rx) = d
        .scope()
        .child("mem")
        .async_fifo::<u8>("req", (core, dram), 2, 2)
        .unwrap();
    d.add(probe(core, move |_| tx.push(0)));
    let e = run(d, 10).unwrap_err();
    assert_eq!((e.module.as_str(), e.signal.as_str()), ("top.mem", "req"));
    assert_eq!(e.violation, Violation::Overflow { capacity: 2 });
    assert_eq!(e.cycle, Some(2));
}
