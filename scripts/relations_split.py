#!/usr/bin/env python3
"""The relations metric of a trajectory split by what lies between each relation's ends
(issue 31's Intel diagnosis, docs/results/graph.md "Issue 31: accuracy"): ends on scan
(FLASER) records or not, the number of scans between the ends, the relation's rotation, the
time from an end to the nearest scan. Poses are looked up as slam-eval does (nearest within
6 ms, the earlier on a tie, file order kept).

Usage: relations_split.py TRAJECTORY.tum FILE.relations LOG.log   (standard library only)
A TUM file of the log's own odometry gives the odometry-only column, e.g.
  awk 'BEGIN{print "# t x y z qx qy qz qw"} /^ODOM/{printf "%.6f %s %s 0 0 0 %.12f %.12f\\n",
       $8, $2, $3, sin($4/2), cos($4/2)} /^FLASER/{n=$2; printf "%.6f %s %s 0 0 0 %.12f %.12f\\n",
       $(n+9), $(n+6), $(n+7), sin($(n+8)/2), cos($(n+8)/2)}' intel.log > odom.tum
"""
import math, sys, bisect
def load(p):
    d = []
    for l in open(p):
        if l.startswith('#') or not l.strip(): continue
        f = l.split(); qz, qw = float(f[6]), float(f[7])
        d.append((float(f[0]), float(f[1]), float(f[2]), 2*math.atan2(qz, qw)))
    d.sort(key=lambda e: e[0]); return d
est = load(sys.argv[1]); T = [e[0] for e in est]
scans = sorted(float(l.split()[-1]) for l in open(sys.argv[3]) if l.startswith('FLASER'))
def at(t):
    i = bisect.bisect_left(T, t); best = None
    for j in (i-1, i):
        if 0 <= j < len(T) and abs(T[j]-t) <= 0.006 and (best is None or abs(T[j]-t) < abs(T[best]-t)): best = j
    return est[best] if best is not None else None
def near_scan(t):
    i = bisect.bisect_left(scans, t)
    return min(abs(scans[j]-t) for j in (i-1, i) if 0 <= j < len(scans))
def nscans_between(a, b):
    a, b = min(a, b), max(a, b)
    return bisect.bisect_right(scans, b) - bisect.bisect_left(scans, a)
rows = []
for l in open(sys.argv[2]):
    f = l.split(); t1, t2 = float(f[0]), float(f[1]); dx, dy, dth = float(f[2]), float(f[3]), float(f[7])
    a, b = at(t1), at(t2)
    if a is None or b is None: continue
    c, s = math.cos(a[3]), math.sin(a[3]); ex, ey = b[1]-a[1], b[2]-a[2]
    rx, ry = c*ex+s*ey, -s*ex+c*ey; rth = (b[3]-a[3]+math.pi)%(2*math.pi)-math.pi
    # error E = delta*^-1 (+) delta
    cs, ss = math.cos(dth), math.sin(dth)
    Ex, Ey = cs*(rx-dx)+ss*(ry-dy), -ss*(rx-dx)+cs*(ry-dy)
    Eth = (rth-dth+math.pi)%(2*math.pi)-math.pi
    rows.append(dict(tr=math.hypot(Ex, Ey), rot=abs(math.degrees(Eth)), sgn=math.degrees(Eth), dth=math.degrees(dth), d=math.hypot(dx,dy),
        ends=(near_scan(t1) < 0.006) + (near_scan(t2) < 0.006), ns=nscans_between(t1, t2), dt=abs(t2-t1), gap=max(near_scan(t1), near_scan(t2))))
def summ(name, rs):
    if not rs: return
    print(f"{name:40s} n={len(rs):5d} trans {sum(r['tr'] for r in rs)/len(rs):.4f} m  rot {sum(r['rot'] for r in rs)/len(rs):.3f} deg")
summ("all", rows)
for e in (0, 1, 2): summ(f"ends on scans = {e}", [r for r in rows if r['ends'] == e])
for lo, hi in ((0, 1), (1, 2), (2, 3), (3, 5), (5, 100)): summ(f"scans between in [{lo},{hi})", [r for r in rows if lo <= r['ns'] < hi])
for lo, hi in ((0, 2), (2, 10), (10, 45), (45, 100), (100, 400)): summ(f"|rel rot| deg in [{lo},{hi})", [r for r in rows if lo <= abs(r['dth']) < hi])
for lo, hi in ((0, .5), (.5, 1), (1, 2), (2, 5), (5, 100)): summ(f"max end-to-scan dt s in [{lo},{hi})", [r for r in rows if lo <= r['gap'] < hi])
# regression of signed rot error on relation rotation
n = len(rows); sx = sum(r['dth'] for r in rows); sy = sum(r['sgn'] for r in rows)
sxx = sum(r['dth']**2 for r in rows); sxy = sum(r['dth']*r['sgn'] for r in rows)
k = (n*sxy - sx*sy)/(n*sxx - sx*sx); print(f"signed rot error = {k:.4f} * rel rot + {(sy-k*sx)/n:.4f} deg")
rs = sorted(r['tr'] for r in rows); print("trans quantiles 50/90/99:", rs[n//2], rs[9*n//10], rs[99*n//100])
rr = sorted(r['rot'] for r in rows); print("rot quantiles 50/90/99:", rr[n//2], rr[9*n//10], rr[99*n//100])
big = sorted(rows, key=lambda r: -r['rot'])[:n//20]; print("top 5% rot errors contribute", sum(r['rot'] for r in big)/sum(r['rot'] for r in rows))
