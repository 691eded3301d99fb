#!/usr/bin/env bash
# `pdsim sweep --slurm` on a real single-node Slurm (tests/cluster/slurm_cluster.sh): every
# point's file bitwise equal to the local sweep's (every dataset and attribute but the wall
# time) and the same summary.csv, and so are those of `srun -n 2 pdsim sweep --ranks` and of
# `mpirun -np 2 pdsim sweep --ranks`; then one task cancelled mid-run (its first frequency
# done), resubmitted with --slurm --resume, and its point bitwise the uninterrupted one. Slurm records a failed task as COMPLETED here
# (proctrack/linuxproc), so the files are checked, not job states. Last, `pdsim map --slurm`
# against the local map.
# Usage: slurm_test.sh PDSIM DECK (a sweep deck; the map deck is made from it).
set -euo pipefail
pdsim=$(realpath "$1")
deck=$(realpath "$2")
for program in munged slurmctld slurmd sbatch srun squeue scancel mpirun; do
  if ! command -v "$program" >/dev/null; then
    echo "FAIL: $program is not installed (bash .ci/install-deps installs Slurm, munge and Open MPI)"
    exit 1
  fi
done
here=$(dirname "$(realpath "$0")")
source "$here/slurm_cluster.sh"
cd "$cluster"
cp "$deck" deck.toml
fail() {
  echo "FAIL: $*"
  for log in "$cluster"/*/*.log; do echo "--- $log"; tail -n 5 "$log"; done
  exit 1
}

# Waits (at most $2 s) until none of the jobs $1 (comma-separated) is queued or running.
wait_jobs() {
  for _ in $(seq $(($2 * 5))); do
    [ -z "$(timeout 5 squeue -h -j "$1" -o %i 2>/dev/null)" ] && return 0
    sleep 0.2
  done
  fail "jobs $1 still in the queue after $2 s"
}

# The two job ids a --slurm submission printed: the array's, then the collect job's.
job_ids() {
  sed -n 's/.* as job array \([0-9]*\) .*/\1/p; s/^job \([0-9]*\) writes .*/\1/p' "$1" | paste -sd,
}

# Every dataset and attribute of two files equal, wall_time_s and the attributes named after
# the two files aside.
same_files() {
  /usr/bin/python3 - "$@" <<'PY'
import sys, h5py, numpy as np
def items(path):
    out = {}
    with h5py.File(path, "r") as f:
        def visit(name, obj):
            if isinstance(obj, h5py.Dataset):
                out[name] = obj[()]
            for key, value in obj.attrs.items():
                if key not in ["wall_time_s"] + sys.argv[3:]:
                    out[name + "@" + key] = value
        visit("/", f)
        f.visititems(visit)
    return out
a, b = items(sys.argv[1]), items(sys.argv[2])
def equal(x, y):
    x, y = np.asarray(x), np.asarray(y)
    if x.dtype.kind in "fc":
        return x.shape == y.shape and np.array_equal(x, y, equal_nan=True)
    return x.shape == y.shape and bool(np.all(x == y))
bad = sorted(k for k in a.keys() | b.keys() if k not in a or k not in b or not equal(a[k], b[k]))
if bad:
    sys.exit(f"{sys.argv[1]} and {sys.argv[2]} differ in {bad[:10]}")
print(f"{sys.argv[2]}: {len(a)} datasets and attributes equal to {sys.argv[1]}")
PY
}

# summary.csv without the wall-time columns.
summary() { cut -d, -f1-5,8- "$1"; }

"$pdsim" sweep deck.toml --threads 1 -o local >local.txt || fail "the local sweep: $(cat local.txt)"

timeout 60 "$pdsim" sweep deck.toml --slurm -o slurm >slurm.txt || fail "submission: $(cat slurm.txt)"
cat slurm.txt
grep -q "4 of 4 points submitted" slurm.txt || fail "4 points not submitted"
[ -x slurm/slurm_array.sh ] || [ -f slurm/slurm_array.sh ] || fail "no slurm/slurm_array.sh"
jobs=$(job_ids slurm.txt)
[[ "$jobs" =~ ^[0-9]+,[0-9]+$ ]] || fail "no job ids in: $(cat slurm.txt)"
wait_jobs "$jobs" 120
for k in 1 2 3 4; do same_files local/p00$k.h5 slurm/p00$k.h5 || fail "point $k"; done
[ -f slurm/summary.csv ] || fail "the collect job wrote no summary: $(cat slurm/collect.log)"
diff <(summary local/summary.csv) <(summary slurm/summary.csv) || fail "summary.csv differs"
grep -q "4 of 4 points finished" slurm/collect.log || fail "collect.log: $(cat slurm/collect.log)"

# srun as the launcher of --ranks: each rank its points (SLURM_PROCID/SLURM_NTASKS), the same
# files, and the last rank's summary.
timeout 120 srun -n 2 --cpus-per-task=1 "$pdsim" sweep deck.toml --ranks --jobs 1 --threads 1 \
  -o ranked >ranked.txt 2>&1 || fail "srun --ranks: $(cat ranked.txt)"
grep -q "rank 1 of 2: 2 of its 2 points finished" ranked.txt || fail "$(cat ranked.txt)"
for k in 1 2 3 4; do same_files local/p00$k.h5 ranked/p00$k.h5 || fail "ranked point $k"; done
diff <(summary local/summary.csv) <(summary ranked/summary.csv) || fail "ranked summary.csv"

# Open MPI's mpirun as the launcher (OMPI_COMM_WORLD_RANK/SIZE; pdsim links no MPI): the same.
timeout 120 mpirun --allow-run-as-root --oversubscribe -np 2 "$pdsim" sweep deck.toml --ranks \
  --jobs 1 --threads 1 -o mpi >mpi.txt 2>&1 || fail "mpirun --ranks: $(cat mpi.txt)"
grep -q "4 of 4 points finished" mpi.txt || fail "$(cat mpi.txt)"
for k in 1 2 3 4; do same_files local/p00$k.h5 mpi/p00$k.h5 || fail "mpirun point $k"; done
diff <(summary local/summary.csv) <(summary mpi/summary.csv) || fail "mpirun summary.csv"

# A task cancelled once its point's first frequency is done, then the point resubmitted alone.
timeout 60 "$pdsim" sweep deck.toml --slurm --jobs 1 -o cancel >cancel.txt || fail "$(cat cancel.txt)"
jobs=$(job_ids cancel.txt)
array=${jobs%,*}
for _ in $(seq 300); do [ -e cancel/p002.h5.partial ] && break; sleep 0.1; done
[ -e cancel/p002.h5.partial ] || fail "point 2 wrote no checkpoint within 30 s"
[ -e cancel/p002.h5 ] && fail "point 2 finished before it could be cancelled"
timeout 10 scancel "${array}_2"
wait_jobs "$jobs" 120
[ -e cancel/p002.h5 ] && fail "the cancelled point 2 has its file"
"$pdsim" sweep deck.toml -o cancel --status >status.txt && fail "--status said all finished"
grep -q "point 2/4 (.*): interrupted" status.txt || fail "--status: $(cat status.txt)"
for k in 1 3 4; do grep -q "point $k/4 (.*): finished" status.txt || fail "$k: $(cat status.txt)"; done
grep -q "3 of 4 points finished" cancel/collect.log || fail "collect.log: $(cat cancel/collect.log)"
timeout 60 "$pdsim" sweep deck.toml --slurm --resume -o cancel >resume.txt || fail "$(cat resume.txt)"
grep -q "1 of 4 points submitted" resume.txt || fail "resubmission: $(cat resume.txt)"
wait_jobs "$(job_ids resume.txt)" 120
grep -q "point 2: continuing from cancel/p002.h5.partial" cancel/p002.log || fail "point 2 started anew: $(cat cancel/p002.log)"
same_files local/p002.h5 cancel/p002.h5 || fail "the resumed point 2"
diff <(summary local/summary.csv) <(summary cancel/summary.csv) || fail "resumed summary.csv"
# A damper map's runs as a job array, the map written by the job after it. Its runs share one
# settled bed, written by whichever run settles it first (the same bed, whichever): /meta/bed
# and particle_steps say whether a run settled the bed or read it, which depends on the order
# in which the tasks ran.
sed '/^\[sweep\]/,$d' deck.toml >mapped.toml
printf '[map]\namplitudes = [5e-5, 1e-3, 1e-2]\nfrequencies = [15.0, 16.0]\n' >>mapped.toml
"$pdsim" map mapped.toml -o local_map.h5 --threads 1 --quiet >/dev/null || fail "the local map"
timeout 60 "$pdsim" map mapped.toml -o slurm_map.h5 --slurm >map.txt || fail "$(cat map.txt)"
grep -q "3 of 3 runs submitted" map.txt || fail "map submission: $(cat map.txt)"
wait_jobs "$(job_ids map.txt)" 120
[ -f slurm_map.h5 ] || fail "no map: $(cat slurm_map_runs/collect.log)"
same_files local_map.h5 slurm_map.h5 bed particle_steps || fail "the map"
for k in 1 2 3; do
  same_files local_map_runs/m00$k.h5 slurm_map_runs/m00$k.h5 bed particle_steps || fail "map run $k"
done
echo "PASS: the Slurm sweep and map equal the local ones; a cancelled task resumed to the same numbers"
