//! Times the reference renderer on SPHERE-FULL (81,920 triangles) at 720×720 and optionally
//! writes the image: `cargo run --release -p imagine-verif --example reference_sphere
//! [-- out.png]`.

use imagine_pipelines::scene::{DEFAULT_SIZE, builtin};
use imagine_verif::reference;
use std::time::Instant;

fn main() -> Result<(), String> {
    let scene = builtin("SPHERE-FULL", DEFAULT_SIZE).map_err(|e| e.to_string())?;
    let mut best = f64::INFINITY;
    let mut image = None;
    for _ in 0..3 {
        let start = Instant::now();
        image = Some(reference::render(&scene));
        best = best.min(start.elapsed().as_secs_f64());
    }
    let image = image.expect("rendered");
    let covered = image.pixels.iter().filter(|p| p[..3] != [0, 0, 0]).count();
    println!(
        "reference::render SPHERE-FULL {}x{}: {} triangles, {covered} pixels covered, best of 3: {:.3} s",
        scene.width,
        scene.height,
        scene.triangles(),
        best
    );
    if let Some(path) = std::env::args().nth(1) {
        image.write_png(&path)?;
        println!("wrote {path}");
    }
    Ok(())
}
