//! The kernel verifier: rejects malformed kernels before they are interpreted or compiled,
//! with a message naming the kernel and the value.

use std::fmt;

use super::builder::signature;
use super::{Dir, Kernel, LoopSpec, Node, Perm, Region, StreamId, Ty, Value};

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VerifyError {
    pub kernel: String,
    pub message: String,
}

impl fmt::Display for VerifyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "kernel `{}`: {}", self.kernel, self.message)
    }
}

impl std::error::Error for VerifyError {}

pub fn verify(k: &Kernel) -> Result<(), VerifyError> {
    let fail = |message: String| {
        Err(VerifyError {
            kernel: k.name.clone(),
            message,
        })
    };
    if k.name.is_empty()
        || !k
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_')
    {
        return fail(format!(
            "`{}` is not a kernel name (letters, digits, `_`)",
            k.name
        ));
    }
    for (i, s) in k.streams.iter().enumerate() {
        if k.streams[..i].iter().any(|t| t.name == s.name) {
            return fail(format!("two streams are named `{}`", s.name));
        }
    }
    let stream_dir = |s: StreamId| k.streams.get(s.0 as usize).map(|x| x.dir);
    match k.main_loop {
        Some(LoopSpec::OverStream(s)) => {
            if stream_dir(s) != Some(Dir::In) {
                return fail(format!(
                    "the main loop runs over stream {}, which is not an input",
                    s.0
                ));
            }
            if k.loop_reads(s) == 0 {
                return fail(format!(
                    "the main loop runs over stream `{}` but its body never reads it \
                     unconditionally",
                    k.streams[s.0 as usize].name
                ));
            }
        }
        Some(LoopSpec::Counted(0)) => return fail("the main loop runs 0 times".into()),
        _ => {}
    }
    for (i, d) in k.nodes.iter().enumerate() {
        let v = Value(i as u32);
        let this = || k.describe(v);
        for a in d.node.operands() {
            let Some(ad) = k.nodes.get(a.index()).filter(|_| a.index() < i) else {
                return fail(format!(
                    "{} uses {a}, which is not defined before it",
                    this()
                ));
            };
            if ad.ty.is_none() {
                return fail(format!(
                    "{} uses {}, which has no value",
                    this(),
                    k.describe(a)
                ));
            }
            let ok = match (ad.region, d.region) {
                (from, to) if from == to || from == Region::Pre => true,
                (Region::Loop, Region::Post) => matches!(ad.node, Node::Carried { .. }),
                _ => false,
            };
            if !ok {
                return fail(format!(
                    "{} ({}) uses {}, defined {}: after the loop only carried values of the \
                     loop are visible",
                    this(),
                    d.region.name(),
                    k.describe(a),
                    ad.region.name()
                ));
            }
        }
        let ty = |x: Value| k.nodes[x.index()].ty.unwrap_or(Ty::Word);
        let want = |x: Value, t: Ty, what: &str| -> Result<(), VerifyError> {
            if ty(x).fits(t) {
                Ok(())
            } else {
                fail(format!(
                    "{}: {what} {} is {}, expected {t}",
                    this(),
                    k.describe(x),
                    ty(x)
                ))
            }
        };
        match &d.node {
            Node::Op { op, args } => {
                if args.len() != op.arity() {
                    return fail(format!(
                        "{} takes {} operands, has {}",
                        this(),
                        op.arity(),
                        args.len()
                    ));
                }
                let tys: Vec<Ty> = args.iter().map(|&a| ty(a)).collect();
                let (want_tys, _) = signature(*op, &tys);
                for (n, (&a, &t)) in args.iter().zip(&want_tys).enumerate() {
                    want(a, t, &format!("operand {n}"))?;
                }
            }
            Node::Read { stream, cond } => {
                if stream_dir(*stream) != Some(Dir::In) {
                    return fail(format!(
                        "{} reads stream {}, which is not an input",
                        this(),
                        stream.0
                    ));
                }
                if let Some((c, _)) = cond {
                    want(*c, Ty::Cc, "condition")?;
                }
            }
            Node::Write {
                stream,
                cond,
                value,
            } => {
                if stream_dir(*stream) != Some(Dir::Out) {
                    return fail(format!(
                        "{} writes stream {}, which is not an output",
                        this(),
                        stream.0
                    ));
                }
                want(*value, Ty::Word, "value")?;
                if let Some(c) = cond {
                    want(*c, Ty::Cc, "condition")?;
                }
            }
            Node::SpRead { offset, .. } | Node::SpWrite { offset, .. } => {
                if let Some(o) = offset {
                    want(*o, Ty::I32, "offset")?;
                }
            }
            Node::Comm { value, perm } => {
                want(*value, Ty::Word, "value")?;
                if let Perm::PerCluster(p) = perm {
                    want(*p, Ty::I32, "source cluster")?;
                }
            }
            Node::Carried { init, next } => {
                if d.region != Region::Loop {
                    return fail(format!("{} is carried but not in the loop", this()));
                }
                let Some(n) = next else {
                    return fail(format!("{} never gets its next value (`set_next`)", this()));
                };
                let nd = &k.nodes[n.index()];
                if nd.ty.is_none() || !matches!(nd.region, Region::Loop | Region::Pre) {
                    return fail(format!(
                        "{}: next value {} must be a value of the loop",
                        this(),
                        k.describe(*n)
                    ));
                }
                if k.nodes[init.index()].region != Region::Pre {
                    return fail(format!(
                        "{}: initial value {} must be defined before the loop",
                        this(),
                        k.describe(*init)
                    ));
                }
                let t = d.ty.unwrap_or(Ty::Word);
                want(*init, t, "initial value")?;
                want(*n, t, "next value")?;
            }
            Node::Const(_) | Node::ClusterId | Node::Param(_) | Node::Cast { .. } => {}
        }
    }
    Ok(())
}
