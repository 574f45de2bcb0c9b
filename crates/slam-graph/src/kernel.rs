//! Robust kernels ρ(s) of the squared Mahalanobis error s = eᵀΩe, applied by iteratively
//! reweighted least squares (IRLS): each edge's block of the normal equations is scaled by
//! w = ρ′(s) at the current estimate (g2o's `RobustKernel::robustify`, Kümmerle et al. 2011).
//!
//! A kernel bounds the pull of an edge whose error is far larger than its information claims,
//! which is what a false loop closure looks like.

use serde::{Deserialize, Serialize};

/// A robust cost ρ of the squared error s = eᵀΩe (dimensionless, χ²-distributed for a correct
/// edge). Every kernel has ρ(s) = s and ρ′(s) = 1 for small s, so inliers are treated as
/// plain least squares.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
#[serde(
    tag = "kind",
    rename_all = "kebab-case",
    deny_unknown_fields,
    from = "KernelInFile"
)]
pub enum RobustKernel {
    /// Plain least squares: ρ(s) = s.
    #[default]
    None,
    /// Huber: ρ(s) = s for s ≤ δ², 2δ√s − δ² beyond (linear growth in ‖e‖; g2o's
    /// `RobustKernelHuber`). δ is in units of standard deviations of the whitened error.
    Huber {
        /// Threshold δ > 0 on √s.
        delta: f64,
    },
    /// Cauchy: ρ(s) = c² ln(1 + s/c²), w = 1/(1 + s/c²) (g2o's `RobustKernelCauchy`).
    Cauchy {
        /// Scale c > 0, in whitened standard deviations.
        c: f64,
    },
    /// Dynamic Covariance Scaling (Agarwal, Tipaldi, Spinello, Stachniss and Burgard, ICRA
    /// 2013, eq. 11): the error is scaled by σ = min(1, 2Φ/(Φ + s)), so w = σ². The cost whose
    /// IRLS weight this is, ρ(s) = s for s ≤ Φ and 3Φ − 4Φ²/(Φ + s) beyond, is continuous,
    /// bounded by 3Φ and is what the Levenberg-Marquardt acceptance test compares.
    Dcs {
        /// Φ > 0, the squared error at which scaling starts (the paper uses Φ = 1).
        phi: f64,
    },
    /// Truncated least squares ρ(s) = min(s, c²) under graduated non-convexity (Yang,
    /// Antonante, Tzoumas and Carlone, "Graduated non-convexity for robust spatial
    /// perception", RA-L 2020, eq. 13 and Prop. 5, written in s = r²): the surrogate
    /// ρ_μ(s) = s for s ≤ μ/(μ+1)·c², 2c√(μ(μ+1)s) − μ(c² + s) up to (μ+1)/μ·c², and c²
    /// beyond, whose weight w = ρ′_μ(s) is 1, c√(μ(μ+1)/s) − μ and 0 on the three pieces.
    /// Small μ makes ρ_μ nearly convex; μ → ∞ gives the truncated cost. The optimiser's GNC
    /// stage sets it on the closures with a growing μ; it is not a configuration choice (not
    /// read or written).
    #[serde(skip)]
    GncTls {
        /// c² > 0, the squared error beyond which an edge counts as an outlier.
        c2: f64,
        /// μ > 0, the continuation parameter.
        mu: f64,
    },
}

/// A kernel as a configuration file gives it. `kind = "none"` is a struct variant without
/// fields here, so that a parameter beside it (`kind = "none"` and `delta = 5.0`: a Huber
/// kernel meant, none written) is an unknown key: as a unit variant of the internally
/// tagged enum, serde ignored every other key of its table.
#[derive(Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
enum KernelInFile {
    None {},
    Huber { delta: f64 },
    Cauchy { c: f64 },
    Dcs { phi: f64 },
}

impl From<KernelInFile> for RobustKernel {
    fn from(k: KernelInFile) -> Self {
        match k {
            KernelInFile::None {} => RobustKernel::None,
            KernelInFile::Huber { delta } => RobustKernel::Huber { delta },
            KernelInFile::Cauchy { c } => RobustKernel::Cauchy { c },
            KernelInFile::Dcs { phi } => RobustKernel::Dcs { phi },
        }
    }
}

impl RobustKernel {
    /// ρ(s) and w = ρ′(s) for s = eᵀΩe ≥ 0.
    #[inline]
    pub fn robustify(&self, s: f64) -> (f64, f64) {
        match *self {
            RobustKernel::None => (s, 1.0),
            RobustKernel::Huber { delta } => {
                if s <= delta * delta {
                    (s, 1.0)
                } else {
                    let r = s.sqrt();
                    (2.0 * delta * r - delta * delta, delta / r)
                }
            }
            RobustKernel::Cauchy { c } => {
                let c2 = c * c;
                let q = 1.0 + s / c2;
                (c2 * q.ln(), 1.0 / q)
            }
            RobustKernel::Dcs { phi } => {
                if s <= phi {
                    (s, 1.0)
                } else {
                    let scale = 2.0 * phi / (phi + s);
                    (3.0 * phi - 4.0 * phi * phi / (phi + s), scale * scale)
                }
            }
            RobustKernel::GncTls { c2, mu } => {
                if s <= mu / (mu + 1.0) * c2 {
                    (s, 1.0)
                } else if s >= (mu + 1.0) / mu * c2 {
                    (c2, 0.0)
                } else {
                    let m = (mu * (mu + 1.0)).sqrt();
                    let root = (c2 * s).sqrt();
                    (2.0 * m * root - mu * (c2 + s), m * (c2 / s).sqrt() - mu)
                }
            }
        }
    }

    /// The kernel's parameter, or `None` for plain least squares.
    pub fn parameter(&self) -> Option<f64> {
        match *self {
            RobustKernel::None => None,
            RobustKernel::Huber { delta } => Some(delta),
            RobustKernel::Cauchy { c } => Some(c),
            RobustKernel::Dcs { phi } => Some(phi),
            RobustKernel::GncTls { c2, .. } => Some(c2),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// w = ρ′(s), checked by central differences, and ρ continuous at the switch points.
    #[test]
    fn weight_is_the_derivative_of_the_cost() {
        for k in [
            RobustKernel::None,
            RobustKernel::Huber { delta: 1.5 },
            RobustKernel::Cauchy { c: 2.0 },
            RobustKernel::Dcs { phi: 1.0 },
            RobustKernel::GncTls { c2: 2.0, mu: 0.5 },
            RobustKernel::GncTls {
                c2: 16.27,
                mu: 0.01,
            },
        ] {
            for s in [0.01f64, 0.5, 0.99, 1.01, 2.2, 2.3, 7.0, 100.0, 1e4] {
                let h = 1e-6 * s.max(1.0);
                let d = (k.robustify(s + h).0 - k.robustify(s - h).0) / (2.0 * h);
                let w = k.robustify(s).1;
                assert!(
                    (d - w).abs() < 1e-6 * w.max(1e-3),
                    "{k:?} s={s}: {d} vs {w}"
                );
            }
            let p = k.parameter().unwrap_or(1.0);
            let edge = if matches!(k, RobustKernel::Huber { .. }) {
                p * p
            } else {
                p
            };
            let (a, b) = (
                k.robustify(edge * (1.0 - 1e-12)).0,
                k.robustify(edge * (1.0 + 1e-12)).0,
            );
            assert!((a - b).abs() < 1e-9, "{k:?} jumps at {edge}");
        }
        // GNC-TLS: continuous at both ends of its middle piece, ρ_μ → min(s, c²) as μ grows.
        for (c2, mu) in [(2.0f64, 0.5f64), (16.27, 0.01), (16.27, 40.0)] {
            let k = RobustKernel::GncTls { c2, mu };
            for edge in [mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2] {
                let (a, b) = (
                    k.robustify(edge * (1.0 - 1e-12)),
                    k.robustify(edge * (1.0 + 1e-12)),
                );
                assert!((a.0 - b.0).abs() < 1e-9, "{k:?} jumps at {edge}");
                assert!((a.1 - b.1).abs() < 1e-5, "{k:?}: weight jumps at {edge}");
            }
        }
        let tls = RobustKernel::GncTls { c2: 16.27, mu: 1e6 };
        for s in [1.0, 16.0, 16.5, 1e4] {
            assert!((tls.robustify(s).0 - s.min(16.27)).abs() < 1e-3 * s.min(16.27));
        }
    }

    #[test]
    fn redescending_kernels_bound_the_cost() {
        let dcs = RobustKernel::Dcs { phi: 1.0 };
        assert!(dcs.robustify(1e12).0 < 3.0);
        assert!(dcs.robustify(1e6).1 < 1e-11);
        let cauchy = RobustKernel::Cauchy { c: 1.0 };
        assert!(cauchy.robustify(1e6).1 < 1e-5);
    }

    /// A kernel table is read with every key checked: `kind = "none"` beside a parameter
    /// (a Huber kernel meant, `none` written) is an unknown key named in the error, as a
    /// parameter of another kind is; the kinds with their parameters read as before and
    /// round-trip.
    #[test]
    fn a_kernel_table_refuses_keys_its_kind_has_not() {
        #[derive(Debug, serde::Deserialize, serde::Serialize)]
        struct Holder {
            kernel: RobustKernel,
        }
        let read = |text: &str| toml::from_str::<Holder>(text).map(|h| h.kernel);
        for text in [
            "[kernel]\nkind = \"none\"\ndelta = 5.0\n",
            "[kernel]\nkind = \"huber\"\nphi = 5.0\n",
            "[kernel]\nkind = \"none\"\nbogus = 1\n",
        ] {
            let e = read(text).unwrap_err().to_string();
            assert!(e.contains("unknown field"), "{text}: {e}");
        }
        for k in [
            RobustKernel::None,
            RobustKernel::Huber { delta: 2.0 },
            RobustKernel::Cauchy { c: 1.5 },
            RobustKernel::Dcs { phi: 1.0 },
        ] {
            let text = toml::to_string(&Holder { kernel: k }).unwrap();
            assert_eq!(read(&text).unwrap(), k, "{text}");
        }
        assert_eq!(
            read("[kernel]\nkind = \"none\"\n").unwrap(),
            RobustKernel::None
        );
    }
}
