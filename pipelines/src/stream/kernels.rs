//! Kernels by name: a stream program registers the kernels it may call, each under a name
//! and with a typed handle; only those it calls are compiled — up front, on the host's
//! cores, for the ones every frame reaches ([`KernelLibrary::compile_now`]), or the first
//! time they are called for the ones only some frames reach (a merge stage, say).

use std::time::Instant;

use imagine_units::desc::MachineDesc;

use crate::compile::cache::Outcome;
use crate::compile::{CompileCache, CompileError, Compiled};
use crate::kernel::{Dir, Kernel};

/// A registered kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct KernelId(usize);

pub(crate) struct Entry {
    /// The name the program calls it by (a kernel may be registered twice, built for two
    /// uses, such as `compact_recycle` with two null records).
    pub name: String,
    pub kernel: Kernel,
    pub compiled: Option<Compiled>,
    /// Its program index in the stream controller, once loaded.
    pub program: Option<usize>,
}

/// The kernels of a stream program.
pub struct KernelLibrary {
    desc: MachineDesc,
    cache: CompileCache,
    pub(crate) entries: Vec<Entry>,
    compile_seconds: f64,
    from_cache: usize,
}

impl KernelLibrary {
    /// Kernels for `desc`, compiled through `cache` (microcode kept on disk between runs).
    pub fn new(desc: &MachineDesc, cache: CompileCache) -> KernelLibrary {
        KernelLibrary {
            desc: desc.clone(),
            cache,
            entries: Vec::new(),
            compile_seconds: 0.0,
            from_cache: 0,
        }
    }

    /// Of the kernels compiled, how many were read from the compile cache.
    pub fn from_cache(&self) -> usize {
        self.from_cache
    }

    /// Registers `kernel` under `name` (unique within the program).
    pub fn register(&mut self, name: &str, kernel: Kernel) -> KernelId {
        assert!(
            self.entries.iter().all(|e| e.name != name),
            "kernel `{name}` registered twice"
        );
        self.entries.push(Entry {
            name: name.into(),
            kernel,
            compiled: None,
            program: None,
        });
        KernelId(self.entries.len() - 1)
    }

    /// Every registered kernel with its name, in the order registered.
    pub fn into_kernels(self) -> Vec<(String, Kernel)> {
        self.entries
            .into_iter()
            .map(|e| (e.name, e.kernel))
            .collect()
    }

    /// The name `program` (an index in the stream controller's programs) was registered
    /// under, if it is one of these kernels'.
    pub fn name_of_program(&self, program: usize) -> Option<&str> {
        self.entry_of_program(program).map(|e| e.name.as_str())
    }

    fn entry_of_program(&self, program: usize) -> Option<&Entry> {
        self.entries.iter().find(|e| e.program == Some(program))
    }

    pub fn name(&self, k: KernelId) -> &str {
        &self.entries[k.0].name
    }

    pub fn kernel(&self, k: KernelId) -> &Kernel {
        &self.entries[k.0].kernel
    }

    pub(crate) fn entry_mut(&mut self, k: KernelId) -> &mut Entry {
        &mut self.entries[k.0]
    }

    pub(crate) fn entry(&self, k: KernelId) -> &Entry {
        &self.entries[k.0]
    }

    /// Host seconds spent compiling so far.
    pub fn compile_seconds(&self) -> f64 {
        self.compile_seconds
    }

    /// The registered kernels that were compiled (called, or compiled up front).
    pub fn built(&self) -> Vec<&str> {
        self.entries
            .iter()
            .filter(|e| e.compiled.is_some())
            .map(|e| e.name.as_str())
            .collect()
    }

    /// The registered kernels never compiled.
    pub fn not_built(&self) -> Vec<&str> {
        self.entries
            .iter()
            .filter(|e| e.compiled.is_none())
            .map(|e| e.name.as_str())
            .collect()
    }

    /// Compiles `kernels` (those not compiled yet) on the host's cores.
    pub fn compile_now(&mut self, kernels: &[KernelId]) -> Result<(), CompileError> {
        let mut todo: Vec<usize> = Vec::new();
        // Each once, in order: objects that share a program name its kernels again.
        for i in kernels.iter().map(|k| k.0) {
            if self.entries[i].compiled.is_none() && !todo.contains(&i) {
                todo.push(i);
            }
        }
        if todo.is_empty() {
            return Ok(());
        }
        let start = Instant::now();
        let list: Vec<&Kernel> = todo.iter().map(|&i| &self.entries[i].kernel).collect();
        let done = compile_in_parallel(&list, &self.desc, &self.cache);
        self.compile_seconds += start.elapsed().as_secs_f64();
        for (at, (c, outcome)) in done {
            let i = todo[at];
            self.entries[i].compiled = Some(c?);
            self.from_cache += usize::from(outcome == Outcome::Hit);
        }
        Ok(())
    }

    /// The initiation interval of the compiled loop of the kernel loaded as program
    /// `program` (`None`: not loaded, or no loop).
    pub fn ii_of_program(&self, program: usize) -> Option<u32> {
        self.entry_of_program(program)?.compiled.as_ref()?.report.ii
    }

    /// The stream names of a kernel in binding order: its declared streams, then its
    /// parameters' stream (`params`) if the compiler gave it one.
    pub fn binding_names(&self, k: KernelId) -> Vec<(String, Dir)> {
        let e = &self.entries[k.0];
        let mut names: Vec<(String, Dir)> = e
            .kernel
            .streams
            .iter()
            .map(|s| (s.name.clone(), s.dir))
            .collect();
        if e.compiled
            .as_ref()
            .is_some_and(|c| c.params_stream.is_some())
        {
            names.push((PARAMS.into(), Dir::In));
        }
        names
    }
}

/// The binding name of a kernel's parameter stream.
pub const PARAMS: &str = "params";

/// A kernel's compile result and where its microcode came from.
type Compile = (Result<Compiled, CompileError>, Outcome);

/// Compiles `kernels` through `cache` on as many host threads as there are cores (each
/// kernel on its own; the microcode does not depend on which thread compiled it), in their
/// order.
fn compile_in_parallel(
    kernels: &[&Kernel],
    desc: &MachineDesc,
    cache: &CompileCache,
) -> Vec<(usize, Compile)> {
    use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
    let next = AtomicUsize::new(0);
    // After a failure no further kernel is started: a machine the pipeline cannot serve is
    // refused in the time of one compile, not of all. Kernels are taken in order and those
    // started are finished, so the first kernel in the list that fails is always compiled
    // and reported, whatever the timing.
    let failed = AtomicBool::new(false);
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(kernels.len());
    let mut done: Vec<(usize, Compile)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut mine = Vec::new();
                    while !failed.load(Ordering::Relaxed) {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(k) = kernels.get(i) else { break };
                        let result = cache.compile_with_outcome(k, desc);
                        if result.0.is_err() {
                            failed.store(true, Ordering::Relaxed);
                        }
                        mine.push((i, result));
                    }
                    mine
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a compiler thread panicked"))
            .collect()
    });
    done.sort_by_key(|&(i, _)| i);
    done
}
