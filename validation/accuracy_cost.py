#!/usr/bin/python3
"""Accuracy against cost of pdsim's speed settings, each measured against its finest setting.

Usage: validation/accuracy_cost.py [--pdsim build/pdsim] [--studies 1,2,3,4,5] [--realisations 5]
                                   [-o MD] [--keep]

Five studies, each a table with one row per setting: dt, the wall time (/meta wall_time_s), the
CPU time of the process (steadier than wall time on a shared machine), the speed-ups against the
reference row and the accuracy metric against the reference (finest) row.
  1. contact softening: Hertz young 2e11 .. 2e8 on the shaken box (dt follows the Rayleigh time);
     relative change of /prescribed/dissipated_power and force_amplitude against 2e11.
  2. time step: solver.dt_safety 0.05 .. 0.35 on the shaken box with young 2e10; same metrics
     against 0.05.
  3. coupling: the single-ball impact damper in free decay, scheme loose/interleaved/tight and
     coupling.every 1/5/20; max |x - x_ref| / x0 against tight, every 1, dt_safety 0.005.
  4. steady-state tolerance: a small stepped sine, settle.tolerance 0.1 .. 0.005; max relative
     first-harmonic amplitude difference over the frequencies against 0.005, how many of those
     differences lie within both 95 % intervals, and the periods used.
  5. the step's own error: the energy ledger's force-driven sine (tests/src/energy_ledger_test.cpp:
     24 spheres on an SDOF, friction, rolling resistance, gravity) with Hertz and with linear
     contacts, solver.dt_safety 0.3 .. 0.0375; the largest |/energy/imbalance| over the work put
     in, and its order in dt, with friction (history or directional) and without. The step is
     velocity Verlet as LAMMPS runs it (tests/kernels/contact_normal_test.cpp), so this is what
     a second-order step leaves.
The shaken box is chaotic and 4 averaged periods scatter by about 10 % from run to run, so each
shaken-box setting is run --realisations times with dt_safety changed by 1-3 % (a new trajectory,
no measurable bias) and reported as mean, standard deviation and the standard error of the change;
study 4 adds a second realisation of its reference (another fill seed) as the metric's noise floor.
Every run uses --threads 1. A run that exits with code 2 (simulation failure, e.g. a blow-up) is
recorded as "blew up" and the study goes on. The tables are printed and written, with the date,
the machine, the pdsim version and the command, to validation/results/accuracy_cost.md.
"""
import argparse
import datetime
import math
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

import h5py
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

# examples/shaken_box.toml with a 0.3 s run averaged over its last 4 periods (of 20 Hz).
SHAKEN_BOX = """\
title = "shaken box, accuracy-cost study"
[[damper]]
container = {{ shape = "box", size = [0.04, 0.04, 0.04] }}
particles = {{ count = 196, diameter = 0.005, density = 7800.0, fill = "lattice" }}
[contact]
model = "hertz"
tangential = "history"
young = {young!r}
poisson = 0.3
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "prescribed"
motion = {{ axis = [1.0, 0.0, 0.0], amplitude = 0.004, frequency = 20.0 }}
duration = 0.3
settle = {{ average_periods = 4 }}
[solver]
dt = "auto"
dt_safety = {dt_safety!r}
"""

# Masri & Caughey's impact damper as in tests/src/coupling_test.cpp: one 30 mm steel ball of
# 0.110 kg in a slot of 10 mm clearance along x, no gravity, no friction.
BALL_DIAMETER = 0.03  # m
BALL_DENSITY = 0.110 / (math.pi / 6 * BALL_DIAMETER**3)  # kg/m^3, a 0.110 kg ball
DECAY_START = 0.008  # m, initial displacement of the free decay
IMPACT_DAMPER = """\
title = "impact damper free decay, accuracy-cost study"
[structure]
kind = "sdof"
mass = 2.37
stiffness = 21500.0
damping_ratio = 0.01
direction = [1.0, 0.0, 0.0]
[[damper]]
container = {{ shape = "box", size = [0.04, 0.036, 0.036] }}
particles = {{ count = 1, diameter = 0.03, density = {density!r}, fill = "lattice" }}
[contact]
model = "linear"
tangential = "none"
stiffness = 1e8
restitution = 0.6
[excitation]
kind = "free_decay"
initial_displacement = {x0!r}
duration = 0.3
[coupling]
scheme = "{scheme}"
every = {every}
[solver]
dt = "auto"
dt_safety = {dt_safety!r}
[output]
every = 1e-4
"""

# tests/decks/tiny_stepped_sine.toml with five frequencies and room to settle.
TINY_STEPPED_SINE = """\
title = "tiny stepped sine, accuracy-cost study"
[structure]
kind = "sdof"
mass = 0.5
stiffness = 5000.0
damping_ratio = 0.02
[[damper]]
container = {{ shape = "box", size = [0.02, 0.02, 0.02] }}
particles = {{ count = 20, diameter = 0.004, density = 7800.0, seed = {seed!r} }}
[contact]
model = "linear"
tangential = "history"
stiffness = 2000.0
young = 2.0e8
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "stepped_sine"
amplitude = 1.0
frequencies = {{ start = 13.0, stop = 17.0, step = 1.0 }}
settle = {{ min_periods = 10, max_periods = 400, tolerance = {tolerance!r} }}
[coupling]
scheme = "tight"
[solver]
dt_safety = {dt_safety!r}
"""


def read_datasets(path):
    """Every dataset of an HDF5 file by its path ("frf/amplitude"), plus wall_s and dt."""
    data = {}
    with h5py.File(path, "r") as h5:
        h5.visititems(lambda name, item: data.__setitem__(name, item[()])
                      if isinstance(item, h5py.Dataset) else None)
        data["wall_s"] = float(h5["meta"].attrs["wall_time_s"])
        data["dt"] = float(h5["meta"].attrs["dt"])
    return data


def run_deck(pdsim, workdir, name, text):
    """Runs one deck; returns a dict: rc, cpu_s, error, data (read_datasets, None on failure)."""
    deck = os.path.join(workdir, name + ".toml")
    out = os.path.join(workdir, name + ".h5")
    with open(deck, "w", encoding="utf-8") as f:
        f.write(text)
    # The process's own CPU time (os.wait4), so that runs may go side by side in threads.
    with tempfile.TemporaryFile("w+", encoding="utf-8") as log:
        proc = subprocess.Popen([pdsim, "run", deck, "--quiet", "--threads", "1", "--force", "-o",
                                 out], stdout=log, stderr=subprocess.STDOUT)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        log.seek(0)
        output = log.read()
    cpu = usage.ru_utime + usage.ru_stime
    run = {"name": name, "rc": proc.returncode, "cpu_s": cpu, "data": None, "error": None}
    if proc.returncode != 0:
        message = output.strip().splitlines()
        run["error"] = message[-1] if message else ""
        print(f"  {name}: exit {proc.returncode}: {run['error']}", file=sys.stderr)
        return run
    run["data"] = read_datasets(out)
    print(f"  {name}: {run['data']['wall_s']:.2f} s wall, {cpu:.2f} s CPU", file=sys.stderr)
    return run


def failure_text(run):
    return "blew up" if run["rc"] == 2 else f"failed (exit {run['rc']})"


def relative(value, reference):
    return (value - reference) / reference


def percent(x):
    return f"{100 * x:+.2f} %"


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


COST_HEADER = ["dt (s)", "wall (s)", "CPU (s)", "speed-up (wall)", "speed-up (CPU)"]


def cost_cells(run, reference):
    """COST_HEADER cells; blanks and a failure note for a failed run."""
    if run["data"] is None:
        return ["-", "-", f"{run['cpu_s']:.2f}", failure_text(run), "-"]
    wall, cpu = run["data"]["wall_s"], run["cpu_s"]
    wall_speedup = cpu_speedup = "-"
    if reference["data"] is not None and wall > 0 and cpu > 0:
        wall_speedup = f"{reference['data']['wall_s'] / wall:.2f}"
        cpu_speedup = f"{reference['cpu_s'] / cpu:.2f}"
    return [f"{run['data']['dt']:.3g}", f"{wall:.2f}", f"{cpu:.2f}", wall_speedup, cpu_speedup]


JITTER = (1.0, 0.99, 1.01, 0.98, 1.02, 0.97, 1.03)  # dt_safety factors, one per realisation


def shaken_box_runs(pdsim, workdir, name, young, dt_safety, realisations):
    """Realisations of one shaken-box setting, dt_safety scaled by JITTER: a 1 % change in dt
    biases nothing measurably, but the granular motion is chaotic, so each is a new trajectory."""
    runs = []
    for factor in JITTER[:realisations]:
        text = SHAKEN_BOX.format(young=young, dt_safety=dt_safety * factor)
        runs.append(run_deck(pdsim, workdir, f"{name}_x{factor:g}", text))
    return runs


def mean_sd(values):
    values = np.asarray(values, dtype=float)
    sd = float(np.std(values, ddof=1)) if values.size > 1 else float("nan")
    return float(np.mean(values)), sd


def change_text(values, reference_values):
    """(mean - ref mean) / ref mean, +- the standard error of that difference of means."""
    mean, sd = mean_sd(values)
    ref_mean, ref_sd = mean_sd(reference_values)
    error = np.sqrt(sd**2 / len(values) + ref_sd**2 / len(reference_values)) / ref_mean
    return f"{100 * (mean - ref_mean) / ref_mean:+.1f} ± {100 * error:.1f} %"


def prescribed_rows(settings, label):
    """Rows of a shaken-box study; settings = [(setting, runs)], the first the reference."""
    reference = [run for run in settings[0][1] if run["data"] is not None]
    ref_wall = np.mean([run["data"]["wall_s"] for run in reference]) if reference else None
    ref_cpu = np.mean([run["cpu_s"] for run in reference]) if reference else None
    rows = []
    for setting, runs in settings:
        done = [run for run in runs if run["data"] is not None]
        failed = [run for run in runs if run["data"] is None]
        cells = [label(setting)]
        if failed:
            cells[0] += f" ({failure_text(failed[0])} in {len(failed)} of {len(runs)} runs)"
        if not done or not reference:
            rows.append(cells + ["-"] * 9)
            continue
        wall = np.mean([run["data"]["wall_s"] for run in done])
        cpu = np.mean([run["cpu_s"] for run in done])
        power = [float(run["data"]["prescribed/dissipated_power"][0]) for run in done]
        force = [float(run["data"]["prescribed/force_amplitude"][0]) for run in done]
        ref_power = [float(run["data"]["prescribed/dissipated_power"][0]) for run in reference]
        ref_force = [float(run["data"]["prescribed/force_amplitude"][0]) for run in reference]
        cells += [f"{done[0]['data']['dt']:.3g}", f"{wall:.2f}", f"{cpu:.2f}",
                  f"{ref_wall / wall:.2f}", f"{ref_cpu / cpu:.2f}"]
        is_reference = runs is settings[0][1]
        cells += ["{:.3f} ± {:.3f}".format(*mean_sd(power)),
                  "reference" if is_reference else change_text(power, ref_power),
                  "{:.3f} ± {:.3f}".format(*mean_sd(force)),
                  "reference" if is_reference else change_text(force, ref_force)]
        rows.append(cells)
    return rows


PRESCRIBED_HEADER = COST_HEADER + ["power (W), mean ± sd", "power change ± se",
                                   "force amp. (N), mean ± sd", "force change ± se"]
PRESCRIBED_NOTE = ("Each row is the mean of {n} realisations with dt_safety scaled by {factors}"
                   " (the granular motion is chaotic: these 1 % changes give new trajectories and"
                   " no measurable bias); times are the mean per run, sd the sample standard"
                   " deviation over the realisations, se the standard error of the difference"
                   " of the two means. A change within about 2 se of zero is not resolved by"
                   " this run length.")


def study_softening(pdsim, workdir, realisations):
    settings = [(young, shaken_box_runs(pdsim, workdir, f"soften_{young:.0e}", young, 0.15,
                                        realisations)) for young in (2e11, 2e10, 2e9, 2e8)]
    rows = prescribed_rows(settings, lambda young: f"young {young:.0e} Pa")
    note = PRESCRIBED_NOTE.format(n=realisations, factors=", ".join(
        f"{f:g}" for f in JITTER[:realisations]))
    return ("1. Contact softening (shaken box, 196 spheres, 4 mm at 20 Hz, 0.3 s, last 4 periods;"
            " dt = 0.15 x Rayleigh time; reference young = 2e11 Pa, real steel)",
            table(["setting"] + PRESCRIBED_HEADER, rows) + "\n\n" + note)


def study_time_step(pdsim, workdir, realisations):
    settings = [(safety, shaken_box_runs(pdsim, workdir, f"dt_{safety:g}", 2e10, safety,
                                         realisations)) for safety in (0.05, 0.1, 0.15, 0.25, 0.35)]
    rows = prescribed_rows(settings, lambda safety: f"dt_safety {safety:g}" +
                           (" (default)" if safety == 0.15 else ""))
    note = PRESCRIBED_NOTE.format(n=realisations, factors=", ".join(
        f"{f:g}" for f in JITTER[:realisations]))
    return ("2. Time step (shaken box as in 1 with young = 2e10 Pa; dt = dt_safety x Rayleigh time;"
            " reference dt_safety = 0.05)",
            table(["setting"] + PRESCRIBED_HEADER, rows) + "\n\n" + note)


def decay_error(run, reference):
    """max |x(t) - x_ref(t)| / x0, the reference interpolated at the run's sample times."""
    t = run["data"]["timeseries/time"]
    x = run["data"]["timeseries/displacement"]
    t_ref = reference["data"]["timeseries/time"]
    x_ref = reference["data"]["timeseries/displacement"]
    inside = t <= t_ref[-1]
    return float(np.max(np.abs(x[inside] - np.interp(t[inside], t_ref, x_ref)))) / DECAY_START


def study_coupling(pdsim, workdir, realisations):
    def deck(scheme, every, safety):
        return IMPACT_DAMPER.format(density=BALL_DENSITY, x0=DECAY_START, scheme=scheme,
                                    every=every, dt_safety=safety)

    reference = run_deck(pdsim, workdir, "coupling_reference", deck("tight", 1, 0.005))
    runs = [(("tight", 1, 0.005), reference)]
    for scheme, every in (("tight", 1), ("interleaved", 1), ("interleaved", 5),
                          ("interleaved", 20), ("loose", 1), ("loose", 5), ("loose", 20)):
        name = f"coupling_{scheme}_{every}"
        runs.append(((scheme, every, 0.02), run_deck(pdsim, workdir, name, deck(scheme, every,
                                                                             0.02))))
    rows = []
    for (scheme, every, safety), run in runs:
        cells = [f"{scheme}, every {every}, dt_safety {safety:g}"] + cost_cells(run, reference)
        ok = run["data"] is not None and reference["data"] is not None
        if not ok:
            rows.append(cells + ["-"])
            continue
        error = "reference" if run is reference else percent(decay_error(run, reference))
        rows.append(cells + [error.lstrip("+")])
    return ("3. Coupling (single-ball impact damper, free decay from 8 mm over 0.3 s; dt ="
            " dt_safety x linear contact time; reference tight, every 1, dt_safety 0.005)",
            table(["setting"] + COST_HEADER + ["max abs(x - x_ref) / x0"], rows) +
            "\n\nThe tight row at dt_safety 0.02 isolates the error of the DEM time step; the"
            " other rows add the coupling's. One exchange every 20 steps is"
            f" {20 * 0.02:g} of the contact time. The structure here is one DOF and one ball, so"
            " an exchange costs next to nothing and the speed-up of coupling.every is not shown by"
            " this scene. The coupling tests (tests/src/coupling_test.cpp) also hold every scheme"
            " at every = 1 (dt_safety 0.02) within 3 % of x0 of an exact event-driven model of"
            " this impact damper (tests/support/impact_damper_exact.hpp).")


def study_tolerance(pdsim, workdir, realisations):
    del realisations  # one run per tolerance, and one second realisation (fill) of the reference
    runs = []
    for tolerance in (5e-3, 1e-2, 2e-2, 5e-2, 1e-1):
        text = TINY_STEPPED_SINE.format(tolerance=tolerance, dt_safety=0.02, seed=3)
        label = f"tolerance {tolerance:g}" + (" (default)" if tolerance == 2e-2 else "")
        runs.append((label, run_deck(pdsim, workdir, f"settle_{tolerance:g}", text)))
    # another fill (seed): a new trajectory of the chaotic particles, the noise floor of the metric
    text = TINY_STEPPED_SINE.format(tolerance=5e-3, dt_safety=0.02, seed=4)
    runs.append(("tolerance 0.005, fill seed 4 (a second realisation of the reference)",
                 run_deck(pdsim, workdir, "settle_0.005_seed4", text)))
    reference = runs[0][1]
    rows = []
    for label, run in runs:
        cells = [label] + cost_cells(run, reference)
        if run["data"] is None or reference["data"] is None:
            rows.append(cells + ["-"] * 4)
            continue
        frf, ref = run["data"], reference["data"]
        difference = np.abs(frf["frf/amplitude"] - ref["frf/amplitude"])
        worst = np.max(difference / ref["frf/amplitude"])
        # Within the two 95 % intervals combined: the difference is not resolved.
        within = difference <= np.hypot(frf["frf/amplitude_ci"], ref["frf/amplitude_ci"])
        rows.append(cells + ["reference" if run is reference else percent(worst).lstrip("+"),
                             "-" if run is reference else f"{int(within.sum())} / {within.size}",
                             str(int(np.sum(frf["frf/periods"]))),
                             f"{int(np.sum(frf['frf/converged']))} / {frf['frf/converged'].size}"])
    periods = ", ".join(f"{f:g} Hz: {int(n)}{'' if c else ' (not converged)'}" for f, n, c in zip(
        reference["data"]["frf/frequency"], reference["data"]["frf/periods"],
        reference["data"]["frf/converged"])) if reference["data"] is not None else "-"
    return ("4. Steady-state tolerance (tiny stepped sine, 20 spheres, tight coupling, 13..17 Hz"
            " step 1, predicted starts, 10 to 400 periods; reference tolerance 0.005)",
            table(["setting"] + COST_HEADER + ["max rel. amplitude diff.",
                                             "diff. within both 95 % intervals",
                                             "periods (sum)", "converged"], rows) +
            f"\n\nPeriods per frequency of the reference: {periods}. `settle.tolerance` bounds"
            " the relative 95 % half-width of each amplitude; a difference within both"
            " intervals combined is not resolved. The last row is another fill (seed) at the"
            " reference tolerance: its difference is the noise floor of the metric.")


# tests/src/energy_ledger_test.cpp's force-driven sine: 24 spheres on an SDOF, 0.4 s at 15 Hz.
LEDGER_SINE = """\
title = "energy ledger sine, accuracy-cost study"
[structure]
kind = "sdof"
mass = 0.5
stiffness = 5000.0
damping_ratio = 0.02
direction = [1.0, 0.0, 0.0]
[[damper]]
container = {{ shape = "box", size = [0.02, 0.02, 0.02] }}
particles = {{ count = 24, diameter = 0.004, density = 7800.0, seed = 3 }}
[contact]
model = "{model}"
tangential = "history"
stiffness = 2000.0
young = 2.0e8
restitution = 0.5
friction = 0.3
rolling_friction = 0.02
[gravity]
vector = [0.0, 0.0, -9.81]
[bed]
settle = false
[excitation]
kind = "sine"
input = "force"
amplitude = 1.0
frequency = 15.0
duration = 0.4
[solver]
dt_safety = {dt_safety!r}
[output]
file = "ledger.h5"
energy = true
"""


def study_ledger(pdsim, workdir, realisations):
    del realisations  # the ledger's imbalance is a sum over thousands of contacts
    normal_only = {'tangential = "history"': 'tangential = "none"', "friction = 0.3\n": "",
                   "rolling_friction = 0.02\n": ""}
    hertz = (0.3, 0.15, 0.075, 0.0375)
    series = (("Hertz, Mindlin history, friction, rolling", "hertz", {}, hertz),
              ("Hertz, directional friction, rolling", "hertz",
               {'tangential = "history"': 'tangential = "directional"'}, hertz),
              ("Hertz, normal only", "hertz", normal_only, hertz),
              ("linear, Mindlin history, friction, rolling", "linear", {},
               (0.04, 0.02, 0.01, 0.005)))
    rows, averages = [], []
    for label, model, changes, safeties in series:
        runs = []
        for safety in safeties:
            text = LEDGER_SINE.format(model=model, dt_safety=safety)
            for old, new in changes.items():
                text = text.replace(old, new)
            name = f"ledger_{model}_{len(changes)}_{safety:g}"
            runs.append((safety, run_deck(pdsim, workdir, name, text)))
        worst = [None if r["data"] is None else
                 float(np.max(np.abs(r["data"]["energy/imbalance"]))) /
                 float(r["data"]["energy/work_in"][-1] - r["data"]["energy/work_in"][0])
                 for _, r in runs]
        for k, (safety, run) in enumerate(runs):
            cells = [f"{label}, dt_safety {safety:g}"] + cost_cells(run, runs[0][1])
            if worst[k] is None:
                rows.append(cells + ["-", "-"])
                continue
            order = "-" if k == 0 or worst[k - 1] is None else \
                f"{math.log2(worst[k - 1] / worst[k]):.2f}"
            rows.append(cells + [f"{worst[k]:.2e}", order])
        if worst[0] is not None and worst[-1] is not None:
            averages.append(f"{label} {math.log2(worst[0] / worst[-1]) / (len(runs) - 1):.2f}")
    return ("5. The step's own error (the energy ledger's force-driven sine: 24 spheres, 4 mm,"
            " on an SDOF at 15 Hz, 0.4 s, gravity; Hertz young 2e8 Pa, linear 2000 N/m;"
            " speed-ups against each series' largest dt)",
            table(["setting"] + COST_HEADER + ["max abs(imbalance) / work in",
                                             "order (log2 of the ratio to the row above)"],
                  rows) +
            "\n\nOrder over the whole series (log2 of the first row's imbalance over the last's,"
            " per halving): " + "; ".join(averages) + "."
            " The step is velocity Verlet as LAMMPS runs it: the same positions to the last"
            " bit, its full-step velocity the mean of two stored ones"
            " (tests/kernels/contact_normal_test.cpp), where a single Hertz-Tsuji impact's energy"
            " balance falls as dt^2. A second-order step is therefore no lever: it would move the"
            " same bodies. Each dt is a new trajectory of the chaotic bed, so the order scatters"
            " about its trend. Normal contacts alone close as a second-order step should; the"
            " first-order part comes with the tangential forces, with or without history:"
            " friction's stick-slip switches, which a fixed step resolves to within a step, make"
            " time-stepping schemes first order (Acary and Brogliato 2008, Numerical Methods for"
            " Nonsmooth Dynamical Systems). dt is the lever.")


STUDIES = {"1": study_softening, "2": study_time_step, "3": study_coupling, "4": study_tolerance,
           "5": study_ledger}


def machine_lines(pdsim):
    model = "unknown"
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    version = subprocess.run([pdsim, "--version"], capture_output=True, text=True,
                             check=False).stdout.strip()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return [f"- date: {datetime.datetime.now().isoformat(timespec='seconds')}",
            f"- machine: {os.cpu_count()} CPUs (nproc), {model}; load average at the start {load}",
            f"- pdsim: {version}",
            "- command: `" + shlex.join([sys.executable] + sys.argv) + "`"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pdsim", default="build/pdsim", help="pdsim executable")
    parser.add_argument("--studies", default="1,2,3,4,5",
                        help="comma-separated subset of 1,2,3,4,5")
    parser.add_argument("-o", "--output", default=os.path.join(HERE, "results",
                                                                "accuracy_cost.md"),
                        help="markdown file to write")
    parser.add_argument("--realisations", type=int, default=5, choices=range(1, len(JITTER) + 1),
                        metavar="N", help="shaken-box runs per setting (1..7, default 5)")
    parser.add_argument("--keep", action="store_true", help="keep the decks and HDF5 files")
    args = parser.parse_args()
    chosen = [s.strip() for s in args.studies.split(",") if s.strip()]
    unknown = [s for s in chosen if s not in STUDIES]
    if unknown:
        sys.exit(f"accuracy_cost.py: unknown studies {unknown}; expected some of 1,2,3,4,5")
    if not os.access(args.pdsim, os.X_OK):
        sys.exit(f"accuracy_cost.py: {args.pdsim} is not an executable; build pdsim or pass"
                 " --pdsim")

    sections = ["# Accuracy against cost", ""] + machine_lines(args.pdsim)
    sections += ["", "Every run single-threaded (`--threads 1`). Wall time is /meta wall_time_s; "
                 "CPU time is the pdsim process's user + system time (steadier than wall time "
                 "when the machine is shared). Speed-up = reference time / time, in wall and in "
                 "CPU time. Changes are (value - reference) / reference."]
    workdir = tempfile.mkdtemp(prefix="pdsim_accuracy_cost_")
    for key in chosen:
        print(f"study {key} ...", file=sys.stderr)
        title, body = STUDIES[key](args.pdsim, workdir, args.realisations)
        sections += ["", "## " + title, "", body]
    report = "\n".join(sections) + "\n"
    print(report)
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    with open(args.output, "w", encoding="utf-8") as f:
        f.write(report)
    print(f"wrote {args.output}", file=sys.stderr)
    if args.keep:
        print(f"decks and results kept in {workdir}", file=sys.stderr)
    else:
        shutil.rmtree(workdir)


if __name__ == "__main__":
    main()
