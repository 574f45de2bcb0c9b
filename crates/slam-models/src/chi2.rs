//! Chi-square quantiles and Monte Carlo consistency bands.
//!
//! Used for gating (a range-bearing innovation is accepted when νᵀS⁻¹ν ≤ χ²₂(p)) and for
//! NEES/NIS consistency bands (Bar-Shalom, Li & Kirubarajan 2001, §5.4.2). The quantile is
//! found by bisection on the regularised lower incomplete gamma function
//! P(k/2, x/2) = F(x; k), so any number of degrees of freedom is exact to double precision.

use crate::detmath;

/// ln Γ(x) for x > 0 (Lanczos approximation, g = 7, n = 9; relative error < 1e-15).
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Reflection: Γ(x)Γ(1−x) = π / sin(πx).
        let pi = std::f64::consts::PI;
        return detmath::ln(pi / detmath::sin(pi * x)) - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut a = C[0];
    let t = x + G + 0.5;
    for (i, c) in C.iter().enumerate().skip(1) {
        a += c / (x + i as f64);
    }
    0.5 * detmath::ln(2.0 * std::f64::consts::PI) + (x + 0.5) * detmath::ln(t) - t + detmath::ln(a)
}

/// The regularised lower incomplete gamma function P(a, x) = γ(a, x)/Γ(a), a > 0, x ≥ 0:
/// its series for x < a + 1 and the Lentz continued fraction of Q = 1 − P otherwise
/// (Numerical Recipes, 3rd ed., §6.2). NaN for invalid arguments.
pub fn regularized_gamma_p(a: f64, x: f64) -> f64 {
    if a.is_nan() || x.is_nan() || a <= 0.0 || x < 0.0 || a.is_infinite() {
        return f64::NAN;
    }
    if x == 0.0 {
        return 0.0;
    }
    if x.is_infinite() {
        return 1.0;
    }
    let lead = a * detmath::ln(x) - x - ln_gamma(a);
    if x < a + 1.0 {
        let (mut ap, mut sum, mut del) = (a, 1.0 / a, 1.0 / a);
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        detmath::exp(detmath::ln(sum) + lead).min(1.0)
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (1.0 - (detmath::exp(lead) * h)).max(0.0)
    }
}

/// The quantile x with P(χ²(dof) ≤ x) = p, i.e. P(dof/2, x/2) = p, found by bisection on
/// the monotone [`regularized_gamma_p`] to full double precision. NaN when dof = 0 or
/// p ∉ [0, 1); 0 for p = 0.
pub fn chi2_quantile(dof: usize, p: f64) -> f64 {
    if dof == 0 || !(0.0..1.0).contains(&p) {
        return f64::NAN;
    }
    if p == 0.0 {
        return 0.0;
    }
    let a = dof as f64 / 2.0;
    let cdf = |x: f64| regularized_gamma_p(a, x / 2.0);
    let mut hi = dof as f64 + 10.0 * (2.0 * dof as f64).sqrt() + 10.0;
    while cdf(hi) < p {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-14 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The two-sided `prob` (e.g. 0.95) acceptance band of an average NEES (or NIS) over
/// `runs` Monte Carlo runs of a `dof`-dimensional error: runs·ε̄ ~ χ²(runs·dof), so the
/// band is [χ²⁻¹((1−prob)/2), χ²⁻¹((1+prob)/2)] / runs (Bar-Shalom et al. 2001, §5.4.2).
/// (NaN, NaN) when dof or runs is 0 or prob ∉ (0, 1).
pub fn chi2_band(dof: usize, runs: usize, prob: f64) -> (f64, f64) {
    if dof == 0 || runs == 0 || !(prob > 0.0 && prob < 1.0) {
        return (f64::NAN, f64::NAN);
    }
    let k = dof * runs;
    let r = runs as f64;
    (
        chi2_quantile(k, (1.0 - prob) / 2.0) / r,
        chi2_quantile(k, (1.0 + prob) / 2.0) / r,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables() {
        // Abramowitz & Stegun table 26.8 / NIST handbook values.
        let cases = [
            (1, 0.025, 0.000982069),
            (1, 0.975, 5.023886),
            (2, 0.95, 5.991465),
            (3, 0.025, 0.2157953),
            (3, 0.975, 9.348404),
            (10, 0.025, 3.246973),
            (10, 0.975, 20.48318),
            (100, 0.025, 74.22193),
            (100, 0.975, 129.5612),
            (300, 0.5, 299.3334),
        ];
        for (k, p, want) in cases {
            let q = chi2_quantile(k, p);
            assert!(
                ((q - want) / want).abs() < 2e-6,
                "χ²({k}) at {p}: {q} vs {want}"
            );
        }
        for (k, &want) in crate::gaussian::CHI2_95.iter().enumerate() {
            assert!((chi2_quantile(k + 1, 0.95) - want).abs() < 1e-5);
        }
        // Closed form for 2 dof: P(χ² ≤ x) = 1 − e^(−x/2).
        assert!((regularized_gamma_p(1.0, 1.3) - (1.0 - (-1.3f64).exp())).abs() < 1e-14);
        assert!(chi2_quantile(0, 0.5).is_nan() && chi2_quantile(3, 1.0).is_nan());
    }

    #[test]
    fn band_for_monte_carlo_runs() {
        // 50 runs, 3 dof: χ²(150) at 2.5 % / 97.5 % is 117.985 / 185.800 (tables), ÷ 50.
        let (lo, hi) = chi2_band(3, 50, 0.95);
        assert!((lo - 117.9845 / 50.0).abs() < 1e-3, "{lo}");
        assert!((hi - 185.8004 / 50.0).abs() < 1e-3, "{hi}");
        assert!(chi2_band(0, 5, 0.95).0.is_nan());
    }

    #[test]
    fn two_dof_closed_form() {
        // F(x; 2) = 1 − e^(−x/2), so χ²₂(p) = −2 ln(1 − p).
        for p in [0.5, 0.9, 0.99, 0.999] {
            assert!((chi2_quantile(2, p) + 2.0 * (1.0 - p).ln()).abs() < 1e-9);
        }
    }
}
