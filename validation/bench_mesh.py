#!/usr/bin/python3
"""What a mesh container costs against the analytic container of the same shape, and whether it
gives the same physics: one shaken bed in each, side by side in one run.

Usage: validation/bench_mesh.py [--pdsim build/pdsim] [--rounds 2] [--fills 4] [-o MD]

The scene: 250 steel spheres d = 5 mm (E softened to 2e9 Pa, e = 0.5, mu = 0.3, Hertz +
Mindlin history, gravity), random fills, shaken 3 mm at 20 Hz along x for 0.3 s after the bed
settles, the last 4 periods averaged; --fills fills per run. Containers: the analytic cylinder
r = 28 mm, h = 50 mm (axis z) against STL cylinders of 2,048 and 10,240 triangles
(validation/cavity_stl.py), and the analytic 40 mm cube against its 12 triangles. Each run is
`pdsim run --threads 1`, the scenes taken in turn --rounds times (this machine's speed drifts:
ratios come from runs side by side). Printed and written to validation/results/
mesh_containers.md: wall and CPU time (median of the rounds), particle-steps per second of wall
time (the run's own /meta figures: set-up, fill and bed included), the cost against the analytic
container, the CPU time per particle-step of the shaken bed alone (the extra steps of a run
shaken 1.3 s), and the dissipated power and force harmonic with their 95 % intervals.
"""
import argparse
import datetime
import os
import resource
import shlex
import statistics
import subprocess
import sys
import tempfile

import h5py

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import cavity_stl  # noqa: E402

DECK = """title = "mesh benchmark: {name}"
[[damper]]
container = {container}
particles = {{ count = 250, diameter = 0.005, density = 7800.0, seed = 5, fill = "random" }}
[contact]
model = "hertz"
tangential = "history"
young = 2.0e9
poisson = 0.3
restitution = 0.5
friction = 0.3
[gravity]
vector = [0.0, 0.0, -9.81]
[excitation]
kind = "prescribed"
motion = {{ axis = [1.0, 0.0, 0.0], amplitude = 0.003, frequency = 20.0 }}
duration = {duration}
settle = {{ average_periods = 4, realisations = {fills}, max_realisations = {fills} }}
[output]
file = "out.h5"
"""


LONG = 1.3  # s: the longer run whose extra steps the per-step cost counts


def scenes(workdir):
    """(name, container table, the analytic scene it is measured against)."""
    out = []
    cylinder = '{ shape = "cylinder", radius = 0.028, height = 0.05 }'
    out.append(("analytic cylinder", cylinder, None))
    for segments in (512, 2560):
        path = os.path.join(workdir, f"cylinder_{segments}.stl")
        t = cavity_stl.cylinder(28.0, 50.0, segments)
        cavity_stl.write_binary(t, path)
        out.append((f"mesh cylinder, {len(t):,} triangles",
                    f'{{ shape = "mesh", file = "{path}", scale = 0.001 }}', "analytic cylinder"))
    out.append(("analytic box", '{ shape = "box", size = [0.04, 0.04, 0.04] }', None))
    path = os.path.join(workdir, "box.stl")
    cavity_stl.write_binary(cavity_stl.box(40.0, 40.0, 40.0), path)
    out.append(("mesh box, 12 triangles", f'{{ shape = "mesh", file = "{path}", scale = 0.001 }}',
                "analytic box"))
    return out


def run(pdsim, workdir, name, container, fills, duration=0.3):
    deck = os.path.join(workdir, "deck.toml")
    with open(deck, "w") as f:
        f.write(DECK.format(name=name, container=container, fills=fills, duration=duration))
    out = os.path.join(workdir, "out.h5")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([pdsim, "run", deck, "--quiet", "--threads", "1", "--force", "-o", out],
                   check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    with h5py.File(out, "r") as h:
        meta, p = h["meta"].attrs, h["prescribed"]
        return {"wall": float(meta["wall_time_s"]), "steps": float(meta["particle_steps"]),
                "cpu": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
                "power": float(p["dissipated_power"][0]),
                "power_ci": float(p["dissipated_power_ci"][0]),
                "force": float(p["force_amplitude"][0]),
                "force_ci": float(p["force_amplitude_ci"][0]),
                "fills": int(p["realisations"][0]), "variant": str(meta["kernel_variant"])}


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--pdsim", default=os.path.join(HERE, "..", "build", "pdsim"))
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--fills", type=int, default=4)
    parser.add_argument("-o", default=os.path.join(HERE, "results", "mesh_containers.md"))
    a = parser.parse_args()
    with tempfile.TemporaryDirectory() as workdir:
        todo = scenes(workdir)
        runs = {name: [] for name, _, _ in todo}
        for r in range(a.rounds):
            for name, container, _ in todo:
                runs[name].append(run(a.pdsim, workdir, name, container, a.fills))
                long = run(a.pdsim, workdir, name, container, a.fills, LONG)
                runs[name][-1]["shaken"] = ((long["cpu"] - runs[name][-1]["cpu"]) /
                                            (long["steps"] - runs[name][-1]["steps"]))
                print(f"round {r + 1}: {name}: {runs[name][-1]['wall']:.2f} s", flush=True)
    rows = []
    header = ("| container | wall s | CPU s | particle-steps/s | cost vs analytic | "
              "CPU ns per particle-step, shaken | vs analytic | "
              "dissipated power (W) | force harmonic (N) | fills |")
    rows += [header, "|" + "---|" * 10]
    median = {n: {k: statistics.median(x[k] for x in v)
                  for k in ("wall", "cpu", "steps", "shaken")}
              for n, v in runs.items()}
    for name, _, reference in todo:
        m, last = median[name], runs[name][-1]
        rate = m["steps"] / m["wall"]
        cost = "" if reference is None else f"{m['wall'] / median[reference]['wall']:.3f}x"
        shaken = "" if reference is None else f"{m['shaken'] / median[reference]['shaken']:.2f}x"
        rows.append(f"| {name} | {m['wall']:.2f} | {m['cpu']:.2f} | {rate:.3g} | {cost} | "
                    f"{1e9 * m['shaken']:.0f} | {shaken} | "
                    f"{last['power']:.4f} +- {last['power_ci']:.4f} | "
                    f"{last['force']:.3f} +- {last['force_ci']:.3f} | {last['fills']} |")
    version = subprocess.run([a.pdsim, "--version"], capture_output=True, text=True).stdout.strip()
    text = "\n".join([
        "# Mesh containers against analytic ones: cost and physics",
        "",
        f"{datetime.date.today()}, {version}, {os.cpu_count()} cores; "
        f"`{' '.join(shlex.quote(x) for x in sys.argv)}`. Scene and method: "
        "`validation/bench_mesh.py --help`. Wall and CPU time are medians of "
        f"{a.rounds} rounds taken in turn; power and force are the last round's, each a mean "
        f"over {a.fills} fills with its 95 % interval. The cost per particle-step, shaken, is "
        f"the difference between the same run shaken {LONG} s and 0.3 s (the same steps up to "
        "there): the steps of the shaken bed alone, without the set-up (mesh checks, bins, "
        "fill) and the settling that the whole run's figures include.",
        "",
        *rows,
        ""])
    print(text)
    with open(a.o, "w") as f:
        f.write(text)


if __name__ == "__main__":
    main()
