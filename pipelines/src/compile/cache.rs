//! The compile cache (ARCHITECTURE §5): compiled microcode kept on disk, keyed by a hash of
//! the kernel IR, the machine description and the compiler's version, so that a render
//! compiles only the kernels it has not compiled before.
//!
//! The directory is `$IMAGINE_CACHE_DIR`, else the platform's cache directory
//! (`~/.cache/imagine` on Linux); [`CompileCache::disabled`] (`--no-cache`) never touches
//! it. An entry is one file, named by the key in hex, laid out little-endian as
//!
//! | bytes | content |
//! |---|---|
//! | 4 | magic `IMKC` |
//! | 4 | cache format version ([`CACHE_FORMAT`]) |
//! | 32 | the key (BLAKE3), which must match the file's name |
//! | 8 | payload length |
//! | 32 | BLAKE3 checksum of the payload |
//! | n | payload: 4-byte length and JSON (kernel and machine names, the report, the hidden `params` stream), then the microcode image ([`write_image`]) |
//!
//! An entry is trusted only if every field checks out, the image decodes and the program
//! passes [`Program::check`](imagine_units::microcode::Program::check) against the machine
//! (which [`read_image`] does); anything else (a corrupt, truncated or stale entry, or one
//! of an older format) counts as a miss: the kernel is compiled again and the entry
//! overwritten. Entries are written to a temporary file in the same directory and renamed
//! into place, so a concurrent render never sees a half-written one. A cache that cannot
//! be written (a read-only directory, a full disk) warns once and compiles as if it were
//! not there; cache I/O never fails a compile.
//!
//! The compiler's version is the crate version and a fingerprint of the sources that
//! decide the microcode (`build.rs`: the compiler, the kernel IR, the microcode format, the
//! ops and the description's fields), so an edited compiler never reads what an older one
//! wrote.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

use serde::{Deserialize, Serialize};

use imagine_units::desc::MachineDesc;
use imagine_units::microcode::image::{read_image, write_image};

use super::{CompileError, Compiled, Report};
use crate::kernel::Kernel;

/// Version of the entry layout and of the key's contents: bump it when either changes.
pub const CACHE_FORMAT: u32 = 1;

/// BLAKE3 of the compiler's sources (see `build.rs`).
pub const COMPILER_FINGERPRINT: &str = env!("IMAGINE_COMPILER_FINGERPRINT");

/// The environment variable naming the cache directory.
pub const CACHE_DIR_VAR: &str = "IMAGINE_CACHE_DIR";

const MAGIC: &[u8; 4] = b"IMKC";
/// Magic, version, key, payload length, checksum.
const HEADER: usize = 4 + 4 + 32 + 8 + 32;
/// File name extension of an entry.
const EXTENSION: &str = "imkc";

/// Where a compile's microcode came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Read from a valid entry.
    Hit,
    /// Compiled (no entry, or one that was not trusted); stored if the cache could be
    /// written.
    Miss,
    /// Compiled without looking: the cache is disabled.
    Bypassed,
}

#[derive(Debug, Default)]
struct Counters {
    hits: AtomicUsize,
    misses: AtomicUsize,
    /// Entries found but not trusted (corrupt, truncated, stale).
    rejected: AtomicUsize,
    /// A write failed (warned once).
    warned: AtomicBool,
}

/// Compiled microcode on disk; cheap to clone (clones share their counters).
#[derive(Clone, Debug)]
pub struct CompileCache {
    dir: Option<PathBuf>,
    counters: Arc<Counters>,
}

impl PartialEq for CompileCache {
    /// Caches are equal when they use the same directory (or are both disabled).
    fn eq(&self, other: &Self) -> bool {
        self.dir == other.dir
    }
}

impl Eq for CompileCache {}

impl Default for CompileCache {
    /// Disabled: a library caller opts in (the CLI uses [`CompileCache::from_env`]).
    fn default() -> Self {
        CompileCache::disabled()
    }
}

/// What an entry holds besides the microcode image.
#[derive(Serialize, Deserialize)]
struct Meta {
    kernel: String,
    machine: String,
    report: Report,
    params_stream: Option<usize>,
}

impl CompileCache {
    /// The cache in `$IMAGINE_CACHE_DIR` if set (and not empty), else in the platform's
    /// cache directory; disabled if the platform has none.
    pub fn from_env() -> Self {
        match std::env::var_os(CACHE_DIR_VAR) {
            Some(dir) if !dir.is_empty() => CompileCache::at(dir),
            _ => match Self::default_dir() {
                Some(dir) => CompileCache::at(dir),
                None => CompileCache::disabled(),
            },
        }
    }

    /// The platform's cache directory for imagine (`~/.cache/imagine` on Linux).
    pub fn default_dir() -> Option<PathBuf> {
        directories::ProjectDirs::from("", "", "imagine").map(|p| p.cache_dir().to_path_buf())
    }

    /// A cache that is never read or written.
    pub fn disabled() -> Self {
        CompileCache {
            dir: None,
            counters: Arc::default(),
        }
    }

    /// The cache in `dir` (created when the first entry is written).
    pub fn at(dir: impl Into<PathBuf>) -> Self {
        CompileCache {
            dir: Some(dir.into()),
            counters: Arc::default(),
        }
    }

    /// The directory, if the cache is enabled.
    pub fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    pub fn is_enabled(&self) -> bool {
        self.dir.is_some()
    }

    /// Compiles served from the cache so far (by this cache and its clones).
    pub fn hits(&self) -> usize {
        self.counters.hits.load(Ordering::Relaxed)
    }

    /// Compiles that looked in the cache and compiled.
    pub fn misses(&self) -> usize {
        self.counters.misses.load(Ordering::Relaxed)
    }

    /// Entries found but not trusted (and so compiled again).
    pub fn rejected(&self) -> usize {
        self.counters.rejected.load(Ordering::Relaxed)
    }

    /// The key of `kernel` compiled for `desc` by this build of the compiler.
    pub fn key(kernel: &Kernel, desc: &MachineDesc) -> blake3::Hash {
        let mut h = blake3::Hasher::new();
        let mut field = |bytes: &[u8]| {
            h.update(&(bytes.len() as u64).to_le_bytes());
            h.update(bytes);
        };
        field(b"imagine compile cache");
        field(&CACHE_FORMAT.to_le_bytes());
        field(COMPILER_FINGERPRINT.as_bytes());
        field(env!("CARGO_PKG_VERSION").as_bytes());
        // Debug output is deterministic: the IR and the description hold only vectors,
        // strings, numbers and enums (no hash maps).
        field(format!("{kernel:?}").as_bytes());
        field(format!("{desc:?}").as_bytes());
        h.finalize()
    }

    /// The file that holds (or would hold) the entry of `kernel` on `desc`.
    pub fn entry_path(&self, kernel: &Kernel, desc: &MachineDesc) -> Option<PathBuf> {
        let key = Self::key(kernel, desc);
        self.dir
            .as_ref()
            .map(|d| d.join(format!("{}.{EXTENSION}", key.to_hex())))
    }

    /// [`compile`](super::compile) through the cache.
    pub fn compile(&self, kernel: &Kernel, desc: &MachineDesc) -> Result<Compiled, CompileError> {
        self.compile_with_outcome(kernel, desc).0
    }

    /// [`compile`](Self::compile), and where the microcode came from.
    pub fn compile_with_outcome(
        &self,
        kernel: &Kernel,
        desc: &MachineDesc,
    ) -> (Result<Compiled, CompileError>, Outcome) {
        let Some(dir) = &self.dir else {
            return (super::compile(kernel, desc), Outcome::Bypassed);
        };
        let key = Self::key(kernel, desc);
        let path = dir.join(format!("{}.{EXTENSION}", key.to_hex()));
        match std::fs::read(&path) {
            Ok(bytes) => match decode(&bytes, &key, kernel, desc) {
                Some(c) => {
                    self.counters.hits.fetch_add(1, Ordering::Relaxed);
                    return (Ok(c), Outcome::Hit);
                }
                None => {
                    self.counters.rejected.fetch_add(1, Ordering::Relaxed);
                }
            },
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            // (Unreadable: compile, and try to replace it.)
            Err(_) => {
                self.counters.rejected.fetch_add(1, Ordering::Relaxed);
            }
        }
        self.counters.misses.fetch_add(1, Ordering::Relaxed);
        let result = super::compile(kernel, desc);
        if let Ok(c) = &result
            && let Err(e) = store(dir, &path, &encode(&key, c, desc))
            && !self.counters.warned.swap(true, Ordering::Relaxed)
        {
            eprintln!(
                "warning: cannot write the compile cache in `{}` ({e}); compiling without it",
                dir.display()
            );
        }
        (result, Outcome::Miss)
    }
}

fn encode(key: &blake3::Hash, c: &Compiled, desc: &MachineDesc) -> Vec<u8> {
    let meta = Meta {
        kernel: c.program.name.clone(),
        machine: desc.name.clone(),
        report: c.report.clone(),
        params_stream: c.params_stream,
    };
    let json = serde_json::to_vec(&meta).expect("a report serialises");
    let image = write_image(&c.program, desc);
    let mut payload = Vec::with_capacity(4 + json.len() + image.len());
    payload.extend_from_slice(&(json.len() as u32).to_le_bytes());
    payload.extend_from_slice(&json);
    payload.extend_from_slice(&image);
    let mut out = Vec::with_capacity(HEADER + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&CACHE_FORMAT.to_le_bytes());
    out.extend_from_slice(key.as_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(blake3::hash(&payload).as_bytes());
    out.extend_from_slice(&payload);
    out
}

/// The entry in `bytes` if every check passes.
fn decode(
    bytes: &[u8],
    key: &blake3::Hash,
    kernel: &Kernel,
    desc: &MachineDesc,
) -> Option<Compiled> {
    if bytes.len() < HEADER || &bytes[..4] != MAGIC {
        return None;
    }
    let version = u32::from_le_bytes(bytes[4..8].try_into().ok()?);
    if version != CACHE_FORMAT || &bytes[8..40] != key.as_bytes() {
        return None;
    }
    let len = u64::from_le_bytes(bytes[40..48].try_into().ok()?);
    let payload = &bytes[HEADER..];
    if len != payload.len() as u64 || blake3::hash(payload).as_bytes() != &bytes[48..80] {
        return None;
    }
    let json_len = u32::from_le_bytes(payload.get(..4)?.try_into().ok()?) as usize;
    let json = payload.get(4..4usize.checked_add(json_len)?)?;
    let image = &payload[4 + json_len..];
    let meta: Meta = serde_json::from_slice(json).ok()?;
    if meta.kernel != kernel.name || meta.machine != desc.name || meta.report.kernel != kernel.name
    {
        return None;
    }
    let program = read_image(image, desc).ok()?;
    if program.name != kernel.name
        || meta
            .params_stream
            .is_some_and(|s| s >= program.streams.len())
    {
        return None;
    }
    Some(Compiled {
        program,
        report: meta.report,
        params_stream: meta.params_stream,
    })
}

/// Writes `bytes` to `path` through a temporary file in the same directory.
fn store(dir: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static NEXT: AtomicU64 = AtomicU64::new(0);
    std::fs::create_dir_all(dir)?;
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("entry");
    let temp = dir.join(format!(
        ".{name}.{}.{}.tmp",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    let written = std::fs::File::create(&temp)
        .and_then(|mut f| f.write_all(bytes))
        .and_then(|()| std::fs::rename(&temp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&temp);
    }
    written
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::AtomicUsize;

    use super::*;
    use crate::kernels::find;

    /// A fresh directory under the system's temporary directory, removed on drop (tests
    /// never use the user's cache).
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(name: &str) -> Self {
            static NEXT: AtomicUsize = AtomicUsize::new(0);
            let dir = std::env::temp_dir().join(format!(
                "imagine-cache-test-{name}-{}-{}",
                std::process::id(),
                NEXT.fetch_add(1, Ordering::Relaxed)
            ));
            let _ = std::fs::remove_dir_all(&dir);
            TempDir(dir)
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    fn kernel(name: &str, desc: &MachineDesc) -> Kernel {
        (find(name).expect("a library kernel").build)(desc).expect("gold8 serves it")
    }

    fn files(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .map(|rd| {
                rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    }

    /// `c` is what a fresh compile gives, to the byte.
    fn assert_fresh(c: &Compiled, fresh: &Compiled, desc: &MachineDesc) {
        assert_eq!(
            write_image(&c.program, desc),
            write_image(&fresh.program, desc)
        );
        assert_eq!(c.program, fresh.program);
        assert_eq!(c.report, fresh.report);
        assert_eq!(c.params_stream, fresh.params_stream);
    }

    #[test]
    fn a_hit_returns_the_microcode_of_a_fresh_compile() {
        let dir = TempDir::new("hit");
        let desc = MachineDesc::gold8();
        let cache = CompileCache::at(&dir.0);
        // `compact` has a parameter (the hidden `params` stream); `prefix_sum` none.
        for name in ["prefix_sum", "compact"] {
            let k = kernel(name, &desc);
            let fresh = super::super::compile(&k, &desc).unwrap();
            let (cold, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Miss, "{name}");
            assert_fresh(&cold.unwrap(), &fresh, &desc);
            assert!(cache.entry_path(&k, &desc).unwrap().is_file());
            let (warm, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Hit, "{name}");
            assert_fresh(&warm.unwrap(), &fresh, &desc);
            // Another cache on the same directory (another render) finds it too.
            let other = CompileCache::at(&dir.0);
            assert_fresh(&other.compile(&k, &desc).unwrap(), &fresh, &desc);
            assert_eq!((other.hits(), other.misses()), (1, 0));
        }
        assert_eq!((cache.hits(), cache.misses(), cache.rejected()), (2, 2, 0));
        assert_eq!(files(&dir.0).len(), 2);
    }

    #[test]
    fn keys_are_deterministic_and_tell_kernels_and_machines_apart() {
        let gold8 = MachineDesc::gold8();
        let a = CompileCache::key(&kernel("compact", &gold8), &gold8);
        assert_eq!(a, CompileCache::key(&kernel("compact", &gold8), &gold8));
        assert_ne!(a, CompileCache::key(&kernel("prefix_sum", &gold8), &gold8));
        let gold32 = MachineDesc::resolve("gold32").unwrap();
        assert_ne!(a, CompileCache::key(&kernel("compact", &gold32), &gold32));
    }

    #[test]
    fn a_changed_machine_description_misses() {
        let dir = TempDir::new("machine");
        let cache = CompileCache::at(&dir.0);
        let gold8 = MachineDesc::gold8();
        let k = kernel("prefix_sum", &gold8);
        assert_eq!(cache.compile_with_outcome(&k, &gold8).1, Outcome::Miss);
        assert_eq!(cache.compile_with_outcome(&k, &gold8).1, Outcome::Hit);
        // One changed field, even one the compiler does not read, is another machine.
        let mut changed = gold8.clone();
        changed.latency.comm += 1;
        let (c, outcome) = cache.compile_with_outcome(&k, &changed);
        assert_eq!(outcome, Outcome::Miss);
        assert_fresh(
            &c.unwrap(),
            &super::super::compile(&k, &changed).unwrap(),
            &changed,
        );
        let mut renamed = gold8.clone();
        renamed.stream_controller.min_kernel_cycles += 1;
        assert_eq!(cache.compile_with_outcome(&k, &renamed).1, Outcome::Miss);
        assert_eq!(cache.compile_with_outcome(&k, &gold8).1, Outcome::Hit);
        assert_eq!(files(&dir.0).len(), 3);
    }

    #[test]
    fn damaged_entries_are_compiled_again_and_replaced() {
        let dir = TempDir::new("damage");
        let cache = CompileCache::at(&dir.0);
        let desc = MachineDesc::gold8();
        let k = kernel("compact", &desc);
        let fresh = super::super::compile(&k, &desc).unwrap();
        assert_eq!(cache.compile_with_outcome(&k, &desc).1, Outcome::Miss);
        let path = cache.entry_path(&k, &desc).unwrap();
        let good = std::fs::read(&path).unwrap();
        let key = CompileCache::key(&k, &desc);
        let flip = |at: usize| {
            let mut b = good.clone();
            b[at] ^= 0x10;
            b
        };
        // A valid checksum over a payload that is not this kernel's.
        let other = super::super::compile(&kernel("prefix_sum", &desc), &desc).unwrap();
        let stale = encode(&key, &other, &desc);
        // A valid checksum over a payload whose image is cut short.
        let short_image = {
            let payload = &good[HEADER..good.len() - 8];
            let mut b = good[..HEADER].to_vec();
            b[40..48].copy_from_slice(&(payload.len() as u64).to_le_bytes());
            b[48..80].copy_from_slice(blake3::hash(payload).as_bytes());
            b.extend_from_slice(payload);
            b
        };
        let mut wrong_version = good.clone();
        wrong_version[4..8].copy_from_slice(&(CACHE_FORMAT + 1).to_le_bytes());
        let mut longer = good.clone();
        longer.push(0);
        let damaged: Vec<(&str, Vec<u8>)> = vec![
            ("empty", vec![]),
            ("magic", flip(0)),
            ("key", flip(20)),
            ("length", flip(41)),
            ("checksum", flip(60)),
            ("payload start", flip(HEADER + 2)),
            ("payload middle", flip(HEADER + (good.len() - HEADER) / 2)),
            ("last byte", flip(good.len() - 1)),
            ("truncated header", good[..HEADER - 1].to_vec()),
            ("truncated payload", good[..good.len() / 2].to_vec()),
            ("one byte short", good[..good.len() - 1].to_vec()),
            ("trailing byte", longer),
            ("wrong version", wrong_version),
            ("another kernel", stale),
            ("short image", short_image),
        ];
        for (i, (what, bytes)) in damaged.into_iter().enumerate() {
            std::fs::write(&path, &bytes).unwrap();
            let (c, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Miss, "{what}");
            assert_fresh(&c.unwrap(), &fresh, &desc);
            assert_eq!(cache.rejected(), i + 1, "{what}");
            // The entry was replaced by a good one.
            assert_eq!(std::fs::read(&path).unwrap(), good, "{what}");
            let (c, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Hit, "{what}");
            assert_fresh(&c.unwrap(), &fresh, &desc);
        }
        assert_eq!(files(&dir.0).len(), 1, "no temporary files left");
    }

    #[test]
    fn concurrent_compiles_agree_and_leave_no_temporary_files() {
        let dir = TempDir::new("concurrent");
        let desc = MachineDesc::gold8();
        let k = kernel("compact", &desc);
        let fresh = write_image(&super::super::compile(&k, &desc).unwrap().program, &desc);
        let images: Vec<Vec<u8>> = std::thread::scope(|s| {
            let workers: Vec<_> = (0..6)
                .map(|_| {
                    // Each thread as its own render would: a cache of its own on the dir.
                    let cache = CompileCache::at(&dir.0);
                    let k = &k;
                    let desc = &desc;
                    s.spawn(move || {
                        (0..3)
                            .map(|_| write_image(&cache.compile(k, desc).unwrap().program, desc))
                            .collect::<Vec<_>>()
                    })
                })
                .collect();
            workers
                .into_iter()
                .flat_map(|w| w.join().unwrap())
                .collect()
        });
        assert_eq!(images.len(), 18);
        assert!(images.iter().all(|i| *i == fresh));
        let names = files(&dir.0);
        assert_eq!(
            names,
            vec![format!(
                "{}.{EXTENSION}",
                CompileCache::key(&k, &desc).to_hex()
            )]
        );
    }

    #[test]
    fn a_disabled_cache_never_touches_its_directory() {
        let dir = TempDir::new("disabled");
        let desc = MachineDesc::gold8();
        let k = kernel("prefix_sum", &desc);
        let cache = CompileCache::disabled();
        assert!(!cache.is_enabled() && cache.dir().is_none());
        assert_eq!(cache.entry_path(&k, &desc), None);
        for _ in 0..2 {
            let (c, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Bypassed);
            assert!(c.is_ok());
        }
        assert_eq!((cache.hits(), cache.misses()), (0, 0));
        assert!(!dir.0.exists());
        assert_eq!(CompileCache::default(), CompileCache::disabled());
    }

    #[test]
    fn a_cache_that_cannot_be_written_still_compiles() {
        // A file where the directory should be: every write fails (as root too, unlike
        // a read-only directory).
        let dir = TempDir::new("unwritable");
        std::fs::write(&dir.0, b"not a directory").unwrap();
        let desc = MachineDesc::gold8();
        let k = kernel("prefix_sum", &desc);
        let fresh = super::super::compile(&k, &desc).unwrap();
        let cache = CompileCache::at(dir.0.join("cache"));
        for _ in 0..2 {
            let (c, outcome) = cache.compile_with_outcome(&k, &desc);
            assert_eq!(outcome, Outcome::Miss);
            assert_fresh(&c.unwrap(), &fresh, &desc);
        }
        assert_eq!(std::fs::read(&dir.0).unwrap(), b"not a directory");
        std::fs::remove_file(&dir.0).unwrap();
    }
}
