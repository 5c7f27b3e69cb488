//! The input limits: every bound that keeps a run finite and its memory bounded, in one
//! place. Each is checked where its input is read (machine descriptions, scene files and
//! their assets, microcode, DRAM traces, command-line options) and named, with its value,
//! in the error that refuses it. The README's "Input limits" table lists them.
//!
//! The bounds are far above what the published machines and scenes need (the largest
//! built-in machine has 32 clusters, the largest scene 81,920 triangles in a 1024² window);
//! they are there so that a typo or a hostile file is refused in milliseconds instead of
//! allocating terabytes or simulating for days. Those a real user could need to raise have
//! an option (`--max-cycles`).

use std::io::{self, Read};
use std::path::Path;

// ---- machine descriptions (`machines/*.toml`) ----

/// The most clusters a machine may have (the model keeps per-cluster state in arrays of
/// this size).
pub const MAX_CLUSTERS: usize = 256;
/// The most streams one kernel may address (`srf.kernel_streams`; the model keeps
/// per-stream state of a kernel in arrays of this size).
pub const MAX_KERNEL_STREAMS: usize = 64;
/// The most functional units of one class in a cluster.
pub const MAX_UNITS: usize = 32;
/// The longest latency of a unit, in core cycles.
pub const MAX_LATENCY: u32 = 256;
/// The fastest clock, in MHz (above it a frequency is taken for a typo).
pub const MAX_MHZ: u64 = 100_000;
/// How many `base` links a description may follow (a longer chain is taken for a cycle).
pub const MAX_BASE_DEPTH: usize = 8;
/// The longest host dispatch overhead of a kernel, `stream_controller.min_kernel_cycles`.
pub const MAX_MIN_KERNEL_CYCLES: u64 = 1 << 24;

// ---- DRAM traces (`imagine dram --trace`) ----

/// The most requests a trace may hold (16 Mi, about 40 times the longest microbenchmark
/// of the paper); also the bound on `--requests` for the generated ones.
pub const MAX_TRACE_REQUESTS: usize = 1 << 24;

/// The latest cycle a request may name, 2^44 (about 1.8 · 10^13 cycles, 29 hours at
/// 167 MHz): even at the slowest DRAM clock a machine may have (1 MHz), the simulator's
/// picosecond clock (a `u64`) reaches it without wrapping, and cycle arithmetic stays far
/// from overflow.
pub const MAX_TRACE_CYCLE: u64 = 1 << 44;

/// The longest line a trace may have, in bytes (comments included), so that a file with
/// no line breaks is not read whole.
pub const MAX_TRACE_LINE: usize = 4096;

// ---- scenes ----

/// Largest window side the pipeline accepts (pixel addresses stay well inside 32 bits and
/// window coordinates stay exact in fp32).
pub const MAX_WINDOW: u32 = 4096;

/// Rasterizing accelerators an S3 machine may have (`s3.accelerators`).
pub const MAX_S3_ACCELERATORS: usize = 64;

/// Primitives an S3 trace may hold: each needs a distinct 24-bit order tag in the depth
/// buffer (0 is the clear value's).
pub const MAX_S3_PRIMITIVES: usize = (1 << 24) - 1;
/// Largest `|x|` or `|y|` of a `.tri` vertex, in pixels: beyond it fp32 edge functions
/// lose every bit of sub-pixel precision.
pub const MAX_TRI_COORDINATE: f32 = 1.0e6;
/// Most quads a patch may be diced into per side.
pub const MAX_TESSELLATE: u32 = 256;
/// Most triangles a scene or `--batch` may ask of a batch (the machine's scratchpad and SRF
/// then bound it further).
pub const MAX_BATCH: u32 = 1 << 16;
/// Most rings or segments of a `uv_sphere`.
pub const MAX_SPHERE_DIVISIONS: u32 = 4096;
/// Most triangles of a scene, all objects together: 16 times SPHERE's, 8 times RATE-1's in
/// its 720 × 720 window, more than a machine's DRAM holds. A primitive or patch object that
/// would pass it is refused before its mesh is built, so that a line of a scene file cannot
/// ask for gigabytes (a `uv_sphere` of 4096 × 4096 is 33.5 M triangles).
pub const MAX_TRIANGLES: usize = 1 << 22;
/// Most subdivisions of an icosphere (7: 327,680 triangles).
pub const MAX_SUBDIVISIONS: u32 = 7;

// ---- runs ----

/// The longest a frame may take, in core cycles, before the host gives up (40 s of the
/// modelled machine at 500 MHz; `render --max-cycles` raises it).
pub const MAX_RUN_CYCLES: u64 = 20_000_000_000;
/// Most loop iterations of random input `imagine kernel check --rows` runs (the input
/// streams must fit the SRF anyway; this refuses a typo before anything is allocated).
pub const MAX_CHECK_ROWS: usize = 1 << 16;
/// Most words one `imagine kernel run --input` stream may hold.
pub const MAX_INPUT_WORDS: usize = 1 << 24;
/// Most entries of the demonstration design's clock-crossing FIFO (`demo
/// --crossing-capacity`).
pub const MAX_CROSSING_CAPACITY: usize = 1 << 16;
/// Most core cycles `imagine demo --cycles` and `imagine machine bench --cycles` simulate
/// (2^32: minutes of host time; a larger count is taken for a typo).
pub const MAX_DEMO_CYCLES: u64 = 1 << 32;

// ---- files ----

/// Largest input file read: a scene, a mesh, a machine description, microcode, a trace.
/// Files are read whole, so this bounds the memory a hostile path (`/dev/zero`, a
/// multi-gigabyte file given by mistake) can take.
pub const MAX_FILE_BYTES: u64 = 1 << 30;

/// Reads a whole file of at most [`MAX_FILE_BYTES`]: a larger one, or a device that never
/// ends, is an error rather than an allocation of all the host's memory.
pub fn read_file(path: &Path) -> io::Result<Vec<u8>> {
    read_at_most(path, MAX_FILE_BYTES)
}

/// Opens an input file for reading, refusing what could never be read to its end: a
/// directory, and a named pipe (opening one waits for a writer, for ever if none comes).
pub fn open_input(path: &Path) -> io::Result<std::fs::File> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if std::fs::metadata(path)?.file_type().is_fifo() {
            return Err(io::Error::other(
                "is a named pipe: give a file (a pipe may never be written)",
            ));
        }
    }
    let file = std::fs::File::open(path)?;
    if file.metadata()?.is_dir() {
        return Err(io::Error::other("is a directory"));
    }
    Ok(file)
}

fn read_at_most(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let file = open_input(path)?;
    let meta = file.metadata()?;
    let too_large = || {
        io::Error::other(format!(
            "larger than the {limit} bytes an input file may have (MAX_FILE_BYTES)"
        ))
    };
    if meta.len() > limit {
        return Err(too_large());
    }
    // Devices and pipes report no length: read one byte past the limit to tell.
    let mut bytes = Vec::new();
    file.take(limit + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large());
    }
    Ok(bytes)
}

/// Reads a whole UTF-8 text file of at most [`MAX_FILE_BYTES`].
pub fn read_text_file(path: &Path) -> io::Result<String> {
    String::from_utf8(read_file(path)?).map_err(|e| {
        io::Error::new(
            io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (byte {} is not valid UTF-8)",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_endless_device_is_refused_not_read_forever() {
        let err = read_at_most(Path::new("/dev/zero"), 4096).unwrap_err();
        assert!(err.to_string().contains("4096 bytes"), "{err}");
        assert_eq!(read_at_most(Path::new("/dev/null"), 4096).unwrap(), b"");
    }

    #[test]
    fn a_directory_and_binary_text_are_errors() {
        let dir = std::env::temp_dir();
        assert!(
            read_file(&dir)
                .unwrap_err()
                .to_string()
                .contains("directory")
        );
        let path = dir.join(format!("imagine-limits-{}.bin", std::process::id()));
        std::fs::write(&path, [b'a', 0xff, 0xfe]).unwrap();
        let err = read_text_file(&path).unwrap_err();
        std::fs::remove_file(&path).unwrap();
        assert!(err.to_string().contains("byte 1"), "{err}");
    }
}
