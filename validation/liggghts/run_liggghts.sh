#!/usr/bin/env bash
# Runs the shaken-box scene in LIGGGHTS 3.8 and prints one throughput line.
#
# usage: run_liggghts.sh SCENE NP STEPS
#   SCENE: a (196 particles, 0.04 m cube), b (8000, 0.11 x 0.11 x 0.2 m),
#          c (100000, 0.26 x 0.26 x 0.4 m): steel (E = 2e11 Pa, e = 0.5), dt = 1e-6 s, shaken
#          4 mm at 20 Hz; p (the dense pile of `pdsim bench`: 250 particles, 0.05 m cube,
#          E = 2e9 Pa, e = 0.6, dt = 4e-6 s, shaken 1 mm at 15 Hz); y (250 particles in the
#          cylinder r = 28 mm, h = 50 mm given as STL, E = 2e9 Pa, e = 0.5, dt = 4e-6 s, shaken
#          3 mm at 20 Hz; needs STL and BED); NP: MPI ranks; STEPS: timed time steps.
# environment (optional):
#   SKIN=<m>           neighbour skin, default 0.0005 m (0.1 d, the faster of the tried ones)
#   WARMUP=<k>         time steps run before the timed ones (the fall from the lattice), default 0
#   SAMPLE_EVERY=<k>   write force_log.txt (per-k-step averages of F and power) and
#                      force_instant.txt (instantaneous F every k steps)
#   KEEP_DIR=<dir>     run in <dir> (kept) instead of a temporary directory
#   THERMO=<k>         thermo output interval in steps, default STEPS
#   JITTER_Y=<m>       random y displacement of the lattice (diagnostic; see make_lattice_data.py)
#   AMPLITUDE=<m>, FREQUENCY=<Hz>, DT=<s>  the box's motion and the step instead of the scene's
#                      (a damper map point; power_force.py needs whole periods of DT)
#   BED=<bed.h5>:<fill>  start from that fill of a bed pdsim settled instead of the lattice
#   STL=<file.stl>     the container as this ASCII STL (metres, in the frame [0, L] of the
#                      scene's box) instead of the box
#   MPIRUN_FLAGS       extra mpirun flags
# output: liggghts scene=<s> particles=<n> ranks=<np> steps=<k> wall_s=<loop time>
#         particle_steps_per_s=<r> total_wall_s=<process wall time incl. start-up and input>
#         cpu_s=<user+system CPU s of all ranks> load=<load averages 1/5/15 min at the end>
set -euo pipefail

if [[ $# -ne 3 ]]; then
  sed -n "2,29p" "$0" >&2
  exit 2
fi
scene=$1 ranks=$2 steps=$3
[[ $ranks =~ ^[1-9][0-9]*$ && $steps =~ ^[1-9][0-9]*$ ]] ||
  { echo "NP and STEPS must be positive integers, got '$ranks' and '$steps'" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)

diameter=0.005 young=2.0e11 restitution=0.5 dt=1.0e-6 amplitude=0.004 period=0.05
case $scene in
  a | 196) scene=a count=196 box=(0.04 0.04 0.04) ;;
  b | 8000) scene=b count=8000 box=(0.11 0.11 0.2) ;;
  c | 100k) scene=c count=100000 box=(0.26 0.26 0.4) ;;
  p | pile) scene=p count=250 box=(0.05 0.05 0.05) young=2.0e9 restitution=0.6 dt=4.0e-6
    amplitude=0.001 period=0.0666666666666667 ;;
  y | cylinder) scene=y count=250 box=(0.056 0.056 0.05) young=2.0e9 restitution=0.5 dt=4.0e-6
    amplitude=0.003 period=0.05 ;;
  *) echo "unknown scene '$scene' (a, b, c, p or y)" >&2; exit 2 ;;
esac
amplitude=${AMPLITUDE:-$amplitude} dt=${DT:-$dt}
[[ -n ${FREQUENCY:-} ]] && period=$(python3 -c "print(repr(1.0 / float('$FREQUENCY')))")

binary=$(command -v liggghts || compgen -c lmp_ | head -n1 || true)
[[ -n $binary ]] || { echo "no liggghts or lmp_* binary on PATH (apt-get install liggghts)" >&2; exit 1; }

if [[ -n ${KEEP_DIR:-} ]]; then
  workdir=$KEEP_DIR
  mkdir -p "$workdir"
else
  workdir=$(mktemp -d)
  trap 'rm -rf "$workdir"' EXIT
fi

# the domain must hold the mesh over its whole stroke: amplitude plus a diameter along x
margin_x=0.01 margin=0.002
if [[ -n ${STL:-} ]]; then
  cp "$STL" "$workdir/box.stl"
else
  python3 "$here/make_box_stl.py" "${box[@]}" "$workdir/box.stl"
fi
if [[ -n ${BED:-} ]]; then
  /usr/bin/python3 "$here/bed_data.py" "${BED%:*}" "${BED##*:}" "$diameter" 7800 "${box[@]}" \
    "$margin_x" "$margin" "$workdir/lattice.data"
else
  python3 "$here/make_lattice_data.py" "$count" "$diameter" 7800 "${box[@]}" "$margin_x" "$margin" \
    "$workdir/lattice.data" "${JITTER_Y:-0}"
fi

sample_prefix='#'
[[ -n ${SAMPLE_EVERY:-} ]] && sample_prefix=''
sed -e "s/^@S@/$sample_prefix/" \
  -e "s/@SKIN@/${SKIN:-0.0005}/" \
  -e "s/@YOUNG@/$young/; s/@POISSON@/0.3/; s/@RESTITUTION@/$restitution/; s/@FRICTION@/0.3/" \
  -e "s/@DT@/$dt/g; s/@AMPLITUDE@/$amplitude/g; s/@PERIOD@/$period/g" \
  -e "s/@SAMPLE_EVERY@/${SAMPLE_EVERY:-100}/g; s/@THERMO@/${THERMO:-$steps}/; s/@STEPS@/$steps/" \
  -e "s/@WARMUP@/${WARMUP:-0}/" \
  "$here/shaken_box.in.template" >"$workdir/in.shaken_box"

start=$(date +%s.%N)
# bash's `time` reports the CPU seconds of all ranks: on a loaded machine it is the figure that
# other processes do not inflate (for one rank; with two, MPI's busy waiting counts as CPU time)
TIMEFORMAT='cpu %U %S'
read -ra mpirun_flags <<<"${MPIRUN_FLAGS:-}"
# -screen none crashes with mesh walls in 3.8, so the screen goes to /dev/null
{ time (cd "$workdir" && mpirun --allow-run-as-root "${mpirun_flags[@]}" -np "$ranks" "$binary" \
  -in in.shaken_box -log log.liggghts -screen /dev/null); } 2>"$workdir/mpirun.err" ||
  { echo "LIGGGHTS failed:" >&2; cat "$workdir/mpirun.err" >&2; tail -n 20 "$workdir/log.liggghts" >&2; exit 1; }
end=$(date +%s.%N)
cpu=$(awk '$1 == "cpu" {print $2 + $3}' "$workdir/mpirun.err")

load=$(cut -d' ' -f1-3 /proc/loadavg | tr ' ' /)  # 1/5/15-minute load averages at the end
loop=$(awk '/^Loop time of/ {t = $4} END {print t}' "$workdir/log.liggghts")
[[ -n $loop ]] || { echo "no 'Loop time' line in $workdir/log.liggghts" >&2; exit 1; }
atoms=$(sed -n 's/^Loop time of .* steps with \([0-9]*\) atoms.*/\1/p' "$workdir/log.liggghts" | tail -n1)
[[ $atoms == "$count" ]] || echo "warning: run ended with $atoms particles, not $count" >&2
awk -v s="$scene" -v n="$count" -v p="$ranks" -v k="$steps" -v w="$loop" -v t0="$start" -v t1="$end" \
  -v c="$cpu" -v load="$load" 'BEGIN {
  printf "liggghts scene=%s particles=%d ranks=%d steps=%d wall_s=%.3f particle_steps_per_s=%.4g total_wall_s=%.3f cpu_s=%.3f load=%s\n",
    s, n, p, k, w, n * k / w, t1 - t0, c, load }'
