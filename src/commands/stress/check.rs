//! The properties a stress case's frame must keep, each a pure function of the frame's
//! words (so that a test can hand it a broken frame and see it fail): no invalid value in
//! any pixel, the same frame on every run, a mesh that tiles its window exactly once, an
//! empty frame where nothing is visible, and an error against the reference within a
//! bound. Each returns `Err` with a one-line reason naming the first offending pixel.

use imagine_pipelines::opengl::render::Frame;
use imagine_pipelines::scene::model::TriangleId;
use imagine_verif::image::Metrics;

/// The words of a frame the checks read (row 0 at the bottom, as in [`Frame`]).
pub struct FrameWords<'a> {
    pub width: u32,
    pub pixels: &'a [u32],
    pub depths: &'a [u32],
    pub triangles: &'a [Option<TriangleId>],
}

impl<'a> FrameWords<'a> {
    pub fn of(frame: &'a Frame) -> FrameWords<'a> {
        FrameWords {
            width: frame.width,
            pixels: &frame.pixels,
            depths: &frame.depths,
            triangles: &frame.triangles,
        }
    }

    fn at(&self, i: usize) -> (usize, usize) {
        (i % self.width as usize, i / self.width as usize)
    }
}

/// No NaN or infinity reached a pixel: every depth word is a finite fp32 in [0, 1] (the
/// colour is RGBA8 and cannot hold one; a NaN colour shows as an error against the
/// reference), and every drawn pixel is opaque (alpha 255, as every colour the pipeline
/// writes is).
pub fn valid_values(f: &FrameWords) -> Result<(), String> {
    let bad_depth: Vec<usize> = (0..f.depths.len())
        .filter(|&i| {
            let z = f32::from_bits(f.depths[i]);
            !(z.is_finite() && (0.0..=1.0).contains(&z))
        })
        .collect();
    if let Some(&i) = bad_depth.first() {
        let (x, y) = f.at(i);
        return Err(format!(
            "{} pixels hold an invalid depth, the first ({x}, {y}) {} (word {:#010x})",
            bad_depth.len(),
            f32::from_bits(f.depths[i]),
            f.depths[i]
        ));
    }
    let translucent: Vec<usize> = (0..f.pixels.len())
        .filter(|&i| f.triangles[i].is_some() && f.pixels[i] >> 24 != 0xFF)
        .collect();
    if let Some(&i) = translucent.first() {
        let (x, y) = f.at(i);
        return Err(format!(
            "{} drawn pixels are not opaque, the first ({x}, {y}) {:#010x}",
            translucent.len(),
            f.pixels[i]
        ));
    }
    Ok(())
}

/// The same pixels, depths and visible triangles (the cycles may differ).
pub fn same_image(a: &Frame, b: &Frame) -> Result<(), String> {
    let first = |x: &[u32], y: &[u32]| x.iter().zip(y).position(|(p, q)| p != q);
    let at = |i: usize| (i % a.width as usize, i / a.width as usize);
    if let Some(i) = first(&a.pixels, &b.pixels) {
        let n = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .filter(|(p, q)| p != q)
            .count();
        return Err(format!("{n} pixels differ, the first {:?}", at(i)));
    }
    if let Some(i) = first(&a.depths, &b.depths) {
        return Err(format!("depths differ, the first at {:?}", at(i)));
    }
    if let Some(i) = a
        .triangles
        .iter()
        .zip(&b.triangles)
        .position(|(p, q)| p != q)
    {
        return Err(format!(
            "visible triangles differ, the first at {:?}",
            at(i)
        ));
    }
    Ok(())
}

/// Two renders of one scene gave the same frame ([`same_image`]) in the same cycles.
pub fn same_frames(a: &Frame, b: &Frame) -> Result<(), String> {
    same_image(a, b).map_err(|e| format!("a second render differs: {e}"))?;
    if a.stats.cycles != b.stats.cycles {
        return Err(format!(
            "a second render took {} cycles, the first {}",
            b.stats.cycles, a.stats.cycles
        ));
    }
    Ok(())
}

/// A mesh drawn with additive blending, every triangle of grey `level`, covered each pixel
/// exactly once: every pixel's RGB is `level`. Background (0) is a crack; more is double
/// coverage.
pub fn tiles_once(f: &FrameWords, level: u8) -> Result<(), String> {
    let (mut cracks, mut doubles, mut other) = (Vec::new(), Vec::new(), Vec::new());
    for (i, &p) in f.pixels.iter().enumerate() {
        let rgb = [p as u8, (p >> 8) as u8, (p >> 16) as u8];
        if rgb == [level; 3] {
            continue;
        }
        if rgb == [0; 3] {
            cracks.push(i);
        } else if rgb.iter().all(|&c| c > level) {
            doubles.push(i);
        } else {
            other.push(i);
        }
    }
    let show = |what: &str, v: &[usize]| {
        let (x, y) = f.at(v[0]);
        format!("{} pixels {what}, the first ({x}, {y})", v.len())
    };
    match (cracks.is_empty(), doubles.is_empty(), other.is_empty()) {
        (true, true, true) => Ok(()),
        (false, _, _) => Err(show("uncovered (a crack)", &cracks)),
        (_, false, _) => Err(show("covered twice or more", &doubles)),
        _ => Err(show(
            &format!("neither background nor grey {level}"),
            &other,
        )),
    }
}

/// Nothing was drawn.
pub fn empty(f: &FrameWords) -> Result<(), String> {
    match f.triangles.iter().position(Option::is_some) {
        None => Ok(()),
        Some(i) => {
            let (x, y) = f.at(i);
            let n = f.triangles.iter().filter(|t| t.is_some()).count();
            Err(format!(
                "{n} pixels drawn where nothing is visible, the first ({x}, {y})"
            ))
        }
    }
}

/// Every drawn pixel's RGB is one of `colours`.
pub fn only_colours(f: &FrameWords, colours: &[[u8; 3]]) -> Result<(), String> {
    let other: Vec<usize> = (0..f.pixels.len())
        .filter(|&i| {
            let p = f.pixels[i];
            f.triangles[i].is_some()
                && !colours.contains(&[p as u8, (p >> 8) as u8, (p >> 16) as u8])
        })
        .collect();
    match other.first() {
        None => Ok(()),
        Some(&i) => {
            let (x, y) = f.at(i);
            Err(format!(
                "{} drawn pixels show a colour not in {colours:?}, the first ({x}, {y}) {:#08x}",
                other.len(),
                f.pixels[i] & 0xFF_FFFF
            ))
        }
    }
}

/// How far a frame may be from the reference renderer's.
#[derive(Clone, Copy, Debug)]
pub struct Bound {
    /// Largest share of the window covered in one frame only.
    pub coverage: f64,
    /// Largest share of the window covered in both that shows another triangle (the
    /// depth test decided otherwise).
    pub visibility: f64,
    /// Largest RGB difference over the pixels that show the same triangle in both, levels
    /// of 255.
    pub levels: u8,
}

impl Bound {
    /// Coverage and visibility as the reference's, colour up to the last bit of an 8-bit
    /// channel.
    pub const TIGHT: Bound = Bound {
        coverage: 0.0,
        visibility: 0.0,
        levels: 1,
    };
}

/// The reference's frame: its image and the triangle each pixel shows.
pub struct ReferenceFrame<'a> {
    pub pixels: &'a [[u8; 4]],
    pub triangles: &'a [Option<TriangleId>],
}

/// The largest RGB difference over the pixels showing the same triangle in both frames.
pub fn same_triangle_error(f: &FrameWords, r: &ReferenceFrame) -> u8 {
    (0..f.pixels.len())
        .filter(|&i| f.triangles[i].is_some() && f.triangles[i] == r.triangles[i])
        .flat_map(|i| {
            let p = f.pixels[i];
            let q = r.pixels[i];
            [p as u8, (p >> 8) as u8, (p >> 16) as u8]
                .into_iter()
                .zip(q)
                .map(|(a, b)| a.abs_diff(b))
        })
        .max()
        .unwrap_or(0)
}

/// The error against the reference within `bound`: `m` the window's metrics, `levels` the
/// [`same_triangle_error`].
pub fn within(m: &Metrics, levels: u8, bound: Bound) -> Result<(), String> {
    let coverage = m.wrongly_covered_share + m.missed_share;
    if coverage > bound.coverage {
        return Err(format!(
            "coverage differs from the reference on {:.3} % of pixels ({:.3} % wrongly \
             covered, {:.3} % missed), bound {:.3} %",
            100.0 * coverage,
            100.0 * m.wrongly_covered_share,
            100.0 * m.missed_share,
            100.0 * bound.coverage
        ));
    }
    let visibility = m.visibility_differing_share.unwrap_or(0.0);
    if visibility > bound.visibility {
        return Err(format!(
            "{:.3} % of pixels show another triangle than the reference's, bound {:.3} %",
            100.0 * visibility,
            100.0 * bound.visibility
        ));
    }
    if levels > bound.levels {
        return Err(format!(
            "colour differs from the reference by up to {levels} levels where both show the \
             same triangle (bound {})",
            bound.levels
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const GREY: u32 = 0xFF40_4040;

    fn words<'a>(
        pixels: &'a [u32],
        depths: &'a [u32],
        triangles: &'a [Option<TriangleId>],
    ) -> FrameWords<'a> {
        FrameWords {
            width: 2,
            pixels,
            depths,
            triangles,
        }
    }

    const T: Option<TriangleId> = Some(TriangleId {
        object: 0,
        triangle: 0,
    });

    #[test]
    fn a_nan_or_infinite_depth_or_a_translucent_pixel_fails() {
        let one = 1f32.to_bits();
        let good = [GREY; 4];
        let tris = [T, T, None, T];
        assert_eq!(
            valid_values(&words(&good, &[one, 0, one, 0x3F00_0000], &tris)),
            Ok(())
        );
        for (bad, says) in [
            (f32::NAN.to_bits(), "NaN"),
            (f32::INFINITY.to_bits(), "inf"),
            ((-0.25f32).to_bits(), "-0.25"),
            (1.5f32.to_bits(), "1.5"),
        ] {
            let e = valid_values(&words(&good, &[one, one, one, bad], &tris)).unwrap_err();
            assert!(e.contains("(1, 1)") && e.contains(says), "{e}");
        }
        let e =
            valid_values(&words(&[GREY, 0x0040_4040, GREY, GREY], &[one; 4], &tris)).unwrap_err();
        assert!(e.contains("not opaque") && e.contains("(1, 0)"), "{e}");
        // An undrawn pixel may hold anything in its alpha.
        assert!(valid_values(&words(&[GREY, GREY, 0, GREY], &[one; 4], &tris)).is_ok());
    }

    #[test]
    fn a_crack_or_a_double_cover_fails_the_tiling() {
        let tris = [T; 4];
        let z = [0; 4];
        assert_eq!(tiles_once(&words(&[GREY; 4], &z, &tris), 0x40), Ok(()));
        let e = tiles_once(&words(&[GREY, GREY, 0xFF00_0000, GREY], &z, &tris), 0x40);
        assert!(e.unwrap_err().contains("crack"));
        let e = tiles_once(&words(&[GREY, GREY, GREY, 0xFF80_8080], &z, &tris), 0x40);
        let e = e.unwrap_err();
        assert!(e.contains("twice") && e.contains("(1, 1)"), "{e}");
        let e = tiles_once(&words(&[GREY, 0xFF10_2030, GREY, GREY], &z, &tris), 0x40);
        assert!(e.unwrap_err().contains("neither"));
    }

    #[test]
    fn colour_counts_only_where_both_show_the_same_triangle() {
        let other = Some(TriangleId {
            object: 0,
            triangle: 1,
        });
        let shown = [T, other, T, None];
        let f = words(&[GREY, 0xFF00_00FF, GREY, 0], &[0; 4], &shown);
        let grey = [0x40, 0x40, 0x40, 0xFF];
        let r = ReferenceFrame {
            pixels: &[grey, grey, [0x43, 0x40, 0x40, 0xFF], [9, 9, 9, 0xFF]],
            triangles: &[T, T, T, other],
        };
        // Pixel 1 shows another triangle, pixel 3 is covered by the reference alone.
        assert_eq!(same_triangle_error(&f, &r), 3);
    }

    #[test]
    fn a_drawn_pixel_fails_an_empty_frame() {
        let z = [0; 4];
        assert_eq!(empty(&words(&[0; 4], &z, &[None; 4])), Ok(()));
        let e = empty(&words(&[0; 4], &z, &[None, None, None, T])).unwrap_err();
        assert!(e.contains("1 pixels") && e.contains("(1, 1)"), "{e}");
    }
}
