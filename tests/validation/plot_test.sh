#!/usr/bin/env bash
# validation/plot.py on a small stepped sine, a free decay with its energy ledger, a
# prescribed motion with particle snapshots, and a damper map with the FRF predicted from it
# over the coupled one: every kind of plot, as PNG and as PDF, must be
# written and non-empty. Then an ensemble FRF written here (two sweeps, fills in branches, a
# point of several branches, a point that is not a result above the peak) and an older FRF
# file: plot_frf.py must draw them and print their peaks as the /frf attributes (or the
# columns) give them.
# usage: plot_test.sh PDSIM SOURCE_DIR
set -euo pipefail
pdsim=$1
root=$2
plot=(/usr/bin/python3 "$root/validation/plot.py")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"

"$pdsim" run "$root/tests/decks/tiny_stepped_sine.toml" -o frf.h5 --quiet > /dev/null
sed -e 's/^kind = "stepped_sine"/kind = "free_decay"\ninitial_displacement = 0.002\nduration = 0.2/' \
    -e '/^amplitude =/d' -e '/^frequencies =/d' -e '/^settle =/d' \
    -e 's/^file = .*/file = "x.h5"\nenergy = true/' \
    "$root/tests/decks/tiny_stepped_sine.toml" > decay.toml
"$pdsim" run decay.toml -o decay.h5 --quiet > /dev/null
"$pdsim" run "$root/tests/decks/tiny_prescribed.toml" -o box.h5 --quiet > /dev/null
# A damper map of the tiny deck and the deck's FRF predicted from it.
cp "$root/tests/decks/tiny_stepped_sine.toml" mapped.toml
printf '[map]\namplitudes = [5e-5, 1e-3, 1e-2]\nfrequencies = [15.0, 16.0]\n' >> mapped.toml
"$pdsim" map mapped.toml -o map.h5 --quiet > /dev/null
"$pdsim" predict mapped.toml --map map.h5 -o hb.h5 > /dev/null

for format in png pdf; do
  "${plot[@]}" frf frf.h5 --receptance --bare -o "frf.$format" > "frf.$format.txt"
  "${plot[@]}" timeseries frf.h5 --frequency 16 -o "timeseries.$format"
  "${plot[@]}" energy decay.h5 -o "energy.$format"
  "${plot[@]}" timeseries decay.h5 -o "decay.$format"
  "${plot[@]}" prescribed box.h5 -o "prescribed.$format"
  "${plot[@]}" bed box.h5 --time 0.05 -o "bed.$format"
  "${plot[@]}" map map.h5 -o "map.$format"
  "${plot[@]}" frf frf.h5 --hb hb.h5 -o "hb.$format" > /dev/null
  for kind in frf timeseries energy prescribed decay bed map hb; do
    [ -s "$kind.$format" ] || { echo "$kind.$format is missing or empty" >&2; exit 1; }
  done
done

# The tiny deck's two points are not results (4 periods a fill): no peak, but the higher of
# their means is still said, as pdsim's summary line says it.
grep -q "^frf.h5: peak amplitude: no result point (0 of 2 points are results)$" frf.png.txt
grep -q "^  higher, NOT a result: .* mm at 16 Hz$" frf.png.txt

# frf_table.py: one row per point of /frf, and a file against itself as its own reference:
# no difference, within its interval and 3 %, its prediction interval holding its own fills.
/usr/bin/python3 "$root/validation/frf_table.py" frf.h5 --reference frf.h5 > table.md
points=$(/usr/bin/python3 -c 'import h5py, sys; print(h5py.File(sys.argv[1])["frf/frequency"].size)' frf.h5)
[ "$(grep -c '^| [0-9.]* | [012] |' table.md)" -eq "$points" ] || { cat table.md; exit 1; }
[ "$(grep -c '| +0.0 % | yes | yes | yes |$' table.md)" -eq "$points" ] || { cat table.md; exit 1; }

# An ensemble FRF written here: two sweeps, four fills a point, two branches at 14.5 Hz down
# (result 2, the peak: 0.878 ± 0.183 mm, highest fill 1.042 mm) and at 15 Hz down, which is
# not a result and has a higher mean (1.84 ± 0.43 mm); and an older file without sweep,
# result, spread, fills or peak attributes.
/usr/bin/python3 - <<'EOF'
import h5py
import numpy as np

f = [14.0, 14.5, 15.0, 15.5, 16.0]
amplitude = np.array([0.40, 0.70, 0.80, 0.60, 0.30, 0.45, 0.878, 1.84, 0.65, 0.30]) * 1e-3
ci = np.array([0.02] * 6 + [0.183, 0.43] + [0.02] * 2) * 1e-3
spread = 3 * ci
spread[4] = np.nan  # one fill there
result = [1, 1, 1, 1, 1, 1, 2, 0, 1, 1]
phase = np.linspace(-0.3, -2.8, 5).tolist() * 2
with h5py.File("ensemble.h5", "w") as h5:
    h5.create_group("meta").attrs["title"] = "ensemble"
    frf = h5.create_group("frf")
    for name, values, units in (
            ("frequency", f + f, "Hz"), ("sweep", [1] * 5 + [-1] * 5, "1"),
            ("amplitude", amplitude, "m"), ("amplitude_ci", ci, "m"),
            ("amplitude_spread", spread, "m"), ("phase", phase, "rad"),
            ("phase_ci", [0.05] * 10, "rad"), ("phase_spread", [0.2] * 10, "rad"),
            ("result", result, "1"), ("converged", [int(r > 0) for r in result], "1")):
        frf.create_dataset(name, data=np.asarray(values)).attrs["units"] = units
    for name, value in (("amplitude", 0.878e-3), ("amplitude_ci", 0.183e-3),
                        ("frequency", 14.5), ("upper", 1.042e-3), ("sweep", -1.0)):
        frf.attrs["peak_" + name] = value
    fills = {name: [] for name in ("frequency", "sweep", "realisation", "branch", "amplitude",
                                   "phase")}
    for k in range(10):
        values, branches = {6: ([1.042, 1.0, 0.72, 0.75], [0, 0, 1, 1]),
                            7: ([2.3, 2.2, 1.4, 1.46], [0, 0, 1, 1])}.get(
            k, (amplitude[k] * 1e3 + np.array([-0.02, -0.01, 0.01, 0.02]), [0] * 4))
        for r in range(4):
            for name, value in (("frequency", f[k % 5]), ("sweep", 1 if k < 5 else -1),
                                ("realisation", r), ("branch", branches[r]),
                                ("amplitude", values[r] * 1e-3),
                                ("phase", phase[k] + 0.05 * (r - 1.5))):
                fills[name].append(value)
    for name, values in fills.items():
        frf.create_dataset("fills/" + name, data=np.asarray(values))
with h5py.File("old.h5", "w") as h5:
    for name, values in (("frequency", f), ("amplitude", [4e-4, 7e-4, 9e-4, 6e-4, 3e-4]),
                         ("amplitude_ci", [1e-5] * 5), ("converged", [1, 1, 0, 1, 1])):
        h5.create_dataset("frf/" + name, data=np.asarray(values))
EOF
printf 'frequency_hz,amplitude_m\n14.2,0.0005\n15.2,0.0009\n15.8,0.0005\n' > measured.csv
"${plot[@]}" frf ensemble.h5 old.h5 --measured measured.csv -o ensemble.png > ensemble.txt
[ -s ensemble.png ] || { echo "ensemble.png is missing or empty" >&2; exit 1; }
expect() {
  grep -qxF -- "$1" ensemble.txt || {
    echo "expected the line '$1' in:" >&2
    cat ensemble.txt >&2
    exit 1
  }
}
peak="ensemble.h5: peak amplitude 0.878 ± 0.183 mm at 14.5 Hz (down sweep) over the result"
expect "$peak points (highest single fill 1.042 mm)"
expect "  higher, NOT a result: 1.84 ± 0.43 mm at 15 Hz (down sweep)"
grep -q "^ensemble.h5 (up): RMS relative difference" ensemble.txt
grep -q "^ensemble.h5 (down): RMS relative difference" ensemble.txt
expect "old.h5: peak amplitude 0.7 ± 0.01 mm at 14.5 Hz over the result points"
expect "  higher, NOT a result: 0.9 ± 0.01 mm at 15 Hz"
# A wrong request is an error, not an empty picture.
if "${plot[@]}" energy box.h5 -o none.png 2> error.txt; then
  echo "plot.py energy on a file without /energy succeeded" >&2
  exit 1
fi
grep -q "has no /energy group" error.txt
echo "all plots written"
