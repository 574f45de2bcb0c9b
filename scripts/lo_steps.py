#!/usr/bin/env python3
"""Laser odometry's per-scan increments against a reference trajectory's (issue 32's
diagnosis of the bench logs without odometry, docs/results.md "Laser-only mapping").

Each consecutive pair of FLASER scans of a bench log: the increment of the estimate
(`slam run --filter known-poses --odometry none ... --out OUT` writes OUT/trajectory.tum,
laser odometry alone) in the frame of the first scan, against the reference's (X.ref.tum,
GMapping's corrected poses at the same stamps), and what the second scan sees: end points
in range, and how well they fix the position along their weakest direction (the smallest
eigenvalue over the largest of Σ n nᵀ over the end points' normals: near 0 in a corridor,
whose walls give no normal along it; 1 when the normals spread evenly; a rough guide only:
normals from neighbouring beams are noisy at short range, and acapulco's corridor scores
0.2-0.36 like many scans that match well), and that direction's angle in the scanner's
frame, degrees (columns hits, ratio, weak).

Usage: lo_steps.py bench/X.log OUT/trajectory.tum bench/X.ref.tum [--all] [--max-range 30]
Prints every step more than 0.2 m or 3 deg off (all steps with --all), then a summary.
Standard library only.
"""
import math
import statistics
import sys


def load_tum(path):
    d = {}
    for line in open(path):
        if line.startswith('#') or not line.strip():
            continue
        f = line.split()
        qz, qw = float(f[6]), float(f[7])
        d[round(float(f[0]), 6)] = (float(f[1]), float(f[2]), 2 * math.atan2(qz, qw))
    return d


def load_scans(path):
    """(t, ranges) of every FLASER line, 1-degree beams from -90 deg (361: 0.5 deg)."""
    out = []
    for line in open(path):
        if not line.startswith('FLASER'):
            continue
        f = line.split()
        n = int(f[1])
        out.append((round(float(f[-3]), 6), [float(v) for v in f[2:2 + n]]))
    return out


def between(a, b):
    """b in the frame of a."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    c, s = math.cos(a[2]), math.sin(a[2])
    dth = math.atan2(math.sin(b[2] - a[2]), math.cos(b[2] - a[2]))
    return [c * dx + s * dy, -s * dx + c * dy, dth]


def geometry(ranges, max_range):
    """(end points in range, weakest-direction ratio, weakest direction's angle in the
    scanner's frame, degrees)."""
    n = len(ranges)
    ang = [-math.pi / 2 + i * math.pi / (n - 1) for i in range(n)]
    ok = [0.05 < r < max_range for r in ranges]
    p = [(r * math.cos(a), r * math.sin(a)) for r, a in zip(ranges, ang)]
    sxx = sxy = syy = 0.0
    for i in range(1, n - 1):
        if not (ok[i - 1] and ok[i] and ok[i + 1]):
            continue
        tx, ty = p[i + 1][0] - p[i - 1][0], p[i + 1][1] - p[i - 1][1]
        L = math.hypot(tx, ty)
        if L < 1e-6 or L > 0.5:
            continue
        nx, ny = -ty / L, tx / L
        sxx, sxy, syy = sxx + nx * nx, sxy + nx * ny, syy + ny * ny
    # Eigenvalues of [[sxx, sxy], [sxy, syy]] and the weakest direction.
    m, d = 0.5 * (sxx + syy), math.hypot(0.5 * (sxx - syy), sxy)
    lo, hi = m - d, m + d
    ratio = lo / hi if hi > 0 else 0.0
    weak = 0.5 * math.atan2(2 * sxy, sxx - syy) + math.pi / 2
    return sum(ok), ratio, math.degrees(math.atan2(math.sin(weak), math.cos(weak)))


def main():
    args = [a for a in sys.argv[1:] if not a.startswith('--')]
    show_all = '--all' in sys.argv
    max_range = 30.0
    if '--max-range' in sys.argv:
        max_range = float(sys.argv[sys.argv.index('--max-range') + 1])
        args.remove(str(sys.argv[sys.argv.index('--max-range') + 1]))
    log, est_path, ref_path = args[:3]
    scans = load_scans(log)
    est, ref = load_tum(est_path), load_tum(ref_path)
    bad, errs = 0, []
    print(' k      t    est dx    dy   dth |  ref dx    dy   dth |  err xy  err th  hits ratio weak')
    for k in range(1, len(scans)):
        t0, t1 = scans[k - 1][0], scans[k][0]
        if t0 not in est or t1 not in est or t0 not in ref or t1 not in ref:
            continue
        e = between(est[t0], est[t1])
        r = between(ref[t0], ref[t1])
        d = [e[0] - r[0], e[1] - r[1], math.atan2(math.sin(e[2] - r[2]), math.cos(e[2] - r[2]))]
        exy, eth = math.hypot(d[0], d[1]), abs(math.degrees(d[2]))
        errs.append((exy, eth))
        big = exy > 0.2 or eth > 3.0
        bad += big
        if big or show_all:
            hits, ratio, weak = geometry(scans[k][1], max_range)
            print(f'{k:4d} {t1:7.1f} {e[0]:6.2f} {e[1]:5.2f} {math.degrees(e[2]):5.1f} | '
                  f'{r[0]:6.2f} {r[1]:5.2f} {math.degrees(r[2]):5.1f} | {exy:6.2f} {eth:6.1f} '
                  f'{hits:5d} {ratio:5.2f} {weak:5.0f}{"  *" if big else ""}')
    xy, th = [e[0] for e in errs], [e[1] for e in errs]
    print(f'{len(errs)} steps; {bad} more than 0.2 m or 3 deg off; median '
          f'{statistics.median(xy):.3f} m {statistics.median(th):.2f} deg; > 0.5 m: '
          f'{sum(v > 0.5 for v in xy)}; > 10 deg: {sum(v > 10 for v in th)}')


if __name__ == '__main__':
    main()
