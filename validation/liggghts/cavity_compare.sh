#!/usr/bin/env bash
# A non-box cavity in both codes: 250 steel spheres (E = 2e9 Pa, e = 0.5, mu = 0.3, Hertz +
# tangential history, gravity) in a closed cylinder r = 28 mm, h = 50 mm given as one STL of
# 2,048 triangles (validation/cavity_stl.py), shaken 3 mm at 20 Hz across its axis for 0.5 s
# at dt = 4e-6 s. pdsim settles FILLS random fills and runs them (shape = "mesh"); LIGGGHTS 3.8
# runs each of the same settled fills (run_liggghts.sh scene y, BED=...:k) with the same STL
# (fix mesh/surface). Both average the last 5 periods; the codes' dissipated power and force
# harmonic are compared as means over the fills with their 95 % intervals, and printed and
# written to validation/results/mesh_liggghts.md.
# usage: cavity_compare.sh [PDSIM] [FILLS]   (defaults: build/pdsim, 4; about 3 minutes)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pdsim=$(realpath "${1:-$here/../../build/pdsim}")
fills=${2:-4}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

python3 "$here/../cavity_stl.py" cylinder pdsim.stl --radius 0.028 --length 0.05 --ascii >/dev/null
python3 "$here/../cavity_stl.py" cylinder liggghts.stl --radius 0.028 --length 0.05 --ascii \
  --offset 0.028 0.028 0.025 >/dev/null
cat >deck.toml <<EOF
title = "2,048-triangle cylinder, pdsim against LIGGGHTS"
[[damper]]
container = { shape = "mesh", file = "pdsim.stl" }
particles = { count = 250, diameter = 0.005, density = 7800.0, seed = 5, fill = "random" }
[contact]
model = "hertz"
tangential = "history"
young = 2.0e9
poisson = 0.3
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "prescribed"
motion = { axis = [1.0, 0.0, 0.0], amplitude = 0.003, frequency = 20.0 }
duration = 0.5
settle = { average_periods = 5, realisations = $fills, max_realisations = $fills }
[bed]
file = "$work/bed.h5"
[solver]
dt = 4.0e-6
[output]
file = "pdsim.h5"
EOF
"$pdsim" run deck.toml --quiet --threads 1 -o pdsim.h5
for ((k = 0; k < fills; k++)); do
  KEEP_DIR=$work/l$k SAMPLE_EVERY=50 BED=$work/bed.h5:$k STL=$work/liggghts.stl \
    "$here/run_liggghts.sh" y 1 125000 >"l$k.timing"
  /usr/bin/python3 "$here/power_force.py" "l$k/force_log.txt" --frequency 20 --amplitude 0.003 \
    --dt 4e-6 --periods 5 >"l$k.txt"
done

/usr/bin/python3 - "$work" "$fills" "$(dpkg-query -W -f='${Version}' liggghts 2>/dev/null)" \
  "$("$pdsim" --version)" "$here/../results/mesh_liggghts.md" <<'PY'
import datetime, os, sys
import h5py
import numpy as np
from scipy.stats import t as student
work, fills, liggghts, version, out = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4], sys.argv[5]
with h5py.File(os.path.join(work, "pdsim.h5"), "r") as h:
    p = h["prescribed"]
    pdsim = {"power": (p["dissipated_power"][0], p["dissipated_power_ci"][0]),
             "force": (p["force_amplitude"][0], p["force_amplitude_ci"][0])}
    assert int(p["realisations"][0]) == fills
    pdsim_rate = h["meta"].attrs["particle_steps"] / h["meta"].attrs["wall_time_s"]
rates = []
for k in range(fills):
    line = open(os.path.join(work, "l%d.timing" % k)).read()
    rates.append(float(line.split("particle_steps_per_s=")[1].split()[0]))
def value(k, key):
    for line in open(os.path.join(work, "l%d.txt" % k)):
        if line.startswith(key + " = "):
            return float(line.split("=")[1].split("#")[0])
    sys.exit("no %s in l%d.txt" % (key, k))
rows = ["| quantity | pdsim (%d fills) | LIGGGHTS %s (the same fills) | difference | allowed |"
        % (fills, liggghts), "|---|---|---|---|---|"]
ok = True
for name, key, unit in (("dissipated power", "power", "W"), ("force harmonic", "force", "N")):
    v = np.array([value(k, "dissipated_power" if key == "power" else "force_amplitude")
                  for k in range(fills)])
    mean, ci = v.mean(), student.ppf(0.975, fills - 1) * v.std(ddof=1) / np.sqrt(fills)
    m, c = pdsim[key]
    allowed = c + ci
    ok &= abs(m - mean) < allowed
    rows.append("| %s (%s) | %.4f +- %.4f | %.4f +- %.4f (fills: %s) | %+.4f | %.4f |"
                % (name, unit, m, c, mean, ci, " ".join("%.4f" % x for x in v), m - mean, allowed))
text = "\n".join([
    "# A cylinder given as STL (2,048 triangles) in pdsim and in LIGGGHTS",
    "",
    "%s, %s, LIGGGHTS %s; `validation/liggghts/cavity_compare.sh` (scene and method in its "
    "header). Each code's mean over the same %d settled fills with its 95 %% interval (pdsim's "
    "own; LIGGGHTS': Student t over the fills); they agree when the means differ by less than "
    "the sum of the half-widths: %s." % (datetime.date.today(), version, liggghts, fills,
                                          "they do" if ok else "they DO NOT"),
    "", *rows, "",
    "Speed, one thread each: pdsim %.3g particle-steps/s over its whole run (fills settled, "
    "filled and run); LIGGGHTS %.3g over its time-step loops (median of the fills)."
    % (pdsim_rate, float(np.median(rates))), ""])
print(text)
open(out, "w").write(text)
sys.exit(0 if ok else 1)
PY
