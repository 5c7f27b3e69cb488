//! One stream buffer: a small FIFO between the SRF port and the clusters.
//!
//! The buffer is a ring of `cap` words stored twice (a mirrored ring of `2 × cap` words:
//! word `p` lives at `p` and `p + cap`), so any run of up to `cap` words starting inside
//! the ring is one contiguous slice: the clusters get `&[u32]` straight out of it and the
//! SRF port copies whole transfers in and out with `copy_from_slice`.
//!
//! State is two-phase. `head`, `level`, `moved`, `done` and `mode` are the committed
//! (`q`) values; during a cycle the clusters' accesses only accumulate in `pending` (their
//! words are read from or written to ring positions that the SRF port cannot touch in the
//! same cycle), and the port's transfer is decided from committed state by the arbiter and
//! applied in [`StreamBuffer::commit`].

/// What a stream buffer is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum SbMode {
    /// Not bound to a stream.
    Idle = 0,
    /// Bound to an input stream: the SRF fills it, the clusters read it.
    Input = 1,
    /// Bound to an output stream: the clusters fill it, the SRF drains it in whole
    /// transfers.
    Output = 2,
    /// An output stream whose kernel has ended: the SRF drains what is left, including a
    /// last partial transfer.
    Flushing = 3,
}

impl SbMode {
    /// The 2-bit value of the `sbN.mode` probe.
    pub fn bits(self) -> u64 {
        self as u64
    }

    /// Whether the buffer is bound to an output stream (writing or flushing).
    pub fn is_output(self) -> bool {
        matches!(self, SbMode::Output | SbMode::Flushing)
    }
}

#[derive(Clone, Debug)]
pub(crate) struct StreamBuffer {
    pub mode: SbMode,
    /// First SRF word of the bound stream (a block boundary).
    pub start: usize,
    /// Input: the stream's length; output: the capacity of the bound region.
    pub len: usize,
    /// Words moved between the SRF and this buffer (committed).
    pub moved: usize,
    /// Input: words delivered to the clusters; output: words accepted from them
    /// (committed).
    pub done: usize,
    /// Ring index of the oldest buffered word (committed).
    pub head: usize,
    /// Buffered words (committed).
    pub level: usize,
    /// Words the clusters read (input) or wrote (output) in the current cycle.
    pub pending: usize,
    /// `flush` was called this cycle; the mode becomes `Flushing` at the edge.
    pub flush_req: bool,
    /// Words from SRF address `start + moved` to the next multiple of the port width (kept
    /// incrementally: no division per cycle).
    line_left: usize,
    cap: usize,
    ring: Box<[u32]>,
}

impl StreamBuffer {
    pub fn new(cap: usize) -> Self {
        StreamBuffer {
            mode: SbMode::Idle,
            start: 0,
            len: 0,
            moved: 0,
            done: 0,
            head: 0,
            level: 0,
            pending: 0,
            flush_req: false,
            line_left: 0,
            cap,
            ring: vec![0; 2 * cap].into_boxed_slice(),
        }
    }

    /// Binds the buffer to the stream `[start, start + len)` (for output: a region of
    /// `len` words), empty; `line` is the SRF port width.
    pub fn bind(&mut self, mode: SbMode, start: usize, len: usize, line: usize) {
        self.line_left = line - start % line;
        self.mode = mode;
        self.start = start;
        self.len = len;
        self.moved = 0;
        self.done = 0;
        self.head = 0;
        self.level = 0;
        self.pending = 0;
        self.flush_req = false;
    }

    pub fn unbind(&mut self) {
        self.bind(SbMode::Idle, 0, 0, 1);
    }

    /// Words the clusters may still read this cycle (input).
    #[inline(always)]
    pub fn available(&self) -> usize {
        self.level - self.pending
    }

    /// Free words the clusters may still write this cycle (output).
    #[inline(always)]
    pub fn space(&self) -> usize {
        self.cap - self.level - self.pending
    }

    /// Ring index `head + k` (`k ≤ cap`), wrapped into `[0, cap)`.
    #[inline(always)]
    fn at(&self, k: usize) -> usize {
        let p = self.head + k;
        if p >= self.cap { p - self.cap } else { p }
    }

    /// The transfer this buffer asks the SRF port for this cycle (0: none), from committed
    /// state. A transfer never crosses a multiple of the port width in SRF addresses.
    #[inline(always)]
    pub fn request(&self) -> usize {
        let to_line_end = self.line_left;
        match self.mode {
            SbMode::Input => {
                let n = to_line_end.min(self.len - self.moved);
                if n > 0 && self.cap - self.level >= n {
                    n
                } else {
                    0
                }
            }
            SbMode::Output if self.level >= to_line_end => to_line_end,
            #[cfg(feature = "inject-bugs")]
            SbMode::Flushing
                if self.level < to_line_end
                    && imagine_hdl::inject::active(
                        imagine_hdl::inject::Bug::SrfFlushKeepsPartialLine,
                    ) =>
            {
                0
            }
            SbMode::Flushing => self.level.min(to_line_end),
            _ => 0,
        }
    }

    /// Takes the next `n ≤ available()` words for the clusters.
    #[inline(always)]
    pub fn take(&mut self, n: usize) -> &[u32] {
        debug_assert!(n <= self.available());
        let p = self.at(self.pending);
        self.pending += n;
        &self.ring[p..p + n]
    }

    /// Appends `data` (`len ≤ space()`) from the clusters.
    #[inline(always)]
    pub fn put(&mut self, data: &[u32]) {
        debug_assert!(data.len() <= self.space());
        let p = self.at(self.level + self.pending);
        ring_write(&mut self.ring, self.cap, p, data);
        self.pending += data.len();
    }

    /// Ends the cycle: applies the clusters' accesses and a port transfer of `grant` words
    /// (0: none) between this buffer and `srf`.
    #[inline]
    pub fn commit(&mut self, grant: usize, line: usize, srf: &mut [u32]) {
        // Most buffers see neither the clusters nor the port in a cycle: nothing changes.
        if grant == 0 && self.pending == 0 && !self.flush_req {
            return;
        }
        if grant > 0 {
            debug_assert!(grant <= self.line_left);
            self.line_left -= grant;
            if self.line_left == 0 {
                self.line_left = line;
            }
        }
        match self.mode {
            SbMode::Input => {
                self.head = self.at(self.pending);
                self.level -= self.pending;
                self.done += self.pending;
                if grant > 0 {
                    let a = self.start + self.moved;
                    let tail = self.at(self.level);
                    ring_write(&mut self.ring, self.cap, tail, &srf[a..a + grant]);
                    self.level += grant;
                    self.moved += grant;
                }
            }
            SbMode::Output | SbMode::Flushing => {
                if grant > 0 {
                    let a = self.start + self.moved;
                    srf[a..a + grant].copy_from_slice(&self.ring[self.head..self.head + grant]);
                    self.head = self.at(grant);
                    self.level -= grant;
                    self.moved += grant;
                }
                self.level += self.pending;
                self.done += self.pending;
                if self.flush_req {
                    self.mode = SbMode::Flushing;
                    self.flush_req = false;
                }
            }
            SbMode::Idle => {}
        }
        self.pending = 0;
    }

    /// Whether nothing written to this buffer remains outside the SRF: true unless it is
    /// an output buffer that has not been flushed or still holds words.
    pub fn flushed(&self) -> bool {
        match self.mode {
            SbMode::Output => false,
            SbMode::Flushing => self.level == 0 && self.pending == 0,
            _ => true,
        }
    }
}

/// Writes `data` (at most `cap` words) into the mirrored ring at index `p < cap`.
#[inline(always)]
fn ring_write(ring: &mut [u32], cap: usize, p: usize, data: &[u32]) {
    let n = data.len();
    ring[p..p + n].copy_from_slice(data);
    // The part in the lower copy is mirrored up, the part that ran into the upper copy
    // (the wrap) is mirrored down.
    let lower = (cap - p).min(n);
    ring.copy_within(p..p + lower, p + cap);
    if n > lower {
        ring.copy_within(cap..p + n, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mirrored_ring_gives_contiguous_runs_across_the_wrap() {
        let mut sb = StreamBuffer::new(8);
        let mut srf: Vec<u32> = (100..164).collect();
        sb.bind(SbMode::Input, 0, 64, 4);
        let mut next = 100;
        // Fill 4, read 3, repeatedly: the window walks round the ring many times.
        for _ in 0..20 {
            let n = sb.request();
            let take = sb.available().min(3);
            let got = sb.take(take).to_vec();
            assert_eq!(got, (next..next + take as u32).collect::<Vec<_>>());
            next += take as u32;
            sb.commit(n, 4, &mut srf);
        }
        assert!(next > 140, "{next}");
    }

    #[test]
    fn an_output_buffer_drains_whole_lines_until_flushed() {
        let mut sb = StreamBuffer::new(8);
        let mut srf = vec![0u32; 32];
        sb.bind(SbMode::Output, 0, 32, 4);
        sb.put(&[1, 2, 3]);
        assert_eq!(sb.request(), 0, "nothing committed yet");
        sb.commit(0, 4, &mut srf);
        assert_eq!(sb.request(), 0, "3 words, less than a line");
        sb.put(&[4, 5]);
        sb.commit(0, 4, &mut srf);
        assert_eq!(sb.request(), 4);
        sb.commit(4, 4, &mut srf);
        assert_eq!(sb.level, 1);
        sb.flush_req = true;
        assert_eq!(sb.request(), 0);
        assert!(!sb.flushed());
        sb.commit(0, 4, &mut srf);
        assert_eq!(sb.mode, SbMode::Flushing);
        assert_eq!(sb.request(), 1);
        sb.commit(1, 4, &mut srf);
        assert!(sb.flushed());
        assert_eq!(&srf[..6], &[1, 2, 3, 4, 5, 0]);
    }
}
