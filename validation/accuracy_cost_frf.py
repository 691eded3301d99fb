#!/usr/bin/python3
"""Accuracy against cost on the Saeki FRF: one speed lever at a time against a reference.

Usage: validation/accuracy_cost_frf.py [--pdsim build/pdsim] [--levers all|name,name]
                                       [--jobs 2] [--band 14,16,0.5] [--fills N] [-o MD] [--keep]
       validation/accuracy_cost_frf.py --from-json RESULTS.json [-o MD]
       validation/accuracy_cost_frf.py --merge RESULTS.json --levers ... (runs only the new ones)
       validation/accuracy_cost_frf.py --merge RESULTS.json --levers ... --more-fills N

The scene is examples/saeki_250.toml (250 steel spheres, Hertz + Mindlin history, gravity,
stepped sine of 1 N, predicted starts, the ensemble FRF: two fills a point, up to four where
they disagree; --fills N: N a point, every row) over --band (start, stop, step in Hz; default
14-16 Hz in 0.5 Hz, where the example's resonance lies; start = stop: one frequency), each point
capped at 300 periods a fill (settle.max_periods) so that a lever costs a bounded time. The
reference row is that deck as it stands (young 2e9 Pa, dt_safety 0.15, interleaved coupling
every step, tolerance 0.02); every other row changes one lever (LEVERS below). Per row: the
highest point (mean over its fills, result or not, with its 95 % interval), the result points,
the change at the reference's highest point with the two 95 % intervals combined, the RMS over
every point, result or not, of (mean - reference mean) / reference peak, how many of those
differences lie within the two 95 % intervals combined (a difference inside them is not
resolved), the wall time (/meta wall_time_s), the CPU time of the pdsim process, the CPU s a
fill a point and the speed-up against the reference in those (rows with other fill counts
compare). Runs go --jobs at a time, each with --threads 1 (wall times of concurrent runs share
the machine: the CPU times compare). Written to validation/results/accuracy_cost_frf.md with
the date, machine, version and command, the runs' figures beside it (.json, which --from-json
reads back to redo the table and plot without running) and the Pareto plot (.png, against CPU
s a fill: the change at the peak, or over a band the curve's RMS error; the peak with its
interval; every fill at the reference's highest point, lever by lever). --more-fills N runs N
more fills of each named lever of a --merge run (fill seeds after the ones it ran) and pools
them with its fills point by point: the mean over every fill with its Student-t 95 % interval,
as the engine gives an ensemble of fills.
"""
import argparse
import concurrent.futures
import datetime
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import accuracy_cost  # noqa: E402
DECK = os.path.join(HERE, "..", "examples", "saeki_250.toml")
MAX_PERIODS = 300  # a fill's cap (settle.max_periods), the same for every lever

# name -> (what it changes, {table: {key: value}} overriding the reference deck)
LEVERS = {
    "reference": ("the deck as it stands (young 2e9 Pa, dt_safety 0.15, interleaved, tol. 0.02)",
                  {}),
    "young 2e8": ("contacts 10x softer (dt follows the Rayleigh time)",
                  {"contact": {"young": 2.0e8}}),
    "young 2e7": ("contacts 100x softer", {"contact": {"young": 2.0e7}}),
    "young 2e6": ("contacts 1000x softer", {"contact": {"young": 2.0e6}}),
    "dt_safety 0.3": ("time step 2x", {"solver": {"dt_safety": 0.3}}),
    "loose every 5": ("loose coupling, one exchange every 5 steps",
                      {"coupling": {"scheme": "loose", "every": 5}}),
    "tolerance 0.05": ("steady-state tolerance 0.05 (5 % half-width)",
                       {"settle": {"tolerance": 0.05}}),
    # k matches Hertz's contact time at 0.1 m/s (about the bed's speeds at resonance):
    # t = 2.87 (m*^2 / (R* E*^2 v))^(1/5) = 1.53e-4 s for these spheres, k = m* (pi / t)^2.
    "linear": ("linear spring-dashpot, k = 1.07e5 N/m (Hertz's contact time at 0.1 m/s)",
               {"contact": {"model": "linear", "stiffness": 1.07e5}}),
    "linear dt_safety 0.1": ("as linear, dt 0.1 of its contact time (5x the default 0.02)",
                              {"contact": {"model": "linear", "stiffness": 1.07e5},
                               "solver": {"dt_safety": 0.1}}),
    "no friction history": ("directional Coulomb friction instead of Mindlin history",
                            {"contact": {"tangential": "directional"}}),
    "other fills": ("the reference with other fills (seed 101): the metrics' noise floor",
                    {"particles": {"seed": 101}}),
    "young 2e10": ("contacts 10x stiffer (a finer reference: about 3x the time)",
                   {"contact": {"young": 2.0e10}}),
    # Rigid spheres (kernels/nonsmooth.hpp): the penalty law's keys removed (None).
    "rigid": ("rigid spheres: non-smooth contacts (APGD), dt_safety 0.2 of r / v",
              {"contact": {"model": "nonsmooth", "young": None, "poisson": None,
                           "tangential": None}}),
    "rigid dt_safety 0.1": ("rigid, half the step",
                            {"contact": {"model": "nonsmooth", "young": None, "poisson": None,
                                         "tangential": None},
                             "solver": {"dt_safety": 0.1}}),
}


def example_deck():
    import tomllib  # Python 3.11+
    with open(DECK, "rb") as f:
        return tomllib.load(f)


def deck_text(band, overrides, fills=None):
    """examples/saeki_250.toml with the band, the periods cap, the fills and the lever's keys."""
    deck = example_deck()
    start, stop, step = band
    x = deck["excitation"]
    x["frequencies"] = {"start": start, "stop": stop, "step": step}
    x["settle"] = dict(x.get("settle", {}), max_periods=MAX_PERIODS)
    if fills:
        x["settle"].update(realisations=fills, max_realisations=fills)
    for table, keys in overrides.items():
        target = {"settle": x["settle"], "particles": deck["damper"][0]["particles"]}.get(table)
        target = target if target is not None else deck.setdefault(table, {})
        target.update({k: v for k, v in keys.items() if v is not None})
        for k in [k for k, v in keys.items() if v is None]:
            target.pop(k, None)
    deck.pop("output", None)
    return dumps(deck)


def dumps(value, prefix=""):
    """A small TOML writer for the deck's tables, arrays of tables and inline tables."""
    def scalar(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return '"' + v + '"'
        if isinstance(v, list):
            return "[" + ", ".join(scalar(e) for e in v) + "]"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {scalar(e)}" for k, e in v.items()) + " }"
        return repr(v)
    lines = [f"{k} = {scalar(v)}" for k, v in value.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and
                                                 isinstance(v[0], dict))]
    for k, v in value.items():
        if isinstance(v, dict):
            lines += ["", f"[{prefix}{k}]", dumps(v, prefix + k + ".")]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for e in v:
                lines += ["", f"[[{prefix}{k}]]", dumps(e, prefix + k + ".")]
    return "\n".join(lines)


def run(pdsim, workdir, name, text):
    """One run (accuracy_cost.run_deck); (name, the figures the table and plot read)."""
    done = accuracy_cost.run_deck(pdsim, workdir, name.replace(" ", "_"), text)
    result = {"rc": done["rc"], "cpu_s": done["cpu_s"], "error": done["error"]}
    if done["data"] is not None:
        data = done["data"]
        result.update({k: data["frf/" + k] for k in ("frequency", "amplitude", "amplitude_ci",
                                                     "result", "realisations", "periods")})
        result.update({"fills_" + k: data["frf/fills/" + k]
                       for k in ("frequency", "amplitude", "periods")})
        result.update(wall_s=data["wall_s"], dt=data["dt"])
    return name, result


def curve_peak(r):
    """The highest point mean of a run (result or not): (index, amplitude, interval)."""
    k = int(np.argmax(r["amplitude"]))
    return k, float(r["amplitude"][k]), float(r["amplitude_ci"][k])


def curve_error(r, ref):
    """RMS over every point of (mean - reference mean) / reference peak, and how many of those
    differences lie within the two 95 % intervals combined (not resolved)."""
    d = np.asarray(r["amplitude"]) - np.asarray(ref["amplitude"])
    rms = float(np.sqrt(np.mean(d**2))) / curve_peak(ref)[1]
    within = np.abs(d) <= np.hypot(r["amplitude_ci"], ref["amplitude_ci"])
    return rms, int(within.sum())


def pooled(old, new):
    """Two runs of one lever on other fills as one: per point the mean over every fill with its
    Student-t 95 % interval (a point's result: 0 unless both runs had one)."""
    from scipy import stats
    both = {k: np.concatenate([np.asarray(old[k]), np.asarray(new[k])])
            for k in ("fills_frequency", "fills_amplitude", "fills_periods")}
    r = dict(old, **both, cpu_s=old["cpu_s"] + new["cpu_s"], wall_s=old["wall_s"] + new["wall_s"])
    r.update(amplitude=[], amplitude_ci=[], realisations=[], periods=[],
             result=[min(a, b) for a, b in zip(old["result"], new["result"])])
    for f in old["frequency"]:
        at = np.isclose(both["fills_frequency"], f)
        a, n = both["fills_amplitude"][at], int(np.sum(at))
        r["amplitude"].append(float(np.mean(a)))
        r["amplitude_ci"].append(float(stats.t.ppf(0.975, n - 1) * np.std(a, ddof=1) / n**0.5))
        r["realisations"].append(n)
        r["periods"].append(int(np.max(both["fills_periods"][at])))
    return r


def at_reference_peak(r, ref):
    """(mean - reference mean) / reference mean at the reference's highest point, and the 95 %
    half-width of that difference (the two intervals combined); None where r lacks the point."""
    k, peak, ci = curve_peak(ref)
    at = np.flatnonzero(np.isclose(r["frequency"], ref["frequency"][k]))
    if at.size == 0:
        return None
    j = int(at[0])
    return (r["amplitude"][j] - peak) / peak, float(np.hypot(r["amplitude_ci"][j], ci)) / peak


def cpu_per_fill(r):
    """CPU s a fill a point: comparable between rows run with different fills."""
    return r["cpu_s"] / float(np.sum(r["realisations"]))


def row(name, r, ref):
    what = LEVERS[name][0]
    if r["rc"] != 0:
        return [name, what] + ["-"] * 5 + [f"failed (exit {r['rc']}): {r.get('error', '')}"] + \
            ["-"] * 4
    k, peak, ci = curve_peak(r)
    flag = "" if r["result"][k] > 0 else " (not a result)"
    fills = int(np.sum(np.isclose(r["fills_frequency"], r["frequency"][k])))
    cells = [name, what, f"{r['dt']:.3g}",
             f"{1e3 * peak:.3f} ± {1e3 * ci:.3f} mm at {r['frequency'][k]:g} Hz, {fills} fills"
             f"{flag}", f"{int(np.sum(np.asarray(r['result']) > 0))} / {len(r['result'])}"]
    if name == "reference" or ref is None or ref["rc"] != 0:
        cells += ["reference" if name == "reference" else "-", "-", "-"]
    else:
        rms, within = curve_error(r, ref)
        change = at_reference_peak(r, ref)
        cells += ["-" if change is None else f"{100 * change[0]:+.1f} ± {100 * change[1]:.1f} %",
                  f"{100 * rms:.1f} %", f"{within} / {len(r['result'])}"]
    speedup = "-" if ref is None or ref["rc"] != 0 else \
        f"{cpu_per_fill(ref) / cpu_per_fill(r):.2f}"
    return cells + [f"{r['wall_s']:.0f}", f"{r['cpu_s']:.0f}", f"{cpu_per_fill(r):.0f}", speedup]


def plot(results, names, path):
    """The Pareto plot against CPU time a fill: the error (the RMS over the curve; over one point
    the signed change with its interval), the peak with its interval, and every fill at the
    reference's highest point (the ensemble's states, lever by lever)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ref = results.get("reference")
    ok = [n for n in names if results[n]["rc"] == 0]
    fig, (left, middle, right) = plt.subplots(1, 3, figsize=(16, 4.6))
    single = ref is not None and ref["rc"] == 0 and len(ref["frequency"]) == 1
    for i, n in enumerate(ok):
        r, cost, colour = results[n], cpu_per_fill(results[n]), f"C{i}"
        if n != "reference" and ref is not None and ref["rc"] == 0:
            change = at_reference_peak(r, ref)
            if single and change is not None:
                left.errorbar(cost, 100 * change[0], yerr=100 * change[1], fmt="o", capsize=3,
                              color=colour)
                y = 100 * change[0]
            else:
                y = 100 * curve_error(r, ref)[0]
                left.plot(cost, y, "o", color=colour)
            left.annotate(n, (cost, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        k, peak, ci = curve_peak(r)
        middle.errorbar(cost, 1e3 * peak, yerr=1e3 * ci, fmt="o", capsize=3, color=colour)
        middle.annotate(f"{n} ({r['frequency'][k]:g} Hz)", (cost, 1e3 * peak),
                        textcoords="offset points", xytext=(4, 4), fontsize=8)
    if single:
        left.axhspan(-3, 3, color="0.9", zorder=0, label="± 3 %")
        left.axhline(0, color="0.5", lw=0.8)
        left.legend(fontsize=8)
    left.set(xscale="log", xlabel="CPU s a fill",
             ylabel="peak - reference (%), 95 % CI" if single else
             "RMS diff. / reference peak (%)", title="error against cost")
    middle.set(xscale="log", xlabel="CPU s a fill", ylabel="peak amplitude (mm), 95 % CI",
               title="highest point of the FRF (mean over fills)")
    if ref is not None and ref["rc"] == 0:
        frequency = ref["frequency"][curve_peak(ref)[0]]
        rng = np.random.default_rng(0)
        for i, n in enumerate(ok):
            r = results[n]
            a = 1e3 * np.asarray(r["fills_amplitude"])[np.isclose(r["fills_frequency"], frequency)]
            at = np.flatnonzero(np.isclose(r["frequency"], frequency))
            if at.size == 0:
                continue
            right.plot(i + rng.uniform(-0.25, 0.25, a.size), a, ".", alpha=0.6, color=f"C{i}")
            j = int(at[0])
            right.errorbar(i + 0.35, 1e3 * r["amplitude"][j], yerr=1e3 * r["amplitude_ci"][j],
                           fmt="k_", capsize=3)
        right.set_xticks(range(len(ok)), ok, rotation=20, fontsize=8)
        right.set(ylabel="amplitude (mm)",
                  title=f"every fill at {frequency:g} Hz (black: mean, 95 % CI)")
    for axis in (left, middle, right):
        axis.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pdsim", default="build/pdsim")
    parser.add_argument("--levers", default="all", help="comma-separated names, or all")
    parser.add_argument("--jobs", type=int, default=2, help="runs at a time")
    parser.add_argument("--band", default="14,16,0.5", help="start,stop,step in Hz")
    parser.add_argument("--fills", type=int, help="fills a point for every row (default: the "
                        "deck's, two and up to four where they disagree)")
    parser.add_argument("-o", "--output",
                        default=os.path.join(HERE, "results", "accuracy_cost_frf.md"))
    parser.add_argument("--more-fills", type=int, help="with --merge: N more fills of each "
                        "named lever, pooled with its saved ones")
    parser.add_argument("--keep", action="store_true", help="keep decks, logs and HDF5 files")
    parser.add_argument("--from-json", help="redo the table and plot from a run's .json")
    parser.add_argument("--merge", help="a run's .json: keep its runs, run only the levers it "
                        "lacks, and write them all")
    args = parser.parse_args()
    stem = os.path.splitext(args.output)[0]
    if args.from_json:
        with open(args.from_json, encoding="utf-8") as f:
            saved = json.load(f)
        write(saved["head"], saved["names"], saved["results"], args.output, stem)
        return
    names = list(LEVERS) if args.levers == "all" else \
        ["reference"] + [n.strip() for n in args.levers.split(",") if n.strip() != "reference"]
    unknown = [n for n in names if n not in LEVERS]
    if unknown:
        sys.exit(f"accuracy_cost_frf.py: unknown levers {unknown}; expected some of "
                 f"{', '.join(LEVERS)}")
    for option, value in (("--fills", args.fills), ("--more-fills", args.more_fills)):
        if value is not None and value < 1:
            sys.exit(f"accuracy_cost_frf.py: {option} {value}: expected at least 1")
    if args.more_fills and not args.merge:
        sys.exit("accuracy_cost_frf.py: --more-fills needs --merge RESULTS.json (the fills to "
                 "add to)")
    band = tuple(float(v) for v in args.band.split(","))
    if len(band) != 3 or not band[0] <= band[1] or band[2] <= 0:
        sys.exit(f"accuracy_cost_frf.py: --band {args.band}: expected start,stop,step in Hz")
    if not os.access(args.pdsim, os.X_OK):
        sys.exit(f"accuracy_cost_frf.py: {args.pdsim} is not an executable; build pdsim or "
                 "pass --pdsim")
    saved, more = {"head": [], "names": [], "results": {}}, []
    if args.merge:
        with open(args.merge, encoding="utf-8") as f:
            saved = json.load(f)
        more = [n for n in names if n in saved["results"]] if args.more_fills else []
        names = saved["names"] + [n for n in names if n not in saved["names"]]
    decks = {n: deck_text(band, LEVERS[n][1], args.fills) for n in names
             if n not in saved["results"]}
    for n in more:
        old = saved["results"][n]
        points = np.arange(band[0], band[1] + band[2] / 2, band[2])
        if old["rc"] != 0 or len(old["frequency"]) != len(points) or \
                not np.allclose(old["frequency"], points):
            sys.exit(f"accuracy_cost_frf.py: --more-fills: {args.merge}'s '{n}' did not run "
                     f"--band {args.band}; more fills must go to the points it ran")
        # The next fill seeds: the lever's seed (the deck's unless it sets one) + fills it ran.
        first = LEVERS[n][1].get("particles", {}).get(
            "seed", example_deck()["damper"][0]["particles"]["seed"])
        overrides = {**LEVERS[n][1], "particles": {"seed": first + max(old["realisations"])}}
        decks[n] = deck_text(band, overrides, args.more_fills)
    workdir = tempfile.mkdtemp(prefix="pdsim_accuracy_frf_")
    started = datetime.datetime.now()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run, args.pdsim, workdir, n, text) for n, text in decks.items()]
        new = dict(f.result() for f in futures)
    results = dict(saved["results"])
    for n, r in new.items():
        if n in more and r["rc"] != 0:
            print(f"  {n}: the more fills failed; its saved fills stand alone", file=sys.stderr)
        else:
            results[n] = pooled(results[n], r) if n in more else r
    version = subprocess.run([args.pdsim, "--version"], capture_output=True, text=True,
                             check=False).stdout.strip()
    where = f"at {band[0]:g} Hz" if band[0] == band[1] else \
        f"over {band[0]:g}-{band[1]:g} Hz in {band[2]:g} Hz"
    head = saved["head"] + [
            f"- date: {started.isoformat(timespec='seconds')}, {args.jobs} runs at a time",
            f"- machine: {os.cpu_count()} CPUs; load average at the start {load}",
            f"- pdsim: {version}",
            "- command: `" + shlex.join([sys.executable] + sys.argv) + "`",
            f"- scene: examples/saeki_250.toml {where}, at most {MAX_PERIODS} periods a fill"
            + (f", {args.fills} fills a point" if args.fills else "")
            + (f", {args.more_fills} more fills of {', '.join(decks)}" if args.more_fills else "")
            + "; one lever a row (see `validation/accuracy_cost_frf.py` --help)"]
    results = {n: {k: v.tolist() if isinstance(v, np.ndarray) else v for k, v in r.items()}
               for n, r in results.items()}
    with open(stem + ".json", "w", encoding="utf-8") as f:
        json.dump({"head": head, "names": names, "results": results}, f, indent=1)
    write(head, names, results, args.output, stem)
    if args.keep:
        print(f"kept in {workdir}", file=sys.stderr)
    else:
        shutil.rmtree(workdir)


def resolution(ref):
    """What resolving a 3 % change of the reference's peak takes: fills at its spread."""
    if ref is None or ref["rc"] != 0:
        return ""
    k, peak, ci = curve_peak(ref)
    at = np.isclose(ref["fills_frequency"], ref["frequency"][k])
    amplitude = ref["fills_amplitude"][at]
    mean, sd = float(np.mean(amplitude)), float(np.std(amplitude, ddof=1))
    # A 95 % half-width of 3 %: on one mean, and on a change (two means at the same spread).
    one = int(np.ceil((1.96 * sd / (0.03 * mean))**2))
    per_period = ref["cpu_s"] / float(np.sum(ref["fills_periods"]))
    hours = 2 * one * float(np.mean(ref["fills_periods"][at])) * per_period / 3600
    capped = int(np.sum(ref["fills_periods"][at] >= MAX_PERIODS))
    return (f"At the reference's highest point ({ref['frequency'][k]:g} Hz) its {amplitude.size}"
            f" fills read {1e3 * mean:.3f} mm with a standard deviation of {1e3 * sd:.3f} mm"
            f" ({100 * sd / mean:.0f} %): the fills of one design differ by that much (the"
            f" ensemble's spread, not noise that more periods remove). Its 95 % interval is"
            f" {100 * ci / peak:.1f} % of the peak; a 3 % interval takes about {one} fills, and a"
            f" lever's change known to 3 % (two means) about {2 * one} fills a row, about"
            f" {hours:.1f} CPU hours for the reference's row at its {per_period:.2f} CPU s a"
            " period. A change within its interval (the column beside the peak) is not"
            f" resolved. {capped} of the reference's {amplitude.size} fills there ran to the cap"
            f" of {MAX_PERIODS} periods without settling on their own, which makes the point not"
            " a result by the engine's test; every row has the same cap.")


def write(head, names, results, output, stem):
    """The table (markdown, printed too) and the Pareto plot."""
    results = {n: {k: np.array(v) if isinstance(v, list) else v for k, v in r.items()}
               for n, r in results.items()}
    ref = results.get("reference")
    header = ["lever", "what it changes", "dt (s)", "highest point, mean ± 95 % CI",
              "result points", "at the ref. peak: change ± 95 % CI", "RMS diff. / ref. peak",
              "diffs within both 95 % CI", "wall (s)", "CPU (s)", "CPU s a fill",
              "speed-up (CPU a fill)"]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row(n, results[n], ref)) + " |" for n in names]
    report = "\n".join(["# Accuracy against cost on the Saeki FRF", ""] + head +
                        ["", "\n".join(lines), "", resolution(ref), "",
                         f"![error and peak against CPU time]({os.path.basename(stem)}.png)", ""])
    print(report)
    with open(output, "w", encoding="utf-8") as f:
        f.write(report)
    plot(results, names, stem + ".png")
    print(f"wrote {output} and {stem}.png", file=sys.stderr)


if __name__ == "__main__":
    main()
