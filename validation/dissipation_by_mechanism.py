#!/usr/bin/python3
"""Dissipation by mechanism from two pdsim binaries side by side (issue 19's before/after table).

Runs, with each binary given:
  * the LIGGGHTS shaken box (examples/shaken_box.toml) from random fills (the exact lattice stays
    planar: seven 2-D slices), output.energy on, 10 periods; what the last 5 periods' input went to;
  * the Saeki deck (examples/saeki_250.toml) as a stepped sine over 14, 15, 16 Hz, 40 periods each,
    one realisation: the per-frequency tallies against the containers' input.
Prints Markdown tables. The shaken box's rows differ by realisation (the motion is chaotic); the
tallies' error is the 'unaccounted' column, input minus dissipation minus the change of stored
energy (kinetic, gravity, contact springs), which a closed ledger makes zero.

usage: dissipation_by_mechanism.py BEFORE_BINARY AFTER_BINARY [--seeds 1 2 3]
"""
import argparse
import os
import re
import subprocess
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
EXAMPLES = os.path.join(HERE, "..", "examples")


def deck(path, edits):
    text = open(path).read()
    for pattern, replacement in edits:
        text, n = re.subn(pattern, replacement, text, count=1, flags=re.M)
        assert n == 1, pattern
    return text


def run(binary, text, work, name):
    path = os.path.join(work, name + ".toml")
    out = os.path.join(work, name + ".h5")
    open(path, "w").write(text)
    subprocess.run([binary, "run", path, "--output", out, "--force"], check=True,
                   stdout=subprocess.DEVNULL)
    return h5py.File(out, "r")


def box_row(f, start):
    e = f["energy"]
    t = e["time"][:]
    i, j = np.searchsorted(t, start), len(t) - 1
    d = lambda key: e[key][j] - e[key][i]
    stored_keys = ["kinetic", "potential"] if "potential" in e else ["kinetic", "elastic"]
    work = d("work_in")
    normal, tangential = d("dissipated_normal"), d("dissipated_tangential")
    stored = sum(d(k) for k in stored_keys)
    return work, normal, tangential, work - normal - tangential - stored


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    a = ap.parse_args()
    binaries = {"before": os.path.abspath(a.before), "after": os.path.abspath(a.after)}
    with tempfile.TemporaryDirectory() as work:
        print("Shaken box, 196 spheres, random fill, periods 6-10 (J):\n")
        print("| binary | seed | input | normal | tangential | unaccounted | of input |")
        print("|---|---|---|---|---|---|---|")
        for seed in a.seeds:
            text = deck(os.path.join(EXAMPLES, "shaken_box.toml"), [
                (r'fill = "lattice"', f'fill = "random", seed = {seed}'),
                (r'^file = .*$', 'file = "box.h5"\nenergy = true')])
            for label, binary in binaries.items():
                w, n, t, u = box_row(run(binary, text, work, f"box_{label}_{seed}"), 0.25)
                print(f"| {label} | {seed} | {w:.4f} | {n:.4f} | {t:.4f} | {u:+.5f} | "
                      f"{100 * u / w:+.2f} % |")
        print("\nSaeki 250, stepped sine, 40 periods a frequency (J per period):\n")
        print("| binary | f (Hz) | input | normal | tangential | (normal + tangential) / input - 1 |")
        print("|---|---|---|---|---|---|")
        text = deck(os.path.join(EXAMPLES, "saeki_250.toml"), [
            (r'^frequencies = .*$', 'frequencies = [14.0, 15.0, 16.0]\n'
             'settle = { min_periods = 40, max_periods = 40, batches = 5, realisations = 1 }')])
        for label, binary in binaries.items():
            frf = run(binary, text, work, f"saeki_{label}")["frf"]
            for k, freq in enumerate(frf["frequency"][:]):
                w = frf["dissipated_energy"][k]
                n, t = frf["dissipated_normal"][k], frf["dissipated_tangential"][k]
                print(f"| {label} | {freq:g} | {w:.3e} | {n:.3e} | {t:.3e} | "
                      f"{100 * ((n + t) / w - 1):+.2f} % |")


if __name__ == "__main__":
    main()
