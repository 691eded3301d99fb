#!/usr/bin/python3
"""Plot stepped-sine frequency responses (/frf) of pdsim runs, optionally against a measured curve.

Usage: validation/plot_frf.py OUT.h5 [OTHER.h5 ...] [--measured CSV] [--receptance] [--bare]
                              [-o frf.png]
(also `validation/plot.py frf ...`, with the other plots of a result)

Draws two stacked panels sharing the frequency axis (Hz): the first-harmonic displacement
amplitude (mm, /frf/amplitude) and its phase against the input sin(angle) (rad, /frf/phase, as
stored), one colour per file, labelled by the /meta attribute `title` (else the file name) and
the /meta attribute `start` (predicted, carried or independent) when present.
- Converged points (/frf/converged = 1) are filled markers with 95 % confidence error bars
  (± /frf/amplitude_ci, ± /frf/phase_ci), joined by a line only between neighbouring converged
  points: the line breaks wherever an unconverged point lies between them.
- Unconverged points (/frf/converged = 0) are not results: hollow markers, no line, no error
  bars, one legend entry "not converged (not a result)".
- Where several realisations disagree (/frf/interval = 2: coexisting regimes of the bed, the
  interval is the spread of their means), each realisation's own mean (over its stationary
  periods in /periods) is drawn as a small cross at that frequency, to show the regimes.
Files written before the _ci columns existed (or with NaN CIs) get no error bars for those points.
The output format follows the extension of -o: .png (200 dpi), .pdf or .svg (vector).

Prints for each file its peak amplitude over the converged points, with its confidence
half-width, e.g. "peak amplitude 1.408 ± 0.012 mm at 15 Hz (converged points only)", or
"no converged point". A file without /frf (e.g. a prescribed-motion result, /prescribed) is an
error (exit status 1).

--receptance: amplitude per newton of drive (m/N, /meta/deck's excitation.amplitude), for
force input only; files driven otherwise are an error.
--bare: the bare structure's analytic response (single-DOF structures under force input, from
the first file's deck: mass, stiffness and damping), drawn as a thin black line.

--measured CSV: a digitised measured curve (e.g. Saeki 2002, fig. 5b), plain text, comma
separated, first line exactly the header `frequency_hz,amplitude_m`, then one point per line
in SI units (Hz, m, amplitude > 0); lines starting with '#' are comments. Example:
    frequency_hz,amplitude_m
    # Saeki (2002) fig. 5b, 250 particles, digitised by hand
    12.0,0.00051
    15.2,0.00230
It is drawn on the amplitude panel. For each file the script then prints the RMS relative
difference sqrt(mean(((sim - meas) / meas)^2)), with the simulated amplitude interpolated
linearly at the measured frequencies between the file's converged points only; measured points
outside the frequency range of the converged points are left out and counted.
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
import numpy as np  # noqa: E402
import h5py  # noqa: E402

HEADER = "frequency_hz,amplitude_m"
FORMATS = (".png", ".pdf", ".svg")
NOT_CONVERGED = "not converged (not a result)"
DISAGREE = "one realisation's mean (where they disagree)"


def text(value):
    """An HDF5 string attribute as str (h5py gives bytes for fixed-length strings)."""
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value


def read_frf(path):
    """Returns a dict of the /frf columns sorted by frequency, with label; absent CIs are None."""
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

            def column(name):
                # Older writers lack some columns, and an empty one is as good as missing.
                if name not in frf or frf[name].shape[0] != n:
                    return None
                units = text(frf[name].attrs.get("units"))
                expected = {"frequency": "Hz", "amplitude": "m", "amplitude_ci": "m",
                            "phase": "rad", "phase_ci": "rad"}.get(name)
                if units is not None and expected is not None and units != expected:
                    sys.exit(f"plot_frf.py: {path}: /frf/{name} is in '{units}', "
                             f"expected '{expected}'")
                return frf[name][()]

            data = {name: column(name) for name in ("frequency", "amplitude", "amplitude_ci",
                                                    "phase", "phase_ci", "converged", "interval")}
            data["runs"] = realisation_means(h5, data["frequency"], data["interval"])
            meta = h5["meta"].attrs if "meta" in h5 else {}
            title, start = text(meta.get("title")), text(meta.get("start"))
    except OSError as error:
        sys.exit(f"plot_frf.py: cannot read {path}: {error}")
    if data["phase"] is None:
        data["phase"] = np.full(n, np.nan)
    if data["converged"] is None:  # files from before the column: every point counted
        data["converged"] = np.ones(n, dtype=int)
    runs = data.pop("runs")
    order = np.argsort(data["frequency"])
    data = {name: None if values is None else values[order] for name, values in data.items()}
    data["runs"] = runs
    data["converged"] = data["converged"].astype(bool)
    data["label"] = (title or os.path.basename(path)) + (f" (start: {start})" if start else "")
    return data


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


def plot_panel(axes, frequency, values, ci, converged, color, label):
    """Draws one file on one panel: converged points joined and with error bars, others hollow."""
    # NaN at the unconverged points makes matplotlib break the line there, so no segment
    # ever passes through (or bridges over) a point that is not a result.
    joined = np.where(converged, values, np.nan)
    axes.plot(frequency, joined, "o-", ms=4, color=color, label=label)
    if ci is not None:
        axes.errorbar(frequency[converged], values[converged], yerr=ci[converged], fmt="none",
                      ecolor=color, elinewidth=1, capsize=2)
    axes.plot(frequency[~converged], values[~converged], "o", ms=4, mfc="none", color=color)


def print_peak(path, data):
    """Prints the peak amplitude over the converged points, with its CI when the file has one."""
    converged = data["converged"]
    if not converged.any():
        print(f"{path}: peak amplitude: no converged point "
              f"(0 of {converged.size} frequencies converged)")
        return
    indices = np.flatnonzero(converged)
    peak = indices[np.argmax(data["amplitude"][indices])]
    ci = data["amplitude_ci"]
    spread = (f" ± {ci[peak] * 1e3:.2g}" if ci is not None and np.isfinite(ci[peak])
              else " (no CI)")
    print(f"{path}: peak amplitude {data['amplitude'][peak] * 1e3:.4g}{spread} mm at "
          f"{data['frequency'][peak]:.4g} Hz (converged points only)")


def main(argv=None):
    parser = argparse.ArgumentParser(prog="plot_frf.py", description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="pdsim HDF5 outputs with an /frf group")
    parser.add_argument("--measured", help=f"digitised measured curve, CSV with header {HEADER}")
    parser.add_argument("--receptance", action="store_true",
                        help="amplitude per newton of drive, m/N (force input only)")
    parser.add_argument("--bare", action="store_true",
                        help="draw the bare single-DOF structure's analytic response")
    parser.add_argument("-o", "--output", default="frf.png",
                        help="image to write; .png (200 dpi), .pdf or .svg")
    args = parser.parse_args(argv)
    extension = os.path.splitext(args.output)[1].lower()
    if extension not in FORMATS:
        sys.exit(f"plot_frf.py: {args.output}: the output must end in {', '.join(FORMATS)}")

    measured = read_measured(args.measured) if args.measured else None
    figure, (amplitude_axes, phase_axes) = plt.subplots(2, 1, sharex=True, figsize=(7, 6.5))
    any_unconverged = any_disagree = False
    # Displacement in mm, or receptance in um/N (the same numbers per newton).
    unit = "receptance (\u00b5m/N)" if args.receptance else "displacement amplitude (mm)"
    for index, path in enumerate(args.files):
        data = read_frf(path)
        frequency, converged = data["frequency"], data["converged"]
        color = f"C{index % 10}"
        ci = data["amplitude_ci"]
        scale = 1e6 / force_amplitude(path) if args.receptance else 1e3
        plot_panel(amplitude_axes, frequency, data["amplitude"] * scale,
                   None if ci is None else ci * scale, converged, color, data["label"])
        if args.bare and index == 0:
            dense = np.linspace(frequency.min(), frequency.max(), 400)
            amplitude, phase = bare_response(path, dense)
            bare_scale = 1e6 / force_amplitude(path) if args.receptance else 1e3
            amplitude_axes.plot(dense, amplitude * bare_scale, "k-", lw=0.8,
                                label="bare structure (analytic)")
            phase_axes.plot(dense, phase, "k-", lw=0.8)
        plot_panel(phase_axes, frequency, data["phase"], data["phase_ci"], converged, color, None)
        any_unconverged |= bool((~converged).any())
        for f, amplitude, phase in data["runs"]:
            amplitude_axes.plot(f, amplitude * scale, "x", ms=4, color=color)
            phase_axes.plot(f, phase, "x", ms=4, color=color)
        any_disagree = any_disagree or bool(data["runs"])
        print_peak(path, data)
        if measured is not None:
            if not converged.any():
                print(f"{path}: RMS relative difference to {args.measured}: no converged point "
                      f"to compare")
                continue
            kept = frequency[converged]
            rms, used, outside = rms_relative_difference(kept, data["amplitude"][converged],
                                                         *measured)
            print(f"{path}: RMS relative difference to {args.measured}: {rms:.4g} "
                  f"({used} measured points, {outside} outside {kept[0]:.4g}-"
                  f"{kept[-1]:.4g} Hz left out; converged points only)")
    if measured is not None:
        measured_scale = 1e6 / force_amplitude(args.files[0]) if args.receptance else 1e3
        amplitude_axes.plot(measured[0], measured[1] * measured_scale, "ks--", mfc="none",
                            label="measured")
    handles, labels = amplitude_axes.get_legend_handles_labels()
    if any_unconverged:
        # One grey entry for all files: the hollow marker means the same whatever the colour.
        handles.append(Line2D([], [], ls="none", marker="o", ms=4, mfc="none", color="0.4"))
        labels.append(NOT_CONVERGED)
    if any_disagree:
        handles.append(Line2D([], [], ls="none", marker="x", ms=4, color="0.4"))
        labels.append(DISAGREE)
    amplitude_axes.legend(handles, labels, fontsize="small")
    amplitude_axes.set_ylabel(unit)
    phase_axes.set_ylabel("phase (rad)")
    phase_axes.set_xlabel("frequency (Hz)")
    for axes in (amplitude_axes, phase_axes):
        axes.grid(True, alpha=0.3)
    amplitude_axes.set_title("first harmonic; error bars: 95 % confidence", fontsize="small")
    figure.tight_layout()
    figure.savefig(args.output, dpi=200)
    plt.close(figure)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
