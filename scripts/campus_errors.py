#!/usr/bin/env python3
"""Per-record error of a `slam run --sim campus` trajectory against the simulator's truth
(`slam sim campus --seed S --out DIR` writes DIR/ground_truth.tum), for issue 31's
diagnosis (docs/results/graph.md, "Issue 31: accuracy"): the SE(2)-aligned ATE, the scale
a Sim(2) alignment would apply and the ATE after it, the mean error per 50 m of route and
lap (along / across the road), and relative errors over windows of path length.

Usage: campus_errors.py OUT/trajectory.tum DIR/ground_truth.tum   (standard library only)
"""
import math, sys
def load(p):
    d = {}
    for l in open(p):
        if l.startswith('#') or not l.strip(): continue
        f = l.split(); t = round(float(f[0]), 4)
        qz, qw = float(f[6]), float(f[7])
        d[t] = (float(f[1]), float(f[2]), 2*math.atan2(qz, qw))
    return d
est, gt = load(sys.argv[1]), load(sys.argv[2])
ts = sorted(t for t in est if t in gt)
E = [est[t] for t in ts]; G = [gt[t] for t in ts]
n = len(ts)
# SE(2) alignment est -> gt (least squares)
mx = sum(e[0] for e in E)/n; my = sum(e[1] for e in E)/n
gx = sum(g[0] for g in G)/n; gy = sum(g[1] for g in G)/n
sxx = sum((e[0]-mx)*(g[0]-gx)+(e[1]-my)*(g[1]-gy) for e, g in zip(E, G))
sxy = sum((e[0]-mx)*(g[1]-gy)-(e[1]-my)*(g[0]-gx) for e, g in zip(E, G))
th = math.atan2(sxy, sxx); c, s = math.cos(th), math.sin(th)
A = [(gx + c*(e[0]-mx) - s*(e[1]-my), gy + s*(e[0]-mx) + c*(e[1]-my), e[2]+th) for e in E]
err = [(a[0]-g[0], a[1]-g[1]) for a, g in zip(A, G)]
rm = math.sqrt(sum(ex*ex+ey*ey for ex, ey in err)/n)
print(f"records {n}, aligned ATE {rm:.3f} m (rotation {math.degrees(th):.3f} deg)")
# Sim(2) alignment: scale
vx = sum((e[0]-mx)**2+(e[1]-my)**2 for e in E)/n
scale = math.hypot(sxx, sxy)/n/vx
A2 = [(gx + scale*(c*(e[0]-mx) - s*(e[1]-my)), gy + scale*(s*(e[0]-mx) + c*(e[1]-my))) for e in E]
rm2 = math.sqrt(sum((a[0]-g[0])**2+(a[1]-g[1])**2 for a, g in zip(A2, G))/n)
print(f"Sim(2) scale {scale:.5f} ({(scale-1)*100:+.3f} % to apply), aligned ATE with scale {rm2:.3f} m")
# path length along truth
path = [0.0]
for i in range(1, n): path.append(path[-1] + math.hypot(G[i][0]-G[i-1][0], G[i][1]-G[i-1][1]))
L = path[-1]; lap = L/2
print(f"path {L:.0f} m")
# bins of 50 m along the route, per lap: mean |err|, along/across components
ROADS = [20, 85, 150, 215]
def where(g):
    x, y = g[0], g[1]
    cx = min(ROADS, key=lambda r: abs(x-r)); cy = min(ROADS, key=lambda r: abs(y-r))
    if abs(x-cx) < abs(y-cy): return f"x={cx}", 1  # road along y
    return f"y={cy}", 0
bins = {}
for i in range(n):
    key = (int(path[i] % lap // 50), int(path[i]//lap))
    bins.setdefault(key, []).append(i)
print("bin(m)  road   lap0: |e| along across   lap1: |e| along across  (signed mean, m)")
for b in range(int(lap//50)+1):
    row = f"{b*50:5d}  "
    for l in (0, 1):
        idx = bins.get((b, l), [])
        if not idx: continue
        r, ax = where(G[idx[len(idx)//2]])
        m = math.sqrt(sum(err[i][0]**2+err[i][1]**2 for i in idx)/len(idx))
        # along the road's axis ax (0: x, 1: y)
        al = sum(err[i][ax] for i in idx)/len(idx); ac = sum(err[i][1-ax] for i in idx)/len(idx)
        if l == 0: row += f"{r:6s} "
        row += f"  {m:6.3f} {al:+6.3f} {ac:+6.3f}   "
    print(row)
# relative drift: for windows of D metres, error of relative pose est vs gt
def rel(a, b):
    dx, dy = b[0]-a[0], b[1]-a[1]; c, s = math.cos(a[2]), math.sin(a[2])
    return (c*dx+s*dy, -s*dx+c*dy, (b[2]-a[2]+math.pi) % (2*math.pi) - math.pi)
for D in (5, 20, 50, 100, 200):
    j = 0; es = []; ea = []; along = []
    for i in range(0, n, 10):
        while j < n and path[j] - path[i] < D: j += 1
        if j >= n: break
        re, rg = rel(E[i], E[j]), rel(G[i], G[j])
        es.append(math.hypot(re[0]-rg[0], re[1]-rg[1])); ea.append(abs((re[2]-rg[2]+math.pi)%(2*math.pi)-math.pi))
        along.append((math.hypot(re[0], re[1]) - math.hypot(rg[0], rg[1])))
    es.sort(); 
    print(f"RPE over {D:4d} m: trans rms {math.sqrt(sum(e*e for e in es)/len(es)):.3f} m median {es[len(es)//2]:.3f}, rot rms {math.degrees(math.sqrt(sum(e*e for e in ea)/len(ea))):.3f} deg, length error mean {sum(along)/len(along)*100/D:+.3f} %  rms {math.sqrt(sum(a*a for a in along)/len(along)):.3f} m")
