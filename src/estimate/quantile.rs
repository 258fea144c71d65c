//! Quantiles of the reported intervals: Student's t at 0.975 (the factor of every ± t·se
//! interval) and the quantile an interval was formed at (its longer side over its
//! standard error).

/// 0.975 quantile of Student's t with `dof` degrees of freedom (the factor of a
/// two-sided 95 % interval).
///
/// Exact (table, to 1e-15) for dof ≤ 30, Cornish-Fisher expansion beyond (Abramowitz &
/// Stegun 26.7.5; error below 3e-8 for dof > 30); ∞ for dof = 0.
pub fn t_quantile_975(dof: usize) -> f64 {
    // scipy.stats.t.ppf(0.975, dof) for dof = 1..=30.
    const TABLE: [f64; 30] = [
        12.706204736174694,
        4.302652729749462,
        3.182446305283708,
        2.776445105197793,
        2.570581835636315,
        2.446911851144979,
        2.364624251592784,
        2.306004135204166,
        2.262157162798205,
        2.228138851986274,
        2.200985160091639,
        2.178812829667228,
        2.160368656462791,
        2.144786687917804,
        2.131449545559776,
        2.119905299221255,
        2.109815577833316,
        2.100922040241038,
        2.093024054408309,
        2.085963447265864,
        2.07961384472768,
        2.073873067904025,
        2.068657610419049,
        2.063898561628025,
        2.059538552753297,
        2.055529438642874,
        2.051830516480285,
        2.048407141795245,
        2.045229642132703,
        2.042272456301238,
    ];
    const Z: f64 = 1.959_963_984_540_054;
    match dof {
        0 => f64::INFINITY,
        1..=30 => TABLE[dof - 1],
        _ => {
            let n = dof as f64;
            let z2 = Z * Z;
            let g1 = (z2 + 1.0) * Z / 4.0;
            let g2 = ((5.0 * z2 + 16.0) * z2 + 3.0) * Z / 96.0;
            let g3 = (((3.0 * z2 + 19.0) * z2 + 17.0) * z2 - 15.0) * Z / 384.0;
            let g4 = ((((79.0 * z2 + 776.0) * z2 + 1482.0) * z2 - 1920.0) * z2 - 945.0) * Z / 92160.0;
            Z + g1 / n + g2 / (n * n) + g3 / (n * n * n) + g4 / (n * n * n * n)
        }
    }
}

/// The quantile an interval was formed at: its longer side over the standard error,
/// `max(hi − value, value − lo)/std_error` (dimensionless; [`t_quantile_975`]`(dof)` for
/// `value ± t·std_error`, more for a side widened by a restricted or a widened interval).
/// An interval's heaviness as one number: the precision gate reads a parameter's reach by
/// it, and a quantity of two parameters takes the heavier of theirs.
///
/// `ci95`: `[lo, hi]`, the unit of `value` and `std_error`. ±∞ or NaN where the standard
/// error is 0, NaN where it or an end is NaN, 0 where it is ∞ and the ends finite (the
/// caller decides the fallback: the precision gate and `k_m` keep a finite result only);
/// no errors.
pub fn interval_quantile(ci95: [f64; 2], value: f64, std_error: f64) -> f64 {
    (ci95[1] - value).max(value - ci95[0]) / std_error
}

#[cfg(test)]
mod tests {
    use super::{interval_quantile, t_quantile_975};

    #[test]
    fn t_quantile_matches_reference_values() {
        // scipy.stats.t.ppf(0.975, dof)
        for (dof, q) in [
            (1, 12.706204736174694),
            (5, 2.570581835636315),
            (30, 2.042272456301238),
            (31, 2.039513446396408),
            (100, 1.983971518523552),
            (100_000, 1.959987707534609),
        ] {
            assert!((t_quantile_975(dof) - q).abs() < 3e-8, "dof {dof}: {} vs {q}", t_quantile_975(dof));
        }
        assert!(t_quantile_975(0).is_infinite());
    }

    #[test]
    fn an_intervals_quantile_is_its_longer_side_over_its_standard_error() {
        let t = t_quantile_975(12);
        approx::assert_relative_eq!(
            interval_quantile([2.0 - t * 0.5, 2.0 + t * 0.5], 2.0, 0.5),
            t,
            max_relative = 1e-15
        );
        approx::assert_relative_eq!(
            interval_quantile([2.0 - 1.2 * 0.5, 2.0 + 3.0 * 0.5], 2.0, 0.5),
            3.0,
            max_relative = 1e-15
        );
        approx::assert_relative_eq!(
            interval_quantile([2.0 - 3.0 * 0.5, 2.0 + 1.2 * 0.5], 2.0, 0.5),
            3.0,
            max_relative = 1e-15
        );
        assert!(interval_quantile([1.0, 3.0], 2.0, 0.0).is_infinite());
        assert_eq!(interval_quantile([1.0, 3.0], 2.0, f64::INFINITY), 0.0);
    }
}
