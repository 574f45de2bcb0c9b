//! Cached chi-square gate thresholds (the quantiles come from `slam_models::chi2`).
//!
//! Range-bearing innovations contribute two degrees of freedom each, so every joint gate in
//! this crate has an even dimension 2·pairs.

pub(crate) use slam_models::chi2::chi2_quantile;

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
            self.by_pairs.push(chi2_quantile(2 * k, self.p));
        }
        self.by_pairs[pairs - 1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slam_models::gaussian::CHI2_95;

    #[test]
    fn table_caches_in_order() {
        let mut t = GateTable::new(0.95);
        assert!((t.threshold(3) - CHI2_95[5]).abs() < 1e-5);
        assert!((t.threshold(1) - CHI2_95[1]).abs() < 1e-5);
    }
}
