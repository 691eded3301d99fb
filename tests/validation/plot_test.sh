#!/usr/bin/env bash
# validation/plot.py on a small stepped sine, a free decay with its energy ledger and a
# prescribed motion with particle snapshots: every kind of plot, as PNG and as PDF, must be
# written and non-empty.
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

for format in png pdf; do
  "${plot[@]}" frf frf.h5 --receptance --bare -o "frf.$format"
  "${plot[@]}" timeseries frf.h5 --frequency 16 -o "timeseries.$format"
  "${plot[@]}" energy decay.h5 -o "energy.$format"
  "${plot[@]}" timeseries decay.h5 -o "decay.$format"
  "${plot[@]}" prescribed box.h5 -o "prescribed.$format"
  "${plot[@]}" bed box.h5 --time 0.05 -o "bed.$format"
  for kind in frf timeseries energy prescribed decay bed; do
    [ -s "$kind.$format" ] || { echo "$kind.$format is missing or empty" >&2; exit 1; }
  done
done
# A wrong request is an error, not an empty picture.
if "${plot[@]}" energy box.h5 -o none.png 2> error.txt; then
  echo "plot.py energy on a file without /energy succeeded" >&2
  exit 1
fi
grep -q "has no /energy group" error.txt
echo "all plots written"
