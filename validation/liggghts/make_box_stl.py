#!/usr/bin/env python3
"""Writes a closed axis-aligned box as an ASCII STL of 12 triangles (normals outward).

LIGGGHTS mesh walls (fix mesh/surface + fix wall/gran) act on both sides of a triangle, so the
normal orientation does not change the contact; outward normals keep the file a valid solid.

usage: make_box_stl.py LX LY LZ OUT.stl      (box [0,LX] x [0,LY] x [0,LZ], metres)
"""
import sys


def box_triangles(lx, ly, lz):
    """Yields (normal, (a, b, c)) with counter-clockwise vertices seen from outside."""
    p = [(x, y, z) for z in (0.0, lz) for y in (0.0, ly) for x in (0.0, lx)]
    # corner index = x_bit + 2 y_bit + 4 z_bit; each face as a counter-clockwise quad from outside
    faces = [
        ((0.0, 0.0, -1.0), (0, 2, 3, 1)),  # z = 0
        ((0.0, 0.0, 1.0), (4, 5, 7, 6)),  # z = lz
        ((0.0, -1.0, 0.0), (0, 1, 5, 4)),  # y = 0
        ((0.0, 1.0, 0.0), (2, 6, 7, 3)),  # y = ly
        ((-1.0, 0.0, 0.0), (0, 4, 6, 2)),  # x = 0
        ((1.0, 0.0, 0.0), (1, 3, 7, 5)),  # x = lx
    ]
    for normal, (a, b, c, d) in faces:
        yield normal, (p[a], p[b], p[c])
        yield normal, (p[a], p[c], p[d])


def cross(u, v):
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def write_stl(path, lx, ly, lz):
    lines = ["solid box"]
    for normal, (a, b, c) in box_triangles(lx, ly, lz):
        winding = cross([b[i] - a[i] for i in range(3)], [c[i] - a[i] for i in range(3)])
        if sum(winding[i] * normal[i] for i in range(3)) <= 0.0:
            raise AssertionError("triangle winding disagrees with its outward normal")
        lines.append("  facet normal %g %g %g" % normal)
        lines.append("    outer loop")
        for v in (a, b, c):
            lines.append("      vertex %.9g %.9g %.9g" % v)
        lines.append("    endloop")
        lines.append("  endfacet")
    lines.append("endsolid box")
    with open(path, "w") as out:
        out.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    lx, ly, lz = (float(s) for s in sys.argv[1:4])
    if min(lx, ly, lz) <= 0.0:
        sys.exit("box sizes must be > 0 m")
    write_stl(sys.argv[4], lx, ly, lz)
