#!/usr/bin/python3
"""Print a stepped-sine FRF's ensemble as a Markdown table, one row per point.

Usage: validation/frf_table.py OUT.h5 [--reference LONG.h5] [--hb HB.h5]

Columns: frequency (and sweep when the file has both), /frf/result, fills, branches, the
ensemble mean amplitude (mm) with its 95 % half-width and the prediction half-width (where one
fill lies) as per cent of the mean, and every fill's own mean amplitude (mm) with the periods it
ran (a fill that held still at settle.max_periods without meeting the tolerance is marked
"wide", one still drifting "drifting").

--reference LONG.h5: a second run of the same deck whose fills ran long (e.g. 600 periods at
14, 15 and 16 Hz). For each of its frequencies the table below the first says whether the
ensemble mean lies within the reference's interval and within 3 %, and whether the prediction
interval (mean +- amplitude_spread) holds every long fill.

--hb HB.h5: a prediction of the same deck from a damper map (pdsim predict, /frf_hb). The table
below the first gives, per frequency, the coupled mean with its interval and its fills, every
stable predicted root (mm, 95 %; "up"/"down" for a map's amplitudes stepped up or down), the
difference of the root nearest the mean, and how many of the fills lie on a predicted root (within
the root's interval or 3 %, whichever is wider).
"""
import argparse
import sys

import h5py
import numpy as np


def table(path, group):
    try:
        with h5py.File(path, "r") as h5:
            if group not in h5:
                sys.exit(f"frf_table.py: {path} has no /{group}")
            return {name: h5[group][name][()] for name in h5[group]
                    if isinstance(h5[group][name], h5py.Dataset)}
    except OSError as error:
        sys.exit(f"frf_table.py: cannot read {path}: {error}")


def fills_at(fills, frequency, sweep):
    return np.flatnonzero((fills["frequency"] == frequency) & (fills["sweep"] == sweep))


RESULTS = {0: "not a result", 1: "one state", 2: "branches"}
WAYS = {0: "", 1: " up", -1: " down"}


def prediction(frf, fills, hb):
    """The coupled FRF against the stable roots of a harmonic-balance prediction."""
    print()
    print("| f (Hz) | coupled mean (mm, 95 %) | coupled point | its fills (mm) | "
          "predicted, stable (mm, 95 %) | nearest root | fills on a root |")
    print("|---|---|---|---|---|---|---|")
    sweep_of = hb.get("sweep", np.zeros(len(hb["frequency"]), dtype=int))
    for i, f in enumerate(frf["frequency"]):
        mean, ci = frf["amplitude"][i], frf["amplitude_ci"][i]
        values = fills["amplitude"][fills_at(fills, f, frf["sweep"][i])]
        rows = np.flatnonzero(np.isclose(hb["frequency"], f) & (hb["stable"] == 1))
        roots = hb["amplitude"][rows]
        widths = np.maximum(hb["amplitude_ci"][rows], 0.03 * roots)
        text = ", ".join(f"{hb['amplitude'][k] * 1e3:.4f} +- {hb['amplitude_ci'][k] * 1e3:.4f}"
                         f"{WAYS[int(sweep_of[k])]}" for k in rows) or "none"
        nearest = f"{100 * (roots[np.argmin(np.abs(roots - mean))] - mean) / mean:+.1f} %" \
            if roots.size else "-"
        on = sum(bool(np.any(np.abs(v - roots) <= widths)) for v in values)
        print(f"| {f:g} | {mean * 1e3:.4f} +- {ci * 1e3:.4f} | "
              f"{RESULTS.get(int(frf['result'][i]), '?')} | "
              f"{', '.join(f'{v * 1e3:.3f}' for v in values)} | {text} | {nearest} | "
              f"{on} of {len(values)} |")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file")
    parser.add_argument("--reference", help="a run of the same deck with long fills")
    parser.add_argument("--hb", help="a pdsim predict output of the same deck")
    args = parser.parse_args()
    frf, fills = table(args.file, "frf"), table(args.file, "frf/fills")
    both = len(set(frf["sweep"])) > 1
    print("| f (Hz) | result | fills | branches | mean (mm) | 95 % CI | one fill within | "
          "fills: mm (periods) |")
    print("|---|---|---|---|---|---|---|---|")
    for i, f in enumerate(frf["frequency"]):
        sweep = frf["sweep"][i]
        mean = frf["amplitude"][i]
        own = []
        for k in fills_at(fills, f, sweep):
            state = ("" if fills["converged"][k] else
                     ", wide" if fills.get("settled", fills["converged"])[k] else ", drifting")
            own.append(f"{fills['amplitude'][k] * 1e3:.3f} ({fills['periods'][k]}{state})")
        name = f"{f:g}" + ((" up" if sweep > 0 else " down") if both else "")
        print(f"| {name} | {frf['result'][i]} | {frf['realisations'][i]} | "
              f"{frf['branches'][i]} | {mean * 1e3:.4f} | "
              f"{100 * frf['amplitude_ci'][i] / mean:.2f} % | "
              f"{100 * frf['amplitude_spread'][i] / mean:.1f} % | {', '.join(own)} |")
    if args.hb:
        prediction(frf, fills, table(args.hb, "frf_hb"))
    if not args.reference:
        return
    long_frf, long_fills = table(args.reference, "frf"), table(args.reference, "frf/fills")
    print()
    print("| f (Hz) | ensemble (mm) | long fills (mm) | long mean (mm) | difference | "
          "within the long interval | within 3 % | prediction holds every long fill |")
    print("|---|---|---|---|---|---|---|---|")
    for j, f in enumerate(long_frf["frequency"]):
        rows = np.flatnonzero((frf["frequency"] == f) & (frf["sweep"] == long_frf["sweep"][j]))
        if not rows.size:
            continue
        i = rows[0]
        mean, ci, spread = (frf[name][i] for name in ("amplitude", "amplitude_ci",
                                                        "amplitude_spread"))
        reference, reference_ci = long_frf["amplitude"][j], long_frf["amplitude_ci"][j]
        values = long_fills["amplitude"][fills_at(long_fills, f, long_frf["sweep"][j])]
        difference = (mean - reference) / reference
        # The two means agree when their difference is within the two intervals combined.
        within = abs(mean - reference) <= np.hypot(ci, reference_ci)
        holds = bool(np.all(np.abs(values - mean) <= spread))
        print(f"| {f:g} | {mean * 1e3:.4f} +- {ci * 1e3:.4f} | "
              f"{', '.join(f'{v * 1e3:.3f}' for v in values)} | "
              f"{reference * 1e3:.4f} +- {reference_ci * 1e3:.4f} | {100 * difference:+.1f} % | "
              f"{'yes' if within else 'no'} | {'yes' if abs(difference) <= 0.03 else 'no'} | "
              f"{'yes' if holds else 'no'} |")


if __name__ == "__main__":
    main()
