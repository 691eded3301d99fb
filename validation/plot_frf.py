"""Plot stepped-sine frequency responses (/frf) of pdsim runs, optionally against a measured curve.

Usage: validation/plot_frf.py OUT.h5 [OTHER.h5 ...] [--measured CSV] [--receptance] [--bare]
                              [--hb HB.h5 ...] [-o frf.png]
(also `validation/plot.py frf ...`, with the other plots of a result)

Draws two stacked panels sharing the frequency axis (Hz): the first-harmonic displacement
amplitude (mm, /frf/amplitude) and its phase against the input sin(angle) (rad, /frf/phase, as
stored), one colour per file, labelled by the /meta attribute `title` (else the file name) and
the /meta attribute `start` (predicted, carried or independent) when present. A point's value
is the mean over an ensemble of fills (random packings of the same damper). On both panels:
- Result points (/frf/result > 0; files without that column: /frf/converged = 1) are filled
  markers with the 95 % confidence error bars of the ensemble mean (± /frf/amplitude_ci,
  ± /frf/phase_ci), joined by a line only between neighbouring result points: the line breaks
  wherever a point that is not a result lies between them. A circle is a point in one state
  (result 1); a diamond one of several branches (result 2: fills of the same damper in
  distinct states, the mean between them and its error bar their spread), legend entry
  "several branches (result 2)".
- Points that are not results (result 0) are hollow circles: no line, no error bars, one
  legend entry "not a result".
- A light band in the file's colour, mean ± /frf/amplitude_spread (phase: ± /frf/phase_spread),
  is the 95 % prediction interval over the fills: where one fill (one damper of this design)
  lies, wider than the error bar of the mean (the amplitude band stops at zero). It spans the
  runs of neighbouring points where the spread is finite (it is NaN with one fill), whether
  results or not; legend entry "where one fill lies (95 % prediction)". Files without the columns have no band.
- Every fill's own mean at every point (/frf/fills amplitude and phase) is a small
  semi-transparent marker in the file's colour at its frequency, its shape the fill's branch
  there (/frf/fills/branch, 0 the highest amplitude): x branch 0, + branch 1, tri-down
  branch 2, tri-up branch 3, then again from x; legend entry "one fill (marker: its branch)".
  Files without /frf/fills show instead, where their realisations disagree (/frf/interval = 2),
  each realisation's mean over its stationary periods in /periods as a small cross, legend
  entry "one realisation's mean (where they disagree)".
- A file holding both sweep directions (/frf/sweep +1 and -1: excitation.direction = "both")
  is drawn as two curves in its colour, each sorted by frequency: the up sweep solid and
  labelled "... (up)", the down sweep dashed and labelled "... (down)"; each fill goes with
  the sweep of its /frf/fills/sweep. Files without /frf/sweep are one up sweep.
Files written before the _ci columns existed (or with NaN CIs) get no error bars for those points.
The legend sits below the panels, the grey entries standing for every file's colour.
The output format follows the extension of -o: .png (200 dpi), .pdf or .svg (vector).

Prints for each file its peak: the highest ensemble mean amplitude over the result points with
its 95 % half-width, and the highest single fill at a result point, as one line, e.g.
    OUT.h5: peak amplitude 0.878 ± 0.183 mm at 14.5 Hz over the result points
    (highest single fill 1.042 mm)
taken from the /frf attributes peak_amplitude, peak_amplitude_ci, peak_frequency, peak_upper
and peak_sweep when the file has them, else from the columns (the highest single fill then
from /frf/fills, left out without it); "(no CI)" stands for a missing half-width, and a file
with both sweeps names the sweep after each frequency, e.g. "at 14.5 Hz (down sweep)".
When a point that is not a result has a higher mean than the peak, a second line gives the
highest such point:
      higher, NOT a result: 1.84 ± 0.43 mm at 15 Hz
A file without a result point prints "no result point (0 of N points are results)" and, on the
second line, its highest mean all the same (as pdsim's summary line and frf_peak() do). A file
without /frf (e.g. a prescribed-motion result, /prescribed) is an error (exit status 1).

--receptance: amplitude per newton of drive (m/N, /meta/deck's excitation.amplitude), for
force input only; files driven otherwise are an error.
--bare: the bare structure's analytic response (single-DOF structures under force input, from
the first file's deck: mass, stiffness and damping), drawn as a thin black line.
--hb HB.h5: a harmonic-balance prediction (pdsim predict, /frf_hb) over the coupled FRF, a thin
line through each branch, stable roots filled, unstable ones hollow: squares from a map's points
run from the settled bed, triangles up (solid) and down (dashed) from its amplitudes stepped up
and down.

--measured CSV: a digitised measured curve (e.g. Saeki 2002, fig. 5b), plain text, comma
separated, first line exactly the header `frequency_hz,amplitude_m`, then one point per line
in SI units (Hz, m, amplitude > 0); lines starting with '#' are comments. Example:
    frequency_hz,amplitude_m
    # Saeki (2002) fig. 5b, 250 particles, digitised by hand
    12.0,0.00051
    15.2,0.00230
It is drawn on the amplitude panel. For each file (each sweep of a file with both) the script
then prints the RMS relative difference sqrt(mean(((sim - meas) / meas)^2)), with the
simulated amplitude (the ensemble mean) interpolated linearly at the measured frequencies
between the result points only; measured points outside the frequency range of the result
points are left out and counted.
"""
import argparse
import math
import os
import sys
import tomllib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
import numpy as np  # noqa: E402
import h5py  # noqa: E402

HEADER = "frequency_hz,amplitude_m"
FORMATS = (".png", ".pdf", ".svg")
NOT_RESULT = "not a result"
BRANCHED = "several branches (result 2)"
SPREAD = "where one fill lies (95 % prediction)"
FILL = "one fill (marker: its branch)"
DISAGREE = "one realisation's mean (where they disagree)"
BRANCH_MARKERS = ("x", "+", "1", "2")  # a fill's branch 0, 1, 2, 3, then again
UNITS = {"frequency": "Hz", "amplitude": "m", "amplitude_ci": "m", "amplitude_spread": "m",
         "phase": "rad", "phase_ci": "rad", "phase_spread": "rad"}
PEAK = ("amplitude", "amplitude_ci", "frequency", "upper", "sweep")  # /frf attributes peak_*


def text(value):
    """An HDF5 string attribute as str (h5py gives bytes for fixed-length strings)."""
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value


def columns(path, group, names):
    """The named columns of an HDF5 group (/frf or /frf/fills) as arrays; None for a column
    the group lacks or holds with another length than its frequency column (older writers lack
    some columns, and an empty one is as good as missing). Exits on a column in wrong units."""
    n = group["frequency"].shape[0]
    out = {}
    for name in names:
        if name not in group or group[name].shape[0] != n:
            out[name] = None
            continue
        units, expected = text(group[name].attrs.get("units")), UNITS.get(name)
        if units is not None and expected is not None and units != expected:
            sys.exit(f"plot_frf.py: {path}: {group.name}/{name} is in '{units}', "
                     f"expected '{expected}'")
        out[name] = group[name][()]
    return out


def read_frf(path):
    """Returns a dict of the /frf columns sorted by frequency, with label, result (0, 1, 2),
    sweep (+1, -1), fills (the /frf/fills columns, or None) and peak (the /frf peak_*
    attributes without the prefix, or None); absent CIs and spreads are None."""
    try:
        with h5py.File(path, "r") as h5:
            if "frf" not in h5:
                held = ", ".join("/" + name for name in h5) or "nothing"
                kind = " (a prescribed-motion result?)" if "prescribed" in h5 else ""
                sys.exit(f"plot_frf.py: {path} has no /frf (stepped-sine FRF) group; "
                         f"it holds {held}{kind}")
            frf = h5["frf"]
            if "frequency" not in frf or "amplitude" not in frf:
                sys.exit(f"plot_frf.py: {path} has no /frf/frequency and /frf/amplitude")
            n = frf["frequency"].shape[0]
            data = columns(path, frf, ("frequency", "amplitude", "amplitude_ci",
                                       "amplitude_spread", "phase", "phase_ci", "phase_spread",
                                       "result", "converged", "sweep", "interval"))
            fills, group = None, frf.get("fills")
            if (group is not None and "frequency" in group and "amplitude" in group
                    and group["frequency"].size):
                fills = columns(path, group, ("frequency", "sweep", "branch", "amplitude",
                                              "phase"))
                m = fills["frequency"].size
                for name, fallback in (("sweep", 1), ("branch", 0), ("phase", np.nan)):
                    if fills[name] is None:
                        fills[name] = np.full(m, fallback)
                fills["sweep"] = np.where(fills["sweep"] < 0, -1, 1)
            peak = None
            if "peak_amplitude" in frf.attrs:
                peak = {name: float(frf.attrs["peak_" + name]) for name in PEAK
                        if "peak_" + name in frf.attrs}
            # Files without /frf/fills: the realisations' means from /periods instead.
            runs = (realisation_means(h5, data["frequency"], data["interval"]) if fills is None
                    else [])
            meta = h5["meta"].attrs if "meta" in h5 else {}
            title, start = text(meta.get("title")), text(meta.get("start"))
    except OSError as error:
        sys.exit(f"plot_frf.py: cannot read {path}: {error}")
    if data["phase"] is None:
        data["phase"] = np.full(n, np.nan)
    if data["result"] is None:  # files from before the column: converged, else every point
        data["result"] = data["converged"] if data["converged"] is not None else np.ones(n)
    if data["sweep"] is None:  # files from before the column: one sweep up
        data["sweep"] = np.ones(n)
    order = np.argsort(data["frequency"], kind="stable")
    data = {name: None if values is None else values[order] for name, values in data.items()}
    data["result"] = data["result"].astype(int)
    data["sweep"] = np.where(data["sweep"] < 0, -1, 1)
    data.update(fills=fills, peak=peak, runs=runs)
    data["label"] = (title or os.path.basename(path)) + (f" (start: {start})" if start else "")
    return data


def sweeps(data):
    """Yields (name, line style, rows of /frf, rows of /frf/fills or None) for each sweep
    direction in the file: up solid, down dashed, named only when the file holds both."""
    directions = [s for s in (1, -1) if (data["sweep"] == s).any()]
    for s in directions:
        both = len(directions) > 1
        fills = None if data["fills"] is None else data["fills"]["sweep"] == s
        yield (("up" if s > 0 else "down") if both else None, "--" if both and s < 0 else "-",
               data["sweep"] == s, fills)


def deck_of(path):
    """The deck a result was run from (/meta/deck), parsed."""
    with h5py.File(path, "r") as h5:
        text_ = text(h5["meta"].attrs.get("deck", "")) if "meta" in h5 else ""
    try:
        return tomllib.loads(text_)
    except tomllib.TOMLDecodeError as error:
        sys.exit(f"plot_frf.py: {path}: /meta/deck does not parse: {error}")


def force_amplitude(path):
    """The drive's force amplitude (N) of a force-driven result; exits for other inputs."""
    excitation = deck_of(path).get("excitation", {})
    if excitation.get("input", "force") != "force":
        sys.exit(f"plot_frf.py: {path}: --receptance needs input = \"force\", the deck has "
                 f"input = \"{excitation.get('input')}\"")
    return float(excitation["amplitude"])


def bare_response(path, frequency):
    """Amplitude (m) and phase (rad) of the bare single-DOF structure under the file's force."""
    deck = deck_of(path)
    structure, excitation = deck.get("structure", {}), deck.get("excitation", {})
    if structure.get("kind") != "sdof" or excitation.get("input", "force") != "force":
        sys.exit(f"plot_frf.py: {path}: --bare needs a single-DOF structure under force input")
    mass, stiffness = float(structure["mass"]), float(structure["stiffness"])
    damping = float(structure.get("damping", 2 * float(structure.get("damping_ratio", 0.0))
                                  * math.sqrt(stiffness * mass)))
    w = 2 * np.pi * frequency
    h = float(excitation["amplitude"]) / (stiffness - mass * w**2 + 1j * damping * w)
    return np.abs(h), np.angle(h)


def realisation_means(h5, frequency, interval):
    """Returns [(frequency, amplitude, phase)] of every realisation's stationary mean at the
    frequencies whose realisations disagree (interval = 2), from /periods."""
    if interval is None or "periods" not in h5 or not (interval == 2).any():
        return []
    p = {name: h5["periods"][name][()] for name in
         ("frequency", "realisation", "stationary", "amplitude", "phase")}
    harmonic = p["amplitude"] * np.exp(1j * p["phase"])
    out = []
    for f in frequency[interval == 2]:
        for r in np.unique(p["realisation"][p["frequency"] == f]):
            kept = (p["frequency"] == f) & (p["realisation"] == r) & (p["stationary"] == 1)
            if kept.any():
                mean = harmonic[kept].mean()
                out.append((f, abs(mean), np.angle(mean)))
    return out


def read_measured(path):
    """Returns (frequency_hz, amplitude_m) from a digitised CSV, sorted by frequency."""
    try:
        with open(path, encoding="utf-8") as f:
            lines = [(number, line.strip()) for number, line in enumerate(f, start=1)]
    except OSError as error:
        sys.exit(f"plot_frf.py: cannot read {path}: {error}")
    lines = [(number, line) for number, line in lines if line and not line.startswith("#")]
    if not lines or lines[0][1].replace(" ", "") != HEADER:
        sys.exit(f"plot_frf.py: {path}: first line must be the header '{HEADER}'")
    points = []
    for number, line in lines[1:]:
        try:
            frequency, amplitude = (float(field) for field in line.split(","))
        except ValueError:
            sys.exit(f"plot_frf.py: {path}:{number}: expected two numbers, got '{line}'")
        if amplitude <= 0:
            sys.exit(f"plot_frf.py: {path}:{number}: amplitude must be > 0 m, got '{line}'")
        points.append((frequency, amplitude))
    if not points:
        sys.exit(f"plot_frf.py: {path}: no data lines after the header")
    points.sort()
    return np.array([p[0] for p in points]), np.array([p[1] for p in points])


def rms_relative_difference(frequency, amplitude, measured_frequency, measured_amplitude):
    """Returns (rms relative difference, points used, points outside the simulated range)."""
    inside = (measured_frequency >= frequency[0]) & (measured_frequency <= frequency[-1])
    if not inside.any():
        return float("nan"), 0, int(inside.size)
    simulated = np.interp(measured_frequency[inside], frequency, amplitude)
    relative = (simulated - measured_amplitude[inside]) / measured_amplitude[inside]
    return float(np.sqrt(np.mean(relative**2))), int(inside.sum()), int((~inside).sum())


def plot_panel(axes, part, name, scale, color, label, line):
    """Draws one sweep of one file (part: its /frf columns) on one panel, column name
    (amplitude or phase) times scale: the band where one fill lies, result points joined and
    with error bars (diamonds of several branches), the others hollow."""
    frequency, values, result = part["frequency"], part[name] * scale, part["result"]
    ci, spread = (None if part.get(name + suffix) is None else part[name + suffix] * scale
                  for suffix in ("_ci", "_spread"))
    if spread is not None:
        finite = np.isfinite(values) & np.isfinite(spread)
        # An amplitude is never negative: the band stops at zero.
        lower = np.maximum(values - spread, 0) if name == "amplitude" else values - spread
        axes.fill_between(frequency, lower, values + spread, where=finite,
                          color=color, alpha=0.15, lw=0)
    results = result > 0
    # NaN at the points that are not results makes matplotlib break the line there, so no
    # segment ever passes through (or bridges over) a point that is not a result.
    joined = np.where(results, values, np.nan)
    axes.plot(frequency, joined, ls=line, marker="o", markevery=list(result == 1), ms=4,
              color=color, label=label)
    axes.plot(frequency[result == 2], values[result == 2], "D", ms=4.5, color=color)
    if ci is not None:
        axes.errorbar(frequency[results], values[results], yerr=ci[results], fmt="none",
                      ecolor=color, elinewidth=1, capsize=2)
    axes.plot(frequency[~results], values[~results], "o", ms=4, mfc="none", color=color)


def plot_fills(axes, frequency, values, branch, color):
    """Draws every fill's own value as a small marker whose shape is its branch."""
    shape = branch.astype(int) % len(BRANCH_MARKERS)
    for k in np.unique(shape):
        axes.plot(frequency[shape == k], values[shape == k], BRANCH_MARKERS[k], ms=4, mew=0.8,
                  alpha=0.5, color=color)


def peak_of(data):
    """The file's peak as the /frf peak_* attributes give it (amplitude, amplitude_ci,
    frequency, upper, sweep; amplitude NaN without a result point), computed from the columns
    for files without them (upper, the highest single fill, NaN without /frf/fills)."""
    if data["peak"] is not None:
        return data["peak"]
    nan = float("nan")
    results = data["result"] > 0
    if not results.any():
        return {"amplitude": nan}
    amplitude, ci, fills = data["amplitude"], data["amplitude_ci"], data["fills"]
    peak = np.flatnonzero(results)[np.argmax(amplitude[results])]
    upper = nan
    if fills is not None:
        points = set(zip(data["frequency"][results], data["sweep"][results]))
        kept = np.array([point in points for point in zip(fills["frequency"], fills["sweep"])])
        if kept.any():
            upper = max(amplitude[peak], fills["amplitude"][kept].max())
    return {"amplitude": amplitude[peak], "amplitude_ci": nan if ci is None else ci[peak],
            "frequency": data["frequency"][peak], "upper": upper, "sweep": data["sweep"][peak]}


def print_peak(path, data):
    """Prints the peak amplitude over the result points, with its CI and the highest single
    fill when known, and the highest point that is not a result when its mean is higher."""
    results, amplitude, ci = data["result"] > 0, data["amplitude"], data["amplitude_ci"]
    peak = peak_of(data)
    both = (data["sweep"] > 0).any() and (data["sweep"] < 0).any()

    def mm(value, half_width):
        spread = f" ± {half_width * 1e3:.3g}" if np.isfinite(half_width) else " (no CI)"
        return f"{value * 1e3:.4g}{spread} mm"

    def at(frequency, sweep):
        named = both and np.isfinite(sweep)
        return f"{frequency:.4g} Hz" + (f" ({'up' if sweep > 0 else 'down'} sweep)" if named
                                       else "")

    found = np.isfinite(peak["amplitude"])
    upper = peak.get("upper", float("nan"))
    if found:
        print(f"{path}: peak amplitude "
              f"{mm(peak['amplitude'], peak.get('amplitude_ci', np.nan))} at "
              f"{at(peak['frequency'], peak.get('sweep', np.nan))} over the result points"
              + (f" (highest single fill {upper * 1e3:.4g} mm)" if np.isfinite(upper) else ""))
    else:
        print(f"{path}: peak amplitude: no result point "
              f"({results.sum()} of {results.size} points are results)")
    # As frf_peak() in pdsim: the highest mean where not a result, when above the peak (or
    # there is no result), so that the hard part is never left out.
    others = np.flatnonzero(~results & np.isfinite(amplitude))
    if others.size:
        higher = others[np.argmax(amplitude[others])]
        if not found or amplitude[higher] > peak["amplitude"]:
            print(f"  higher, NOT a result: "
                  f"{mm(amplitude[higher], np.nan if ci is None else ci[higher])} at "
                  f"{at(data['frequency'][higher], data['sweep'][higher])}")


def plot_hb(amplitude_axes, phase_axes, path, scale, color):
    """The harmonic-balance branches of a pdsim predict output: lines through each branch
    number, stable roots filled, unstable hollow."""
    try:
        with h5py.File(path, "r") as h5:
            if "frf_hb" not in h5:
                sys.exit(f"plot_frf.py: {path} has no /frf_hb group (a pdsim predict output)")
            hb = columns(path, h5["frf_hb"], ["frequency", "sweep", "branch", "amplitude",
                                             "phase", "stable"])
    except OSError as error:
        sys.exit(f"plot_frf.py: cannot read {path}: {error}")
    label = f"harmonic balance ({os.path.basename(path)})"
    if hb["sweep"] is None:  # older predictions had one map, from the settled bed
        hb["sweep"] = np.zeros(len(hb["frequency"]), dtype=int)
    if (hb["sweep"] != 0).any():
        label = label[:-1] + "; ^ its map stepped up, v down)"
    # Roots from a map stepped up: solid line, triangles up; stepped down: dashed, triangles
    # down; from points run from the settled bed: solid, squares.
    styles = {0: ("-", "s"), 1: ("-", "^"), -1: ("--", "v")}
    labelled = False
    for way in (0, 1, -1):
        for branch in np.unique(hb["branch"]):
            rows = (hb["branch"] == branch) & (hb["sweep"] == way)
            if not rows.any():
                continue
            order = np.argsort(hb["frequency"][rows])
            f = hb["frequency"][rows][order]
            line, marker = styles[way]
            for axes, values, s in ((amplitude_axes, hb["amplitude"], scale),
                                    (phase_axes, hb["phase"], 1)):
                v = values[rows][order] * s
                stable = hb["stable"][rows][order] == 1
                axes.plot(f, v, line, lw=0.8, color=color,
                          label=label if axes is amplitude_axes and not labelled else None)
                axes.plot(f[stable], v[stable], marker, ms=3.5, color=color)
                axes.plot(f[~stable], v[~stable], marker, ms=3.5, mfc="none", color=color)
            labelled = True


def main(argv=None):
    parser = argparse.ArgumentParser(prog="plot_frf.py", description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="pdsim HDF5 outputs with an /frf group")
    parser.add_argument("--measured", help=f"digitised measured curve, CSV with header {HEADER}")
    parser.add_argument("--receptance", action="store_true",
                        help="amplitude per newton of drive, m/N (force input only)")
    parser.add_argument("--bare", action="store_true",
                        help="draw the bare single-DOF structure's analytic response")
    parser.add_argument("--hb", action="append", default=[],
                        help="a pdsim predict output (/frf_hb): its branches over the FRF, "
                             "stable filled, unstable hollow")
    parser.add_argument("-o", "--output", default="frf.png",
                        help="image to write; .png (200 dpi), .pdf or .svg")
    args = parser.parse_args(argv)
    extension = os.path.splitext(args.output)[1].lower()
    if extension not in FORMATS:
        sys.exit(f"plot_frf.py: {args.output}: the output must end in {', '.join(FORMATS)}")

    measured = read_measured(args.measured) if args.measured else None
    figure, (amplitude_axes, phase_axes) = plt.subplots(2, 1, sharex=True, figsize=(7, 7.5))
    shown = set()  # the legend's grey entries this figure needs
    # Displacement in mm, or receptance in um/N (the same numbers per newton).
    unit = "receptance (\u00b5m/N)" if args.receptance else "displacement amplitude (mm)"
    for index, path in enumerate(args.files):
        data = read_frf(path)
        frequency, result, fills = data["frequency"], data["result"], data["fills"]
        color = f"C{index % 10}"
        scale = 1e6 / force_amplitude(path) if args.receptance else 1e3

        if args.bare and index == 0:
            dense = np.linspace(frequency.min(), frequency.max(), 400)
            amplitude, phase = bare_response(path, dense)
            amplitude_axes.plot(dense, amplitude * scale, "k-", lw=0.8,
                                label="bare structure (analytic)")
            phase_axes.plot(dense, phase, "k-", lw=0.8)
        print_peak(path, data)
        for name, line, rows, fill_rows in sweeps(data):
            label = data["label"] + (f" ({name})" if name else "")
            part = {key: values[rows] for key, values in data.items()
                    if isinstance(values, np.ndarray)}
            plot_panel(amplitude_axes, part, "amplitude", scale, color, label, line)
            plot_panel(phase_axes, part, "phase", 1, color, None, line)
            if fills is not None:
                plot_fills(amplitude_axes, fills["frequency"][fill_rows],
                           fills["amplitude"][fill_rows] * scale, fills["branch"][fill_rows],
                           color)
                plot_fills(phase_axes, fills["frequency"][fill_rows], fills["phase"][fill_rows],
                           fills["branch"][fill_rows], color)
            if measured is not None:
                where = path + (f" ({name})" if name else "")
                kept = rows & (result > 0)
                if not kept.any():
                    print(f"{where}: RMS relative difference to {args.measured}: no result "
                          f"point to compare")
                    continue
                rms, used, outside = rms_relative_difference(
                    frequency[kept], data["amplitude"][kept], *measured)
                print(f"{where}: RMS relative difference to {args.measured}: {rms:.4g} "
                      f"({used} measured points, {outside} outside {frequency[kept][0]:.4g}-"
                      f"{frequency[kept][-1]:.4g} Hz left out; result points only)")
        spread = data["amplitude_spread"]
        shown |= {NOT_RESULT} if (result == 0).any() else set()
        shown |= {BRANCHED} if (result == 2).any() else set()
        shown |= {SPREAD} if spread is not None and np.isfinite(spread).any() else set()
        shown |= {FILL} if fills is not None else set()
        for f, amplitude, phase in data["runs"]:
            amplitude_axes.plot(f, amplitude * scale, "x", ms=4, color=color)
            phase_axes.plot(f, phase, "x", ms=4, color=color)
            shown.add(DISAGREE)
    for index, path in enumerate(args.hb):
        plot_hb(amplitude_axes, phase_axes, path,
                1e6 / force_amplitude(path) if args.receptance else 1e3, f"C{(index + 5) % 10}")
    if measured is not None:
        measured_scale = 1e6 / force_amplitude(args.files[0]) if args.receptance else 1e3
        amplitude_axes.plot(measured[0], measured[1] * measured_scale, "ks--", mfc="none",
                            label="measured")
    handles, labels = amplitude_axes.get_legend_handles_labels()
    # One grey entry each for all files: the markers and the band mean the same whatever the
    # colour.
    grey = "0.4"
    for entry, handle in (
            (NOT_RESULT, Line2D([], [], ls="none", marker="o", ms=4, mfc="none", color=grey)),
            (BRANCHED, Line2D([], [], ls="none", marker="D", ms=4.5, color=grey)),
            (SPREAD, Patch(color=grey, alpha=0.25, lw=0)),
            (FILL, Line2D([], [], ls="none", marker="x", ms=4, mew=0.8, color=grey)),
            (DISAGREE, Line2D([], [], ls="none", marker="x", ms=4, color=grey))):
        if entry in shown:
            handles.append(handle)
            labels.append(entry)
    # Below the panels, where it covers no data.
    legend = figure.legend(handles, labels, loc="lower center", ncol=2, fontsize="small",
                           frameon=False)
    amplitude_axes.set_ylabel(unit)
    phase_axes.set_ylabel("phase (rad)")
    phase_axes.set_xlabel("frequency (Hz)")
    for axes in (amplitude_axes, phase_axes):
        axes.grid(True, alpha=0.3)
    amplitude_axes.set_title("first harmonic, mean over the fills; error bars: its 95 % "
                             "confidence", fontsize="small")
    figure.canvas.draw()  # sizes the legend
    figure.tight_layout(rect=(0, legend.get_window_extent().height / figure.bbox.height, 1, 1))
    figure.savefig(args.output, dpi=200)
    plt.close(figure)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
