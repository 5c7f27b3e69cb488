//! `sweep --plot`: the points' error (PSNR against the reference, dB, higher is better)
//! against their cycles, each point labelled with its knob values, and the Pareto
//! frontier — the points no other point beats on both, fewest cycles for a given PSNR —
//! joined by a line and ringed. A PNG drawn with `plotters`' bitmap backend; its text uses
//! a font bundled in the binary (DejaVu Sans, `assets/fonts/`), so no system font library
//! is needed.

use std::path::Path;
use std::sync::Once;

use anyhow::{Result, anyhow};
use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

/// One point on the plot.
pub struct PlotPoint {
    /// Its knob values, as `batch=8 machine=gold16`.
    pub label: String,
    pub cycles: u64,
    /// `None` when the frame equals the reference (an infinite PSNR).
    pub psnr_db: Option<f64>,
}

const FONT: &[u8] = include_bytes!("../../../assets/fonts/DejaVuSans.ttf");
const FONT_NAME: &str = "imagine-sans";

fn register_bundled_font() -> Result<()> {
    static REGISTER: Once = Once::new();
    let mut result = Ok(());
    REGISTER.call_once(|| {
        result = register_font(FONT_NAME, FontStyle::Normal, FONT)
            .map_err(|_| anyhow!("the bundled font is not a TrueType font"));
    });
    result
}

/// The indices of the Pareto frontier's points, by cycles: each has a higher PSNR than
/// every point with as few cycles or fewer (an infinite PSNR is the highest).
pub fn pareto_frontier(points: &[PlotPoint]) -> Vec<usize> {
    let psnr = |p: &PlotPoint| p.psnr_db.unwrap_or(f64::INFINITY);
    let mut order: Vec<usize> = (0..points.len()).collect();
    // Fewest cycles first; of equal cycles, the best PSNR first (it alone can be on it).
    order.sort_by(|&a, &b| {
        (points[a].cycles)
            .cmp(&points[b].cycles)
            .then(psnr(&points[b]).total_cmp(&psnr(&points[a])))
    });
    let mut frontier = Vec::new();
    let mut best = f64::NEG_INFINITY;
    for i in order {
        if psnr(&points[i]) > best {
            best = psnr(&points[i]);
            frontier.push(i);
        }
    }
    frontier
}

/// Draws the plot of `points` titled `title` into the PNG `path`.
pub fn write(path: &Path, title: &str, points: &[PlotPoint]) -> Result<()> {
    register_bundled_font()?;
    let finite: Vec<f64> = points.iter().filter_map(|p| p.psnr_db).collect();
    let (low, high) = finite
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    let (low, high) = if finite.is_empty() {
        (0.0, 100.0)
    } else {
        (low, high)
    };
    let margin = ((high - low) * 0.15).max(1.0);
    // A frame equal to the reference is drawn at the top edge and says so.
    let top = high + 2.0 * margin;
    let y_of = |p: &PlotPoint| p.psnr_db.unwrap_or(top);
    let max_cycles = points.iter().map(|p| p.cycles).max().unwrap_or(1) as f64;
    let min_cycles = points.iter().map(|p| p.cycles).min().unwrap_or(0) as f64;
    let x_margin = ((max_cycles - min_cycles) * 0.15).max(max_cycles * 0.05);
    let x_range = (min_cycles - x_margin).max(0.0)..max_cycles + 2.0 * x_margin;

    let root = BitMapBackend::new(path, (1200, 800)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, (FONT_NAME, 24))
        .margin(20)
        .x_label_area_size(50)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, (low - margin)..top + margin)
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_mesh()
        .x_desc("core cycles per frame, millions (fewer is faster)")
        .y_desc("PSNR against the reference, dB (higher is better)")
        .label_style((FONT_NAME, 14))
        .axis_desc_style((FONT_NAME, 16))
        .x_label_formatter(&|x| format!("{:.2} M", x / 1e6))
        .draw()
        .map_err(|e| anyhow!("{e}"))?;

    let frontier = pareto_frontier(points);
    let frontier_colour = RGBColor(200, 30, 30);
    chart
        .draw_series(LineSeries::new(
            frontier
                .iter()
                .map(|&i| (points[i].cycles as f64, y_of(&points[i]))),
            frontier_colour.stroke_width(2),
        ))
        .map_err(|e| anyhow!("{e}"))?
        .label("Pareto frontier (fewest cycles for a given PSNR)")
        .legend(move |(x, y)| PathElement::new([(x, y), (x + 20, y)], frontier_colour));
    chart
        .draw_series(frontier.iter().map(|&i| {
            Circle::new(
                (points[i].cycles as f64, y_of(&points[i])),
                9,
                frontier_colour.stroke_width(2),
            )
        }))
        .map_err(|e| anyhow!("{e}"))?;
    let label_style = TextStyle::from((FONT_NAME, 13)).color(&BLACK);
    // Points close together would print their labels over each other: each label moves
    // down a line for every earlier point near it.
    let (x_span, y_span) = (
        max_cycles - min_cycles + 2.0 * x_margin,
        top - low + 2.0 * margin,
    );
    let near = |a: &PlotPoint, b: &PlotPoint| {
        (a.cycles as f64 - b.cycles as f64).abs() < 0.25 * x_span
            && (y_of(a) - y_of(b)).abs() < 0.05 * y_span
    };
    chart
        .draw_series(points.iter().enumerate().map(|(i, p)| {
            let text = match p.psnr_db {
                Some(_) => p.label.clone(),
                None => format!("{} (equals the reference)", p.label),
            };
            let line = points[..i].iter().filter(|q| near(p, q)).count() as i32;
            EmptyElement::at((p.cycles as f64, y_of(p)))
                + Circle::new((0, 0), 4, BLUE.filled())
                + Text::new(text, (8, -14 + 16 * line), label_style.clone())
        }))
        .map_err(|e| anyhow!("{e}"))?;
    chart
        .configure_series_labels()
        .label_font((FONT_NAME, 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("{e}"))?;
    root.present()
        .map_err(|e| anyhow!("cannot write `{}`: {e}", path.display()))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(cycles: u64, psnr_db: Option<f64>) -> PlotPoint {
        PlotPoint {
            label: format!("{cycles}"),
            cycles,
            psnr_db,
        }
    }

    #[test]
    fn the_frontier_keeps_the_points_nothing_beats() {
        let points = [
            point(100, Some(30.0)),
            point(200, Some(25.0)), // slower and worse than the first
            point(300, Some(40.0)),
            point(100, Some(35.0)), // as fast as the first, better
            point(400, None),       // exact
            point(500, Some(60.0)), // slower than the exact one
        ];
        assert_eq!(pareto_frontier(&points), vec![3, 2, 4]);
    }
}
