#!/bin/bash
# Whether two pdsim builds compute the same numbers: the decks below run with each (one thread,
# so that the order of every sum is the same), and their files are compared bitwise by
# validation/same_results.py (every dataset and attribute but wall time, version and deck
# path); the bench scenes' final-state fingerprints are compared as printed. A change meant to
# keep results is checked against the commit before it this way.
#
#   validation/same_results.sh OLD_PDSIM NEW_PDSIM [--long]
#
# --long adds the FRF examples (saeki_250, capsule_damper, horizontal_cylinder: half an hour or
# more each, a build).
# SAME_IGNORE="identity ..." skips more attributes (identity: a build before it was written).
# Exit 0 when everything is the same, 1 when something differs.
set -euo pipefail
old=$(realpath "$1") new=$(realpath "$2")
repo=$(cd "$(dirname "$0")/.." && pwd)
python=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
decks=(tests/decks/tiny_stepped_sine.toml tests/decks/tiny_rigid_stepped_sine.toml
       tests/decks/tiny_prescribed.toml tests/decks/good_beam.toml examples/bare_sdof.toml
       examples/shaken_box.toml)
[[ "${3:-}" == "--long" ]] &&
  decks+=(examples/saeki_250.toml examples/capsule_damper.toml examples/horizontal_cylinder.toml)
status=0
compare() {  # old file, new file
  if [[ ! -f "$1" || ! -f "$2" ]]; then
    echo "DIFFERENT: $(basename "$2") was not written by both builds"; status=1; return
  fi
  # shellcheck disable=SC2086
  if "$python" "$repo/validation/same_results.py" "$1" "$2" --ignore ${SAME_IGNORE:-}; then
    echo "same: $(basename "$2")"
  else
    status=1
  fi
}
for side in old new; do
  mkdir -p "$work/$side"
  cp "$repo"/examples/*.stl "$repo"/tests/decks/tiny_map.toml "$repo"/tests/decks/tiny_sweep.toml \
    "$work/$side/"
done
for deck in "${decks[@]}"; do
  name=$(basename "$deck" .toml)
  cp "$repo/$deck" "$work/old/" && cp "$repo/$deck" "$work/new/"
  for side in old new; do
    bin=$old; [[ $side == new ]] && bin=$new
    (cd "$work/$side" && "$bin" run --quiet --threads 1 --jobs 1 -o "$name.h5" "$name.toml" \
      > "$name.log" 2>&1) || echo "$side: $name failed (exit $?)"
  done
  compare "$work/old/$name.h5" "$work/new/$name.h5"
done
# A sweep (4 points), a map (4 points, each run's file too) and its prediction.
for side in old new; do
  bin=$old; [[ $side == new ]] && bin=$new
  (cd "$work/$side" && "$bin" sweep --threads 1 --jobs 1 -o sweep tiny_sweep.toml \
    > sweep.log 2>&1 && "$bin" map --quiet --threads 1 --jobs 1 -o map.h5 tiny_map.toml \
    > map.log 2>&1 && "$bin" predict --map map.h5 -o hb.h5 tiny_map.toml > hb.log 2>&1) ||
    echo "$side: the sweep, map or prediction failed (exit $?)"
done
for point in "$work"/new/sweep/p*.h5; do compare "$work/old/sweep/$(basename "$point")" "$point"; done
for run in "$work"/new/map_runs/m*.h5; do compare "$work/old/map_runs/$(basename "$run")" "$run"; done
compare "$work/old/map.h5" "$work/new/map.h5"
# The same map with rigid contacts, stepped up and down: each run its own step and bed.
for side in old new; do
  bin=$old; [[ $side == new ]] && bin=$new
  sed -e 's/model = "linear"/model = "nonsmooth"/' -e '/^stiffness = 2000/d' -e '/^young/d' \
    -e '/^tangential/d' "$work/$side/tiny_map.toml" > "$work/$side/rigid_map.toml"
  echo 'steps = "both"' >> "$work/$side/rigid_map.toml"
  (cd "$work/$side" && "$bin" map --quiet --threads 1 --jobs 1 -o rigid.h5 rigid_map.toml \
    > rigid.log 2>&1) || echo "$side: the rigid map failed (exit $?)"
done
for run in "$work"/new/rigid_runs/*.h5; do compare "$work/old/rigid_runs/$(basename "$run")" "$run"; done
compare "$work/old/rigid.h5" "$work/new/rigid.h5"
compare "$work/old/hb.h5" "$work/new/hb.h5"
# The bench scenes: their final states' fingerprints (the last column, every digit).
for side in old new; do
  bin=$old; [[ $side == new ]] && bin=$new
  "$bin" bench --steps 2000 --particles 196,8000 --threads 1 --repeat 1 2>/dev/null |
    awk '/^ *[0-9]/ {print $1, $NF}' > "$work/$side/bench.txt"
done
if cmp -s "$work/old/bench.txt" "$work/new/bench.txt" && [[ -s "$work/new/bench.txt" ]]; then
  echo "same: bench fingerprints ($(wc -l < "$work/new/bench.txt") scenes)"
else
  echo "DIFFERENT: bench fingerprints"; diff "$work/old/bench.txt" "$work/new/bench.txt" || true
  status=1
fi
exit $status
