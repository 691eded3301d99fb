#!/usr/bin/python3
"""Plots of pdsim results: frequency response, time series, energy ledger, prescribed motion.

Usage:
  validation/plot.py frf OUT.h5 [MORE.h5 ...] [--measured CSV] [--receptance] [--bare] [-o F]
  validation/plot.py timeseries OUT.h5 [--frequency HZ] [-o F]
  validation/plot.py energy OUT.h5 [-o F]
  validation/plot.py prescribed OUT.h5 [MORE.h5 ...] [-o F]
  validation/plot.py bed OUT.h5 [--time S] [--damper K] [-o F]
  validation/plot.py map MAP.h5 [-o F]

The format follows the extension of -o: .png (200 dpi), .pdf or .svg (vector); the default is
<kind>.png. Every axis is labelled with its unit; each plot says what its error bars are.
- frf: /frf amplitude (or receptance) and phase, the mean over the fills with its 95 %
  interval, the band where one fill lies and every fill's own value (validation/plot_frf.py,
  which documents the markers and the options).
- timeseries: /timeseries displacement (mm) and damper force (N, at the samples and averaged
  between them) against time; --frequency keeps the samples taken at that drive frequency (a
  stepped sine records every frequency in turn).
- energy: the /energy ledger (output.energy = true): the input's work, the dissipation by
  mechanism and the stored energy's change (J, cumulative), and the imbalance as a share of the
  input.
- prescribed: /prescribed dissipated power (W) and first-harmonic force amplitude (N) against the
  drive frequency, with 95 % intervals, one colour per file.
- map: a damper map (pdsim map, /map): effective mass (kg) and damping (N s/m) against the
  motion's amplitude (mm), one curve per frequency, with 95 % intervals (amplitudes stepped up:
  triangles up; back down: triangles down, dashed).
- bed: one particle snapshot (output.particles) in 3-D, the container's frame, each sphere to
  scale and coloured by its speed (the snapshot nearest --time, default the last); ParaView
  plays them all (OUT.xdmf).
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection  # noqa: E402
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
    bottom.plot(ts["time"][keep], ts["damper_force"][keep], lw=0.5, color="0.6",
                label="at the sample")
    if "damper_force_mean" in ts:  # files before the column had only the samples
        bottom.plot(ts["time"][keep], ts["damper_force_mean"][keep], lw=0.9, color="C1",
                    label="mean since the previous sample (impulse / interval)")
        bottom.legend(fontsize="small")
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
    mechanisms = [k for k in e if k.startswith("dissipated_")]  # structure and the contacts'
    dissipated = sum(since[k] for k in mechanisms)
    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6),
                                         gridspec_kw={"height_ratios": [3, 1]})
    top.plot(t, since["work_in"], "k-", label="work of the input")
    top.plot(t, dissipated, "k--", label="dissipated, all mechanisms")
    for key in mechanisms:
        if np.any(since[key] != 0):
            top.plot(t, since[key], label="dissipated, " + key.removeprefix("dissipated_"))
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


def damper_map(args):
    m, title = group(args.file, "map")
    figure, (top, bottom) = plt.subplots(2, 1, sharex=True, figsize=(7, 6))
    frequencies = np.unique(m["frequency"])
    sweep = m.get("sweep", np.zeros(len(m["frequency"]), dtype=int))
    # Points from the settled bed: circles; amplitudes stepped up: triangles up, solid; back
    # down: triangles down, dashed (the bed's hysteresis is where the two differ).
    styles = {0: "o-", 1: "^-", -1: "v--"}
    for index, f in enumerate(frequencies):
        color = plt.cm.viridis(index / max(1, len(frequencies) - 1))
        for way in (0, 1, -1):
            rows = (m["frequency"] == f) & (sweep == way)
            if not rows.any():
                continue
            order = np.argsort(m["amplitude"][rows])
            x = 1e3 * m["amplitude"][rows][order]
            first = way == sweep[m["frequency"] == f][0]
            for axes, key in ((top, "effective_mass"), (bottom, "effective_damping")):
                axes.errorbar(x, m[key][rows][order], yerr=m[key + "_ci"][rows][order],
                              fmt=styles[way], ms=3, capsize=2, color=color,
                              label=f"{f:g} Hz" if axes is top and first else None)
    top.set_ylabel("effective mass (kg)")
    bottom.set_ylabel("effective damping (N s/m)")
    bottom.set_xlabel("motion amplitude (mm)")
    bottom.set_xscale("log")
    top.legend(fontsize="x-small", ncol=2)
    stepped = "; stepped up ^, down v --" if (sweep != 0).any() else ""
    top.set_title(f"{title}: damper map; error bars: 95 % confidence{stepped}", fontsize="small")
    for axes in (top, bottom):
        axes.grid(True, alpha=0.3)
    save(figure, args.output)


def bed(args):
    try:
        with h5py.File(args.file, "r") as h5:
            if "particles" not in h5:
                sys.exit(f"plot.py: {args.file} has no /particles (run with output.particles)")
            times = h5["particles/time"][()]
            t = len(times) - 1 if args.time is None else int(np.argmin(np.abs(times - args.time)))
            d = h5[f"particles/damper{args.damper}"]
            position, velocity = d["position"][t], d["velocity"][t]
            radius, size = d["radius"][()], d["container_size"][()]
            centre, axes = d["container_position"][t], d["container_axes"][t]
            shape = plot_frf.text(d.attrs["shape"])
            outline = None  # files of pdsim before 2026-12-04 have none
            if "container_outline_points" in d:
                outline = (d["container_outline_points"][()] * 1e3,
                           d["container_outline_segments"][()])
            title = plot_frf.text(h5["meta"].attrs.get("title")) or os.path.basename(args.file)
    except (OSError, KeyError) as error:
        sys.exit(f"plot.py: cannot read the snapshots of {args.file}: {error}")
    local = (position - centre) @ axes.T * 1e3  # mm, in the container's frame
    speed = np.linalg.norm(velocity, axis=1)
    figure = plt.figure(figsize=(7, 6))
    view = figure.add_subplot(projection="3d")
    half = 0.5 * size * 1e3
    # Marker area in points^2 for a sphere of the given radius at this axes' scale (roughly).
    scale = (figure.get_size_inches()[0] * 72 * 0.5 / (2 * half.max())) ** 2
    dots = view.scatter(local[:, 0], local[:, 1], local[:, 2], s=np.pi * scale * (radius * 1e3) ** 2,
                        c=speed, cmap="viridis", depthshade=True, edgecolors="k", linewidths=0.2)
    figure.colorbar(dots, ax=view, shrink=0.6, label="speed (m/s)")
    if outline is not None:
        points, segments = outline
        view.add_collection3d(Line3DCollection(points[segments], colors="0.5",
                                               linewidths=0.4 if len(segments) > 200 else 0.8))
    elif shape == "box":
        for a in (-1, 1):
            for b in (-1, 1):
                for axis in range(3):
                    ends = np.zeros((2, 3))
                    ends[:, axis] = [-half[axis], half[axis]]
                    others = [i for i in range(3) if i != axis]
                    ends[:, others[0]] = a * half[others[0]]
                    ends[:, others[1]] = b * half[others[1]]
                    view.plot(*ends.T, color="0.5", lw=0.8)
    else:
        angle = np.linspace(0, 2 * np.pi, 65)
        for z in (-half[2], half[2]):
            view.plot(half[0] * np.cos(angle), half[1] * np.sin(angle), z, color="0.5", lw=0.8)
    for limits, h in ((view.set_xlim3d, half[0]), (view.set_ylim3d, half[1]),
                      (view.set_zlim3d, half[2])):
        limits(-h, h)
    view.set_box_aspect(half.copy())  # matplotlib 3.6 scales the array it is given in place
    view.set_xlabel("x (mm)")
    view.set_ylabel("y (mm)")
    view.set_zlabel("z (mm)")
    view.set_title(f"{title}: t = {times[t]:.4g} s, {len(radius)} particles (container frame)",
                   fontsize="small")
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
    snapshot = kinds.add_parser("bed", help="one particle snapshot in 3-D")
    snapshot.add_argument("file")
    snapshot.add_argument("--time", type=float, help="s; the nearest snapshot (default the last)")
    snapshot.add_argument("--damper", type=int, default=0, help="which damper (default 0)")
    kinds.add_parser("frf", help="amplitude and phase (validation/plot_frf.py)")
    mapped = kinds.add_parser("map", help="a damper map: effective mass and damping")
    mapped.add_argument("file")
    for sub in (one, ledger, power, snapshot, mapped):
        sub.add_argument("-o", "--output", help="image to write: .png, .pdf or .svg")
    args = parser.parse_args()
    args.output = args.output or f"{args.kind}.png"
    if os.path.splitext(args.output)[1].lower() not in FORMATS:
        sys.exit(f"plot.py: {args.output}: the output must end in {', '.join(FORMATS)}")
    {"timeseries": timeseries, "energy": energy, "prescribed": prescribed, "bed": bed,
     "map": damper_map}[args.kind](args)


if __name__ == "__main__":
    main()
