#!/usr/bin/python3
"""Replays a stepped sine's log with variants of the progress line's work model (the model of
src/driver.cpp, planned_remaining(), written again here), to compare them on a run that
happened: at 33 %, 50 % and 80 % of its wall time, each variant's ETA against the time left.

    validation/eta_replay.py LOG OUT.h5

For an SDOF with force input, swept up, as examples/saeki_250.toml. The fills' harmonics come
from OUT.h5 (/frf/fills), the order and times of the points from LOG (pdsim's stderr, a
progress line every 5 s); work a fill does inside a point before it ends is not replayed.
"""
import cmath
import math
import re
import sys
import tomllib

import h5py
import numpy as np

log, h5 = sys.argv[1], sys.argv[2]
f = h5py.File(h5, "r")
deck = tomllib.loads(f["/meta"].attrs["deck"])
st, x = deck["structure"], deck["excitation"]
M, K, zeta, F0 = st["mass"], st["stiffness"], st.get("damping_ratio", 0.0), x["amplitude"]
C = 2 * zeta * math.sqrt(K * M)
freqs = sorted(set(float(v) for v in f["/frf/frequency"][:]))
idx = {v: k for k, v in enumerate(freqs)}
settle = x.get("settle", {})
FMAX, FMIN = settle.get("max_realisations", 4), settle.get("realisations", 2)
MAXP, MINP = settle.get("max_periods", 400), settle.get("min_periods", 10)
N = len(freqs)
fl = f["/frf/fills"]
harm = {}
for fr, r, a, p in zip(fl["frequency"][:], fl["realisation"][:], fl["amplitude"][:], fl["phase"][:]):
    harm[(int(r), idx[float(fr)])] = a * cmath.exp(1j * p)
events, t, wall, first_work = [], 0.0, None, None
for line in open(log, errors="replace"):
    m = re.search(r"elapsed (\d+) s", line)
    if m:
        t = float(m.group(1))
        if first_work is None and line.startswith("f ="): first_work = t
        continue
    m = re.match(r"f = ([0-9.]+) Hz \(fill (\d+)\): .* (\d+) periods", line)
    if m:
        events.append((t, "fill", idx[float(m.group(1))], int(m.group(2)) - 1, int(m.group(3))))
        continue
    m = re.match(r"f = ([0-9.]+) Hz: (\d+) fills: (.*)", line)
    if m:
        s = idx[float(m.group(1))]
        mm = re.search(r"more fills \((\d+) of", m.group(3))
        events.append((t, "want" if mm else "done", s, int(mm.group(1)) if mm else int(m.group(2)), 0))
    m = re.search(r"wall time ([0-9.]+) s", line)
    if m: wall = float(m.group(1))
def model(state, variant):
    periods, want, done, reached, target = state
    seen = {}
    for (r, s), p in periods.items():
        seen.setdefault(s, []).append((p, abs(harm[(r, s)])))
    fin = sorted((np.mean([a for _, a in seen[s]]), s) for s in done if s in seen)
    pts = {s: np.mean([p for p, _ in seen[s]]) for s in seen}
    slope = 0
    if len(fin) >= 2:
        x = np.log([a for a, _ in fin]); y = np.log([pts[s] for _, s in fin])
        slope = min(3, max(0, np.polyfit(x, y, 1)[0]))
    def learned(a):
        if not fin: return MINP, FMIN
        if a <= fin[0][0]: return pts[fin[0][1]], want[fin[0][1]]
        if a >= fin[-1][0]:
            s = fin[-1][1]
            if variant == "nogrowth":
                return pts[s], want[s]
            if variant == "fills":
                return pts[s], FMAX
            if variant == "grow2": return min(pts[s] * min((a / fin[-1][0]) ** slope, 2.0), MAXP), FMAX
            return min(pts[s] * (a / fin[-1][0]) ** slope, MAXP), FMAX
        for k in range(1, len(fin)):
            if a <= fin[k][0]:
                a0, a1 = math.log(fin[k-1][0]), math.log(fin[k][0]); w = (math.log(a) - a0) / (a1 - a0) if a1 > a0 else 1
                s0, s1 = fin[k-1][1], fin[k][1]
                return pts[s0] + w * (pts[s1] - pts[s0]), want[s0] + w * (want[s1] - want[s0])
    last = max([s for (r, s) in periods if r == 0], default=None)
    def predicted(s):
        if last is None: return 0
        w0, w = 2 * math.pi * freqs[last], 2 * math.pi * freqs[s]
        z = F0 / harm[(0, last)] - (K - M * w0 * w0 + 1j * w0 * C)
        zz = z.real * (w / w0) ** 2 + 1j * z.imag * (w / w0)
        return abs(F0 / (K - M * w * w + 1j * w * C + zz))
    cost, fills = [], []
    for s in range(N):
        if s in seen:
            p = pts[s]; expected = learned(np.mean([a for _, a in seen[s]]))[1]
        else:
            p, expected = learned(predicted(s))
        cost.append(p / freqs[s])
        fills.append(want[s] if s in done else min(max(int(round(expected)), want[s]), FMAX))
    rem = 0; reach = dict(target)
    for r in reach:
        for s in range(reached.get(r, -1) + 1, reach[r] + 1): rem += cost[s]
    for s in range(N):
        if s in done: continue
        for r in range(want[s], fills[s]):
            reach.setdefault(r, -1)
            while reach[r] < s: reach[r] += 1; rem += cost[reach[r]]
    return rem
# "fills" is pdsim's: above every point seen, every fill with the periods of the highest point.
variants = ["fills", "nogrowth", "grow", "grow2"]
print("variant", [f"{x:.0%}" for x in (0.33, 0.5, 0.8)])
for v in variants:
    out = []
    for frac in (0.33, 0.5, 0.8):
        T = frac * wall
        periods, want, done, reached, target = {}, [FMIN] * N, set(), {}, {r: N - 1 for r in range(FMIN)}
        for (te, kind, s, a, b) in events:
            if te > T: break
            if kind == "fill": periods[(a, s)] = b; reached[a] = max(reached.get(a, -1), s)
            elif kind == "want":
                for r in range(want[s], a): target[r] = max(target.get(r, -1), s)
                want[s] = a
            else: done.add(s)
        donework = sum(p / freqs[s] for (r, s), p in periods.items())
        rem = model((periods, want, done, reached, target), v)
        eta = (T - first_work) * rem / donework
        out.append(f"{(eta - (wall - T)) / (wall - T):+.0%}")
    print(v, out)
