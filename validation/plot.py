#!/usr/bin/python3
"""Plots of pdsim results: frequency response, time series, energy ledger, prescribed motion.

Usage:
  validation/plot.py frf OUT.h5 [MORE.h5 ...] [--measured CSV] [--receptance] [--bare] [-o F]
  validation/plot.py timeseries OUT.h5 [--frequency HZ] [-o F]
  validation/plot.py energy OUT.h5 [-o F]
  validation/plot.py prescribed OUT.h5 [MORE.h5 ...] [-o F]

The format follows the extension of -o: .png (200 dpi), .pdf or .svg (vector); the default is
<kind>.png. Every axis is labelled with its unit; each plot says what its error bars are.
- frf: /frf amplitude (or receptance) and phase with 95 % intervals (validation/plot_frf.py,
  which documents the options).
- timeseries: /timeseries displacement (mm) and damper force (N) against time; --frequency keeps
  the samples taken at that drive frequency (a stepped sine records every frequency in turn).
- energy: the /energy ledger (output.energy = true): the input's work, the dissipation by
  mechanism and the stored energy's change (J, cumulative), and the imbalance as a share of the
  input.
- prescribed: /prescribed dissipated power (W) and first-harmonic force amplitude (N) against the
  drive frequency, with 95 % intervals, one colour per file.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import h5py  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plot_frf  # noqa: E402

FORMATS = (".png", ".pdf", ".svg")


def group(path, name):
    """The columns of /name as numpy arrays; exits naming what the file holds instead."""
    try:
        with h5py.File(path, "r") as h5:
            if name not in h5:
                held = ", ".join("/" + g for g in h5) or "nothing"
                sys.exit(f"plot.py: {path} has no /{name} group; it holds {held}")
            columns = {key: h5[name][key][()] for key in h5[name]}
            title = plot_frf.text(h5["meta"].attrs.get("title")) if "meta" in h5 else None
    except OSError as error:
        sys.exit(f"plot.py: cannot read {path}: {error}")
    return columns, title or os.path.basename(path)


def save(figure, output):
    figure.tight_layout()
    figure.savefig(output, dpi=200)
    plt.close(figure)
    print(f"wrote {output}")


def timeseries(args):
    ts, title = group(args.file, "timeseries")
    keep = np.ones(ts["time"].size, dtype=bool)
    if args.frequency is not None:
        available = np.unique(ts["frequency"])
        if available.size == 0:
            sys.exit(f"plot.py: {args.file}: /timeseries is empty")
        nearest = available[np.argmin(np.abs(available - args.frequency))]
        if abs(nearest - args.frequency) > 1e-9 * max(1.0, abs(args.frequency)):
            sys.exit(f"plot.py: {args.file}: no samples at {args.frequency:g} Hz; the file has "
                     + ", ".join(f"{f:g}" for f in available) + " Hz")
        keep = ts["frequency"] == nearest
    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 5.5))
    top.plot(ts["time"][keep], ts["displacement"][keep] * 1e3, lw=0.8)
    bottom.plot(ts["time"][keep], ts["damper_force"][keep], lw=0.8, color="C1")
    top.set_ylabel("displacement (mm)")
    bottom.set_ylabel("damper force (N)")
    bottom.set_xlabel("time (s)")
    shown = f" at {args.frequency:g} Hz" if args.frequency is not None else ""
    top.set_title(f"{title}: time series{shown}", fontsize="small")
    for axes in (top, bottom):
        axes.grid(True, alpha=0.3)
    save(figure, args.output)


def energy(args):
    e, title = group(args.file, "energy")
    t = e["time"]
    since = {key: e[key] - e[key][0] for key in e if key != "time"}
    dissipated = sum(since[k] for k in ("dissipated_structure", "dissipated_normal",
                                        "dissipated_tangential", "dissipated_rolling"))
    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6),
                                         gridspec_kw={"height_ratios": [3, 1]})
    top.plot(t, since["work_in"], "k-", label="work of the input")
    top.plot(t, dissipated, "k--", label="dissipated, all mechanisms")
    for key, label in (("dissipated_normal", "normal contact damping"),
                       ("dissipated_tangential", "friction (tangential)"),
                       ("dissipated_rolling", "rolling resistance"),
                       ("dissipated_structure", "structural damping")):
        if np.any(since[key] != 0):
            top.plot(t, since[key], label=label)
    top.plot(t, since["kinetic"] + since["potential"], ":", label="stored (kinetic + potential)")
    top.set_ylabel("energy since the first sample (J)")
    top.legend(fontsize="small")
    reference = np.maximum(np.abs(since["work_in"]), np.abs(e["kinetic"][0] + e["potential"][0]))
    share = np.divide(100 * since["imbalance"], reference, out=np.zeros_like(t),
                      where=reference > 0)
    bottom.plot(t, share, color="C3")
    bottom.set_ylabel("imbalance (% of input)")
    bottom.set_xlabel("time (s)")
    top.set_title(f"{title}: energy ledger (inertial frame)", fontsize="small")
    for axes in (top, bottom):
        axes.grid(True, alpha=0.3)
    save(figure, args.output)


def prescribed(args):
    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    for index, path in enumerate(args.files):
        p, title = group(path, "prescribed")
        order = np.argsort(p["frequency"])
        f = p["frequency"][order]
        color = f"C{index % 10}"
        for axes, key in ((top, "dissipated_power"), (bottom, "force_amplitude")):
            ci = p.get(key + "_ci")
            axes.errorbar(f, p[key][order], yerr=None if ci is None else ci[order], fmt="o-",
                          ms=4, capsize=2, color=color, label=title if axes is top else None)
    top.set_ylabel("dissipated power (W)")
    bottom.set_ylabel("force amplitude on the container (N)")
    bottom.set_xlabel("drive frequency (Hz)")
    top.legend(fontsize="small")
    top.set_title("prescribed motion; error bars: 95 % confidence", fontsize="small")
    for axes in (top, bottom):
        axes.grid(True, alpha=0.3)
    save(figure, args.output)


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "frf":
        plot_frf.main(sys.argv[2:])
        return
    parser = argparse.ArgumentParser(prog="plot.py", description=__doc__.splitlines()[0],
                                     epilog="frf: see validation/plot_frf.py --help")
    kinds = parser.add_subparsers(dest="kind", required=True)
    one = kinds.add_parser("timeseries", help="displacement and damper force against time")
    one.add_argument("file")
    one.add_argument("--frequency", type=float, help="only the samples at this frequency (Hz)")
    ledger = kinds.add_parser("energy", help="the /energy ledger")
    ledger.add_argument("file")
    power = kinds.add_parser("prescribed", help="dissipated power and force against frequency")
    power.add_argument("files", nargs="+")
    kinds.add_parser("frf", help="amplitude and phase (validation/plot_frf.py)")
    for sub in (one, ledger, power):
        sub.add_argument("-o", "--output", help="image to write: .png, .pdf or .svg")
    args = parser.parse_args()
    args.output = args.output or f"{args.kind}.png"
    if os.path.splitext(args.output)[1].lower() not in FORMATS:
        sys.exit(f"plot.py: {args.output}: the output must end in {', '.join(FORMATS)}")
    {"timeseries": timeseries, "energy": energy, "prescribed": prescribed}[args.kind](args)


if __name__ == "__main__":
    main()
