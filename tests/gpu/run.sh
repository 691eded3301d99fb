#!/bin/bash
# Proves or disproves the CUDA engine on a lent GPU machine in one call (tests/gpu/README.md):
# the device, the CUDA engine tests with CUDA required (a failing case rerun alone with
# CUDA_LAUNCH_BLOCKING=1 and PDSIM_CUDA_SYNC=1), compute-sanitizer's four tools on short runs,
# `pdsim bench` on 196 to 1,000,000 spheres on both backends, and a shortened Saeki deck on both.
# Runs from the repository root with the pack of tests/gpu/pack.sh in gpu_pack/.
#
#   bash tests/gpu/run.sh [OUT]    # OUT: $OUT, else gpu_out/
#
# Writes OUT/summary.txt as it goes (a line per stage: ok, FAIL or skipped, seconds, log), then
# OUT/logs.tar.gz (every log), the figures and the Saeki outputs: 6 files, within the device
# tool's 8. Exit 0: everything passed; 1: a stage failed; 2: no GPU here (a dry run: the pack
# and the steps that need no GPU passed, nothing else ran). PDSIM_GPU_BUDGET_S (330)
# is the time the stages may take, so that the device call's timeout_s (360) ends none of them.
set -uo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
out=$(mkdir -p "${1:-${OUT:-$root/gpu_out}}" && cd "${1:-${OUT:-$root/gpu_out}}" && pwd)
pack=$root/gpu_pack
work=$(mktemp -d /tmp/pdsim_gpu.XXXXXX)
budget=${PDSIM_GPU_BUDGET_S:-330}
start=$SECONDS
summary=$out/summary.txt
failed=0
: >"$summary"

say() { echo "$*" | tee -a "$summary"; }

# The logs and figures into OUT whatever happens, the work folder removed.
# shellcheck disable=SC2317  # called by the trap
finish() {
  tar -C "$work" --exclude='*.h5' -czf "$out/logs.tar.gz" . 2>/dev/null
  # The figures, and the Saeki outputs where under the tool's 16 MiB a file.
  for file in "$work"/*.png "$work"/*.h5; do
    [ -e "$file" ] && (($(stat -c %s "$file") < 16 * 1048576)) && cp "$file" "$out/"
  done
  rm -rf "$work"
}
trap finish EXIT

# stage NAME SECONDS COMMAND...: runs COMMAND with its output in NAME.log, within SECONDS and
# what is left of the budget; one summary line.
stage() {
  local name=$1 limit=$2
  shift 2
  local left=$((budget - (SECONDS - start)))
  if ((left < 10)); then
    say "skipped  $name (out of time)"
    failed=1
    return 1
  fi
  ((limit > left)) && limit=$left
  local t0=$SECONDS rc
  timeout -k 5 "$limit" "$@" >"$work/$name.log" 2>&1
  rc=$?
  if ((rc == 0)); then
    say "ok       $name ($((SECONDS - t0)) s)"
  else
    say "FAIL     $name (exit $rc$( ((rc == 124)) && echo ", timed out at $limit s"), $((SECONDS - t0)) s): $name.log"
    tail -n 5 "$work/$name.log" | sed 's/^/         | /' | tee -a "$summary"
    failed=1
  fi
  return $rc
}

say "pdsim GPU check, $(date -u +%FT%TZ), $(git -C "$root" rev-parse --short HEAD 2>/dev/null || echo "no git")"

# ---- the pack: its programs, and every library they need from it or from the system's glibc --
if [ ! -x "$pack/bin/pdsim" ] || [ ! -x "$pack/bin/pdsim_kernels_tests" ]; then
  say "FAIL     no pack: run tests/gpu/pack.sh here first, and carry gpu_pack"
  exit 1
fi
# The machine's C++ runtime where it is as new as the build's (tools that compute-sanitizer loads
# into the process may need the newer one), else the pack's.
export LD_LIBRARY_PATH=$pack/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
if ldd "$pack"/bin/* | grep -q "not found"; then
  LD_LIBRARY_PATH=$pack/lib/cxx:$LD_LIBRARY_PATH
  echo "the machine's C++ runtime is older than the build's: the pack's" >"$work/cxx.log"
fi
export PATH=$pack/bin:$PATH
cat "$pack/manifest.txt" >"$work/pack.log" 2>/dev/null
missing=$(ldd "$pack"/bin/* | grep "not found" | sort -u)
if [ -n "$missing" ]; then
  say "FAIL     the pack lacks libraries: $missing"
  exit 1
fi
stage version 20 pdsim --version
tests=(pdsim_kernels_tests --source-file='*engine_gpu_test.cpp')

# A shortened Saeki deck: two frequencies, two fills each, at most 20 periods a frequency.
deck=$work/saeki_short.toml
sed -e 's/^frequencies = .*/frequencies = [14.5, 15.5]/' \
  -e 's/^settle = .*/settle = { min_periods = 10, max_periods = 20, realisations = 2, max_realisations = 2 }/' \
  -e 's/^file = .*/file = "saeki_short.h5"/' "$root/examples/saeki_250.toml" >"$deck"
if [ "$(grep -c '^frequencies = \[\|^settle = { min\|^file = "saeki_short' "$deck")" != 3 ]; then
  say "FAIL     examples/saeki_250.toml changed: the shortened deck is not shorter"
  failed=1
fi
stage saeki_check 30 pdsim check "$deck"

# ---- the device ------------------------------------------------------------------------------
if ! gpu=$(nvidia-smi --query-gpu=name,driver_version,compute_cap,memory.total \
  --format=csv,noheader 2>&1) || [ -z "$gpu" ]; then
  say "no GPU here (nvidia-smi: ${gpu:-no answer}): a dry run; the pack and deck are checked, nothing ran on a GPU"
  exit $((failed ? 1 : 2))
fi
say "device   $gpu (name, driver, compute capability, memory)"
{ nvidia-smi; nvcc --version; compute-sanitizer --version; uname -a; ldd --version | head -1; } \
  >"$work/device.log" 2>&1
nproc=$(nproc)

# ---- the CUDA engine tests, CUDA required, each case in its own process (a CUDA fault loses its
# process's context), several at once; a failing case again alone, every kernel checked --------
export PDSIM_REQUIRE_CUDA=1
"${tests[@]}" --list-test-cases --no-version >"$work/cases.txt" 2>&1
mapfile -t cases < <(sed -n '/^=\{20,\}/,/^=\{20,\}/p' "$work/cases.txt" | grep -v '^=\|^\[doctest\]')
say "tests    ${#cases[@]} CUDA engine test cases"
run_case() {
  timeout -k 5 "$((budget / 3))" "${tests[@]}" --test-case="${cases[$1]}" --duration=true \
    >"$work/case_$1.log" 2>&1
  echo $? >"$work/case_$1.rc"
}
for i in "${!cases[@]}"; do
  run_case "$i" &
  while (($(jobs -rp | wc -l) >= 6)); do wait -n; done
done
wait
reruns=0
for i in "${!cases[@]}"; do
  rc=$(cat "$work/case_$i.rc" 2>/dev/null || echo none)
  if [ "$rc" = 0 ]; then
    say "ok       case $i: ${cases[$i]}"
  else
    say "FAIL     case $i (exit $rc): ${cases[$i]}: case_$i.log"
    grep -m 5 "ERROR\|FATAL\|CUDA" "$work/case_$i.log" | sed 's/^/         | /' | tee -a "$summary"
    failed=1
    # Two cases at most: where every case fails (a wrong driver), the rest of the budget goes
    # to the stages below.
    if ((reruns++ < 2)); then
      CUDA_LAUNCH_BLOCKING=1 PDSIM_CUDA_SYNC=1 stage "case_${i}_alone_synced" 120 \
        "${tests[@]}" --test-case="${cases[$i]}"
    fi
  fi
done

# ---- compute-sanitizer: the four tools side by side on a short bench run (rebuilds, the step
# and its reductions) and the checkpoint case (three families, the mesh among them) -------------
short_bench=(pdsim bench --backend cuda --particles 2000 --steps 100 --repeat 1 --no-saeki --no-pile)
for tool in memcheck racecheck synccheck initcheck; do
  (
    sanitize=(compute-sanitizer --tool "$tool" --error-exitcode 1 --print-limit 20)
    stage "sanitizer_${tool}_bench" 150 "${sanitize[@]}" "${short_bench[@]}"
    stage "sanitizer_${tool}_checkpoints" 150 "${sanitize[@]}" "${tests[@]}" \
      --test-case='two engines made one after the other save byte-identical checkpoints'
  ) &
done
wait
grep -q FAIL "$summary" && failed=1

# ---- pdsim bench: the shaken box from a lattice, cuda against cpu (all cores), same steps -----
for n in 196 8000 100000 1000000; do
  steps=$((n >= 1000000 ? 200 : 1000))
  stage "bench_cuda_$n" 90 pdsim bench --backend cuda --particles "$n" --steps "$steps" --repeat 1
  stage "bench_cpu_$n" 90 pdsim bench --backend cpu --particles "$n" --threads "$nproc" \
    --steps "$steps" --repeat 1
done
python3 "$root/tests/gpu/plot_bench.py" "$work" "$work/bench.png" >"$work/bench_plot.log" 2>&1
sed -n 's/^bench \([a-z]*\) \(.*\)/\1 \2/p' "$work/bench_plot.log" | tee -a "$summary"

# ---- the Saeki deck, shortened, on both backends at once --------------------------------------
(cd "$work" && stage saeki_cuda 150 pdsim run "$deck" -o saeki_cuda.h5 --backend cuda --force) &
(cd "$work" && stage saeki_cpu 150 pdsim run "$deck" -o saeki_cpu.h5 --backend cpu --force \
  --threads "$((nproc - 2))") &
wait
for backend in cuda cpu; do
  python3 "$root/validation/frf_table.py" "$work/saeki_$backend.h5" >"$work/saeki_${backend}_frf.txt" 2>&1
done
python3 "$root/validation/plot.py" frf "$work/saeki_cpu.h5" "$work/saeki_cuda.h5" \
  -o "$work/saeki_frf.png" >"$work/saeki_plot.log" 2>&1
grep -q FAIL "$summary" && failed=1
say "done in $((SECONDS - start)) s: $( ((failed)) && echo "FAILED (see above)" || echo "all passed")"
exit $failed
