//! The kernel builder: a Rust API that writes the IR of [`super`] in program order.
//!
//! ```
//! use imagine_pipelines::kernel::{KernelBuilder, LoopSpec};
//! let mut b = KernelBuilder::new("scale");
//! let (input, output) = (b.input("in"), b.output("out"));
//! let k = b.param_f32("k");
//! b.begin_loop(LoopSpec::OverStream(input));
//! let x = b.read_f32(input);
//! let y = b.fmul(x, k);
//! b.write(output, y);
//! b.end_loop();
//! let kernel = b.finish().unwrap();
//! assert_eq!(kernel.name, "scale");
//! ```
//!
//! Constants, the cluster index and parameters are hoisted before the loop wherever they
//! are created. Misuse (a loop inside a loop, an operand of the wrong type) is recorded and
//! reported by [`KernelBuilder::finish`] through the verifier, naming the kernel and value.

use imagine_units::ops::Op;

use super::verify::{VerifyError, verify};
use super::{Def, Dir, Kernel, LoopSpec, Node, Perm, Region, Stream, StreamId, Ty, Value};

pub struct KernelBuilder {
    kernel: Kernel,
    region: Region,
    /// Misuse that cannot be represented in the IR (reported by `finish`).
    errors: Vec<String>,
}

/// The operand types an op expects and the type it returns, given its operands' types
/// (logic ops, moves and selects keep their operand's type).
pub fn signature(op: Op, args: &[Ty]) -> (Vec<Ty>, Ty) {
    use Ty::*;
    let name = op.name();
    let same = |want: Ty| -> Ty {
        match args.first() {
            Some(&t) if t != Word && t != Cc && args.iter().all(|&a| a == t) => t,
            _ => want,
        }
    };
    let lanes = if name.contains("16x2") {
        Some(P16)
    } else if name.contains("8x4") {
        Some(P8)
    } else {
        None
    };
    if let Some(p) = lanes {
        return (vec![p, p], p);
    }
    match op {
        Op::FAdd | Op::FSub | Op::FMin | Op::FMax | Op::FMul | Op::FDiv => (vec![F32, F32], F32),
        Op::FAbs | Op::FNeg | Op::FSqrt => (vec![F32], F32),
        Op::FLt | Op::FLe | Op::FEq => (vec![F32, F32], Cc),
        Op::FToI32 | Op::FToI32Trunc => (vec![F32], I32),
        Op::I32ToF => (vec![I32], F32),
        Op::INeg | Op::IAbs => (vec![I32], I32),
        Op::IEq | Op::INe | Op::ILtS | Op::ILeS | Op::ILtU | Op::ILeU => (vec![I32, I32], Cc),
        Op::And | Op::Or | Op::Xor => (vec![Word, Word], same(Word)),
        Op::Not | Op::Mov => (vec![Word], same(Word)),
        Op::Shl | Op::Shr | Op::Sra => (vec![Word, I32], args.first().map_or(Word, |&t| t)),
        Op::Select => {
            let t = match (args.get(1), args.get(2)) {
                (Some(&a), Some(&b)) if a == b => a,
                (Some(&a), _) if a != Word => a,
                (_, Some(&b)) => b,
                _ => Word,
            };
            (vec![Cc, t, t], t)
        }
        _ => (vec![I32, I32], I32),
    }
}

macro_rules! binary {
    ($($(#[$doc:meta])* $name:ident => $op:ident;)*) => {
        $($(#[$doc])* pub fn $name(&mut self, a: Value, b: Value) -> Value {
            self.op(Op::$op, &[a, b])
        })*
    };
}

macro_rules! unary {
    ($($name:ident => $op:ident;)*) => {
        $(pub fn $name(&mut self, a: Value) -> Value {
            self.op(Op::$op, &[a])
        })*
    };
}

impl KernelBuilder {
    pub fn new(name: &str) -> Self {
        KernelBuilder {
            kernel: Kernel {
                name: name.to_string(),
                streams: Vec::new(),
                params: Vec::new(),
                nodes: Vec::new(),
                main_loop: None,
            },
            region: Region::Pre,
            errors: Vec::new(),
        }
    }

    /// The kernel built so far (for inspection while building).
    pub fn kernel(&self) -> &Kernel {
        &self.kernel
    }

    fn push(&mut self, node: Node, ty: Option<Ty>, region: Region) -> Value {
        let v = Value(self.kernel.nodes.len() as u32);
        self.kernel.nodes.push(Def {
            node,
            ty,
            region,
            name: String::new(),
        });
        v
    }

    fn here(&mut self, node: Node, ty: Option<Ty>) -> Value {
        self.push(node, ty, self.region)
    }

    fn stream(&mut self, name: &str, dir: Dir) -> StreamId {
        self.kernel.streams.push(Stream {
            name: name.to_string(),
            dir,
        });
        StreamId(self.kernel.streams.len() as u16 - 1)
    }

    /// Declares an input stream.
    pub fn input(&mut self, name: &str) -> StreamId {
        self.stream(name, Dir::In)
    }

    /// Declares an output stream.
    pub fn output(&mut self, name: &str) -> StreamId {
        self.stream(name, Dir::Out)
    }

    /// Names a value for listings and error messages.
    pub fn name(&mut self, v: Value, name: &str) -> Value {
        if let Some(d) = self.kernel.nodes.get_mut(v.index()) {
            d.name = name.to_string();
        }
        v
    }

    /// A per-kernel parameter: a word given at start, the same in every cluster.
    pub fn param(&mut self, name: &str, ty: Ty) -> Value {
        self.kernel.params.push(name.to_string());
        let i = self.kernel.params.len() as u16 - 1;
        let v = self.push(Node::Param(i), Some(ty), Region::Pre);
        self.name(v, name)
    }

    pub fn param_f32(&mut self, name: &str) -> Value {
        self.param(name, Ty::F32)
    }

    /// A constant word of type `ty`.
    pub fn constant(&mut self, bits: u32, ty: Ty) -> Value {
        self.push(Node::Const(bits), Some(ty), Region::Pre)
    }

    pub fn f32(&mut self, x: f32) -> Value {
        self.constant(x.to_bits(), Ty::F32)
    }

    pub fn i32(&mut self, x: i32) -> Value {
        self.constant(x as u32, Ty::I32)
    }

    pub fn word(&mut self, x: u32) -> Value {
        self.constant(x, Ty::Word)
    }

    /// The cluster's index (`int32`).
    pub fn cluster_id(&mut self) -> Value {
        self.push(Node::ClusterId, Some(Ty::I32), Region::Pre)
    }

    /// Starts the main loop: what follows is its body.
    pub fn begin_loop(&mut self, spec: LoopSpec) {
        if self.region != Region::Pre {
            self.errors
                .push("a kernel has one main loop: `begin_loop` called twice".into());
            return;
        }
        self.kernel.main_loop = Some(spec);
        self.region = Region::Loop;
    }

    /// Ends the main loop: what follows runs after it.
    pub fn end_loop(&mut self) {
        if self.region != Region::Loop {
            self.errors.push("`end_loop` without `begin_loop`".into());
            return;
        }
        self.region = Region::Post;
    }

    /// An arithmetic op (`Select` takes `[cond, a, b]`); its type follows [`signature`].
    pub fn op(&mut self, op: Op, args: &[Value]) -> Value {
        let tys: Vec<Ty> = args
            .iter()
            .map(|a| {
                self.kernel
                    .nodes
                    .get(a.index())
                    .and_then(|d| d.ty)
                    .unwrap_or(Ty::Word)
            })
            .collect();
        let (_, ty) = signature(op, &tys);
        self.here(
            Node::Op {
                op,
                args: args.to_vec(),
            },
            Some(ty),
        )
    }

    binary! {
        fadd => FAdd; fsub => FSub; fmul => FMul; fdiv => FDiv; fmin => FMin; fmax => FMax;
        /// `a < b` as a condition.
        flt => FLt;
        fle => FLe; feq => FEq;
        iadd => IAdd; isub => ISub; imul => IMulLo; imin => IMinS; imax => IMaxS;
        and => And; or => Or; xor => Xor; shl => Shl; shr => Shr; sra => Sra;
        ieq => IEq; ine => INe; ilt => ILtS; ile => ILeS; iltu => ILtU;
    }

    unary! {
        fsqrt => FSqrt; fabs => FAbs; fneg => FNeg; ftoi => FToI32; ftoi_trunc => FToI32Trunc;
        itof => I32ToF; ineg => INeg; not => Not; mov => Mov;
    }

    /// `cond ? a : b`, per cluster.
    pub fn select(&mut self, cond: Value, a: Value, b: Value) -> Value {
        self.op(Op::Select, &[cond, a, b])
    }

    /// The same word under type `ty` (no code).
    pub fn cast(&mut self, value: Value, ty: Ty) -> Value {
        self.here(Node::Cast { value }, Some(ty))
    }

    /// `a·b + c` in two roundings (the machine has no fused multiply-add).
    pub fn fmadd(&mut self, a: Value, b: Value, c: Value) -> Value {
        let p = self.fmul(a, b);
        self.fadd(p, c)
    }

    /// The next word of an input stream.
    pub fn read(&mut self, stream: StreamId) -> Value {
        self.here(Node::Read { stream, cond: None }, Some(Ty::Word))
    }

    pub fn read_f32(&mut self, stream: StreamId) -> Value {
        self.read_as(stream, Ty::F32)
    }

    pub fn read_i32(&mut self, stream: StreamId) -> Value {
        self.read_as(stream, Ty::I32)
    }

    pub fn read_as(&mut self, stream: StreamId, ty: Ty) -> Value {
        self.here(Node::Read { stream, cond: None }, Some(ty))
    }

    /// Conditional read: clusters where `cond` holds take the stream's next words in cluster
    /// order; the others get `otherwise`. The value has `otherwise`'s type.
    pub fn read_if(&mut self, stream: StreamId, cond: Value, otherwise: Value) -> Value {
        let ty = self.kernel.nodes.get(otherwise.index()).and_then(|d| d.ty);
        self.here(
            Node::Read {
                stream,
                cond: Some((cond, otherwise)),
            },
            ty.or(Some(Ty::Word)),
        )
    }

    /// Appends every cluster's word to an output stream, in cluster order.
    pub fn write(&mut self, stream: StreamId, value: Value) {
        self.here(
            Node::Write {
                stream,
                value,
                cond: None,
            },
            None,
        );
    }

    /// Appends the words of the clusters where `cond` holds, in cluster order.
    pub fn write_if(&mut self, stream: StreamId, cond: Value, value: Value) {
        self.here(
            Node::Write {
                stream,
                value,
                cond: Some(cond),
            },
            None,
        );
    }

    /// Scratchpad word `base + offset` (offset an `int32` value, or none).
    pub fn sp_read(&mut self, base: u16, offset: Option<Value>) -> Value {
        self.here(Node::SpRead { base, offset }, Some(Ty::Word))
    }

    pub fn sp_write(&mut self, base: u16, offset: Option<Value>, data: Value) {
        self.here(Node::SpWrite { base, offset, data }, None);
    }

    /// A word from another cluster, chosen by `perm`.
    pub fn comm(&mut self, value: Value, perm: Perm) -> Value {
        let ty = self.kernel.nodes.get(value.index()).and_then(|d| d.ty);
        self.here(Node::Comm { value, perm }, ty.or(Some(Ty::Word)))
    }

    /// A loop-carried value (inside the loop): `init` in the first iteration, then what
    /// [`set_next`](Self::set_next) gave in the previous one. After the loop it holds the
    /// last value.
    pub fn carried(&mut self, init: Value) -> Value {
        if self.region != Region::Loop {
            self.errors
                .push(format!("carried value of {init} created outside the loop"));
        }
        let ty = self.kernel.nodes.get(init.index()).and_then(|d| d.ty);
        self.here(Node::Carried { init, next: None }, ty.or(Some(Ty::Word)))
    }

    /// Sets the value `carried` takes in the next iteration.
    pub fn set_next(&mut self, carried: Value, next: Value) {
        match self.kernel.nodes.get_mut(carried.index()) {
            Some(Def {
                node: Node::Carried { next: n, .. },
                ..
            }) => {
                if n.is_some() {
                    self.errors
                        .push(format!("next value of carried {carried} set twice"));
                }
                *n = Some(next);
            }
            _ => self.errors.push(format!(
                "`set_next` on {carried}, which is not a carried value"
            )),
        }
    }

    /// Checks the kernel and returns it.
    pub fn finish(self) -> Result<Kernel, VerifyError> {
        if let Some(e) = self.errors.first() {
            return Err(VerifyError {
                kernel: self.kernel.name.clone(),
                message: e.clone(),
            });
        }
        if self.region == Region::Loop {
            return Err(VerifyError {
                kernel: self.kernel.name.clone(),
                message: "the main loop is not closed (`end_loop`)".into(),
            });
        }
        verify(&self.kernel)?;
        Ok(self.kernel)
    }
}
