//! The kernel interpreter: runs the IR on the machine's op functions
//! ([`imagine_units::ops::Op::eval`]), one lane per cluster. It is the functional golden
//! model of every kernel: the compiled microcode, run on the clocked machine, must leave
//! identical words in every output stream.

use std::fmt;

use imagine_units::arith::fp32::FpMode;
use imagine_units::desc::MachineDesc;

use super::{Dir, Kernel, LoopSpec, Node, Perm, Region, Value};

/// A kernel's inputs: one word vector per stream (outputs' entries are ignored) and the
/// parameter words.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KernelInputs {
    pub streams: Vec<Vec<u32>>,
    pub params: Vec<u32>,
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct InterpError {
    pub kernel: String,
    pub message: String,
}

impl fmt::Display for InterpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "kernel `{}`: {}", self.kernel, self.message)
    }
}

impl std::error::Error for InterpError {}

/// Scratchpad words a kernel may address on `desc`: conditional streams keep the top
/// words for their buffers (ARCHITECTURE §4).
pub fn scratchpad_words(kernel: &Kernel, desc: &MachineDesc) -> usize {
    let conditional = kernel.nodes.iter().any(|d| {
        matches!(
            d.node,
            Node::Read { cond: Some(_), .. } | Node::Write { cond: Some(_), .. }
        )
    });
    let reserved = if conditional {
        2 * desc.srf.conditional_words_per_cycle
    } else {
        0
    };
    desc.scratchpad.words.saturating_sub(reserved)
}

struct State<'k> {
    k: &'k Kernel,
    lanes: usize,
    mode: FpMode,
    vals: Vec<Vec<u32>>,
    streams: Vec<Vec<u32>>,
    read_pos: Vec<usize>,
    sp: Vec<Vec<u32>>,
    params: &'k [u32],
}

/// Runs `kernel` on `desc`'s cluster count and arithmetic mode; returns every stream's
/// words (inputs as given, outputs as written).
pub fn interpret(
    kernel: &Kernel,
    inputs: &KernelInputs,
    desc: &MachineDesc,
) -> Result<Vec<Vec<u32>>, InterpError> {
    let err = |message: String| InterpError {
        kernel: kernel.name.clone(),
        message,
    };
    if inputs.streams.len() != kernel.streams.len() {
        return Err(err(format!(
            "given {} streams, the kernel has {}",
            inputs.streams.len(),
            kernel.streams.len()
        )));
    }
    if inputs.params.len() != kernel.params.len() {
        return Err(err(format!(
            "given {} parameters, the kernel has {}",
            inputs.params.len(),
            kernel.params.len()
        )));
    }
    let lanes = desc.cluster.count;
    let mut st = State {
        k: kernel,
        lanes,
        mode: desc.fp_mode(),
        vals: vec![Vec::new(); kernel.nodes.len()],
        streams: kernel
            .streams
            .iter()
            .zip(&inputs.streams)
            .map(|(s, w)| {
                if s.dir == Dir::In {
                    w.clone()
                } else {
                    Vec::new()
                }
            })
            .collect(),
        read_pos: vec![0; kernel.streams.len()],
        sp: vec![vec![0; scratchpad_words(kernel, desc)]; lanes],
        params: &inputs.params,
    };
    st.region(Region::Pre).map_err(err)?;
    if let Some(spec) = kernel.main_loop {
        let carried: Vec<(usize, Value, Value)> = kernel
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(i, d)| match d.node {
                Node::Carried {
                    init,
                    next: Some(next),
                } => Some((i, init, next)),
                _ => None,
            })
            .collect();
        for &(i, init, _) in &carried {
            st.vals[i] = st.vals[init.index()].clone();
        }
        let mut iteration = 0u64;
        loop {
            let again = match spec {
                LoopSpec::Counted(n) => iteration < u64::from(n),
                LoopSpec::OverStream(s) => {
                    st.read_pos[s.0 as usize] < st.streams[s.0 as usize].len()
                }
            };
            if !again {
                break;
            }
            st.region(Region::Loop).map_err(err)?;
            let next: Vec<Vec<u32>> = carried
                .iter()
                .map(|&(_, _, n)| st.vals[n.index()].clone())
                .collect();
            for (&(i, _, _), v) in carried.iter().zip(next) {
                st.vals[i] = v;
            }
            iteration += 1;
        }
    }
    st.region(Region::Post).map_err(err)?;
    Ok(st.streams)
}

impl State<'_> {
    fn region(&mut self, region: Region) -> Result<(), String> {
        for i in 0..self.k.nodes.len() {
            if self.k.nodes[i].region == region {
                self.node(i)?;
            }
        }
        Ok(())
    }

    fn val(&self, v: Value) -> &[u32] {
        &self.vals[v.index()]
    }

    fn node(&mut self, i: usize) -> Result<(), String> {
        let k = self.k;
        let lanes = self.lanes;
        let out: Vec<u32> = match &k.nodes[i].node {
            Node::Const(x) => vec![*x; lanes],
            Node::ClusterId => (0..lanes as u32).collect(),
            Node::Param(p) => vec![self.params[*p as usize]; lanes],
            Node::Op { op, args } => {
                let arg = |n: usize| args.get(n).map(|&a| self.val(a));
                let zero = vec![0; lanes];
                let (a, b, c) = (
                    arg(0).unwrap_or(&zero),
                    arg(1).unwrap_or(&zero),
                    arg(2).unwrap_or(&zero),
                );
                (0..lanes)
                    .map(|l| op.eval(a[l], b[l], c[l], self.mode).0)
                    .collect()
            }
            Node::Cast { value } => self.val(*value).to_vec(),
            Node::Carried { .. } => return Ok(()),
            Node::Read { stream, cond } => {
                let s = stream.0 as usize;
                let mask: Vec<bool> = match cond {
                    Some((c, _)) => self.val(*c).iter().map(|&w| w & 1 != 0).collect(),
                    None => vec![true; lanes],
                };
                let need = mask.iter().filter(|&&m| m).count();
                let pos = self.read_pos[s];
                let left = self.streams[s].len() - pos;
                if need > left {
                    return Err(format!(
                        "{} reads {need} words of stream `{}` with only {left} left",
                        k.describe(Value(i as u32)),
                        k.streams[s].name
                    ));
                }
                let mut words = self.streams[s][pos..pos + need].iter();
                self.read_pos[s] += need;
                let otherwise = cond.map(|(_, o)| self.val(o).to_vec());
                mask.iter()
                    .enumerate()
                    .map(|(l, &m)| match (m, &otherwise) {
                        (true, _) => *words.next().expect("counted"),
                        (false, Some(o)) => o[l],
                        (false, None) => unreachable!("unconditional reads take every lane"),
                    })
                    .collect()
            }
            Node::Write {
                stream,
                value,
                cond,
            } => {
                let v = self.val(*value).to_vec();
                let mask: Vec<bool> = match cond {
                    Some(c) => self.val(*c).iter().map(|&w| w & 1 != 0).collect(),
                    None => vec![true; lanes],
                };
                let s = &mut self.streams[stream.0 as usize];
                s.extend(v.iter().zip(&mask).filter(|(_, m)| **m).map(|(w, _)| *w));
                return Ok(());
            }
            Node::SpRead { base, offset } => {
                let mut out = vec![0; lanes];
                for (l, o) in out.iter_mut().enumerate() {
                    let a = self.address(i, *base, *offset, l)?;
                    *o = self.sp[l][a];
                }
                out
            }
            Node::SpWrite { base, offset, data } => {
                for l in 0..lanes {
                    let a = self.address(i, *base, *offset, l)?;
                    self.sp[l][a] = self.vals[data.index()][l];
                }
                return Ok(());
            }
            Node::Comm { value, perm } => {
                let v = self.val(*value);
                let from = |l: usize| -> Result<usize, String> {
                    match *perm {
                        Perm::Rotate(r) => Ok((l + r as usize) % lanes),
                        Perm::Xor(x) if (l ^ x as usize) < lanes => Ok(l ^ x as usize),
                        Perm::Broadcast(b) if (b as usize) < lanes => Ok(b as usize),
                        Perm::PerCluster(p) => Ok(self.val(p)[l] as usize % lanes),
                        _ => Err(format!(
                            "{}: permutation {perm:?} names a cluster outside 0..{lanes}",
                            k.describe(Value(i as u32))
                        )),
                    }
                };
                (0..lanes)
                    .map(|l| from(l).map(|f| v[f]))
                    .collect::<Result<_, _>>()?
            }
        };
        self.vals[i] = out;
        Ok(())
    }

    fn address(
        &self,
        i: usize,
        base: u16,
        offset: Option<Value>,
        lane: usize,
    ) -> Result<usize, String> {
        let a = u32::from(base).wrapping_add(offset.map_or(0, |o| self.val(o)[lane])) as usize;
        if a >= self.sp[lane].len() {
            return Err(format!(
                "{} in cluster {lane}: scratchpad address {a} is outside the {} usable words",
                self.k.describe(Value(i as u32)),
                self.sp[lane].len()
            ));
        }
        Ok(a)
    }
}
