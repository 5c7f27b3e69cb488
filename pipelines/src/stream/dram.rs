//! DRAM buffers by name: a stream program's memory map, laid out once, each buffer on a
//! 1024-word boundary (DRAM rows of its own), checked against the machine's capacity.

use imagine_units::desc::MachineDesc;
use imagine_units::dram::DramParams;
use serde::Serialize;

use super::srf::PlanError;

/// A named DRAM buffer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Buffer(usize);

#[derive(Clone, Debug, Serialize)]
pub struct BufferInfo {
    pub name: String,
    /// First word address.
    pub base: u64,
    pub words: u64,
    /// Written only before it is first read, so the texture cache may serve its loads.
    pub cacheable: bool,
}

/// The memory map.
#[derive(Clone, Debug)]
pub struct DramMap {
    buffers: Vec<BufferInfo>,
    next: u64,
    capacity: u64,
    machine: String,
}

const ALIGN: u64 = 1024;

impl DramMap {
    pub fn new(desc: &MachineDesc) -> DramMap {
        DramMap {
            buffers: Vec::new(),
            next: 0,
            capacity: DramParams::of(desc).capacity_bytes() / 4,
            machine: desc.name.clone(),
        }
    }

    /// A buffer of `words` words; errors naming it when the DRAM is full.
    pub fn buffer(&mut self, name: &str, words: u64) -> Result<Buffer, PlanError> {
        self.add(name, words, false)
    }

    /// A buffer written only before it is first read (uploaded once, like the textures),
    /// whose loads are marked cacheable for a texture cache. The cache drops a line a store
    /// touches, so the upload itself needs no care.
    pub fn read_only_buffer(&mut self, name: &str, words: u64) -> Result<Buffer, PlanError> {
        self.add(name, words, true)
    }

    fn add(&mut self, name: &str, words: u64, cacheable: bool) -> Result<Buffer, PlanError> {
        let base = self.next;
        let end = base.checked_add(words).filter(|&e| e <= self.capacity);
        let Some(end) = end else {
            return Err(PlanError(format!(
                "DRAM buffer `{name}` ({words} words) does not fit: machine `{}` has {} words \
                 of DRAM and {base} are taken",
                self.machine, self.capacity
            )));
        };
        self.buffers.push(BufferInfo {
            name: name.into(),
            base,
            words,
            cacheable,
        });
        self.next = end.div_ceil(ALIGN) * ALIGN;
        Ok(Buffer(self.buffers.len() - 1))
    }

    pub fn info(&self, b: Buffer) -> &BufferInfo {
        &self.buffers[b.0]
    }

    pub fn is_cacheable(&self, b: Buffer) -> bool {
        self.buffers[b.0].cacheable
    }

    pub fn base(&self, b: Buffer) -> u64 {
        self.buffers[b.0].base
    }

    pub fn buffers(&self) -> &[BufferInfo] {
        &self.buffers
    }
}
