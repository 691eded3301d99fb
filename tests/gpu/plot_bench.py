#!/usr/bin/env python3
"""Reads tests/gpu/run.sh's bench_<backend>_<particles>.log files (`pdsim bench --steps`) in
FOLDER: prints a line per run (backend, particles, threads, steps, wall s, particle-steps per s,
bytes per particle) and draws particle-steps per second against particles for each backend.

    python3 tests/gpu/plot_bench.py FOLDER FIGURE.png
"""
import pathlib
import re
import sys


def main():
    folder, figure = pathlib.Path(sys.argv[1]), sys.argv[2]
    runs = {}  # backend -> [(particles, particle-steps per s)]
    for log in sorted(folder.glob("bench_*.log")):
        backend = re.match(r"bench_([a-z]+)_", log.name).group(1)
        for line in log.read_text().splitlines():
            fields = line.split()
            # particles threads steps wall_s psteps_per_s bytes/particle variant state_sum
            if len(fields) == 8 and fields[0].isdigit():
                particles, rate = int(fields[0]), float(fields[4])
                print(f"bench {backend} {particles} particles, {fields[1]} threads, {fields[2]} "
                      f"steps: {float(fields[3]):.2f} s, {rate:.3g} particle-steps/s, "
                      f"{fields[5]} bytes/particle")
                runs.setdefault(backend, []).append((particles, rate))
    if not runs:
        sys.exit("no bench results in " + str(folder))
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for backend, points in sorted(runs.items()):
        points.sort()
        ax.loglog([p for p, _ in points], [r for _, r in points], "o-", label=backend)
    ax.set_xlabel("particles (shaken box, from a lattice)")
    ax.set_ylabel("particle-steps per second")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(figure, dpi=120)


if __name__ == "__main__":
    main()
