#!/usr/bin/env python3
"""Writes a LIGGGHTS read_data file (atom_style granular) of spheres on the pdsim lattice.

The lattice is pdsim's particles.fill = "lattice" (io/decks.md): simple cubic, spacing 1.02 d,
the first centre 0.51 d from each lower wall, x fastest, then y, then z.

usage: make_lattice_data.py COUNT DIAMETER DENSITY LX LY LZ MARGIN_X MARGIN OUT.data [JITTER_Y]
The simulation domain is the box [0,L] widened by MARGIN_X along x (the shaking stroke) and by
MARGIN along y and z, so that the moving mesh stays inside it.
JITTER_Y (m, default 0) displaces every centre along y by a uniform random amount in
[-JITTER_Y, JITTER_Y] (fixed seed). Diagnostic only: without it the x-shaken lattice stays exactly
planar (no force ever has a y component), and a jitter shows whether leaving the plane matters.
"""
import random
import sys


def lattice_centres(count, diameter, lx, ly, lz):
    spacing = 1.02 * diameter
    first = 0.51 * diameter
    # a centre is admissible while the sphere stays inside the wall: c + d/2 <= L
    per_axis = [int((length - first - 0.5 * diameter) / spacing + 1e-9) + 1 for length in (lx, ly, lz)]
    nx, ny, nz = per_axis
    if count > nx * ny * nz:
        raise ValueError("%d particles do not fit in %d x %d x %d lattice sites" % (count, nx, ny, nz))
    centres = []
    for k in range(count):
        i, j, layer = k % nx, (k // nx) % ny, k // (nx * ny)
        centres.append((first + i * spacing, first + j * spacing, first + layer * spacing))
    return centres, per_axis


def write_data(path, count, diameter, density, box, margin_x, margin, jitter_y=0.0):
    lx, ly, lz = box
    centres, _ = lattice_centres(count, diameter, lx, ly, lz)
    if jitter_y > 0.0:
        # neighbours along y are 0.02 d apart: a larger jitter could make them overlap
        assert jitter_y < 0.005 * diameter
        rng = random.Random(1)
        centres = [(x, y + rng.uniform(-jitter_y, jitter_y), z) for x, y, z in centres]
    write_centres(path, "pdsim lattice", centres, diameter, density, box, margin_x, margin)


def write_centres(path, title, centres, diameter, density, box, margin_x, margin):
    """The data file of spheres at `centres` (m, the box's frame [0, L])."""
    lx, ly, lz = box
    count = len(centres)
    lines = [
        "%s: %d spheres d=%g m in box %g x %g x %g m" % (title, count, diameter, lx, ly, lz),
        "",
        "%d atoms" % count,
        "1 atom types",
        "",
        "%.9g %.9g xlo xhi" % (-margin_x, lx + margin_x),
        "%.9g %.9g ylo yhi" % (-margin, ly + margin),
        "%.9g %.9g zlo zhi" % (-margin, lz + margin),
        "",
        "Atoms",
        "",
    ]
    # atom_style granular: atom-ID atom-type diameter density x y z
    for n, (x, y, z) in enumerate(centres, start=1):
        lines.append("%d 1 %.9g %.9g %.12g %.12g %.12g" % (n, diameter, density, x, y, z))
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    if len(sys.argv) not in (10, 11):
        sys.exit(__doc__)
    count = int(sys.argv[1])
    diameter, density, lx, ly, lz, margin_x, margin = (float(s) for s in sys.argv[2:9])
    jitter_y = float(sys.argv[10]) if len(sys.argv) == 11 else 0.0
    write_data(sys.argv[9], count, diameter, density, (lx, ly, lz), margin_x, margin, jitter_y)
