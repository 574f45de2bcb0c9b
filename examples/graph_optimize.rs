//! One timed optimisation of a g2o pose graph, for the comparison with GTSAM
//! (`scripts/gtsam_compare.sh`): prints one JSON line with χ² before and after, the
//! iterations and the wall time of setup (variable layout, pattern of H, symbolic Cholesky)
//! and of each iteration. File reading is not timed.
//!
//! ```text
//! cargo run --release --example graph_optimize -- FILE.g2o [--gn] [--ordering amd|natural]
//! ```
//!
//! Default: Levenberg-Marquardt with slam-graph's defaults (GTSAM's LM defaults), no kernel.

use slam_graph::{Method, Optimizer, OptimizerConfig, Ordering, StopReason};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let path = args
        .first()
        .ok_or("usage: graph_optimize FILE.g2o [--gn] [--ordering amd|natural]")?;
    let mut config = OptimizerConfig::default();
    let mut i = 1;
    while i < args.len() {
        match args[i].as_str() {
            "--gn" => config.method = Method::GaussNewton,
            "--ordering" => {
                i += 1;
                config.ordering = match args.get(i).map(String::as_str) {
                    Some("amd") => Ordering::Amd,
                    Some("natural") => Ordering::Natural,
                    other => return Err(format!("--ordering amd|natural, not {other:?}").into()),
                };
            }
            other => return Err(format!("unknown argument {other:?}").into()),
        }
        i += 1;
    }
    let mut g = slam_io::g2o::read_g2o(std::path::Path::new(path))?;
    let t0 = Instant::now();
    let mut opt = Optimizer::new(&g, config)?;
    let setup = t0.elapsed().as_secs_f64();
    let (chi2_initial, _) = opt.cost(&g)?;
    // The loop of Optimizer::optimize, with a clock around each iteration.
    let mut iters = Vec::new();
    let mut stop = StopReason::MaxIterations;
    for _ in 0..config.max_iterations {
        let t = Instant::now();
        let info = opt.iterate(&mut g)?;
        iters.push((info, t.elapsed().as_secs_f64()));
        if !info.accepted {
            stop = StopReason::LambdaLimit;
            break;
        }
        if let Some(reason) = config.converged(info.cost_before, info.cost_after) {
            stop = reason;
            break;
        }
    }
    let total = t0.elapsed().as_secs_f64();
    let (chi2_final, _) = opt.cost(&g)?;
    let (h_nnz, l_nnz) = opt.nonzeros();
    let json = serde_json::json!({
        "chi2_initial": chi2_initial,
        "chi2_final": chi2_final,
        "iterations": iters.len(),
        "linear_solves": iters.iter().map(|(i, _)| 1 + i.rejected_steps).sum::<usize>(),
        "stop": format!("{stop:?}"),
        "seconds_setup": setup,
        "seconds_iterations": iters.iter().map(|(_, s)| *s).collect::<Vec<_>>(),
        "seconds_total": total,
        "unknowns": opt.dimension(),
        "h_nnz": h_nnz,
        "l_nnz": l_nnz,
    });
    println!("{json}");
    Ok(())
}
