#!/usr/bin/env bash
# pdsim against LIGGGHTS 3.8, side by side in one run: the shaken steel-sphere box (d = 5 mm,
# Hertz + Mindlin history, gravity, dt = 1e-6 s, lattice start, 0.004 sin(2 pi 20 t) along x) with
# 196 and 8,000 spheres, each program at 1 and 2 cores, then the ratio of each program's best.
# pdsim's figure counts its whole run (set-up included); LIGGGHTS' is its loop time.
# Each (program, cores) runs REPEAT times (default 3), the two programs taking turns, and its
# best run counts: on a shared, noisy machine single runs of the same binary vary by 40 %.
# usage: [REPEAT=n] validation/bench_vs_liggghts.sh [PDSIM_BINARY]   (default build/pdsim)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
pdsim=${1:-build/pdsim}
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-active}
printf "%-6s %-9s %-6s %-14s %-14s\n" scene particles cores pdsim_psteps_s liggghts_psteps_s
for spec in "a 196 20000" "b 8000 3000"; do
  read -r scene particles steps <<<"$spec"
  best_pdsim=0 best_liggghts=0
  for cores in 1 2; do
    pdsim_rate=0 liggghts_rate=0
    for _ in $(seq "${REPEAT:-3}"); do
      rate=$("$pdsim" bench --particles "$particles" --threads "$cores" --steps "$steps" |
        awk 'NR == 3 {print $5}')
      pdsim_rate=$(awk -v a="$pdsim_rate" -v b="$rate" 'BEGIN {print (b > a) ? b : a}')
      rate=$("$here/liggghts/run_liggghts.sh" "$scene" "$cores" "$steps" |
        grep -o 'particle_steps_per_s=[^ ]*' | cut -d= -f2)
      liggghts_rate=$(awk -v a="$liggghts_rate" -v b="$rate" 'BEGIN {print (b > a) ? b : a}')
    done
    printf "%-6s %-9s %-6s %-14s %-14s\n" "$scene" "$particles" "$cores" "$pdsim_rate" "$liggghts_rate"
    best_pdsim=$(awk -v a="$best_pdsim" -v b="$pdsim_rate" 'BEGIN {print (b > a) ? b : a}')
    best_liggghts=$(awk -v a="$best_liggghts" -v b="$liggghts_rate" 'BEGIN {print (b > a) ? b : a}')
  done
  awk -v p="$best_pdsim" -v l="$best_liggghts" -v s="$scene" \
    'BEGIN {printf "scene %s: best pdsim %.4g, best LIGGGHTS %.4g particle-steps/s, ratio %.2f\n", s, p, l, p / l}'
done
