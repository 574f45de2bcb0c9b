//! The optimiser's configuration, its per-iteration record, how a run ended and its report.

use crate::error::GraphError;
use crate::kernel::RobustKernel;
use crate::linear::{Factorization, Ordering};
use serde::{Deserialize, Serialize};

/// The nonlinear solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Undamped Gauss-Newton: every step is taken.
    GaussNewton,
    /// Levenberg-Marquardt with λI damping and step rejection.
    #[default]
    LevenbergMarquardt,
}

/// The damping term D of Levenberg-Marquardt's (H + λD) δ = −g.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Damping {
    /// D = I (Levenberg 1944; GTSAM's default).
    #[default]
    Identity,
    /// D = diag(H), each entry at least 1e-9 (Marquardt 1963; GTSAM's `diagonalDamping`).
    Marquardt,
}

/// Where refinement starts (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Initialisation {
    /// LAGO's estimate when the graph is planar pose-only and LAGO's start has the lower cost
    /// F; the input estimates otherwise (default).
    #[default]
    Auto,
    /// The input estimates as given.
    Input,
    /// LAGO's estimate whenever the graph allows it (the input otherwise).
    Lago,
}

/// The start refinement used.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Start {
    /// The input estimates.
    Input,
    /// LAGO's global estimate ([`crate::lago`]).
    Lago,
}

/// What [`Optimizer::initialise`](super::Optimizer::initialise) did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InitReport {
    /// The start kept.
    pub start: Start,
    /// Cost F (stage-1 kernels) of the input estimates.
    pub input_cost: f64,
    /// Cost F of LAGO's estimate, when computed.
    pub lago_cost: Option<f64>,
}

/// Optimiser settings; the defaults are GTSAM's `LevenbergMarquardtParams` defaults, plus the
/// initialisation and loop-closure treatment of the module documentation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", default, deny_unknown_fields)]
pub struct OptimizerConfig {
    /// Gauss-Newton or Levenberg-Marquardt (default).
    pub method: Method,
    /// Robust kernel applied to every edge not under `closure_kernel` (default none).
    pub kernel: RobustKernel,
    /// Kernel on the closures (non-odometry edges) in stage 1, and on the closures stage 2
    /// rejects (default DCS, Φ = 1: Agarwal et al. 2013's value; a closure counts fully only
    /// while eᵀΩe ≤ 1, so a false one pulls with at most 3Φ of cost from the first iteration).
    /// `none` turns the two-stage treatment off.
    pub closure_kernel: RobustKernel,
    /// Stage 2: a closure whose eᵀΩe at the stage-1 result is at most this is an inlier and
    /// returns to full weight (default 16.27, the χ²(3) 99.9 % quantile: one correct 3-DoF
    /// edge in a thousand would exceed it). 2-D edges (points) use the χ²(2) quantile of the
    /// same probability (13.82 for the default).
    pub closure_inlier_chi2: f64,
    /// The GNC stage's truncation c² (see the module documentation): a closure is kept when including it raises the least-squares cost by less than this
    /// (default 21.11, the χ²(3) 99.99 % quantile; 2-D edges use the χ²(2) quantile of the
    /// same probability, 18.42). Only used when the χ² stages leave closures rejected.
    pub closure_gnc_chi2: f64,
    /// Start of the refinement (default auto: LAGO when it gives the lower cost).
    pub initialisation: Initialisation,
    /// LM damping term (default λI).
    pub damping: Damping,
    /// Iteration limit (≥ 1; default 100).
    pub max_iterations: usize,
    /// Stop when the cost's relative decrease is at most this (≥ 0; default 1e-5).
    pub relative_tolerance: f64,
    /// Stop when the cost, or its absolute decrease, is at most this (≥ 0; default 1e-5).
    pub absolute_tolerance: f64,
    /// LM: initial damping λ₀ > 0 (default 1e-5, in units of H's entries).
    pub lambda_initial: f64,
    /// LM: factor f > 1 by which λ grows after a rejected step and shrinks after an accepted
    /// one (default 10).
    pub lambda_factor: f64,
    /// LM: give up (stop) when λ exceeds this (default 1e5).
    pub lambda_max: f64,
    /// Fill-reducing ordering of the sparse Cholesky (default AMD).
    pub ordering: Ordering,
    /// Numeric Cholesky kernel (default: faer chooses).
    pub factorization: Factorization,
}

impl Default for OptimizerConfig {
    fn default() -> Self {
        Self {
            method: Method::LevenbergMarquardt,
            kernel: RobustKernel::None,
            closure_kernel: RobustKernel::Dcs { phi: 1.0 },
            closure_inlier_chi2: 16.27,
            closure_gnc_chi2: 21.11,
            initialisation: Initialisation::Auto,
            damping: Damping::Identity,
            max_iterations: 100,
            relative_tolerance: 1e-5,
            absolute_tolerance: 1e-5,
            lambda_initial: 1e-5,
            lambda_factor: 10.0,
            lambda_max: 1e5,
            ordering: Ordering::Amd,
            factorization: Factorization::Auto,
        }
    }
}

impl OptimizerConfig {
    /// The stopping rule of the module documentation (GTSAM's `checkConvergence` on the cost
    /// F) after an iteration took F from `before` to `after`: `Some(reason)` to stop.
    pub fn converged(&self, before: f64, after: f64) -> Option<Termination> {
        let decrease = before - after;
        if after <= self.absolute_tolerance {
            Some(Termination::CostBelowTolerance)
        } else if decrease <= self.absolute_tolerance {
            Some(Termination::AbsoluteDecrease)
        } else if decrease / before <= self.relative_tolerance {
            Some(Termination::RelativeDecrease)
        } else {
            None
        }
    }

    /// Checks every field against its documented range.
    pub fn validate(&self) -> Result<(), GraphError> {
        let bad = |field, value: f64, expected| {
            Err(GraphError::InvalidConfig(slam_models::ConfigError::new(
                "optimiser",
                field,
                value,
                expected,
            )))
        };
        if self.max_iterations == 0 {
            return bad("max_iterations", 0.0, "≥ 1");
        }
        for (f, v) in [
            ("relative_tolerance", self.relative_tolerance),
            ("absolute_tolerance", self.absolute_tolerance),
        ] {
            if !(v >= 0.0 && v.is_finite()) {
                return bad(f, v, "finite and ≥ 0");
            }
        }
        if !(self.lambda_initial > 0.0 && self.lambda_initial.is_finite()) {
            return bad("lambda_initial", self.lambda_initial, "finite and > 0");
        }
        if !(self.lambda_factor > 1.0 && self.lambda_factor.is_finite()) {
            return bad("lambda_factor", self.lambda_factor, "finite and > 1");
        }
        if !(self.lambda_max >= self.lambda_initial && self.lambda_max.is_finite()) {
            return bad("lambda_max", self.lambda_max, "finite and ≥ lambda_initial");
        }
        for (f, k) in [
            ("kernel parameter", self.kernel),
            ("closure_kernel parameter", self.closure_kernel),
        ] {
            if let Some(p) = k.parameter() {
                if !(p > 0.0 && p.is_finite()) {
                    return bad(f, p, "finite and > 0");
                }
            }
        }
        for (f, v) in [
            ("closure_inlier_chi2", self.closure_inlier_chi2),
            ("closure_gnc_chi2", self.closure_gnc_chi2),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(f, v, "finite and > 0");
            }
        }
        Ok(())
    }
}

/// What one iteration did (faer-style diagnostics, not errors).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IterationInfo {
    /// 0-based iteration number.
    pub iteration: usize,
    /// χ² = Σ eᵀΩe before the iteration (no kernel applied).
    pub chi2_before: f64,
    /// χ² after it (equal to `chi2_before` when no step was accepted).
    pub chi2_after: f64,
    /// The cost minimised, F = Σ ρ(eᵀΩe), before (= χ² without a kernel).
    pub cost_before: f64,
    /// F after.
    pub cost_after: f64,
    /// LM: the λ of the accepted (or last tried) step; 0 for Gauss-Newton.
    pub lambda: f64,
    /// ‖δ‖₂ of the accepted step (0 when none was).
    pub step_norm: f64,
    /// LM: steps rejected (and re-solved with a larger λ) in this iteration.
    pub rejected_steps: usize,
    /// Whether a step was applied.
    pub accepted: bool,
}

/// How optimisation ended: converged by one of three tests, or stopped for another reason.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Termination {
    /// Converged: the cost fell to at most `absolute_tolerance`.
    CostBelowTolerance,
    /// Converged: the cost's absolute decrease was at most `absolute_tolerance`.
    AbsoluteDecrease,
    /// Converged: the cost's relative decrease was at most `relative_tolerance`.
    RelativeDecrease,
    /// Not converged: `max_iterations` iterations ran.
    MaxIterations,
    /// LM: λ exceeded `lambda_max` with no step lowering the cost (at a minimum to working
    /// precision, or stuck).
    LambdaLimit,
    /// Gauss-Newton: a step raised the cost; it was not taken and the graph holds the best
    /// iterate.
    Diverged,
    /// Gauss-Newton: H was not positive definite (an unconstrained variable); the graph holds
    /// the last iterate.
    Singular,
}

/// The former name of [`Termination`].
pub type StopReason = Termination;

impl Termination {
    /// Whether one of the three convergence tests ended the run.
    pub fn converged(&self) -> bool {
        matches!(
            self,
            Termination::CostBelowTolerance
                | Termination::AbsoluteDecrease
                | Termination::RelativeDecrease
        )
    }

    /// Whether the run failed (diverged or singular): not a usable optimum.
    pub fn failed(&self) -> bool {
        matches!(self, Termination::Diverged | Termination::Singular)
    }
}

/// The result of [`Optimizer::optimize`](super::Optimizer::optimize).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptimizeReport {
    /// χ² at the initial guess.
    pub initial_chi2: f64,
    /// χ² at the result.
    pub final_chi2: f64,
    /// F at the initial guess.
    pub initial_cost: f64,
    /// F at the result.
    pub final_cost: f64,
    /// One entry per iteration (both stages).
    pub iterations: Vec<IterationInfo>,
    /// How the (last stage of the) run ended.
    pub stop: Termination,
    /// The initialisation (default when [`Optimizer::refine`](super::Optimizer::refine) is called alone: the input).
    pub init: InitReport,
    /// Iterations of stage 1 (the rest are stage 2's).
    pub stage1_iterations: usize,
    /// Closures down-weighted at the end (indices into [`PoseGraph::edges`](crate::graph::PoseGraph::edges)).
    pub rejected_closures: Vec<usize>,
}

impl OptimizeReport {
    /// Whether the result is worse than the start (cost F under the final kernels higher
    /// than at the input) or the run failed: `slam optimize` exits non-zero then.
    pub fn worse_than_start(&self) -> bool {
        self.final_cost > self.initial_cost || self.stop.failed()
    }
}
