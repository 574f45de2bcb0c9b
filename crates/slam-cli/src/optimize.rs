//! `slam optimize`: reads a g2o or TORO pose graph, optimises it with slam-graph (by default
//! from LAGO's global estimate when that is better, with false loop closures down-weighted:
//! see `slam_graph::optimizer`) and writes `optimized.g2o` (the graph with the optimised
//! estimates), `result.json` ([`OptimizeOutput`]: χ² before and after, how the run ended, the
//! start used, the closures rejected and one entry per iteration), `graph.png` (before |
//! after) and `config.toml` (the optimiser configuration used). It prints the wall time of
//! each phase (read, set-up, initialise, optimise, write); the process exits with status 3
//! when the result is worse than the start or the run diverged or was singular.

use crate::cli::OptimizeArgs;
use crate::config;
use crate::error::CliError;
use crate::outdir::{OutDir, Owner};
use serde::Serialize;
use slam_graph::{
    InitReport, IterationInfo, Optimizer, OptimizerConfig, RobustKernel, Termination,
};
use std::io::Write;
use std::time::Instant;

/// What `slam optimize` wrote to `result.json`. Deterministic: the same input and
/// configuration give the same bytes (no timings).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OptimizeOutput {
    /// The input file, as given.
    pub input: String,
    /// Nodes in the graph.
    pub nodes: usize,
    /// Edges in the graph.
    pub edges: usize,
    /// χ² = Σ eᵀΩe at the input's estimates.
    pub initial_chi2: f64,
    /// χ² at the result.
    pub final_chi2: f64,
    /// The robust cost Σ ρ(eᵀΩe) at the input (= χ² without a kernel).
    pub initial_cost: f64,
    /// The robust cost at the result.
    pub final_cost: f64,
    /// How the run ended: converged by which test, iteration limit, λ limit, diverged or
    /// singular.
    pub stop: Termination,
    /// Whether one of the convergence tests ended it.
    pub converged: bool,
    /// Whether the result is worse than the start (cost under the final kernels), or the run
    /// diverged or was singular; the process then exits with status 3.
    pub worse_than_start: bool,
    /// The start used (input or LAGO) and the costs compared.
    pub init: InitReport,
    /// Loop closures left down-weighted as false (eᵀΩe above `closure-inlier-chi2`).
    pub rejected_closures: usize,
    /// One entry per iteration.
    pub iterations: Vec<IterationInfo>,
}

/// Parses `none`, `huber:δ`, `cauchy:c` or `dcs:Φ`.
fn parse_kernel(s: &str) -> Result<RobustKernel, CliError> {
    let bad = || {
        CliError::InvalidArgument(format!(
            "--kernel {s:?}: expected none, huber:DELTA, cauchy:C or dcs:PHI with a number > 0"
        ))
    };
    if s == "none" {
        return Ok(RobustKernel::None);
    }
    let (name, v) = s.split_once(':').ok_or_else(bad)?;
    let v: f64 = v.parse().map_err(|_| bad())?;
    if !(v > 0.0 && v.is_finite()) {
        return Err(bad());
    }
    match name {
        "huber" => Ok(RobustKernel::Huber { delta: v }),
        "cauchy" => Ok(RobustKernel::Cauchy { c: v }),
        "dcs" => Ok(RobustKernel::Dcs { phi: v }),
        _ => Err(bad()),
    }
}

/// The phases of `slam optimize` between which Ctrl-C stops it: read, optimise, write.
const PHASES: usize = 3;

/// Ctrl-C honoured as `slam run` honours it: after `done` phases, a stop leaves the staged
/// files uncommitted (dropped), so an earlier output in the folder stays as it was.
fn stopped(done: usize) -> Result<(), CliError> {
    if crate::stop_requested() {
        return Err(CliError::Interrupted {
            step: done,
            steps: PHASES,
        });
    }
    Ok(())
}

/// How a run ended, in words.
fn termination_words(t: Termination) -> &'static str {
    match t {
        Termination::CostBelowTolerance => "converged (cost below the absolute tolerance)",
        Termination::AbsoluteDecrease => "converged (absolute decrease below tolerance)",
        Termination::RelativeDecrease => "converged (relative decrease below tolerance)",
        Termination::MaxIterations => "NOT converged: iteration limit reached",
        Termination::LambdaLimit => "stopped: no step lowers the cost (damping at its limit)",
        Termination::Diverged => "DIVERGED: a step raised the cost; the best iterate is kept",
        Termination::Singular => "SINGULAR normal equations: an unconstrained variable?",
    }
}

/// Runs `slam optimize` with `args`, printing a summary to `out`.
pub fn optimize(args: &OptimizeArgs, out: &mut dyn Write) -> Result<OptimizeOutput, CliError> {
    let mut cfg: OptimizerConfig = config::load(args.config.as_deref())?.config;
    if let Some(k) = &args.kernel {
        cfg.kernel = parse_kernel(k)?;
    }
    // Written like slam run's outputs: staged, renamed into place, result.json last; only a
    // new or empty folder, or this command's own earlier output, is written into.
    let mut inputs = vec![("GRAPH", args.graph.as_path())];
    if let Some(c) = &args.config {
        inputs.push(("--config", c.as_path()));
    }
    let staging = OutDir::prepare(&args.out, Owner::Optimize, false, &inputs)?;
    let stage = staging.stage().to_path_buf();
    let t = Instant::now();
    let before = slam_eval::pose_graph::read_pose_graph(&args.graph)?;
    let read = t.elapsed();
    stopped(1)?;
    let mut graph = before.clone();
    // An error about the graph names its file; one about the configuration does not.
    let of_graph = |e: slam_graph::GraphError| match e {
        e @ slam_graph::GraphError::InvalidConfig(_) => CliError::Graph(e),
        e => CliError::GraphFile {
            path: args.graph.clone(),
            source: e,
        },
    };
    let t = Instant::now();
    let mut opt = Optimizer::new(&graph, cfg).map_err(of_graph)?;
    let setup = t.elapsed();
    let t = Instant::now();
    let init = opt.initialise(&mut graph).map_err(of_graph)?;
    let initialise = t.elapsed();
    let t = Instant::now();
    let mut report = opt.refine(&mut graph).map_err(of_graph)?;
    let optimise = t.elapsed();
    stopped(2)?;
    let t = Instant::now();
    // The start is the input, not the initialisation: χ² and cost there, under the final
    // kernels (so that the two costs compare).
    let (initial_chi2, initial_cost) = opt.cost(&before).map_err(of_graph)?;
    report.initial_chi2 = initial_chi2;
    report.initial_cost = initial_cost;
    report.init = init;
    slam_eval::pose_graph::write_pose_graph(&stage.join("optimized.g2o"), &graph)?;
    slam_viz::graph_picture::save_before_after(&before, &graph, &stage.join("graph.png"))?;
    let result = OptimizeOutput {
        input: args.graph.display().to_string(),
        nodes: graph.nodes().len(),
        edges: graph.edges().len(),
        initial_chi2: report.initial_chi2,
        final_chi2: report.final_chi2,
        initial_cost: report.initial_cost,
        final_cost: report.final_cost,
        stop: report.stop,
        converged: report.stop.converged(),
        worse_than_start: report.worse_than_start(),
        init: report.init,
        rejected_closures: report.rejected_closures.len(),
        iterations: report.iterations,
    };
    let write = |name: &str, text: String| {
        let p = stage.join(name);
        std::fs::write(&p, text).map_err(|e| CliError::Write { path: p, source: e })
    };
    let json = serde_json::to_string_pretty(&result)
        .map_err(|e| CliError::InvalidArgument(format!("result.json: {e}")))?;
    write("result.json", json + "\n")?;
    write("config.toml", config::to_toml(&cfg))?;
    stopped(3)?;
    staging.commit(&["optimized.g2o", "graph.png", "config.toml", "result.json"])?;
    let write_time = t.elapsed();
    let lago = match result.init.lago_cost {
        Some(c) => format!("LAGO cost {c:.6e}"),
        None => "LAGO not applicable".to_string(),
    };
    let _ = writeln!(
        out,
        "{}: {} nodes, {} edges\n  start: {:?} (input cost {:.6e}, {lago})\n  \
         χ² {:.6e} → {:.6e} in {} iterations: {}{}\n  {} loop closures rejected as false\n  \
         time: read {:.3} s, set-up {:.3} s, initialise {:.3} s, optimise {:.3} s, write {:.3} s\n  \
         wrote {}",
        args.graph.display(),
        result.nodes,
        result.edges,
        result.init.start,
        result.init.input_cost,
        result.initial_chi2,
        result.final_chi2,
        result.iterations.len(),
        termination_words(result.stop),
        if result.worse_than_start {
            " — WORSE THAN THE START"
        } else {
            ""
        },
        result.rejected_closures,
        read.as_secs_f64(),
        setup.as_secs_f64(),
        initialise.as_secs_f64(),
        optimise.as_secs_f64(),
        write_time.as_secs_f64(),
        args.out.display()
    );
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_parse() {
        assert_eq!(parse_kernel("none").unwrap(), RobustKernel::None);
        assert_eq!(
            parse_kernel("dcs:10").unwrap(),
            RobustKernel::Dcs { phi: 10.0 }
        );
        for bad in ["dcs", "dcs:-1", "dcs:x", "tukey:1", "huber:inf"] {
            assert!(parse_kernel(bad).is_err(), "{bad}");
        }
    }

    /// `configs/graph.toml` is the defaults, key by key.
    #[test]
    fn example_config_is_the_default() {
        let path =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../configs/graph.toml");
        let text = std::fs::read_to_string(&path).unwrap();
        let loaded = config::parse::<OptimizerConfig>(&text, &path).unwrap();
        assert_eq!(loaded.config, OptimizerConfig::default());
        assert!(config::parse::<OptimizerConfig>("lambda = 1\n", &path).is_err());
    }

    /// A square loop whose closure disagrees with the odometry: the program writes every
    /// output, the optimised file reads back with the reported χ², and a bad file or kernel
    /// is an error naming it.
    #[test]
    fn writes_the_outputs() {
        let dir = std::env::temp_dir().join(format!("slam-cli-opt-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let input = dir.join("square.g2o");
        let mut text = String::new();
        for (i, (x, y, t)) in [
            (0.0, 0.0, 0.0),
            (1.1, 0.0, 1.6),
            (1.0, 0.9, 3.1),
            (0.1, 1.2, -1.5),
        ]
        .iter()
        .enumerate()
        {
            text += &format!("VERTEX_SE2 {i} {x} {y} {t}\n");
        }
        for i in 0..4 {
            let dx = if i == 3 { 1.2 } else { 1.0 };
            text += &format!(
                "EDGE_SE2 {i} {} {dx} 0 1.5707963267948966 1 0 0 1 0 1\n",
                (i + 1) % 4
            );
        }
        std::fs::write(&input, text).unwrap();
        let out = dir.join("out");
        let args = [
            "slam",
            "optimize",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        let mut sink = Vec::new();
        let crate::Outcome::Optimized(r) = crate::main_with_args(args, &mut sink).unwrap() else {
            panic!("not an optimisation")
        };
        assert!(r.final_chi2 < r.initial_chi2 && r.final_chi2 > 0.0);
        for f in ["optimized.g2o", "result.json", "graph.png", "config.toml"] {
            assert!(out.join(f).exists(), "{f}");
        }
        let back = slam_eval::pose_graph::read_pose_graph(&out.join("optimized.g2o")).unwrap();
        let o = Optimizer::new(&back, OptimizerConfig::default()).unwrap();
        assert!((o.cost(&back).unwrap().0 - r.final_chi2).abs() < 1e-12);
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap())
                .unwrap();
        assert_eq!(json["final_chi2"].as_f64(), Some(r.final_chi2));

        // Its own earlier output is replaced; a folder of someone else's files is refused
        // before any work and left as it was; so is a folder holding the input.
        assert!(crate::main_with_args(args, &mut sink).is_ok());
        assert!(!out.join(".slam-partial").exists());
        let foreign = dir.join("foreign");
        std::fs::create_dir_all(&foreign).unwrap();
        std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
        let mut into_foreign = args;
        into_foreign[4] = foreign.to_str().unwrap();
        let e = crate::main_with_args(into_foreign, &mut sink)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not empty") && e.contains("notes.txt"), "{e}");
        let names: Vec<_> = std::fs::read_dir(&foreign).unwrap().flatten().collect();
        assert_eq!(names.len(), 1);
        let mut into_input_dir = args;
        into_input_dir[4] = dir.to_str().unwrap();
        let e = crate::main_with_args(into_input_dir, &mut sink)
            .unwrap_err()
            .to_string();
        assert!(e.contains("lies inside"), "{e}");

        std::fs::write(&input, "VERTEX_SE2 0 0 0 0\nEDGE_SE3 0 1\n").unwrap();
        let e = crate::main_with_args(args, &mut sink)
            .unwrap_err()
            .to_string();
        assert!(e.contains("square.g2o:2"), "{e}");
        let mut bad = args.to_vec();
        bad.extend(["--kernel", "tukey:2"]);
        let e = crate::main_with_args(bad, &mut sink)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--kernel"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
