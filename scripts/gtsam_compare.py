#!/usr/bin/env python3
"""GTSAM's Levenberg-Marquardt against slam-graph's on a 2-D g2o pose graph (issue 22).

Both start from the file's initial guess, with no robust kernel, the first pose held (GTSAM:
a prior of variances 1e-6, 1e-6, 1e-8, the form of GTSAM's Pose2SLAMExample_g2o.py), and
the same stopping rule: GTSAM's LevenbergMarquardtParams defaults (lambda 1e-5, factor 10,
upper bound 1e5, relative error tolerance 1e-5, at most 100 iterations), with GTSAM's
absolute tolerance set to 0.5e-5 because GTSAM's error is chi2 / 2 and slam-graph's
tolerances apply to chi2.

The runs alternate, GTSAM then slam-graph (one process per run, `examples/graph_optimize`),
`--rounds` times; file reading is not timed on either side. Prints one JSON object:
GTSAM's figures (its own chi2 = 2 * error, over the file's edges only, and the chi2 of the
g2o error t2v(Z^-1 Xi^-1 Xj) that slam-graph minimises, evaluated at GTSAM's result), ours,
and the median time ratios. Run through scripts/gtsam_compare.sh, which makes the venv.
"""

import argparse
import importlib.metadata
import json
import statistics
import subprocess
import time
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from gtsam_truth import g2o_chi2, optimize  # noqa: E402  (GTSAM's run, shared with the tests)


def run_gtsam(path):
    """GTSAM's run, through tests/gtsam_truth.py (the same reader, prior and parameters)."""
    edges, initial, result, iterations, seconds, cpu = optimize(path)
    return {
        "chi2_initial": 2.0 * edges.error(initial),
        "chi2_final_gtsam_error": 2.0 * edges.error(result),
        "chi2_final_g2o_error": g2o_chi2(edges, result),
        "iterations": iterations,
        "seconds_total": seconds,
        "cpu_seconds_total": cpu,
    }


def run_ours(binary, path):
    out = subprocess.run([binary, path], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def run_slam_process(slam, path, out_dir, config=None):
    """The whole `slam optimize` process (read, set-up, initialise, optimise, write): wall
    seconds and the child's user + system CPU seconds (getrusage of the reaped child)."""
    import resource
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([slam, "optimize", path, "--out", out_dir]
                   + (["--config", config] if config else []), check=True,
                   capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("g2o")
    ap.add_argument("--ours", required=True, help="path of the graph_optimize example binary")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--slam", help="path of the `slam` binary: also time the whole "
                    "`slam optimize` process against GTSAM's optimise call alone")
    ap.add_argument("--slam-config", help="an optimiser configuration (TOML) for that process")
    a = ap.parse_args()
    import tempfile
    scratch = tempfile.mkdtemp(prefix="gtsam-compare-")
    g, o, p = [], [], []
    for _ in range(a.rounds):
        g.append(run_gtsam(a.g2o))
        o.append(run_ours(a.ours, a.g2o))
        if a.slam:
            p.append(run_slam_process(a.slam, a.g2o, scratch, a.slam_config))
    med = statistics.median
    gt_total = med(r["seconds_total"] for r in g)
    gt_iter = med(r["seconds_total"] / r["iterations"] for r in g)
    our_total = med(r["seconds_total"] for r in o)
    our_iter = med(statistics.mean(r["seconds_iterations"]) for r in o)
    print(json.dumps({
        "file": a.g2o,
        "rounds": a.rounds,
        "gtsam_version": importlib.metadata.version("gtsam"),
        "gtsam": g[0] | {"seconds_total_median": gt_total, "seconds_per_iteration_median": gt_iter},
        "ours": {k: o[0][k] for k in ("chi2_initial", "chi2_final", "iterations", "stop")}
        | {"seconds_total_median": our_total, "seconds_per_iteration_median": our_iter,
           "seconds_setup_median": med(r["seconds_setup"] for r in o)},
        "ratio_total_ours_over_gtsam": our_total / gt_total,
        "ratio_per_iteration_ours_over_gtsam": our_iter / gt_iter,
    } | ({
        "slam_optimize_process_wall_median": med(r["wall"] for r in p),
        "slam_optimize_process_cpu_median": med(r["cpu"] for r in p),
        "ratio_process_wall_over_gtsam_optimize": med(r["wall"] for r in p) / gt_total,
        "gtsam_optimize_cpu_median": med(r["cpu_seconds_total"] for r in g),
        "ratio_process_cpu_over_gtsam_optimize_cpu":
            med(r["cpu"] for r in p) / med(r["cpu_seconds_total"] for r in g),
    } if p else {}), indent=2))


if __name__ == "__main__":
    main()
