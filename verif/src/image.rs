//! RGBA8 images, PNG input/output and image error metrics (ARCHITECTURE §6, layer 3).
//!
//! An [`Image`] stores its rows bottom-up, like OpenGL's framebuffer: row 0 is the bottom
//! row of the window, so `pixel(x, y)` uses window coordinates. [`Image::write_png`] flips
//! the rows so that the PNG shows the image the right way up, and [`Image::read_png`]
//! flips them back.
//!
//! [`compare`] measures how far one image is from another: PSNR over the RGB channels
//! (peak 255, alpha ignored), the largest channel difference, the share of pixels whose
//! RGB differ at all, and the share of pixels where exactly one image is background
//! (black) — a coverage mismatch.
//!
//! [`compare_frames`] adds what those mix up: the error over the pixels both frames cover
//! alone (PSNR and largest difference: shading, not edges), coverage split into pixels
//! wrongly covered and pixels missed, and — where both frames say which triangle each pixel
//! shows — the pixels whose visible triangle differs (depth-order and tie-rule errors).
//! Coverage is then the triangles' and not the colour's: an unlit black triangle covers.

use imagine_pipelines::scene::model::TriangleId;
use serde::Serialize;
use std::fs::File;
use std::io::{BufReader, BufWriter};
use std::path::Path;

/// An RGBA8 image with row 0 at the bottom (OpenGL's window origin).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    /// `width × height` pixels, row by row from the bottom row up.
    pub pixels: Vec<[u8; 4]>,
}

/// The background colour: black, opaque.
pub const BACKGROUND: [u8; 4] = [0, 0, 0, 255];

impl Image {
    /// A black, opaque `width × height` image.
    pub fn new(width: u32, height: u32) -> Image {
        Image {
            width,
            height,
            pixels: vec![BACKGROUND; width as usize * height as usize],
        }
    }

    /// An image from packed RGBA8 words (red in the low byte), row 0 at the bottom: the
    /// framebuffer's colour words.
    pub fn from_rgba8_words(width: u32, height: u32, words: &[u32]) -> Image {
        let mut img = Image::new(width, height);
        for (dst, &w) in img.pixels.iter_mut().zip(words) {
            *dst = w.to_le_bytes();
        }
        img
    }

    fn index(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) is outside the {}x{} image",
            self.width,
            self.height
        );
        y as usize * self.width as usize + x as usize
    }

    /// The pixel at window position (`x`, `y`), `y` counted from the bottom row.
    ///
    /// # Panics
    /// When the position is outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        self.pixels[self.index(x, y)]
    }

    /// Sets the pixel at window position (`x`, `y`).
    ///
    /// # Panics
    /// When the position is outside the image.
    pub fn set_pixel(&mut self, x: u32, y: u32, rgba: [u8; 4]) {
        let i = self.index(x, y);
        self.pixels[i] = rgba;
    }

    /// Writes the image as an 8-bit RGBA PNG, top row first.
    pub fn write_png(&self, path: impl AsRef<Path>) -> Result<(), String> {
        let path = path.as_ref();
        let fail = |e: &dyn std::fmt::Display| format!("writing {}: {e}", path.display());
        if self.pixels.len() != self.width as usize * self.height as usize {
            return Err(fail(&format!(
                "{} pixels for a {}x{} image",
                self.pixels.len(),
                self.width,
                self.height
            )));
        }
        if self.width == 0 || self.height == 0 {
            return Err(fail(&"a PNG needs at least one pixel"));
        }
        let file = File::create(path).map_err(|e| fail(&e))?;
        let mut encoder = png::Encoder::new(BufWriter::new(file), self.width, self.height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(|e| fail(&e))?;
        let mut data = Vec::with_capacity(self.pixels.len() * 4);
        for row in self.pixels.chunks(self.width as usize).rev() {
            data.extend(row.iter().flatten());
        }
        writer.write_image_data(&data).map_err(|e| fail(&e))?;
        writer.finish().map_err(|e| fail(&e))
    }

    /// Reads a PNG (any colour type; 16-bit channels are reduced to 8, grey is expanded
    /// to RGB and a missing alpha channel reads as opaque), flipping it so that row 0 is
    /// the bottom row.
    pub fn read_png(path: impl AsRef<Path>) -> Result<Image, String> {
        let path = path.as_ref();
        let fail = |e: &dyn std::fmt::Display| format!("reading {}: {e}", path.display());
        let file = File::open(path).map_err(|e| fail(&e))?;
        let mut decoder = png::Decoder::new(BufReader::new(file));
        decoder.set_transformations(png::Transformations::normalize_to_color8());
        let mut reader = decoder.read_info().map_err(|e| fail(&e))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| fail(&"the image is too large"))?;
        let mut buffer = vec![0; size];
        let info = reader.next_frame(&mut buffer).map_err(|e| fail(&e))?;
        if info.bit_depth != png::BitDepth::Eight {
            return Err(fail(&format!(
                "unsupported bit depth {:?} after expansion",
                info.bit_depth
            )));
        }
        let channels = match info.color_type {
            png::ColorType::Grayscale => 1,
            png::ColorType::GrayscaleAlpha => 2,
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            png::ColorType::Indexed => {
                return Err(fail(&"palette image was not expanded"));
            }
        };
        let (width, height) = (info.width, info.height);
        let mut pixels = Vec::with_capacity(width as usize * height as usize);
        for row in buffer[..info.buffer_size()]
            .chunks(info.line_size)
            .take(height as usize)
            .rev()
        {
            for p in row[..width as usize * channels].chunks(channels) {
                pixels.push(match *p {
                    [g] => [g, g, g, 255],
                    [g, a] => [g, g, g, a],
                    [r, g, b] => [r, g, b, 255],
                    [r, g, b, a] => [r, g, b, a],
                    _ => unreachable!("chunks of 1 to 4 channels"),
                });
            }
        }
        Ok(Image {
            width,
            height,
            pixels,
        })
    }
}

/// A colour channel in [0, 1] to 8 bits: `floor(clamp(c, 0, 1) · 255 + 0.5)` (round half
/// up). NaN maps to 0.
pub fn quantise(c: f64) -> u8 {
    if c.is_nan() {
        return 0;
    }
    (c.clamp(0.0, 1.0) * 255.0 + 0.5).floor() as u8
}

/// How far two images of the same size are apart.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Peak signal-to-noise ratio over the RGB channels, peak 255, in dB;
    /// `f64::INFINITY` when the RGB channels are identical (`serde_json` writes that as
    /// `null`).
    pub psnr_db: f64,
    /// Largest absolute difference of any RGB channel.
    pub max_abs_error: u8,
    /// Share of pixels whose RGB differ at all.
    pub differing_share: f64,
    /// Share of pixels where one image is background (RGB 0, 0, 0) and the other is not.
    pub coverage_mismatch_share: f64,
    /// What the fields below take as a covered pixel.
    pub coverage_from: CoverageFrom,
    /// Pixels both images cover.
    pub covered_in_both_pixels: usize,
    /// PSNR over the RGB channels of the pixels both images cover, peak 255, in dB
    /// (`f64::INFINITY`, JSON `null`, when they are identical there or there are none).
    pub covered_psnr_db: f64,
    /// Largest absolute difference of any RGB channel over the pixels both cover, in
    /// levels of an 8-bit channel.
    pub covered_max_abs_error_levels: u8,
    /// Share of the window's pixels the first image covers and the second does not.
    pub wrongly_covered_share: f64,
    /// Share of the window's pixels the second image covers and the first does not.
    pub missed_share: f64,
    /// Share of the window's pixels both cover that show different triangles; `None` when
    /// the images do not say which triangle each pixel shows.
    pub visibility_differing_share: Option<f64>,
}

/// Where [`Metrics`] takes coverage from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CoverageFrom {
    /// A pixel is covered when its RGB is not black (all a bare image tells).
    BackgroundColour,
    /// A pixel is covered when a triangle was drawn in it (depth test passed).
    Triangles,
}

fn same_size(a: &Image, b: &Image) -> Result<(), String> {
    if a.width != b.width || a.height != b.height {
        return Err(format!(
            "the images differ in size: {}x{} and {}x{}",
            a.width, a.height, b.width, b.height
        ));
    }
    let n = a.width as usize * a.height as usize;
    if a.pixels.len() != n || b.pixels.len() != n {
        return Err(format!(
            "a {}x{} image needs {n} pixels, the images have {} and {}",
            a.width,
            a.height,
            a.pixels.len(),
            b.pixels.len()
        ));
    }
    Ok(())
}

fn rgb(p: [u8; 4]) -> [u8; 3] {
    [p[0], p[1], p[2]]
}

fn is_background(p: [u8; 4]) -> bool {
    rgb(p) == [0, 0, 0]
}

/// The metrics of `b` against `a`, coverage judged from the background colour; an error
/// when the sizes differ.
pub fn compare(a: &Image, b: &Image) -> Result<Metrics, String> {
    same_size(a, b)?;
    let covered = |i: usize| (!is_background(a.pixels[i]), !is_background(b.pixels[i]));
    Ok(measure(a, b, covered, None, CoverageFrom::BackgroundColour))
}

/// The metrics of frame `b` against frame `a` where each also says which triangle every
/// pixel shows (`None`: none was drawn there): coverage and visibility come from the
/// triangles. An error when the sizes differ.
pub fn compare_frames(
    a: &Image,
    a_triangles: &[Option<TriangleId>],
    b: &Image,
    b_triangles: &[Option<TriangleId>],
) -> Result<Metrics, String> {
    same_size(a, b)?;
    let n = a.pixels.len();
    if a_triangles.len() != n || b_triangles.len() != n {
        return Err(format!(
            "{n} pixels, but the frames name the triangles of {} and {}",
            a_triangles.len(),
            b_triangles.len()
        ));
    }
    let covered = |i: usize| (a_triangles[i].is_some(), b_triangles[i].is_some());
    let visible_differs = |i: usize| a_triangles[i] != b_triangles[i];
    Ok(measure(
        a,
        b,
        covered,
        Some(&visible_differs),
        CoverageFrom::Triangles,
    ))
}

/// The metrics of frame `b` against frame `a` where each says which pixels it covers
/// (a frame whose primitives are not the other's triangles, such as a Reyes frame's
/// quads against a diced reference): no visibility comparison. An error when the sizes
/// differ.
pub fn compare_coverage(
    a: &Image,
    a_covered: &[bool],
    b: &Image,
    b_covered: &[bool],
) -> Result<Metrics, String> {
    same_size(a, b)?;
    let n = a.pixels.len();
    if a_covered.len() != n || b_covered.len() != n {
        return Err(format!(
            "{n} pixels, but the frames say which are covered of {} and {}",
            a_covered.len(),
            b_covered.len()
        ));
    }
    let covered = |i: usize| (a_covered[i], b_covered[i]);
    Ok(measure(a, b, covered, None, CoverageFrom::Triangles))
}

/// Peak signal-to-noise ratio of `squared` summed squared channel errors over `channels`
/// channels, peak 255, in dB; infinite without error.
fn psnr_db(squared: u64, channels: usize) -> f64 {
    if squared == 0 {
        f64::INFINITY
    } else {
        let mse = squared as f64 / channels as f64;
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// The metrics, given whether each pixel is covered in `a` and in `b` and, where known,
/// whether a pixel both cover shows different triangles.
fn measure(
    a: &Image,
    b: &Image,
    covered: impl Fn(usize) -> (bool, bool),
    visible_differs: Option<&dyn Fn(usize) -> bool>,
    coverage_from: CoverageFrom,
) -> Metrics {
    let n = a.pixels.len();
    let mut squared = 0u64;
    let mut max_abs_error = 0u8;
    let mut differing = 0usize;
    let mut background_mismatch = 0usize;
    let mut covered_in_both = 0usize;
    let mut covered_squared = 0u64;
    let mut covered_max_abs_error = 0u8;
    let mut wrongly_covered = 0usize;
    let mut missed = 0usize;
    let mut visibility_differing = 0usize;
    for (i, (&p, &q)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        let mut pixel_squared = 0u64;
        let mut pixel_max = 0u8;
        for k in 0..3 {
            let d = p[k].abs_diff(q[k]);
            pixel_squared += u64::from(d) * u64::from(d);
            pixel_max = pixel_max.max(d);
        }
        squared += pixel_squared;
        max_abs_error = max_abs_error.max(pixel_max);
        differing += usize::from(pixel_max != 0);
        background_mismatch += usize::from(is_background(p) != is_background(q));
        match covered(i) {
            (true, true) => {
                covered_in_both += 1;
                covered_squared += pixel_squared;
                covered_max_abs_error = covered_max_abs_error.max(pixel_max);
                if visible_differs.is_some_and(|differs| differs(i)) {
                    visibility_differing += 1;
                }
            }
            (true, false) => wrongly_covered += 1,
            (false, true) => missed += 1,
            (false, false) => {}
        }
    }
    let share = |count: usize| if n == 0 { 0.0 } else { count as f64 / n as f64 };
    Metrics {
        psnr_db: psnr_db(squared, 3 * n),
        max_abs_error,
        differing_share: share(differing),
        coverage_mismatch_share: share(background_mismatch),
        coverage_from,
        covered_in_both_pixels: covered_in_both,
        covered_psnr_db: psnr_db(covered_squared, 3 * covered_in_both),
        covered_max_abs_error_levels: covered_max_abs_error,
        wrongly_covered_share: share(wrongly_covered),
        missed_share: share(missed),
        visibility_differing_share: visible_differs.map(|_| share(visibility_differing)),
    }
}

/// A histogram of per-pixel colour error over the pixels that both images cover (neither
/// is background): entry `e` counts the pixels whose largest RGB channel difference is
/// `e`. It separates shading differences from coverage differences.
pub fn covered_error_histogram(a: &Image, b: &Image) -> Result<[usize; 256], String> {
    same_size(a, b)?;
    let mut histogram = [0usize; 256];
    for (&p, &q) in a.pixels.iter().zip(&b.pixels) {
        if !is_background(p) && !is_background(q) {
            let e = (0..3).map(|k| p[k].abs_diff(q[k])).max().unwrap_or(0);
            histogram[e as usize] += 1;
        }
    }
    Ok(histogram)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantise_rounds_half_up_and_clamps() {
        assert_eq!(quantise(0.0), 0);
        assert_eq!(quantise(1.0), 255);
        assert_eq!(quantise(-3.0), 0);
        assert_eq!(quantise(7.0), 255);
        assert_eq!(quantise(f64::NAN), 0);
        // 0.5 / 255 sits exactly between 0 and 1: half up.
        assert_eq!(quantise(0.5 / 255.0), 1);
        assert_eq!(quantise(0.49 / 255.0), 0);
        assert_eq!(quantise(127.5 / 255.0), 128);
        assert_eq!(quantise(0.5), 128);
    }

    #[test]
    fn pixels_are_addressed_from_the_bottom_row() {
        let mut image = Image::new(3, 2);
        assert!(image.pixels.iter().all(|&p| p == BACKGROUND));
        image.set_pixel(2, 1, [1, 2, 3, 4]);
        assert_eq!(image.pixels[5], [1, 2, 3, 4]);
        assert_eq!(image.pixel(2, 1), [1, 2, 3, 4]);
    }

    #[test]
    fn metrics_of_identical_and_different_images() {
        let a = Image::new(4, 4);
        let m = compare(&a, &a).unwrap();
        assert_eq!(m.psnr_db, f64::INFINITY);
        assert_eq!(m.max_abs_error, 0);
        assert_eq!(m.differing_share, 0.0);
        assert_eq!(m.coverage_mismatch_share, 0.0);

        let mut b = a.clone();
        b.set_pixel(0, 0, [10, 0, 0, 255]); // covered in b only
        let mut c = b.clone();
        c.set_pixel(0, 0, [13, 0, 0, 255]); // both cover, error 3
        c.set_pixel(1, 0, [0, 0, 4, 0]); // covered in c only, alpha ignored
        let m = compare(&b, &c).unwrap();
        assert_eq!(m.max_abs_error, 4);
        assert_eq!(m.differing_share, 2.0 / 16.0);
        assert_eq!(m.coverage_mismatch_share, 1.0 / 16.0);
        // MSE = (9 + 16) / (3 · 16).
        let want = 10.0 * (255.0f64 * 255.0 * 48.0 / 25.0).log10();
        assert!((m.psnr_db - want).abs() < 1e-12, "{} {want}", m.psnr_db);
        let m = compare(&a, &b).unwrap();
        assert_eq!(m.coverage_mismatch_share, 1.0 / 16.0);

        let h = covered_error_histogram(&b, &c).unwrap();
        assert_eq!(h[3], 1);
        assert_eq!(h.iter().sum::<usize>(), 1);

        let e = compare(&a, &Image::new(4, 5)).unwrap_err();
        assert!(e.contains("4x4 and 4x5"), "{e}");
        assert!(covered_error_histogram(&a, &Image::new(5, 4)).is_err());
    }

    #[test]
    fn frames_split_coverage_and_visibility_by_their_triangles() {
        let triangle = |object, triangle| Some(TriangleId { object, triangle });
        // 2 × 2: pixel 0 both cover with the same triangle (error 2), pixel 1 both cover
        // with different triangles (error 6), pixel 2 only `a` covers (with black: still
        // covered), pixel 3 only `b`.
        let mut a = Image::new(2, 2);
        let mut b = Image::new(2, 2);
        a.pixels[0] = [10, 10, 10, 255];
        b.pixels[0] = [12, 10, 10, 255];
        a.pixels[1] = [50, 50, 50, 255];
        b.pixels[1] = [50, 56, 50, 255];
        b.pixels[3] = [90, 0, 0, 255];
        let a_triangles = [triangle(0, 1), triangle(0, 2), triangle(1, 0), None];
        let b_triangles = [triangle(0, 1), triangle(0, 3), None, triangle(1, 5)];
        let m = compare_frames(&a, &a_triangles, &b, &b_triangles).unwrap();
        assert_eq!(m.coverage_from, CoverageFrom::Triangles);
        assert_eq!(m.covered_in_both_pixels, 2);
        assert_eq!(m.covered_max_abs_error_levels, 6);
        // Over the covered pixels' 6 channels: (4 + 36) / 6.
        let want = 10.0 * (255.0f64 * 255.0 * 6.0 / 40.0).log10();
        assert!((m.covered_psnr_db - want).abs() < 1e-12);
        assert_eq!((m.wrongly_covered_share, m.missed_share), (0.25, 0.25));
        assert_eq!(m.visibility_differing_share, Some(0.25));
        // The window-wide figures are compare's.
        let plain = compare(&a, &b).unwrap();
        assert_eq!(
            (m.psnr_db, m.max_abs_error, m.differing_share),
            (plain.psnr_db, plain.max_abs_error, plain.differing_share)
        );
        assert_eq!(plain.coverage_from, CoverageFrom::BackgroundColour);
        assert_eq!(plain.visibility_differing_share, None);
        // Pixel 2 is black in `a`: by colour only pixel 3 differs in coverage, and the
        // covered pixels' error is over pixels 0 and 1 all the same.
        assert_eq!(
            (plain.wrongly_covered_share, plain.missed_share),
            (0.0, 0.25)
        );
        assert_eq!(plain.covered_psnr_db, m.covered_psnr_db);
        assert!(compare_frames(&a, &a_triangles[..3], &b, &b_triangles).is_err());
    }

    #[test]
    fn metrics_serialise_with_their_field_names() {
        let m = compare(&Image::new(1, 1), &Image::new(1, 1)).unwrap();
        let json = serde_json::to_value(m).unwrap();
        for key in [
            "psnr_db",
            "max_abs_error",
            "differing_share",
            "coverage_mismatch_share",
            "coverage_from",
            "covered_in_both_pixels",
            "covered_psnr_db",
            "covered_max_abs_error_levels",
            "wrongly_covered_share",
            "missed_share",
            "visibility_differing_share",
        ] {
            assert!(json.get(key).is_some(), "{key} missing from {json}");
        }
    }

    #[test]
    fn png_round_trip_keeps_pixels_and_orientation() {
        let mut image = Image::new(5, 3);
        for y in 0..3 {
            for x in 0..5 {
                image.set_pixel(x, y, [x as u8 * 40, y as u8 * 70, 9, 200 + x as u8]);
            }
        }
        let dir = std::env::temp_dir().join(format!("imagine-verif-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("round_trip.png");
        image.write_png(&path).unwrap();
        let back = Image::read_png(&path).unwrap();
        assert_eq!(back, image);

        // The PNG's first row is the image's top row (y = 2).
        let decoder = png::Decoder::new(BufReader::new(File::open(&path).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut buffer = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut buffer).unwrap();
        assert_eq!(&buffer[..4], &image.pixel(0, 2));

        let missing = dir.join("missing.png");
        let e = Image::read_png(&missing).unwrap_err();
        assert!(e.contains("missing.png"), "{e}");
        std::fs::write(&missing, b"not a png").unwrap();
        assert!(Image::read_png(&missing).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
