//! A machine frame's error against `verif`'s independent f64 reference renderer: the
//! comparison `render` reports and `sweep` measures at every point, in one place so that
//! the two cannot drift apart.

use std::time::Instant;

use anyhow::Result;
use imagine_pipelines::opengl::render::Frame;
use imagine_pipelines::reyes::frame::ReyesFrame;
use imagine_pipelines::scene::bpt::densely_diced;
use imagine_pipelines::scene::model::{Scene, TriangleId};
use imagine_verif::image::{Image, Metrics, compare_coverage, compare_frames};
use imagine_verif::reference_model as reference;

/// The reference frame and how far the machine's is from it.
pub struct ReferenceError {
    /// The reference renderer's frame.
    pub reference: Image,
    /// For every pixel of it, the triangle it shows (`None`: background).
    pub triangles: Vec<Option<TriangleId>>,
    pub metrics: Metrics,
    /// Host seconds the reference renderer and the comparison took.
    pub seconds: f64,
}

/// The machine's frame as an image.
pub fn image_of(frame: &Frame) -> Image {
    Image::from_rgba8_words(frame.width, frame.height, &frame.pixels)
}

/// Renders `scene` with the reference renderer and compares the machine's `frame` with it:
/// coverage and visibility by the triangles each frame shows in each pixel.
pub fn measure(scene: &Scene, frame: &Frame) -> Result<ReferenceError> {
    let start = Instant::now();
    let (reference, reference_triangles) = reference::render_visible(scene)?;
    let metrics = compare_frames(
        &image_of(frame),
        &frame.triangles,
        &reference,
        &reference_triangles,
    )
    .map_err(anyhow::Error::msg)?;
    Ok(ReferenceError {
        reference,
        triangles: reference_triangles,
        metrics,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Quads per patch side the reference draws a Reyes frame's patches with: at 720×720 the
/// teapot's largest patch spans about 250 pixels, so its triangles are about 4 pixels
/// across and the flat triangles lie within a small fraction of a pixel of the surface.
pub const REFERENCE_DICE: u32 = 64;

/// A Reyes frame's error against the reference renderer drawing the scene's patches
/// diced [`REFERENCE_DICE`]² each (the limit surface, within a small fraction of a pixel):
/// colour over the whole window and over the pixels both cover, and coverage (a pixel the
/// machine drew passed the depth test against the cleared 1.0). Visibility is not
/// compared: quads are not the reference's triangles.
pub fn measure_reyes(scene: &Scene, frame: &ReyesFrame) -> Result<ReferenceError> {
    let start = Instant::now();
    let dense = densely_diced(scene, REFERENCE_DICE);
    let (reference, triangles) = reference::render_visible(&dense)?;
    let image = Image::from_rgba8_words(frame.width, frame.height, &frame.colour);
    let drawn: Vec<bool> = frame.depth.iter().map(|&d| d < 1.0).collect();
    let covered: Vec<bool> = triangles.iter().map(Option::is_some).collect();
    let metrics =
        compare_coverage(&image, &drawn, &reference, &covered).map_err(anyhow::Error::msg)?;
    Ok(ReferenceError {
        reference,
        triangles,
        metrics,
        seconds: start.elapsed().as_secs_f64(),
    })
}
