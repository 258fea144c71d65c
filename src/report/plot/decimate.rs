//! Min-max decimation of a long record to the plot's pixel columns.

/// At most `2 × columns` points `(t, y)` that draw like all of them at `columns` pixel
/// columns: the samples split into `columns` runs of consecutive samples, each
/// represented by its minimum and maximum in the order they occur (one point when they
/// coincide). Fewer samples than `2 × columns` are returned as they are; `columns = 0` or
/// lengths that disagree give no point. Non-finite values are skipped.
pub fn decimate_min_max(t: &[f64], y: &[f64], columns: usize) -> Vec<(f64, f64)> {
    let n = t.len().min(y.len());
    if columns == 0 || t.len() != y.len() {
        return Vec::new();
    }
    let finite = |k: &usize| y[*k].is_finite() && t[*k].is_finite();
    if n <= 2 * columns {
        return (0..n).filter(finite).map(|k| (t[k], y[k])).collect();
    }
    let mut out = Vec::with_capacity(2 * columns);
    for c in 0..columns {
        let (a, b) = (c * n / columns, (c + 1) * n / columns);
        let run = (a..b).filter(finite);
        let lo = run.clone().min_by(|&i, &j| y[i].total_cmp(&y[j]));
        let hi = run.max_by(|&i, &j| y[i].total_cmp(&y[j]));
        if let (Some(lo), Some(hi)) = (lo, hi) {
            let (first, second) = if lo <= hi { (lo, hi) } else { (hi, lo) };
            out.push((t[first], y[first]));
            if second != first {
                out.push((t[second], y[second]));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::decimate_min_max;

    #[test]
    fn decimation_keeps_extremes_and_caps_points() {
        let t: Vec<f64> = (0..10_000).map(|k| k as f64).collect();
        let mut y: Vec<f64> = t.iter().map(|v| (v / 50.0).sin()).collect();
        y[1234] = 7.0;
        y[5678] = -9.0;
        let d = decimate_min_max(&t, &y, 100);
        assert!(d.len() <= 200);
        assert!(d.contains(&(1234.0, 7.0)) && d.contains(&(5678.0, -9.0)));
        assert!(d.windows(2).all(|w| w[0].0 < w[1].0));
        assert_eq!(decimate_min_max(&t[..10], &y[..10], 100).len(), 10);
        assert!(decimate_min_max(&t, &y[..5], 100).is_empty());
    }
}
