#!/usr/bin/env python3
"""GTSAM's figures for the pose-graph tests of issue 30 (tests/graph.rs), run by hand in a
throwaway venv:

    python3 -m venv /tmp/gtsam-venv && /tmp/gtsam-venv/bin/pip install gtsam==4.3.0
    /tmp/gtsam-venv/bin/python tests/gtsam_truth.py FILE... > out.json

For each g2o or TORO file, GTSAM reads it with its own reader (gtsam.load2D, told
NoiseFormatTORO for a file with EDGE2 lines, which reads TORO's order of information entries,
and NoiseFormatG2O otherwise; with smart=False so no edge is dropped), holds
the first pose with a tight prior (variances 1e-6, 1e-6, 1e-8, the form of GTSAM's
Pose2SLAMExample_g2o.py) and runs Levenberg-Marquardt from the file's initial guess with its
default parameters (lambda 1e-5, factor 10, upper bound 1e5, relative tolerance 1e-5, at most
100 iterations) and absolute tolerance 0.5e-5 (GTSAM's error is chi2 / 2). Printed, per file:
the chi2 of g2o's EdgeSE2 error t2v(Z^-1 Xi^-1 Xj) at GTSAM's result, computed from the
factors GTSAM parsed (measurement and information R^T R of each noise model), so the
information order is GTSAM's reading, not ours; GTSAM's own chi2 (2 x its error); iterations;
and the wall time of the optimize call (median of --rounds runs).
"""

import argparse
import importlib.metadata
import json
import math
import statistics
import time

import gtsam
import numpy as np


def g2o_chi2(graph, values):
    """Sum over the between factors of e^T I e, e = t2v(Z^-1 (Xi^-1 Xj)) (g2o's EdgeSE2)."""
    total = 0.0
    for k in range(graph.size()):
        f = graph.at(k)
        if not isinstance(f, gtsam.BetweenFactorPose2):
            continue
        i, j = f.keys()
        z = f.measured()
        r = f.noiseModel().R()
        info = r.T @ r
        a, b = values.atPose2(i), values.atPose2(j)
        c, s = math.cos(a.theta()), math.sin(a.theta())
        dx, dy = b.x() - a.x(), b.y() - a.y()
        d = (c * dx + s * dy, -s * dx + c * dy)
        cz, sz = math.cos(z.theta()), math.sin(z.theta())
        tx, ty = d[0] - z.x(), d[1] - z.y()
        e = np.array([cz * tx + sz * ty, -sz * tx + cz * ty,
                      math.remainder(b.theta() - a.theta() - z.theta(), 2 * math.pi)])
        total += float(e @ info @ e)
    return total


def optimize(path):
    """GTSAM's Levenberg-Marquardt on the file at `path` as the module says: returns the
    file's edges (no prior), the initial values, the result, the iterations and the wall time
    (s) and the process CPU time (s) of the optimize call. scripts/gtsam_compare.py runs GTSAM
    through this too."""
    with open(path) as fh:
        toro = any(line.startswith("EDGE2") for line in fh)
    fmt = gtsam.NoiseFormat.NoiseFormatTORO if toro else gtsam.NoiseFormat.NoiseFormatG2O
    graph, initial = gtsam.load2D(path, None, 0, False, False, fmt)
    edges = gtsam.NonlinearFactorGraph(graph)
    first = min(initial.keys())
    prior = gtsam.noiseModel.Diagonal.Variances(gtsam.Point3(1e-6, 1e-6, 1e-8))
    graph.add(gtsam.PriorFactorPose2(first, initial.atPose2(first), prior))
    params = gtsam.LevenbergMarquardtParams()
    params.setRelativeErrorTol(1e-5)
    params.setAbsoluteErrorTol(0.5e-5)
    params.setMaxIterations(100)
    t0, c0 = time.perf_counter(), time.process_time()
    opt = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
    result = opt.optimize()
    seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
    return edges, initial, result, opt.iterations(), seconds, cpu


def run(path):
    edges, initial, result, iterations, seconds, _cpu = optimize(path)
    return {
        "chi2_initial_g2o_error": g2o_chi2(edges, initial),
        "chi2_final_g2o_error": g2o_chi2(edges, result),
        "chi2_final_gtsam_error": 2.0 * edges.error(result),
        "iterations": iterations,
        "seconds_optimize": seconds,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+")
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    out = {"gtsam_version": importlib.metadata.version("gtsam"), "files": {}}
    for path in a.files:
        runs = [run(path) for _ in range(a.rounds)]
        r = runs[0]
        r["seconds_optimize_median"] = statistics.median(x["seconds_optimize"] for x in runs)
        out["files"][path] = r
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
