#!/bin/bash
# Rigid contacts under slow prescribed motion (validation/results/nonsmooth.md, "Slow motions"):
# the loss factor c_eff / (w m_eff) of one ball rolling on a floor shaken at 0.1 g (it has none;
# m_eff is 2/7 of its mass) at three steps and two tolerances, and of Saeki's 250-sphere pile
# resting at 0.09 g beside the penalty engine's, with the solver's iterations and wall time.
#
#   validation/rigid_slow_motion.sh PDSIM [--pile]
#
# The ball takes seconds a row; --pile adds the pile (about a minute a row, one thread each).
set -euo pipefail
pdsim=$(realpath "$1")
repo=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
report() {  # map file, label
  /usr/bin/python3 - "$1" "$2" <<'EOF'
import glob, math, sys
import h5py
path, label = sys.argv[1], sys.argv[2]
with h5py.File(path) as h:
    m = h["map"]
    rows = ["%g m: loss factor %.4f, m_eff %.4g kg" % (m["amplitude"][i], -math.tan(m["force_phase"][i]),
            m["effective_mass"][i]) for i in range(len(m["frequency"]))]
runs = sorted(glob.glob(path.replace(".h5", "_runs") + "/m*.h5"))
cost = []
for r in runs:
    with h5py.File(r) as h:
        a = h["meta"].attrs
        it = a.get("solver_iterations_per_step")
        cost.append("dt %.3g s, %s iterations a step, %.1f s" % (a["dt"], "-" if it is None else "%.1f" % it, a["wall_time_s"]))
print("%-40s %s | %s" % (label, "; ".join(rows), "; ".join(cost)))
EOF
}
rigid() {  # deck -> the same with rigid contacts (the penalty keys removed)
  sed -e 's/^model = .*/model = "nonsmooth"/' -e '/^stiffness = 2000/d' -e '/^young/d' \
    -e '/^poisson/d' -e '/^tangential/d' "$1"
}
# The ball: the map test's deck at 0.1 g, 15 and 20 Hz.
rigid "$repo/tests/decks/tiny_map.toml" | sed 's/accelerations = \[0.1, 3.0\]/accelerations = [0.1]/' \
  > ball.toml
for safety in 0.2 0.1 0.05; do
  for tolerance in default 1e-6; do
    name=ball_${safety}_${tolerance}
    sed "/^\[solver\]/a dt_safety = $safety" ball.toml > "$name.toml"
    [[ $tolerance == default ]] || sed -i "/^friction = /a tolerance = $tolerance" "$name.toml"
    "$pdsim" map --quiet --threads 1 --jobs 1 -o "$name.h5" "$name.toml" > "$name.log" 2>&1
    report "$name.h5" "ball, dt_safety $safety, tolerance $tolerance"
  done
done
[[ "${2:-}" == "--pile" ]] || exit 0
# The pile: the Saeki example's damper, one fill, 30 periods at 15 Hz at 0.1 and 2 mm.
sed -e 's/^settle = .*/settle = { max_periods = 800, realisations = 1, max_realisations = 1 }/' \
  -e '/^file = /d' "$repo/examples/saeki_250.toml" > pile_penalty.toml
printf '\n[map]\namplitudes = [1e-4, 2e-3]\nfrequencies = [15.0]\nduration = 2.0\n' \
  >> pile_penalty.toml
rigid pile_penalty.toml > pile_rigid.toml
sed '/^friction = /a tolerance = 1.0e-5' pile_rigid.toml > pile_rigid_tight.toml
for name in pile_penalty pile_rigid pile_rigid_tight; do
  "$pdsim" map --quiet --threads 1 --jobs 1 -o "$name.h5" "$name.toml" > "$name.log" 2>&1
  report "$name.h5" "$name"
done
