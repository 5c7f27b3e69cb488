//! The binary microcode image that `imagine kernel asm` writes and `imagine kernel disasm`
//! and `imagine kernel run` read: the kernel's name and streams, then its instructions
//! packed by the machine's [`InstructionLayout`]. All integers little-endian:
//!
//! | bytes | content |
//! |---|---|
//! | 4 | magic `IMUC` |
//! | 1 | format version (3) |
//! | 2 + n | machine name (length, UTF-8) |
//! | 8 | the machine's encoding fingerprint ([`encoding_fingerprint`]) |
//! | 2 + n | kernel name |
//! | 1 | stream count, then per stream: 1 direction (0 in, 1 out), 2 + n name |
//! | 4 | instruction width in bits |
//! | 4 | instruction count, then per instruction `ceil(width / 64)` 64-bit words |
//!
//! Version 2 added the `ctl.pass` bit (a loop body of several passes), so every
//! instruction of a version-1 image is one bit narrower; such images are refused by
//! version rather than by width. Version 3 added the fingerprint: two machines with the
//! same word width but another unit mix, other LRF sizes or other latencies read the same
//! bits as another program (a statically scheduled one, timed for other latencies), so an
//! image is refused on any machine whose fingerprint differs from the one it was built for.

use std::fmt;

use imagine_hdl::WideWord;

use super::layout::InstructionLayout;
use super::{Program, StreamDecl, StreamDir};
use crate::desc::MachineDesc;

const MAGIC: &[u8; 4] = b"IMUC";
const VERSION: u8 = 3;

/// A hash of everything an image's meaning depends on: the instruction word's fields
/// (names, offsets, widths: the unit mix, LRF sizes, condition codes, stream and scratchpad
/// addressing), the latencies the schedule was built for, and the cluster count (which the
/// intercluster permutations assume). FNV-1a over a canonical text, so it is the same on
/// every host and build.
pub fn encoding_fingerprint(desc: &MachineDesc) -> u64 {
    let layout = InstructionLayout::new(desc);
    let mut text = format!("clusters {}\n{:?}\n", desc.cluster.count, desc.latency);
    for f in layout.fields() {
        text += &format!("{} {} {}\n", f.name, f.offset, f.width);
    }
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h: u64, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// An image that cannot be read for this machine.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImageError(pub String);

impl fmt::Display for ImageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "microcode image: {}", self.0)
    }
}

impl std::error::Error for ImageError {}

fn put_str(out: &mut Vec<u8>, s: &str) {
    let len = u16::try_from(s.len()).expect("names are short");
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(s.as_bytes());
}

/// Packs a (checked) program for `desc`.
pub fn write_image(program: &Program, desc: &MachineDesc) -> Vec<u8> {
    let layout = InstructionLayout::new(desc);
    let mut out = Vec::new();
    out.extend_from_slice(MAGIC);
    out.push(VERSION);
    put_str(&mut out, &desc.name);
    out.extend_from_slice(&encoding_fingerprint(desc).to_le_bytes());
    put_str(&mut out, &program.name);
    out.push(program.streams.len() as u8);
    for s in &program.streams {
        out.push(matches!(s.dir, StreamDir::Out) as u8);
        put_str(&mut out, &s.name);
    }
    out.extend_from_slice(&(layout.width() as u32).to_le_bytes());
    out.extend_from_slice(&(program.code.len() as u32).to_le_bytes());
    for word in layout.encode_program(program) {
        for w in word.as_raw_slice() {
            out.extend_from_slice(&w.to_le_bytes());
        }
    }
    out
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], ImageError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                ImageError(format!(
                    "truncated: {what} at byte {} needs {n} bytes",
                    self.at
                ))
            })?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self, what: &str) -> Result<u8, ImageError> {
        Ok(self.take(1, what)?[0])
    }
    fn u16(&mut self, what: &str) -> Result<u16, ImageError> {
        Ok(u16::from_le_bytes(
            self.take(2, what)?.try_into().expect("2 bytes"),
        ))
    }
    fn u32(&mut self, what: &str) -> Result<u32, ImageError> {
        Ok(u32::from_le_bytes(
            self.take(4, what)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self, what: &str) -> Result<u64, ImageError> {
        Ok(u64::from_le_bytes(
            self.take(8, what)?.try_into().expect("8 bytes"),
        ))
    }
    fn string(&mut self, what: &str) -> Result<String, ImageError> {
        let n = self.u16(what)? as usize;
        let b = self.take(n, what)?;
        String::from_utf8(b.to_vec()).map_err(|_| ImageError(format!("{what} is not UTF-8")))
    }
}

/// Reads an image for `desc`; the program is checked against the machine.
pub fn read_image(bytes: &[u8], desc: &MachineDesc) -> Result<Program, ImageError> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(4, "magic")? != MAGIC {
        return Err(ImageError("not a microcode image (no IMUC magic)".into()));
    }
    let version = r.u8("version")?;
    if version != VERSION {
        let hint = if version < VERSION {
            " (written by an older build: assemble the kernel again)"
        } else {
            ""
        };
        return Err(ImageError(format!(
            "format version {version}; this build reads {VERSION}{hint}"
        )));
    }
    let machine = r.string("machine name")?;
    let fingerprint = r.u64("machine fingerprint")?;
    let name = r.string("kernel name")?;
    let ours = encoding_fingerprint(desc);
    if fingerprint != ours {
        return Err(ImageError(format!(
            "kernel `{name}` was built for machine `{machine}` (encoding {fingerprint:016x}); \
             machine `{}` encodes or times its microcode differently ({ours:016x}): \
             assemble the kernel again for it",
            desc.name
        )));
    }
    let streams = (0..r.u8("stream count")?)
        .map(|i| {
            let dir = match r.u8("stream direction")? {
                0 => StreamDir::In,
                1 => StreamDir::Out,
                d => return Err(ImageError(format!("stream {i} has direction {d}"))),
            };
            Ok(StreamDecl {
                dir,
                name: r.string("stream name")?,
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let layout = InstructionLayout::new(desc);
    let width = r.u32("instruction width")? as usize;
    if width != layout.width() {
        return Err(ImageError(format!(
            "kernel `{name}` was assembled for machine `{machine}` ({width}-bit instructions); `{}` uses {} bits",
            desc.name,
            layout.width()
        )));
    }
    let count = r.u32("instruction count")? as usize;
    if count > desc.microcontroller.store_words {
        return Err(ImageError(format!(
            "kernel `{name}` has {count} instructions; the microcode store holds {}",
            desc.microcontroller.store_words
        )));
    }
    let words = width.div_ceil(64);
    let mut code = Vec::with_capacity(count);
    for i in 0..count {
        let mut word = WideWord::with_capacity(words * 64);
        for _ in 0..words {
            word.extend_from_raw_slice(&[r.u64("instruction")?]);
        }
        word.truncate(width);
        code.push(
            layout
                .decode(&word)
                .map_err(|e| ImageError(format!("instruction {i}: {e}")))?,
        );
    }
    if r.at != bytes.len() {
        return Err(ImageError(format!(
            "{} bytes after the last instruction",
            bytes.len() - r.at
        )));
    }
    let program = Program {
        name,
        streams,
        code,
    };
    program.check(desc).map_err(|e| ImageError(e.to_string()))?;
    Ok(program)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::workloads::compute_dense;

    #[test]
    fn images_round_trip_and_reject_damage() {
        let gold8 = MachineDesc::gold8();
        let p = compute_dense(&gold8, 7).unwrap();
        let image = write_image(&p, &gold8);
        assert_eq!(read_image(&image, &gold8).unwrap(), p);
        // Another machine's layout is refused by name.
        let f = MachineDesc::resolve("gold8+F").unwrap();
        let e = read_image(&image, &f).unwrap_err();
        assert!(
            e.to_string().contains("gold8+F") && e.to_string().contains("`gold8`"),
            "{e}"
        );
        // A machine of the same word width that reads the bits otherwise, or runs them with
        // other latencies, is refused with both names.
        let mut mixed = gold8.clone();
        mixed.name = "mixed".into();
        (mixed.cluster.multipliers, mixed.cluster.divsqrt) = (1, 2);
        let mut slower = gold8.clone();
        slower.name = "slower".into();
        slower.latency.mul += 1;
        for same_width in [&mixed, &slower] {
            assert_eq!(
                InstructionLayout::new(same_width).width(),
                InstructionLayout::new(&gold8).width()
            );
        }
        for other in [&mixed, &slower] {
            let e = read_image(&image, other).unwrap_err().to_string();
            assert!(
                e.contains("`gold8`") && e.contains(&format!("`{}`", other.name)),
                "{e}"
            );
        }
        // Truncation, trailing bytes and a wrong magic are errors, never panics.
        for cut in [0, 3, 10, image.len() / 2, image.len() - 1] {
            assert!(read_image(&image[..cut], &gold8).is_err(), "cut at {cut}");
        }
        let mut longer = image.clone();
        longer.push(0);
        assert!(
            read_image(&longer, &gold8)
                .unwrap_err()
                .to_string()
                .contains("after the last")
        );
        // An image of the format before the pass bit is refused by its version.
        let mut old = image.clone();
        old[4] = 1;
        let e = read_image(&old, &gold8).unwrap_err().to_string();
        assert!(
            e.contains("format version 1; this build reads 3") && e.contains("again"),
            "{e}"
        );
        let mut bad = image.clone();
        bad[0] = b'X';
        assert!(
            read_image(&bad, &gold8)
                .unwrap_err()
                .to_string()
                .contains("magic")
        );
    }
}
