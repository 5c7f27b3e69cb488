//! The thesis's model of a rasterizer's peak SRF use (Table 5.3, §5.2.6), evaluated on a
//! frame's batches next to what the frame measured.
//!
//! For a batch of `t` triangles of `f` fragments each with `i` interpolants (beyond x, y
//! and w, depth included), the model's words at the two places each rasterizer peaks:
//!
//! | rasterizer | where | words |
//! |---|---|---|
//! | scanline | during `spangen` (small triangles) | `(18 + 4i + (7 + 2i)s)·t` |
//! | scanline | during `spanrast` (large triangles) | `((7 + 2i)s + (2 + i)f)·t` |
//! | barycentric | during `baryprep` (few interpolants) | `(3i + 9 + 8f)·t` |
//! | barycentric | during `irast` (many interpolants) | `(3i + 5 + (2 + i)f)·t` |
//!
//! with `s = √(2f)` scanlines (a square bounding box, which favours scanline); it ignores
//! barycentric's invalid fragments (which favours barycentric). A rasterizer's peak is the
//! larger of its two rows.
//!
//! Applied to a frame: `i` is the frame's interpolated words per fragment plus depth, and
//! each batch gives `t` (its triangles, before culling) and `f` (its fragments over `t`);
//! the model's peak is the largest over the batches. Measured beside it, largest over the
//! batches: the rasterizer's working set as this machine holds it, the batch's
//! interpolation records (`baryprep`'s, one per triangle) and the words its fragments held
//! in the SRF at its largest rasterization pass (`xyrast`'s five streams, or the
//! interpolated records); and the words the SRF plan gives a batch's streams (sized for
//! the worst batch, not for this frame's).

use serde::Serialize;

use super::stats::BatchRow;

/// A batch as the model sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelBatch {
    pub triangles: f64,
    pub interpolants: f64,
    pub fragments_per_triangle: f64,
}

impl ModelBatch {
    /// The model's scanlines per triangle, `√(2f)`.
    pub fn scanlines(self) -> f64 {
        (2.0 * self.fragments_per_triangle).sqrt()
    }

    /// The scanline rasterizer's peak words (the larger of `spangen`'s and `spanrast`'s).
    pub fn scanline(self) -> f64 {
        let (i, f, s) = (
            self.interpolants,
            self.fragments_per_triangle,
            self.scanlines(),
        );
        let spangen = 18.0 + 4.0 * i + (7.0 + 2.0 * i) * s;
        let spanrast = (7.0 + 2.0 * i) * s + (2.0 + i) * f;
        spangen.max(spanrast) * self.triangles
    }

    /// The barycentric rasterizer's peak words (the larger of `baryprep`'s and `irast`'s).
    pub fn barycentric(self) -> f64 {
        let (i, f) = (self.interpolants, self.fragments_per_triangle);
        let baryprep = 3.0 * i + 9.0 + 8.0 * f;
        let irast = 3.0 * i + 5.0 + (2.0 + i) * f;
        baryprep.max(irast) * self.triangles
    }
}

/// Table 5.3 on a frame (see the module notes).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SrfModelReport {
    /// `i`: interpolated words per fragment, depth included.
    pub interpolants: usize,
    /// The model's peak words over the frame's batches, per rasterizer.
    pub scanline_words: f64,
    pub barycentric_words: f64,
    /// `t` and `f` of the batch where the barycentric model peaks.
    pub peak_batch_triangles: usize,
    pub peak_batch_fragments_per_triangle: f64,
    /// Measured: the most SRF words a batch's interpolation records and fragments held
    /// at once.
    pub measured_words: usize,
    /// The SRF plan's words for a batch's streams (all phases).
    pub plan_words: usize,
}

impl SrfModelReport {
    /// The model over `batches` of a frame with `interpolants` words per fragment (depth
    /// included), interpolation records of `triangle_words` and an SRF plan of
    /// `plan_words`.
    pub fn of(
        batches: &[BatchRow],
        interpolants: usize,
        triangle_words: usize,
        plan_words: usize,
    ) -> SrfModelReport {
        let mut report = SrfModelReport {
            interpolants,
            plan_words,
            ..SrfModelReport::default()
        };
        for b in batches.iter().filter(|b| b.triangles > 0) {
            let model = ModelBatch {
                triangles: b.triangles as f64,
                interpolants: interpolants as f64,
                fragments_per_triangle: b.fragments as f64 / b.triangles as f64,
            };
            report.scanline_words = report.scanline_words.max(model.scanline());
            if model.barycentric() > report.barycentric_words {
                report.barycentric_words = model.barycentric();
                report.peak_batch_triangles = b.triangles;
                report.peak_batch_fragments_per_triangle = model.fragments_per_triangle;
            }
            report.measured_words = report
                .measured_words
                .max(b.triangles * triangle_words + b.srf_fragment_words);
        }
        report
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The spec's self-check of Table 5.3 (peak words per triangle, scanline over
    /// barycentric), including the one case where scanline needs less: i = 4, f = 128.
    #[test]
    fn the_model_gives_the_published_per_triangle_peaks() {
        for (i, f, scanline, barycentric) in [
            (4.0, 16.0, 181.0, 149.0),
            (4.0, 64.0, 554.0, 533.0),
            (4.0, 128.0, 1008.0, 1045.0),
            (16.0, 16.0, 509.0, 341.0),
            (16.0, 128.0, 2928.0, 2357.0),
        ] {
            let b = ModelBatch {
                triangles: 1.0,
                interpolants: i,
                fragments_per_triangle: f,
            };
            assert_eq!(
                (b.scanline().round(), b.barycentric().round()),
                (scanline, barycentric),
                "i = {i}, f = {f}"
            );
        }
    }

    #[test]
    fn a_frame_takes_its_largest_batch() {
        let row = |triangles, fragments, srf_fragment_words| BatchRow {
            triangles,
            fragments,
            srf_fragment_words,
            ..BatchRow::default()
        };
        let r = SrfModelReport::of(
            &[row(64, 640, 900), row(0, 0, 0), row(32, 2048, 3000)],
            4,
            10,
            50_000,
        );
        // (3·4 + 9 + 8·10)·64 = 6464 against (21 + 8·64)·32 = 17056.
        assert_eq!(r.barycentric_words, 17_056.0);
        assert_eq!(
            (r.peak_batch_triangles, r.peak_batch_fragments_per_triangle),
            (32, 64.0)
        );
        // 32·10 + 3000 against 64·10 + 900.
        assert_eq!((r.measured_words, r.plan_words), (3320, 50_000));
        assert!(r.scanline_words > 0.0);
    }
}
