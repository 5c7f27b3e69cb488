//! The thesis's batch-size model (Owens 2002 §5.2.3, Table 5.2): a frame's cycles
//! `r = c∞ + c_b / b` for batches of `b`, from per-kernel costs `c1 + c2·ℓ` over `c4 / b`
//! batches of length `ℓ ∝ b`. `c∞` is the asymptote (the per-element work), `c_b` the
//! per-batch overhead summed over the frame, and `b½ = c_b / c∞` the batch at which the
//! overhead equals the work. Fitted by least squares in `1/b`.

/// A fit of `r = c∞ + c_b / b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchModel {
    pub c_inf: f64,
    pub c_b: f64,
    /// Coefficient of determination of the fit (1: every point on the curve).
    pub r_squared: f64,
}

impl BatchModel {
    /// The batch at which overhead equals work, `c_b / c∞`.
    pub fn b_half(&self) -> f64 {
        self.c_b / self.c_inf
    }

    /// The least-squares fit to `(b, r)` points; `None` without at least two distinct `b`.
    pub fn fit(points: &[(f64, f64)]) -> Option<BatchModel> {
        let n = points.len() as f64;
        let xs: Vec<f64> = points.iter().map(|&(b, _)| 1.0 / b).collect();
        let mean_x = xs.iter().sum::<f64>() / n;
        let mean_r = points.iter().map(|&(_, r)| r).sum::<f64>() / n;
        let sxx: f64 = xs.iter().map(|x| (x - mean_x).powi(2)).sum();
        if sxx.is_nan() || sxx <= 0.0 {
            return None;
        }
        let sxr: f64 = xs
            .iter()
            .zip(points)
            .map(|(x, &(_, r))| (x - mean_x) * (r - mean_r))
            .sum();
        let c_b = sxr / sxx;
        let c_inf = mean_r - c_b * mean_x;
        let total: f64 = points.iter().map(|&(_, r)| (r - mean_r).powi(2)).sum();
        let residual: f64 = xs
            .iter()
            .zip(points)
            .map(|(x, &(_, r))| (r - (c_inf + c_b * x)).powi(2))
            .sum();
        let r_squared = if total > 0.0 {
            1.0 - residual / total
        } else {
            1.0
        };
        Some(BatchModel {
            c_inf,
            c_b,
            r_squared,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_the_curve_give_its_constants_back() {
        let curve = |b: f64| 2.63e6 + 232e6 / b;
        let points: Vec<(f64, f64)> = [8.0, 32.0, 96.0, 288.0]
            .iter()
            .map(|&b| (b, curve(b)))
            .collect();
        let m = BatchModel::fit(&points).unwrap();
        assert!((m.c_inf / 2.63e6 - 1.0).abs() < 1e-9, "{m:?}");
        assert!((m.c_b / 232e6 - 1.0).abs() < 1e-9, "{m:?}");
        assert!((m.b_half() - 232.0 / 2.63).abs() < 1e-6);
        assert!((m.r_squared - 1.0).abs() < 1e-12);
        // Points off the curve lower R².
        let mut off = points.clone();
        off[2].1 *= 2.0;
        off[3].1 *= 0.5;
        assert!(BatchModel::fit(&off).unwrap().r_squared < 0.95);
        assert_eq!(BatchModel::fit(&[(8.0, 1.0), (8.0, 2.0)]), None);
    }
}
