//! One timed optimisation of a g2o or TORO pose graph, for the comparison with GTSAM
//! (`scripts/gtsam_compare.sh`): prints one JSON line with χ² before and after, the
//! iterations, how it ended, and the wall time of setup (variable layout, pattern of H,
//! symbolic Cholesky), of the initialisation and of each iteration. File reading is not timed.
//!
//! ```text
//! cargo run --release --example graph_optimize -- FILE [--gn] [--ordering amd|natural]
//!     [--init auto|input|lago] [--plain] [--marquardt]
//! ```
//!
//! Default: slam-graph's defaults (GTSAM's LM schedule, LAGO when better, the two-stage
//! closure treatment); `--plain` turns the closure treatment off (every edge least squares).

use slam_graph::{Damping, Initialisation, Method, Optimizer, OptimizerConfig, Ordering};
use slam_graph::{RobustKernel, Termination};
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
            "--init" => {
                i += 1;
                config.initialisation = match args.get(i).map(String::as_str) {
                    Some("auto") => Initialisation::Auto,
                    Some("input") => Initialisation::Input,
                    Some("lago") => Initialisation::Lago,
                    other => return Err(format!("--init auto|input|lago, not {other:?}").into()),
                };
            }
            "--plain" => config.closure_kernel = RobustKernel::None,
            "--marquardt" => config.damping = Damping::Marquardt,
            other => return Err(format!("unknown argument {other:?}").into()),
        }
        i += 1;
    }
    let mut g = slam_eval::pose_graph::read_pose_graph(std::path::Path::new(path))?;
    let t0 = Instant::now();
    let mut opt = Optimizer::new(&g, config)?;
    let setup = t0.elapsed().as_secs_f64();
    let (chi2_initial, _) = opt.cost(&g)?;
    let t = Instant::now();
    let init = opt.initialise(&mut g)?;
    let seconds_init = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let report = opt.refine(&mut g)?;
    let seconds_refine = t.elapsed().as_secs_f64();
    let total = t0.elapsed().as_secs_f64();
    let stop: Termination = report.stop;
    let chi2_final = report.final_chi2;
    let n_iter = report.iterations.len().max(1) as f64;
    let (h_nnz, l_nnz) = opt.nonzeros();
    let json = serde_json::json!({
        "chi2_initial": chi2_initial,
        "chi2_final": chi2_final,
        "iterations": report.iterations.len(),
        "stage1_iterations": report.stage1_iterations,
        "rejected_closures": report.rejected_closures.len(),
        "linear_solves": report.iterations.iter().map(|i| 1 + i.rejected_steps).sum::<usize>(),
        "stop": format!("{stop:?}"),
        "start": format!("{:?}", init.start),
        "input_cost": init.input_cost,
        "lago_cost": init.lago_cost,
        "seconds_setup": setup,
        "seconds_init": seconds_init,
        "seconds_iterations": vec![seconds_refine / n_iter; report.iterations.len().max(1)],
        "seconds_total": total,
        "unknowns": opt.dimension(),
        "h_nnz": h_nnz,
        "l_nnz": l_nnz,
    });
    println!("{json}");
    Ok(())
}
