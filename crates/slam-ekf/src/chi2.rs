//! Chi-square quantiles for gates (even degrees of freedom, exact).
//!
//! For an even number of degrees of freedom k = 2m the chi-square CDF has the closed form
//! F(x; 2m) = 1 − e^(−x/2)·Σ_{i<m} (x/2)^i / i!  (the Erlang/Poisson identity), so the
//! quantile is found by bisection to full precision. Range-bearing innovations contribute
//! two degrees of freedom each, so every gate in this crate has an even dimension.

/// F(x; 2m), the chi-square CDF with 2m degrees of freedom at x ≥ 0.
pub(crate) fn cdf_even(x: f64, m: usize) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    let h = 0.5 * x;
    // Sum the Poisson terms e^(−h) h^i / i! in log space for large h.
    let mut log_term = -h;
    let mut sum = 0.0;
    for i in 0..m {
        if i > 0 {
            log_term += h.ln() - (i as f64).ln();
        }
        sum += log_term.exp();
    }
    (1.0 - sum).clamp(0.0, 1.0)
}

/// The `p`-quantile of the chi-square distribution with `dof` (even, ≥ 2) degrees of
/// freedom: the x with F(x; dof) = p. `p` must lie in (0, 1).
pub(crate) fn quantile_even(dof: usize, p: f64) -> f64 {
    debug_assert!(dof >= 2 && dof % 2 == 0 && p > 0.0 && p < 1.0);
    let m = dof / 2;
    let mut lo = 0.0;
    let mut hi = (dof as f64).max(1.0);
    while cdf_even(hi, m) < p {
        lo = hi;
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf_even(mid, m) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Caches gate thresholds χ²_{dof}(p) for one probability, dof = 2, 4, 6, ….
#[derive(Debug, Clone)]
pub(crate) struct GateTable {
    p: f64,
    by_pairs: Vec<f64>,
}

impl GateTable {
    pub(crate) fn new(p: f64) -> Self {
        Self {
            p,
            by_pairs: Vec::new(),
        }
    }

    /// χ²_{2·pairs}(p).
    pub(crate) fn threshold(&mut self, pairs: usize) -> f64 {
        let pairs = pairs.max(1);
        while self.by_pairs.len() < pairs {
            let k = self.by_pairs.len() + 1;
            self.by_pairs.push(quantile_even(2 * k, self.p));
        }
        self.by_pairs[pairs - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::gaussian::CHI2_95;

    #[test]
    fn matches_tables() {
        // Even entries of the 95 % table in slam-models (2, 4, …, 10 dof).
        for k in [2usize, 4, 6, 8, 10] {
            let q = quantile_even(k, 0.95);
            assert!((q - CHI2_95[k - 1]).abs() < 1e-5, "dof {k}: {q}");
        }
        // 2 dof has the closed form −2 ln(1 − p).
        for p in [0.5, 0.9, 0.99, 0.999] {
            let q = quantile_even(2, p);
            assert!((q + 2.0 * (1.0 - p).ln()).abs() < 1e-9);
        }
        // Published values: χ²_{20}(0.99) = 37.566, χ²_{100}(0.975) = 129.561,
        // χ²_{150}(0.025) = 117.985.
        assert!((quantile_even(20, 0.99) - 37.5662).abs() < 1e-3);
        assert!((quantile_even(100, 0.975) - 129.561).abs() < 1e-2);
        assert!((quantile_even(150, 0.025) - 117.985).abs() < 2e-2);
    }

    #[test]
    fn table_caches_in_order() {
        let mut t = GateTable::new(0.95);
        assert!((t.threshold(3) - CHI2_95[5]).abs() < 1e-5);
        assert!((t.threshold(1) - CHI2_95[1]).abs() < 1e-5);
    }
}
