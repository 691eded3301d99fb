#!/usr/bin/python3
"""Damper cavities as binary STL files, for `container = { shape = "mesh", file = ... }`.

Usage: validation/cavity_stl.py capsule OUT.stl [--radius 25] [--length 30] [--segments 48]
                                                [--rings 12] [--ascii [--offset X Y Z]]
       validation/cavity_stl.py cylinder OUT.stl [--radius 28] [--length 50] [--segments 512]
                                                 [--ascii [--offset X Y Z]]

Coordinates are in the units given (mm by default: a deck reads them with scale = 0.001).
  capsule:  a cylinder of `radius` and straight `length` along x with hemispherical end caps,
            centred at the origin; `segments` facets around the axis, `rings` bands per cap.
            examples/capsule_cavity.stl is `capsule` with the defaults (2,304 triangles).
  cylinder: a closed cylinder along z centred at the origin, fans for the end caps
            (4 x `segments` triangles), as the analytic `shape = "cylinder"`.
Triangles run counter-clockwise seen from outside. Pure Python: any python3 runs it.
"""
import argparse
import math
import struct


def revolve(profile, segments):
    """The surface swept by `profile` [(x, rho), ...] (from one pole to the other along x)
    about the x axis: triangles counter-clockwise seen from outside, none at the poles."""
    def at(x, rho, j):
        phi = 2 * math.pi * (j % segments) / segments
        return (x, rho * math.cos(phi), rho * math.sin(phi))
    triangles = []
    for (x0, r0), (x1, r1) in zip(profile, profile[1:]):
        for j in range(segments):
            a, b = at(x0, r0, j), at(x0, r0, j + 1)
            c, d = at(x1, r1, j + 1), at(x1, r1, j)
            if r0 > 0:
                triangles.append((a, b, c))
            if r1 > 0:
                triangles.append((a, c, d))
    return triangles


def capsule(radius, length, segments, rings):
    half = 0.5 * length
    cap = [(half + radius * math.sin(t), radius * math.cos(t))
           for t in (0.5 * math.pi * k / rings for k in range(rings + 1))]
    cap[-1] = (half + radius, 0.0)  # the pole exact, so that its triangles share it
    profile = [(-x, rho) for x, rho in reversed(cap)] + cap
    return revolve(profile, segments)


def cylinder(radius, length, segments):
    """Along z: the x-axis cylinder of revolve() turned by (x, y, z) -> (y, z, x), which keeps
    the orientation."""
    half = 0.5 * length
    profile = [(-half, 0.0), (-half, radius), (half, radius), (half, 0.0)]
    # The caps as fans from their centres: revolve() gives them as such (its pole triangles).
    return [tuple((p[1], p[2], p[0]) for p in t) for t in revolve(profile, segments)]


def box(a, b, c):
    """The box a x b x c centred at the origin: 12 triangles."""
    corners = [(x, y, z) for z in (-c / 2, c / 2) for y in (-b / 2, b / 2) for x in (-a / 2, a / 2)]
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return [t for q in quads for t in ((corners[q[0]], corners[q[1]], corners[q[2]]),
                                       (corners[q[0]], corners[q[2]], corners[q[3]]))]


def write_binary(triangles, path):
    with open(path, "wb") as out:
        out.write(b"pdsim validation/cavity_stl.py".ljust(80, b" "))
        out.write(struct.pack("<I", len(triangles)))
        for t in triangles:
            out.write(struct.pack("<12fH", 0.0, 0.0, 0.0, *(c for p in t for c in p), 0))


def write_ascii(triangles, path, offset=(0.0, 0.0, 0.0)):
    """ASCII STL (LIGGGHTS 3.8 reads no binary STL), every vertex moved by `offset`."""
    with open(path, "w") as out:
        out.write("solid cavity\n")
        for t in triangles:
            out.write("facet normal 0 0 0\nouter loop\n")
            for p in t:
                out.write("vertex %r %r %r\n" % tuple(c + o for c, o in zip(p, offset)))
            out.write("endloop\nendfacet\n")
        out.write("endsolid cavity\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("kind", choices=["capsule", "cylinder"])
    parser.add_argument("out")
    parser.add_argument("--radius", type=float)
    parser.add_argument("--length", type=float)
    parser.add_argument("--segments", type=int)
    parser.add_argument("--rings", type=int, default=12)
    parser.add_argument("--ascii", action="store_true", help="ASCII STL instead of binary")
    parser.add_argument("--offset", type=float, nargs=3, default=(0.0, 0.0, 0.0),
                        metavar=("X", "Y", "Z"), help="move every vertex by this (with --ascii)")
    a = parser.parse_args()
    if a.kind == "capsule":
        t = capsule(a.radius or 25.0, a.length or 30.0, a.segments or 48, a.rings)
    else:
        t = cylinder(a.radius or 28.0, a.length or 50.0, a.segments or 512)
    if a.ascii:
        write_ascii(t, a.out, a.offset)
    else:
        write_binary(t, a.out)
    print(f"{a.out}: {a.kind}, {len(t)} triangles")


if __name__ == "__main__":
    main()
