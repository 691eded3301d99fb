#!/usr/bin/env bash
# pdsim against LIGGGHTS 3.8, side by side in one run: the shaken steel-sphere box (d = 5 mm,
# Hertz + Mindlin history, gravity, dt = 1e-6 s, lattice start, 0.004 sin(2 pi 20 t) along x) with
# 196 and 8,000 spheres, each program at 1 and 2 cores, then the ratio of each program's best.
# pdsim's figure counts its whole run (set-up included); LIGGGHTS' is its loop time.
# Each (program, cores) runs REPEAT times (default 3), the two programs taking turns, and its
# best run counts: on a shared, noisy machine single runs of the same binary vary by 40 %.
# Then the batch row: two copies of the scene at once, one core each, as sweep points run
# (`pdsim sweep`; `pdsim bench --jobs 2`, set-up included) against two single-rank LIGGGHTS
# runs started together (the sum of their loop-time rates).
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
  pdsim_rate=0 liggghts_rate=0
  for _ in $(seq "${REPEAT:-3}"); do
    rate=$("$pdsim" bench --particles "$particles" --threads 1 --steps "$steps" --jobs 2 |
      awk '/copies of each scene/ {batch = 1} batch && $1 == '"$particles"' {print $5}')
    pdsim_rate=$(awk -v a="$pdsim_rate" -v b="$rate" 'BEGIN {print (b > a) ? b : a}')
    rates=$( (
      MPIRUN_FLAGS="--bind-to none ${MPIRUN_FLAGS:-}" "$here/liggghts/run_liggghts.sh" "$scene" 1 "$steps" &
      MPIRUN_FLAGS="--bind-to none ${MPIRUN_FLAGS:-}" "$here/liggghts/run_liggghts.sh" "$scene" 1 "$steps" &
      wait
    ) | grep -o 'particle_steps_per_s=[^ ]*' | cut -d= -f2 | awk '{sum += $1} END {print sum}')
    liggghts_rate=$(awk -v a="$liggghts_rate" -v b="$rates" 'BEGIN {print (b > a) ? b : a}')
  done
  awk -v p="$pdsim_rate" -v l="$liggghts_rate" -v s="$scene" \
    'BEGIN {printf "scene %s, 2 copies at once (1 core each): pdsim %.4g, LIGGGHTS %.4g particle-steps/s, ratio %.2f\n", s, p, l, p / l}'
done
