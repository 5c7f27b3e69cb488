//! The SRF inside an hdl `Design`: its probes are registered under its scope with their
//! real widths, and a traced run reports stream-buffer levels, modes and the arbiter's
//! grants as they change.

use std::collections::BTreeSet;

use imagine_hdl::{
    ContractError, Design, DomainId, Module, Recorder, SignalKind, Sim, Trace, bits_for,
    default_domains,
};
use imagine_units::desc::MachineDesc;
use imagine_units::srf::Srf;

const LEN: usize = 200;

/// A kernel that copies sb0 (input) to sb1 (output) a row per cycle and flushes at the end.
struct CopyKernel {
    domain: DomainId,
    srf: Srf,
    row: Vec<u32>,
    held: bool,
    flushed: bool,
}

impl Module for CopyKernel {
    fn domain(&self) -> DomainId {
        self.domain
    }
    fn eval(&mut self) -> Result<(), ContractError> {
        let lanes = self.srf.lanes();
        if self.held && self.srf.space(1) >= lanes {
            self.srf.write(1, &self.row)?;
            self.held = false;
        }
        if !self.held && self.srf.available(0) >= lanes {
            self.row.copy_from_slice(self.srf.read(0, lanes)?);
            self.held = true;
        }
        if self.srf.exhausted(0) && !self.held && !self.flushed {
            self.srf.flush(1)?;
            self.flushed = true;
        }
        self.srf.eval();
        Ok(())
    }
    fn commit(&mut self) {
        self.srf.commit();
    }
    fn trace(&self, t: &mut Trace) {
        self.srf.trace(t);
    }
}

#[test]
fn srf_probes_have_their_widths_and_follow_the_streams() {
    let desc = MachineDesc::gold8();
    let mut design = Design::new("top", default_domains()).unwrap();
    let core = design.domain("core").unwrap();
    let mut srf = Srf::new(&mut design.scope().child("srf"), &desc);
    let data: Vec<u32> = (0..LEN as u32).map(|i| i * 7 + 1).collect();
    srf.load(0, &data).unwrap();
    srf.bind_input(0, 0, LEN).unwrap();
    srf.bind_output(1, 1024, LEN).unwrap();
    design.add(CopyKernel {
        domain: core,
        srf,
        row: vec![0; desc.cluster.count],
        held: false,
        flushed: false,
    });
    let mut sim = Sim::new(design);
    let recorder = Recorder::default();
    sim.attach(Box::new(recorder.clone())).unwrap();
    sim.run_core_cycles(60, |_| {}).unwrap();
    sim.finish().unwrap();

    let k = sim.modules_of::<CopyKernel>().next().unwrap();
    assert!(k.srf.idle() && k.srf.flushed(1), "the copy finished");
    assert_eq!(k.srf.read_back(1024, LEN).unwrap(), data);

    let recording = recorder.recording();
    let reg = &recording.probes;
    let sig = |path: &str| {
        let id = reg.find(path).unwrap_or_else(|| panic!("no probe {path}"));
        (id, reg.get(id).width, reg.get(id).kind)
    };
    let sbs = desc.srf.stream_buffers;
    let level_bits = bits_for(64);
    assert_eq!(level_bits, 7);
    for i in 0..sbs {
        for (name, width) in [("level", level_bits), ("mode", 2)] {
            let path = format!("top.srf.sb{i}.{name}");
            let (_, w, kind) = sig(&path);
            assert_eq!((w, kind), (width, SignalKind::Reg), "{path}");
        }
    }
    assert!(reg.find(&format!("top.srf.sb{sbs}.level")).is_none());
    for (path, width) in [
        ("top.srf.arbiter.grant", bits_for(sbs as u64)),
        ("top.srf.arbiter.grant_valid", 1),
        ("top.srf.arbiter.words", bits_for(16)),
    ] {
        let (_, w, kind) = sig(path);
        assert_eq!((w, kind), (width, SignalKind::Reg), "{path}");
    }
    assert_eq!(sig("top.srf.arbiter.grant").1, 5);

    let seen = |path: &str| -> Vec<u64> {
        let values = recording
            .values(path)
            .unwrap_or_else(|| panic!("no probe {path}"));
        assert!(!values.is_empty(), "{path} never reported");
        values
    };
    let distinct = |path: &str| seen(path).into_iter().collect::<BTreeSet<_>>();
    // sb0 is an input (1) throughout; sb1 is an output (2), then flushes (3).
    assert_eq!(seen("top.srf.sb0.mode"), [1]);
    assert_eq!(seen("top.srf.sb1.mode"), [2, 3]);
    assert_eq!(seen("top.srf.sb7.mode"), [0], "unbound SBs report once");
    assert_eq!(seen("top.srf.sb7.level"), [0]);
    // Both SBs were granted; the last transfers are partial lines (200 = 12 × 16 + 8).
    assert_eq!(distinct("top.srf.arbiter.grant"), BTreeSet::from([0, 1]));
    assert_eq!(
        distinct("top.srf.arbiter.grant_valid"),
        BTreeSet::from([0, 1])
    );
    assert_eq!(
        distinct("top.srf.arbiter.words"),
        BTreeSet::from([0, 8, 16])
    );
    let levels = distinct("top.srf.sb0.level");
    assert!(levels.contains(&16) && levels.len() > 3, "{levels:?}");
    assert_eq!(*seen("top.srf.sb1.level").last().unwrap(), 0, "drained");
    assert!(seen("top.srf.sb1.level").iter().all(|&l| l <= 64));
}
