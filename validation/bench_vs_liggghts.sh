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
# Each (program, cores) runs REPEAT times (default 1), the programs taking turns; the best counts.
# usage: [REPEAT=n] [SCENES="a b p"] [WARMUP_S=s] [PERIODS=k] validation/bench_vs_liggghts.sh [PDSIM]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pdsim=${1:-build/pdsim}
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-active}
warmup=${WARMUP_S:-0.2} periods=${PERIODS:-1}
best() { awk -v a="$1" -v b="$2" 'BEGIN {print (b > a) ? b : a}'; }
printf "%-6s %-9s %-6s %-14s %-14s\n" scene particles cores pdsim_psteps_s liggghts_psteps_s
for scene in ${SCENES:-a b p}; do
  case $scene in
    a) particles=196 dt=1e-6 frequency=20 flags=(--particles 196 --no-pile) ;;
    b) particles=8000 dt=1e-6 frequency=20 flags=(--particles 8000 --no-pile) ;;
    p) particles=250 dt=4e-6 frequency=15 flags=(--particles 196 --pile) ;;
    *) echo "unknown scene '$scene' (a, b or p)" >&2; exit 2 ;;
  esac
  warm_steps=$(awk -v w="$warmup" -v dt="$dt" 'BEGIN {printf "%d", w / dt + 0.5}')
  steps=$(awk -v p="$periods" -v f="$frequency" -v dt="$dt" 'BEGIN {printf "%d", p / (f * dt) + 0.5}')
  best_pdsim=0 best_liggghts=0
  for cores in 1 2; do
    pdsim_rate=0 liggghts_rate=0
    for _ in $(seq "${REPEAT:-1}"); do
      # the scene's own rows: the last table of the output for the pile, the only one otherwise
      rate=$("$pdsim" bench "${flags[@]}" --threads "$cores" --warmup "$warmup" \
        --periods "$periods" | awk -v n="$particles" '$1 == n {r = $5} END {print r}')
      pdsim_rate=$(best "$pdsim_rate" "$rate")
      rate=$(WARMUP=$warm_steps JITTER_Y=2e-5 "$here/liggghts/run_liggghts.sh" "$scene" "$cores" \
        "$steps" | grep -o 'particle_steps_per_s=[^ ]*' | cut -d= -f2)
      liggghts_rate=$(best "$liggghts_rate" "$rate")
    done
    printf "%-6s %-9s %-6s %-14s %-14s\n" "$scene" "$particles" "$cores" "$pdsim_rate" "$liggghts_rate"
    best_pdsim=$(best "$best_pdsim" "$pdsim_rate")
    best_liggghts=$(best "$best_liggghts" "$liggghts_rate")
  done
  awk -v p="$best_pdsim" -v l="$best_liggghts" -v s="$scene" \
    'BEGIN {printf "scene %s: best pdsim %.4g, best LIGGGHTS %.4g particle-steps/s, ratio %.2f\n", s, p, l, p / l}'
done
