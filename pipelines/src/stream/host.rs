//! The host side of a stream program: the only way a pipeline talks to the processor.
//!
//! Every operation becomes a stream instruction queued on the stream controller, whose
//! scoreboard orders it against the others by the SRF and DRAM words they touch: kernel
//! calls (streams bound by name), loads and stores of records, gathers and scatters by an
//! index stream, host-interface writes into the SRF and read-backs from it. The host waits
//! for the machine only where it needs a number the machine computed — a read-back, the
//! length of a conditional output — and, before it waits for a kernel, queues the work it
//! was told to defer ([`StreamHost::defer`]), so that the clusters have work queued behind
//! that kernel while the host waits (a read-back alone is short and does not flush).
//!
//! Each instruction is tagged with the batch the pipeline was in when it queued it, for
//! per-batch statistics.

use std::fmt;

use imagine_hdl::Sim;
use imagine_units::desc::MachineDesc;
use imagine_units::hwrast::{RasterJob, RasterResult};
use imagine_units::machine::StreamBinding;
use imagine_units::memory::{MemOp, MemOpKind, Pattern};
use imagine_units::processor::{self, Processor, ProcessorOptions, StreamProgram};
use imagine_units::stream_controller::{InstrRecord, StreamInstr};

use super::dram::{Buffer, DramMap};
use super::kernels::{KernelId, KernelLibrary};
use super::srf::Layout;

/// The machine stopped, a kernel could not be compiled or loaded, or the pipeline bound
/// its streams wrongly.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HostError(pub String);

impl fmt::Display for HostError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for HostError {}

/// A queued kernel call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Call {
    pub id: usize,
    pub kernel: KernelId,
}

/// A queued call of the hardware rasterizer (a hardware kernel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RasterCall {
    pub id: usize,
}

/// A deferred kernel call: its kernel and named bindings.
struct Deferred {
    kernel: KernelId,
    bindings: Vec<(String, StreamBinding)>,
    batch: Option<usize>,
}

/// The host driving one processor.
pub struct StreamHost {
    sim: Sim,
    desc: MachineDesc,
    pub kernels: KernelLibrary,
    pub dram: DramMap,
    clusters: usize,
    deferred: Vec<Deferred>,
    batch: Option<usize>,
    /// The batch each instruction was queued in (by instruction index).
    tags: Vec<Option<usize>>,
    max_cycles: u64,
    /// The programs in the microcode store once every queued load has run, oldest load
    /// first: the controller evicts in that order when a load does not fit.
    resident: Vec<usize>,
    /// Queued kernel calls (instruction, program) not yet seen complete.
    pending: Vec<(usize, usize)>,
}

impl StreamHost {
    /// A processor built from `desc` running nothing yet; `on_start` sees the simulation
    /// before its first cycle (to attach a waveform tracer). The run stops with an error
    /// past `max_cycles` core cycles.
    pub fn new(
        desc: &MachineDesc,
        kernels: KernelLibrary,
        dram: DramMap,
        on_start: Option<imagine_units::runner::OnStart>,
        max_cycles: u64,
    ) -> Result<StreamHost, HostError> {
        let opts = ProcessorOptions {
            on_start,
            ..ProcessorOptions::default()
        };
        let program = StreamProgram {
            kernels: Vec::new(),
            instrs: Vec::new(),
        };
        let sim = processor::build(desc, program, opts).map_err(|e| HostError(e.to_string()))?;
        Ok(StreamHost {
            sim,
            desc: desc.clone(),
            kernels,
            dram,
            clusters: desc.cluster.count,
            deferred: Vec::new(),
            batch: None,
            tags: Vec::new(),
            max_cycles,
            resident: Vec::new(),
            pending: Vec::new(),
        })
    }

    pub fn sim(&self) -> &Sim {
        &self.sim
    }

    pub fn sim_mut(&mut self) -> &mut Sim {
        &mut self.sim
    }

    pub fn desc(&self) -> &MachineDesc {
        &self.desc
    }

    pub fn clusters(&self) -> usize {
        self.clusters
    }

    /// Core cycles simulated so far.
    pub fn cycles(&self) -> u64 {
        self.sim.core_cycles()
    }

    /// Tags the instructions queued from now on with batch `b` (`None`: no batch).
    pub fn set_batch(&mut self, b: Option<usize>) {
        self.batch = b;
    }

    /// The batch of each instruction, by index.
    pub fn batch_tags(&self) -> &[Option<usize>] {
        &self.tags
    }

    pub fn records(&self) -> &[InstrRecord] {
        processor::processor(&self.sim).controller().records()
    }

    fn push(&mut self, instr: StreamInstr) -> usize {
        let id = processor::processor_mut(&mut self.sim).push(instr);
        self.tags.resize(id + 1, None);
        self.tags[id] = self.batch;
        id
    }

    /// The controller's program index of `k`: compiled (if it was not) and its microcode
    /// load queued the first time it is called, and again when later loads have evicted
    /// it (the store holds `microcontroller.store_words`; a frame's kernels may not fit).
    fn program(&mut self, k: KernelId) -> Result<usize, HostError> {
        let p = match self.kernels.entry(k).program {
            Some(p) => p,
            None => self.add_program(k)?,
        };
        if self.resident.contains(&p) {
            return Ok(p);
        }
        let size = |s: &Sim, q: usize| {
            processor::processor(s).controller().programs()[q]
                .code
                .len()
        };
        let store = self.desc.microcontroller.store_words;
        let mut used: usize = self.resident.iter().map(|&q| size(&self.sim, q)).sum();
        let mut evicted = Vec::new();
        while used + size(&self.sim, p) > store && !self.resident.is_empty() {
            let q = self.resident.remove(0);
            used -= size(&self.sim, q);
            evicted.push(q);
        }
        if !evicted.is_empty() {
            // The load may run ahead of queued calls: those of the programs it evicts
            // complete first.
            let records =
                |p: &Processor, id: usize| p.controller().records()[id].completed.is_some();
            let processor = processor::processor(&self.sim);
            self.pending.retain(|&(id, _)| !records(processor, id));
            let ids: Vec<usize> = self
                .pending
                .iter()
                .filter(|(_, q)| evicted.contains(q))
                .map(|&(id, _)| id)
                .collect();
            self.run_until(|p, _| ids.iter().all(|&id| records(p, id)))?;
        }
        self.resident.push(p);
        self.push(StreamInstr::LoadMicrocode { program: p });
        Ok(p)
    }

    /// Compiles `k` (if it was not) and adds its microcode to the controller's programs.
    fn add_program(&mut self, k: KernelId) -> Result<usize, HostError> {
        self.kernels.compile_now(&[k]).map_err(|e| {
            HostError(format!(
                "cannot compile kernel `{}`: {e}",
                self.kernels.name(k)
            ))
        })?;
        let code = self
            .kernels
            .entry(k)
            .compiled
            .as_ref()
            .expect("compiled")
            .program
            .clone();
        let p = processor::processor_mut(&mut self.sim)
            .add_program(&self.desc, code)
            .map_err(HostError)?;
        self.kernels.entry_mut(k).program = Some(p);
        Ok(p)
    }

    /// Queues a call of `k` with each of its streams bound by name (its parameters, if
    /// it has any, as [`super::PARAMS`]). Every stream must be bound exactly once.
    pub fn call(
        &mut self,
        k: KernelId,
        bindings: &[(&str, StreamBinding)],
    ) -> Result<Call, HostError> {
        let program = self.program(k)?;
        let names = self.kernels.binding_names(k);
        let kernel = self.kernels.name(k).to_string();
        for (name, _) in bindings {
            if !names.iter().any(|(n, _)| n == name) {
                return Err(HostError(format!(
                    "kernel `{kernel}` has no stream `{name}` (its streams: {})",
                    names
                        .iter()
                        .map(|(n, _)| n.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
        }
        let ordered = names
            .iter()
            .map(|(name, _)| {
                let mut found = bindings.iter().filter(|(n, _)| n == name);
                match (found.next(), found.next()) {
                    (Some(&(_, b)), None) => Ok(b),
                    (None, _) => Err(HostError(format!(
                        "kernel `{kernel}`: stream `{name}` is not bound"
                    ))),
                    (Some(_), Some(_)) => Err(HostError(format!(
                        "kernel `{kernel}`: stream `{name}` is bound twice"
                    ))),
                }
            })
            .collect::<Result<Vec<_>, _>>()?;
        let id = self.push(StreamInstr::Kernel {
            program,
            bindings: ordered,
        });
        if self.pending.len() >= 1024 {
            let sim = &self.sim;
            self.pending.retain(|&(id, _)| {
                processor::processor(sim).controller().records()[id]
                    .completed
                    .is_none()
            });
        }
        self.pending.push((id, program));
        Ok(Call { id, kernel: k })
    }

    /// Queues a call of `k` later: just before the host next waits for a kernel or drains
    /// the machine, or at [`StreamHost::flush_deferred`], whichever comes first.
    pub fn defer(&mut self, k: KernelId, bindings: &[(&str, StreamBinding)]) {
        self.deferred.push(Deferred {
            kernel: k,
            bindings: bindings.iter().map(|(n, b)| (n.to_string(), *b)).collect(),
            batch: self.batch,
        });
    }

    /// Queues every deferred call now.
    pub fn flush_deferred(&mut self) -> Result<(), HostError> {
        self.flush_deferred_through(usize::MAX)
    }

    /// Queues the deferred calls of batches up to `batch` (those deferred outside a batch
    /// too), in the order they were deferred, keeping later batches' deferred.
    pub fn flush_deferred_through(&mut self, batch: usize) -> Result<(), HostError> {
        let keep = self
            .deferred
            .iter()
            .position(|d| d.batch.is_some_and(|b| b > batch))
            .unwrap_or(self.deferred.len());
        let rest = self.deferred.split_off(keep);
        let now = std::mem::replace(&mut self.deferred, rest);
        let batch = self.batch;
        for d in now {
            self.batch = d.batch;
            let b: Vec<(&str, StreamBinding)> =
                d.bindings.iter().map(|(n, b)| (n.as_str(), *b)).collect();
            self.call(d.kernel, &b)?;
        }
        self.batch = batch;
        Ok(())
    }

    /// A memory operation on DRAM buffer `buffer` from word `offset`.
    #[allow(clippy::too_many_arguments)]
    fn mem(
        &mut self,
        kind: MemOpKind,
        buffer: Buffer,
        offset: u64,
        pattern: Pattern,
        layout: Layout,
        records: usize,
        srf: StreamBinding,
    ) {
        let row_records = if layout.cluster_rows && layout.record_words > 1 {
            self.clusters
        } else {
            1
        };
        debug_assert!(records * layout.record_words <= srf.words);
        self.push(StreamInstr::Memory(MemOp {
            kind,
            base: self.dram.base(buffer) + offset,
            pattern,
            record_words: layout.record_words,
            records,
            srf_start: srf.start,
            row_records,
            cacheable: kind == MemOpKind::Load && self.dram.is_cacheable(buffer),
        }));
    }

    /// Loads `records` consecutive records from record `first` of `from` into `to`.
    pub fn load(
        &mut self,
        from: Buffer,
        first: u64,
        layout: Layout,
        records: usize,
        to: StreamBinding,
    ) {
        let w = layout.record_words as u64;
        self.mem(
            MemOpKind::Load,
            from,
            first * w,
            Pattern::Strided { stride: w },
            layout,
            records,
            to,
        );
    }

    /// Loads one word of every `stride`-word record from word `first` of `from`.
    pub fn load_strided(
        &mut self,
        from: Buffer,
        first: u64,
        stride: u64,
        words: usize,
        to: StreamBinding,
    ) {
        self.mem(
            MemOpKind::Load,
            from,
            first,
            Pattern::Strided { stride },
            Layout::words(),
            words,
            to,
        );
    }

    /// Stores `records` records of `from` to `to` from record `first`.
    pub fn store(
        &mut self,
        from: StreamBinding,
        layout: Layout,
        records: usize,
        to: Buffer,
        first: u64,
    ) {
        let w = layout.record_words as u64;
        self.mem(
            MemOpKind::Store,
            to,
            first * w,
            Pattern::Strided { stride: w },
            layout,
            records,
            from,
        );
    }

    /// Gathers `records` records of `from` by the record numbers in `index` (each below
    /// `bound`, which tells the scoreboard the records it may touch).
    pub fn gather(
        &mut self,
        from: Buffer,
        index: StreamBinding,
        bound: u64,
        layout: Layout,
        records: usize,
        to: StreamBinding,
    ) {
        let pattern = Pattern::Indexed {
            index_start: index.start,
            scale: layout.record_words as u64,
            bound: Some(bound),
        };
        self.mem(MemOpKind::Load, from, 0, pattern, layout, records, to);
    }

    /// Scatters `records` records of `from` to the record numbers in `index` of `to`.
    pub fn scatter(
        &mut self,
        from: StreamBinding,
        index: StreamBinding,
        bound: u64,
        layout: Layout,
        records: usize,
        to: Buffer,
    ) {
        let pattern = Pattern::Indexed {
            index_start: index.start,
            scale: layout.record_words as u64,
            bound: Some(bound),
        };
        self.mem(MemOpKind::Store, to, 0, pattern, layout, records, from);
    }

    /// Writes `words` into the SRF at `to` over the host interface.
    pub fn write(&mut self, to: StreamBinding, words: Vec<u32>) {
        debug_assert!(words.len() <= to.words);
        self.push(StreamInstr::WriteSrf {
            start: to.start,
            words,
        });
    }

    /// Writes kernel parameters (each replicated in every cluster) at `to`.
    pub fn write_params(&mut self, to: StreamBinding, words: &[u32]) {
        let c = self.clusters;
        let words = words
            .iter()
            .flat_map(|&w| std::iter::repeat_n(w, c))
            .collect();
        self.write(to, words);
    }

    /// Reads `from` back over the host interface, once every instruction queued before
    /// that writes it has completed.
    pub fn read_back(&mut self, from: StreamBinding) -> Result<Vec<u32>, HostError> {
        let id = self.push(StreamInstr::ReadSrf {
            start: from.start,
            len: from.words,
        });
        self.run_until(|p, _| p.controller().records()[id].completed.is_some())?;
        Ok(self.records()[id].read.clone())
    }

    /// Waits until `call` has completed (later instructions may still be in flight).
    pub fn wait(&mut self, call: Call) -> Result<(), HostError> {
        self.wait_id(call.id)
    }

    /// Queues a call of the machine's hardware rasterizer: a hardware kernel, ordered
    /// against the other instructions by the streams it reads and writes, as a kernel
    /// call is (thesis §6.6).
    pub fn rasterize(&mut self, job: RasterJob) -> Result<RasterCall, HostError> {
        if self.desc.rasterizer.is_none() {
            return Err(HostError(format!(
                "machine `{}` has no hardware rasterizer ([rasterizer] in its description)",
                self.desc.name
            )));
        }
        let id = self.push(StreamInstr::Rasterize(Box::new(job)));
        Ok(RasterCall { id })
    }

    /// Waits until the rasterizer call has completed, and says what it did.
    pub fn raster_result(&mut self, call: RasterCall) -> Result<RasterResult, HostError> {
        self.wait_id(call.id)?;
        self.records()[call.id]
            .raster
            .clone()
            .ok_or_else(|| HostError("a rasterizer call completed without a result".into()))
    }

    /// Words a completed call wrote to its output `stream`.
    pub fn written(&self, call: Call, stream: &str) -> Result<usize, HostError> {
        let names = self.kernels.binding_names(call.kernel);
        let i = names.iter().position(|(n, _)| n == stream).ok_or_else(|| {
            HostError(format!(
                "kernel `{}` has no stream `{stream}`",
                self.kernels.name(call.kernel)
            ))
        })?;
        let r = &self.records()[call.id];
        if r.completed.is_none() {
            return Err(HostError(format!(
                "kernel `{}`: its output `{stream}` is read before the call completed",
                self.kernels.name(call.kernel)
            )));
        }
        Ok(r.outputs[i])
    }

    fn wait_id(&mut self, id: usize) -> Result<(), HostError> {
        self.flush_deferred()?;
        self.run_until(|p, _| p.controller().records()[id].completed.is_some())
    }

    /// Runs until every queued instruction has completed and the memory is idle.
    pub fn drain(&mut self) -> Result<(), HostError> {
        self.flush_deferred()?;
        self.run_until(|p, s| {
            p.is_done()
                && s.modules_of::<imagine_units::dram::DramChannel>()
                    .all(imagine_units::dram::DramChannel::is_idle)
        })
    }

    fn run_until(&mut self, done: impl Fn(&Processor, &Sim) -> bool) -> Result<(), HostError> {
        let left = self.max_cycles.saturating_sub(self.sim.core_cycles());
        let finished = processor::run_until(&mut self.sim, left, done)
            .map_err(|e| HostError(format!("the machine stopped: {e}")))?;
        if !finished {
            return Err(HostError(format!(
                "the program did not finish within {} core cycles (--max-cycles)",
                self.max_cycles
            )));
        }
        Ok(())
    }

    /// The two block-aligned halves of a staging stream.
    fn halves(&self, staging: StreamBinding) -> [StreamBinding; 2] {
        let block = self.desc.srf.block_words.max(1);
        let half = (staging.words / 2) / block * block;
        [0, 1].map(|i| StreamBinding {
            start: staging.start + i * half,
            words: half,
        })
    }

    /// Copies `words` into `to` from word `first` through the host interface: written into
    /// the SRF at `staging` (two halves, alternately, so that one is written while the
    /// other is stored) and stored to DRAM.
    pub fn upload(&mut self, words: &[u32], to: Buffer, first: u64, staging: StreamBinding) {
        let halves = self.halves(staging);
        let half = halves[0].words;
        for (i, chunk) in words.chunks(half.max(1)).enumerate() {
            let buf = halves[i % 2];
            self.write(buf, chunk.to_vec());
            self.store(
                buf,
                Layout::words(),
                chunk.len(),
                to,
                first + (i * half) as u64,
            );
        }
    }

    /// Reads `words` words of `from` from word `first` back to the host, `stride` words
    /// apart (1: consecutive), through the SRF at `staging`.
    pub fn download(
        &mut self,
        from: Buffer,
        first: u64,
        stride: u64,
        words: usize,
        staging: StreamBinding,
    ) -> Result<Vec<u32>, HostError> {
        let halves = self.halves(staging);
        let half = halves[0].words;
        let mut out = Vec::with_capacity(words);
        let mut pending: Option<(usize, StreamBinding)> = None;
        let mut done = 0;
        let mut i = 0;
        while done < words || pending.is_some() {
            // Queue the next load before reading the previous half back.
            let next = (done < words).then(|| {
                let n = half.min(words - done);
                let buf = StreamBinding {
                    start: halves[i % 2].start,
                    words: n,
                };
                self.load_strided(from, first + done as u64 * stride, stride, n, buf);
                done += n;
                i += 1;
                (n, buf)
            });
            if let Some((_, buf)) = pending.take() {
                out.extend(self.read_back(buf)?);
            }
            pending = next;
        }
        Ok(out)
    }

    /// Finishes the waveform, if one is being written.
    pub fn finish(&mut self) -> Result<(), HostError> {
        self.sim
            .finish()
            .map_err(|e| HostError(format!("cannot finish the waveform: {e}")))
    }
}
