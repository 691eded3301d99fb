#!/usr/bin/env bash
# Writes reference_shaken_box_196.txt: LIGGGHTS 3.8 dissipated power and first-harmonic box force
# for scene a (196 spheres, 0.04 m cube), the numbers pdsim's prescribed-motion run is compared to.
#   main keys: 1 rank, 0.5 s (10 periods), statistics over periods 6-10 (as pdsim averages them)
#   np2_*:     the same run on 2 ranks; a different round-off, so a second chaotic realisation
#   long_*:    1 rank, 2.0 s (40 periods), statistics over periods 11-40
#   jitter_*:  as long_*, the lattice displaced along y by up to 1e-6 m: the exact lattice moves in
#              planes (no y force ever), the jittered one leaves them and dissipates differently
# Takes about 2 minutes on an idle 2-core machine (8 under a parallel build).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=$here/reference_shaken_box_196.txt
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

run() {  # name ranks steps [jitter_y]
  KEEP_DIR=$work/$1 SAMPLE_EVERY=100 THERMO=100000 JITTER_Y=${4:-0} \
    "$here/run_liggghts.sh" a "$2" "$3" >"$work/$1.timing"
}
run main 1 500000
run np2 2 500000
run long 1 2000000
run jitter 1 2000000 1e-6
planar_violations=$(awk '!/^#/ && $3 != 0' "$work/main/force_log.txt" "$work/long/force_log.txt" | wc -l)
[[ $planar_violations == 0 ]] || echo "warning: $planar_violations samples with F_y != 0: the 'planar' line is wrong" >&2

# m = 196 rho pi d^3 / 6
particle_mass=$(/usr/bin/python3 -c 'import math; print(196 * 7800.0 * math.pi / 6 * 0.005**3)')
analyse() {  # name periods prefix
  /usr/bin/python3 "$here/power_force.py" "$work/$1/force_log.txt" --periods "$2" \
    --particle-mass "$particle_mass" --prefix "$3"
}
version=$(sed -n '1s/^LIGGGHTS (Version \(.*\), compiled.*/\1/p' "$work/main/log.liggghts")
{
  echo "# LIGGGHTS peer reference for pdsim, scene a (written by make_reference_196.sh; do not edit)"
  echo "liggghts_version = $version  # Debian package liggghts $(dpkg-query -W -f='${Version}' liggghts 2>/dev/null || echo '?')"
  cat <<'SETTINGS'
particles = 196  # steel spheres, simple cubic lattice 7 x 7 x 4, spacing 1.02 d, first centre 0.51 d from the lower walls, x fastest then y then z, at rest at t = 0
diameter = 0.005  # m
density = 7800.0  # kg/m^3
young = 2.0e11  # Pa, particles and walls
poisson = 0.3
restitution = 0.5  # particle-particle and particle-wall
friction = 0.3  # particle-particle and particle-wall
contact = hertz + tangential history  # pair_style gran model hertz tangential history; wall/gran the same; no rolling friction, no cohesion
container = 0.04 x 0.04 x 0.04  # m, closed box [0,0.04]^3 at t = 0, a 12-triangle STL mesh
gravity = 0 0 -9.81  # m/s^2
motion = x_box(t) = 0.004 sin(2 pi 20 t)  # m; fix move/mesh wiggle amplitude 0.004 0 0 period 0.05
frequency = 20.0  # Hz
amplitude = 0.004  # m
dt = 1.0e-6  # s, fixed; neighbour skin 0.0005 m, neigh_modify delay 0
duration = 0.5  # s (10 periods); averages over periods 6-10 (t = 0.25..0.5 s)
sampling = force on the box averaged over each 100 steps (1e-4 s), power F.v averaged over every step
planar = yes  # the exact lattice never leaves the x-z planes: every F_y sample is 0 and v_y = 0; the 7 y-slices of 28 particles (0.1 mm apart) never touch each other, and round-off makes them 7 different 2-D motions
sign_convention = F is the force the particles put on the box (LIGGGHTS f_<mesh>; pdsim damper_force); P = mean(-F_x v_box) = mean(F_box_on_particles . v_box) > 0; force_phase is the phase of F_x on the box relative to x_box = A sin(w t), F_x ~ F1 sin(w t + phase); the force on the particles has phase + 180 deg
SETTINGS
  analyse main 5 ""
  echo "# second realisation: same run on 2 MPI ranks (round-off differs; the motion is chaotic)"
  analyse np2 5 np2_
  echo "# longer statistics: 2.0 s run on 1 rank, periods 11-40 (periods 1-10 equal the main run)"
  analyse long 30 long_
  echo "# sensitivity: as long_*, initial y of every centre displaced by uniform [-1e-6, 1e-6] m (seed 1);"
  echo "# the motion leaves the x-z planes (F_y no longer 0) and the results differ beyond the scatter"
  analyse jitter 30 jitter_
} >"$out"
cat "$work"/{main,np2,long,jitter}.timing
echo "wrote $out"
