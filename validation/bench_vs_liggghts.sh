#!/usr/bin/env bash
# pdsim against LIGGGHTS 3.8 on the user's flows, side by side in one run: whole periods after
# the fall from the fill, each program at 1 and 2 cores, then the ratio of each program's best.
#   a: 196 steel spheres d = 5 mm in a 40 mm cube shaken 4 mm at 20 Hz (fluidised), dt = 1e-6 s
#   b: 8,000 of them in 0.11 x 0.11 x 0.2 m, the same shaking
#   p: the dense pile: 250 spheres in a 50 mm cube, E = 2e9 Pa, e = 0.6, shaken 1 mm at 15 Hz,
#      dt = 4e-6 s (the Saeki damper off resonance)
# Both programs run WARMUP_S seconds (default 0.2) untimed, then PERIODS whole periods (default
# 1) timed, set-up excluded. The exact lattice stays planar, so neither starts from one: pdsim
# from a random fill, LIGGGHTS from the lattice moved by up to 2e-5 m along y (JITTER_Y).
# Each (program, cores) runs REPEAT times (default 3), the programs taking turns. These are
# chaotic flows on a noisy machine: each row gives the median and the range of its runs, and the
# ratio of the best core counts is given as the ratio of medians with its range (the slowest
# pdsim run against the fastest LIGGGHTS run, and the other way round).
# usage: [REPEAT=n] [SCENES="a b p"] [WARMUP_S=s] [PERIODS=k] validation/bench_vs_liggghts.sh [PDSIM]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pdsim=${1:-build/pdsim}
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-active}
warmup=${WARMUP_S:-0.2} periods=${PERIODS:-1} repeat=${REPEAT:-3}
# median, min and max of the numbers given
stats() { printf "%s\n" "$@" | sort -g | awk '{v[NR] = $1} END {m = NR % 2 ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2; printf "%.4g %.4g %.4g\n", m, v[1], v[NR]}'; }
printf "%-6s %-9s %-6s %-32s %-32s\n" scene particles cores "pdsim median [min, max]" \
  "LIGGGHTS median [min, max]"
for scene in ${SCENES:-a b p}; do
  case $scene in
    a) particles=196 dt=1e-6 frequency=20 flags=(--particles 196 --no-pile --no-saeki) ;;
    b) particles=8000 dt=1e-6 frequency=20 flags=(--particles 8000 --no-pile --no-saeki) ;;
    p) particles=250 dt=4e-6 frequency=15 flags=(--no-box --no-saeki) ;;
    *) echo "unknown scene '$scene' (a, b or p)" >&2; exit 2 ;;
  esac
  warm_steps=$(awk -v w="$warmup" -v dt="$dt" 'BEGIN {printf "%d", w / dt + 0.5}')
  steps=$(awk -v p="$periods" -v f="$frequency" -v dt="$dt" 'BEGIN {printf "%d", p / (f * dt) + 0.5}')
  best_p="0 0 0" best_l="0 0 0"  # median min max of each program's best core count
  for cores in 1 2; do
    p_rates=() l_rates=()
    for _ in $(seq "$repeat"); do
      p_rates+=("$("$pdsim" bench "${flags[@]}" --repeat 1 --threads "$cores" --warmup "$warmup" \
        --periods "$periods" | awk -v n="$particles" '$1 == n {r = $5} END {print r}')")
      l_rates+=("$(WARMUP=$warm_steps JITTER_Y=2e-5 "$here/liggghts/run_liggghts.sh" "$scene" \
        "$cores" "$steps" | grep -o 'particle_steps_per_s=[^ ]*' | cut -d= -f2)")
    done
    read -r pm pl ph <<<"$(stats "${p_rates[@]}")"
    read -r lm ll lh <<<"$(stats "${l_rates[@]}")"
    printf "%-6s %-9s %-6s %-32s %-32s\n" "$scene" "$particles" "$cores" "$pm [$pl, $ph]" \
      "$lm [$ll, $lh]"
    awk -v a="$pm" -v b="${best_p%% *}" 'BEGIN {exit !(a > b)}' && best_p="$pm $pl $ph"
    awk -v a="$lm" -v b="${best_l%% *}" 'BEGIN {exit !(a > b)}' && best_l="$lm $ll $lh"
  done
  read -r pm pl ph <<<"$best_p"
  read -r lm ll lh <<<"$best_l"
  awk -v s="$scene" -v pm="$pm" -v pl="$pl" -v ph="$ph" -v lm="$lm" -v ll="$ll" -v lh="$lh" \
    'BEGIN {printf "scene %s: best core counts, medians pdsim %.4g, LIGGGHTS %.4g particle-steps/s: ratio %.2f [%.2f, %.2f]\n", s, pm, lm, pm / lm, pl / lh, ph / ll}'
done
