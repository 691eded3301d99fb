#!/usr/bin/env python3
"""Whether two pdsim output files hold the same numbers, bitwise.

Every group, dataset and attribute of the one must be in the other with the same type, shape
and bytes (NaN equal to NaN), except the attributes named by --ignore (by default what differs
between any two runs of one deck: wall time, version, deck path). Prints each difference and
exits 1 when there is one.

    /usr/bin/python3 validation/same_results.py OLD.h5 NEW.h5 [--ignore NAME ...]
"""
import argparse
import sys

import h5py
import numpy as np

DEFAULT_IGNORED = ["wall_time_s", "version", "deck_path"]


def same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape or a.dtype != b.dtype:
        return False
    if a.dtype.kind in "fc":
        return bool(np.array_equal(a, b, equal_nan=True))
    return bool(np.array_equal(a, b))


def walk(old, new, ignored):
    differences = []

    def attributes(path, x, y):
        for name in sorted(set(x.attrs) | set(y.attrs)):
            if name in ignored:
                continue
            if name not in x.attrs or name not in y.attrs:
                differences.append(f"{path}@{name}: only in {'new' if name in y.attrs else 'old'}")
            elif not same(x.attrs[name], y.attrs[name]):
                differences.append(f"{path}@{name}: {x.attrs[name]!r} then, {y.attrs[name]!r} now")

    def visit(path, x, y):
        attributes(path, x, y)
        if isinstance(x, h5py.Dataset) or isinstance(y, h5py.Dataset):
            if not (isinstance(x, h5py.Dataset) and isinstance(y, h5py.Dataset)):
                differences.append(f"{path}: a dataset in one file only")
            elif not same(x[()], y[()]):
                differences.append(f"{path}: values differ")
            return
        for name in sorted(set(x) | set(y)):
            child = f"{path.rstrip('/')}/{name}"
            if name not in x or name not in y:
                differences.append(f"{child}: only in {'new' if name in y else 'old'}")
            else:
                visit(child, x[name], y[name])

    visit("/", old, new)
    return differences


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("--ignore", nargs="*", default=[], help="more attributes to skip")
    args = parser.parse_args()
    with h5py.File(args.old, "r") as old, h5py.File(args.new, "r") as new:
        differences = walk(old, new, set(DEFAULT_IGNORED + args.ignore))
    for line in differences:
        print(f"{args.new}: {line}")
    return 1 if differences else 0


if __name__ == "__main__":
    sys.exit(main())
