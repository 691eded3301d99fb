#!/usr/bin/python3
"""Print what a pdsim output file holds: the /meta attributes and the shape of every dataset.

Usage: validation/inspect_results.py OUT.h5 [--deck-lines N]

Exits 1, after printing, when the file is not a finished run: its name ends in ".partial" or
its /meta attribute `complete` is 0 or missing (pdsim renames "<out>.partial" to "<out>" only
when the run finishes, see io/results.hpp).
"""
import argparse
import os
import sys

import h5py


def text(value):
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("file", help="pdsim HDF5 output")
    parser.add_argument("--deck-lines", type=int, default=10, help="deck lines to show")
    args = parser.parse_args()

    try:
        h5 = h5py.File(args.file, "r")
    except OSError as error:
        sys.exit(f"inspect_results.py: cannot open {args.file}: {error}")
    with h5:
        meta = h5["meta"].attrs if "meta" in h5 else {}
        print("/meta")
        for name in sorted(meta):
            value = text(meta[name])
            if name == "deck":
                lines = value.splitlines()
                shown = "\n    ".join(lines[: args.deck_lines])
                more = len(lines) - args.deck_lines
                tail = f"\n    ... ({more} more lines)" if more > 0 else ""
                print(f"  deck:\n    {shown}{tail}")
            else:
                print(f"  {name}: {value}")
        datasets = []
        h5.visititems(lambda name, obj: datasets.append((name, obj))
                      if isinstance(obj, h5py.Dataset) else None)
        print("datasets")
        views = 0  # a snapshot's arrays as views of the arrays (HDF5 virtual datasets), for ParaView
        for name, dataset in datasets:
            if dataset.is_virtual:
                views += 1
            else:
                print(f"  /{name}: shape {dataset.shape}, {dataset.dtype}")
        if views:
            print(f"  and {views} views of a snapshot's arrays (/particles/damperK/step/T/...)")
        complete = meta.get("complete")

    if args.file.endswith(".partial"):
        sys.exit(f"inspect_results.py: {args.file} is an unfinished run (name ends in .partial)")
    if complete is None or int(complete) != 1:
        state = "missing" if complete is None else int(complete)
        sys.exit(f"inspect_results.py: {args.file} is not a finished run (/meta complete = {state})")


if __name__ == "__main__":
    main()
