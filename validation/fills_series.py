#!/usr/bin/python3
"""Every fill's per-period first harmonic at every point of a run, as text for
validation/fills_replay.cpp: a line "frequency fill periods", then one line of
"amplitude phase" pairs (m, rad) in the order the fill ran them.

    validation/fills_series.py RUN.h5 > series.txt
"""
import sys

import h5py
import numpy as np


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    with h5py.File(sys.argv[1], "r") as f:
        p = f["/periods"]
        frequency, fill = p["frequency"][:], p["realisation"][:]
        amplitude, phase = p["amplitude"][:], p["phase"][:]
        sweep = p["sweep"][:] if "sweep" in p else np.ones_like(frequency)
    for key in sorted(set(zip(sweep, np.round(frequency, 6), fill))):
        s, hz, r = key
        m = (sweep == s) & np.isclose(frequency, hz) & (fill == r)
        print(f"{hz:g} {r} {m.sum()}")
        print(" ".join(f"{a:.9g} {q:.9g}" for a, q in zip(amplitude[m], phase[m])))


if __name__ == "__main__":
    main()
