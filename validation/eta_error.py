#!/usr/bin/python3
"""How far a run's progress line was from the truth: the ETA it printed at given fractions of
the run's wall time against the time the run really had left.

    validation/eta_error.py LOG [LOG ...] [--at 0.33,0.5,0.8]

LOG is what `pdsim run` wrote on stderr (not a terminal: a progress line every 5 s, "elapsed
E s  ETA A s"); the run's wall time is the last line's "wall time W s". Prints, per fraction,
the ETA, the true remaining time and the error relative to it, and the total the line
predicted (elapsed + ETA) against the wall time.
"""
import argparse
import re
import sys


def read(path):
    lines, wall = [], None
    with open(path, errors="replace") as f:
        for line in f:
            m = re.search(r"elapsed (\d+) s\s+ETA (\d+) s", line)  # "ETA A s [or more ...]"
            if m:
                lines.append((float(m.group(1)), float(m.group(2))))
            m = re.search(r"wall time ([0-9.]+) s", line)
            if m:
                wall = float(m.group(1))
    if wall is None:
        sys.exit(f"{path}: no 'wall time' line (did the run finish?)")
    return lines, wall


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("logs", nargs="+")
    p.add_argument("--at", default="0.33,0.5,0.8", help="fractions of the wall time")
    a = p.parse_args()
    fractions = [float(x) for x in a.at.split(",")]
    print("| run | at | elapsed (s) | ETA (s) | true remaining (s) | ETA error | predicted total / wall |")
    print("|---|---|---|---|---|---|---|")
    for path in a.logs:
        lines, wall = read(path)
        for fr in fractions:
            # The last progress line printed at or before this fraction of the run.
            before = [x for x in lines if x[0] <= fr * wall]
            if not before:
                print(f"| {path} | {fr:.0%} | - | - | - | no ETA yet | - |")
                continue
            elapsed, eta = before[-1]
            left = wall - elapsed
            print(f"| {path} | {fr:.0%} | {elapsed:.0f} | {eta:.0f} | {left:.0f} | "
                  f"{(eta - left) / left:+.0%} | {(elapsed + eta) / wall:.2f} |")


if __name__ == "__main__":
    main()
