#!/usr/bin/env python3
"""How much of a trajectory's relations error is the log's clock (issue 31's Intel bar,
docs/results/graph.md "Intel: the relations are bounded ..."; standard library only).

Where a log stamps several records with one time, the relations metric (nearest pose within
6 ms, the earlier on a tie, file order kept, as slam-eval does) reads the first or the last
record of the run, not the raw scan a relation was measured at. For every relation this
takes, among the records of the runs its two ends fall on, the pair whose relative motion
fits the relation best (an oracle that stands in for the raw scans), and splits the error
the rule sees into
  C: the clock's part, the rule's pair against the best pair, both read on the trajectory;
  E: the estimate's part, the best pair against the relation.
It prints mean |C + s E| for several s: s = 1 reproduces the metric, s = 0 is what a perfect
estimate would score by the rule, and the s at which the mean crosses a bar is how much
smaller the estimate's errors would have to be to meet it.

Usage: relations_clock_model.py TRAJECTORY.tum FILE.relations
"""
import bisect, math, sys

def load(p):
    d = []
    for l in open(p):
        if l.startswith('#') or not l.strip(): continue
        f = l.split(); qz, qw = float(f[6]), float(f[7])
        d.append((float(f[0]), (float(f[1]), float(f[2]), 2 * math.atan2(qz, qw))))
    d.sort(key=lambda e: e[0])  # stable: file order kept among equal times
    return [e[0] for e in d], [e[1] for e in d]

def between(a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]; c, s = math.cos(a[2]), math.sin(a[2])
    return (c * dx + s * dy, -s * dx + c * dy, b[2] - a[2])

def trans_error(d, z):
    """The translation of z^-1 (+) d, as a vector in z's frame."""
    c, s = math.cos(z[2]), math.sin(z[2]); ex, ey = d[0] - z[0], d[1] - z[1]
    return (c * ex + s * ey, -s * ex + c * ey)

T, P = load(sys.argv[1])

def run_of(t):
    """The index the rule reads at t and the indices stamped alike, or (None, [])."""
    i = bisect.bisect_left(T, t)
    c = [(abs(T[j] - t), j) for j in (i - 1, i) if 0 <= j < len(T)]
    if not c: return None, []
    d, j = min(c)
    if d > 0.006: return None, []
    return j, list(range(bisect.bisect_left(T, T[j]), bisect.bisect_right(T, T[j])))

C, E = [], []
for l in open(sys.argv[2]):
    v = [float(x) for x in l.split()]
    if len(v) < 8: continue
    z = (v[2], v[3], v[7])
    j1, r1 = run_of(v[0]); j2, r2 = run_of(v[1])
    if j1 is None or j2 is None: continue
    a, b = min(((a, b) for a in r1 for b in r2),
               key=lambda ab: math.hypot(*trans_error(between(P[ab[0]], P[ab[1]]), z)))
    E.append(trans_error(between(P[a], P[b]), z))
    C.append(trans_error(between(P[j1], P[j2]), between(P[a], P[b])))
print(f"{len(C)} relations")
for s in (1.0, 0.9, 0.8, 0.72, 0.6, 0.5, 0.25, 0.0):
    m = sum(math.hypot(c[0] + s * e[0], c[1] + s * e[1]) for c, e in zip(C, E)) / len(C)
    print(f"s = {s:4.2f}: mean translational error {m:.4f} m")
