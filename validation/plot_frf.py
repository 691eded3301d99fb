#!/usr/bin/python3
"""Plot stepped-sine frequency responses (/frf) of pdsim runs, optionally against a measured curve.

Usage: validation/plot_frf.py OUT.h5 [OTHER.h5 ...] [--measured CSV] [-o frf.png]

Plots the first-harmonic displacement amplitude (mm) against frequency (Hz) for each file,
labelled by the /meta attribute `title` or else the file name; frequencies whose response did
not converge (/frf/converged = 0) are drawn as open markers. Prints each file's peak amplitude
and its frequency.

--measured CSV: a digitised measured curve (e.g. Saeki 2002, fig. 5b), plain text, comma
separated, first line exactly the header `frequency_hz,amplitude_m`, then one point per line
in SI units (Hz, m, amplitude > 0); lines starting with '#' are comments. Example:
    frequency_hz,amplitude_m
    # Saeki (2002) fig. 5b, 250 particles, digitised by hand
    12.0,0.00051
    15.2,0.00230
For each file the script then prints the RMS relative difference
sqrt(mean(((sim - meas) / meas)^2)), with the simulated amplitude interpolated linearly at the
measured frequencies; measured points outside a file's frequency range are left out and counted.
"""
import argparse
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import h5py  # noqa: E402

HEADER = "frequency_hz,amplitude_m"


def read_frf(path):
    """Returns (label, frequency_hz, amplitude_m, converged) sorted by frequency."""
    try:
        with h5py.File(path, "r") as h5:
            if "frf/frequency" not in h5 or "frf/amplitude" not in h5:
                sys.exit(f"plot_frf.py: {path} has no /frf/frequency and /frf/amplitude")
            frequency = h5["frf/frequency"][()]
            amplitude = h5["frf/amplitude"][()]
            converged = h5["frf/converged"][()] if "frf/converged" in h5 else np.ones(
                frequency.shape, dtype=int)
            title = h5["meta"].attrs.get("title") if "meta" in h5 else None
    except OSError as error:
        sys.exit(f"plot_frf.py: cannot read {path}: {error}")
    if isinstance(title, bytes):
        title = title.decode("utf-8", "replace")
    order = np.argsort(frequency)
    return (title or os.path.basename(path), frequency[order], amplitude[order],
            converged[order].astype(bool))


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


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", help="pdsim HDF5 outputs with an /frf group")
    parser.add_argument("--measured", help=f"digitised measured curve, CSV with header {HEADER}")
    parser.add_argument("-o", "--output", default="frf.png", help="image to write")
    args = parser.parse_args()

    measured = read_measured(args.measured) if args.measured else None
    figure, axes = plt.subplots(figsize=(7, 4.5))
    for path in args.files:
        label, frequency, amplitude, converged = read_frf(path)
        line, = axes.plot(frequency, amplitude * 1e3, "-", label=label)
        color = line.get_color()
        axes.plot(frequency[converged], amplitude[converged] * 1e3, "o", ms=4, color=color)
        axes.plot(frequency[~converged], amplitude[~converged] * 1e3, "o", ms=4, mfc="none",
                  color=color)
        peak = int(np.argmax(amplitude))
        print(f"{path}: peak amplitude {amplitude[peak] * 1e3:.4g} mm at {frequency[peak]:.4g} Hz")
        if measured is not None:
            rms, used, outside = rms_relative_difference(frequency, amplitude, *measured)
            print(f"{path}: RMS relative difference to {args.measured}: {rms:.4g} "
                  f"({used} measured points, {outside} outside {frequency[0]:.4g}-"
                  f"{frequency[-1]:.4g} Hz left out)")
    if measured is not None:
        axes.plot(measured[0], measured[1] * 1e3, "ks--", mfc="none", label="measured")
    axes.set_xlabel("frequency (Hz)")
    axes.set_ylabel("displacement amplitude (mm)")
    axes.grid(True, alpha=0.3)
    axes.legend()
    figure.tight_layout()
    figure.savefig(args.output, dpi=150)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
