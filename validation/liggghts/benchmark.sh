#!/usr/bin/env bash
# LIGGGHTS throughput table for the pdsim speed comparison: scenes a (196, 20,000 steps),
# b (8,000, 5,000 steps) and c (100,000, 200 steps), 1 and 2 ranks back to back, REPEATS times.
# The machine may be shared: every line carries the CPU time and the load average, so compare
# 1-rank runs by cpu_s as well as wall_s.
# usage: benchmark.sh [REPEATS]   (default 2; about 1 minute a repeat on an idle 2-core machine)
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
repeats=${1:-2}
for ((repeat = 1; repeat <= repeats; repeat++)); do
  for scene_steps in "a 20000" "b 5000" "c 200"; do
    read -r scene steps <<<"$scene_steps"
    for ranks in 1 2; do
      echo "repeat=$repeat $("$here/run_liggghts.sh" "$scene" "$ranks" "$steps")"
    done
  done
done
