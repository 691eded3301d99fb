#!/usr/bin/python3
"""Writes a LIGGGHTS read_data file (atom_style granular) of a bed pdsim settled (bed.file).

usage: bed_data.py BED.h5 FILL DIAMETER DENSITY LX LY LZ MARGIN_X MARGIN OUT.data
BED.h5 is a pdsim bed file (a map's runs keep theirs in NAME_map_runs/bed.h5); FILL the fill
(0, 1, ...) whose centres are written, moved from pdsim's container frame (centred on the box)
to the box [0, L] that run_liggghts.sh meshes. One diameter: the scene's spheres are all alike.
"""
import sys

import h5py
import numpy as np

from make_lattice_data import write_centres

if len(sys.argv) != 11:
    sys.exit(__doc__)
bed, fill = sys.argv[1], int(sys.argv[2])
diameter, density, lx, ly, lz, margin_x, margin = (float(s) for s in sys.argv[3:10])
with h5py.File(bed, "r") as h5:
    group = h5["checkpoint"]
    key = "bed.r%d.damper0." % fill
    if key + "x" not in group:
        sys.exit("bed_data.py: %s holds no fill %d" % (bed, fill))
    centres = np.column_stack([group[key + axis][()] for axis in "xyz"])
    radius = group[key + "radius"][()]
if not np.allclose(2 * radius, diameter):
    sys.exit("bed_data.py: the bed's spheres are not all of diameter %g m" % diameter)
centres += 0.5 * np.array([lx, ly, lz])
# A settled sphere presses into the wall it rests on by its contact's overlap (um).
slack = 0.01 * diameter
if ((centres < 0.5 * diameter - slack).any()
        or (centres > np.array([lx, ly, lz]) - 0.5 * diameter + slack).any()):
    sys.exit("bed_data.py: the bed does not fit the box %g x %g x %g m" % (lx, ly, lz))
write_centres(sys.argv[10], "pdsim bed %s fill %d" % (bed, fill), [tuple(c) for c in centres],
              diameter, density, (lx, ly, lz), margin_x, margin)
