// The box container: six flat walls, half edge lengths half_size. Everything pdsim knows of a
// container shape is in its header (kernels/shapes.hpp lists them): its walls for the step
// kernels (host and device), the near-wall test, and on the host the fill test, volume, size
// limit and wireframe. The kernels' functions are PDSIM_HOT: inlined into the particle loop,
// which an out-of-line call would keep from vectorising.
#pragma once

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "kernels/dem_types.hpp"

namespace pdsim {

struct BoxShape {
  static constexpr const char* name = "box";
  static constexpr bool kKeyed = false;  // walls() names fixed slots

  // Its geometry from the deck's words (ContainerSpec, kernels/shapes.hpp): `size`, m.
  template <class Spec>
  static ContainerGeometry geometry(const Spec& c) {
    ContainerGeometry g;
    g.half_size = 0.5 * c.size;
    return g;
  }

  // The two walls across one axis of a centre at `along` (container frame) of radius r, walls
  // at -half and +half with slots `slot` and slot + 1 and inward normals `low` and `high` (the
  // container frame): wall(slot, gap, normal) for each, escaped(distance beyond) once.
  template <class Wall, class Escaped>
  PDSIM_HOT static void slab(double along, double half, double r, int slot, Vec3 low, Vec3 high,
                             Wall&& wall, Escaped&& escaped) {
    if (fabs(along) > half - r) {
      wall(slot, along + half, low);
      wall(slot + 1, half - along, high);
      escaped(fabs(along) - half);
    }
  }

  // The walls a centre at `local` (container frame) of radius r may touch, in slot order:
  // wall(slot, gap, normal) (gap may exceed r: the caller skips those), escaped(beyond).
  template <class Wall, class Escaped>
  PDSIM_HOT static void walls(Vec3 local, double r, const ContainerGeometry& g, Wall&& wall,
                              Escaped&& escaped) {
    const Vec3 h = g.half_size;
    slab(local.x, h.x, r, 0, {1, 0, 0}, {-1, 0, 0}, wall, escaped);
    slab(local.y, h.y, r, 2, {0, 1, 0}, {0, -1, 0}, wall, escaped);
    slab(local.z, h.z, r, 4, {0, 0, 1}, {0, 0, -1}, wall, escaped);
  }

  // What decides it, for the scene's identity (src/identity.cpp): add(name, value, unit).
  template <class Add>
  static void identity(const ContainerGeometry& g, Add&& add) {
    add("size", 2 * g.half_size, "m");
  }

  // "box 0.05 x 0.05 x 0.05 m" (pdsim check).
  template <class Spec>
  static std::string describe(const Spec& c) {
    std::ostringstream s;
    s << name << " " << c.size.x << " x " << c.size.y << " x " << c.size.z << " m";
    return s.str();
  }

  // Bounding test: may a centre at `local` of radius r touch a wall (or be outside)?
  PDSIM_HOT static bool near(Vec3 local, double r, const ContainerGeometry& g) {
    const Vec3 inner = g.half_size - Vec3{r, r, r};
    bool near = fabs(local.z) > inner.z;
    near |= (fabs(local.x) > inner.x) | (fabs(local.y) > inner.y);
    return near;
  }

  // Host: a sphere of radius r at `local` lies inside (the fill).
  static bool inside(Vec3 local, double r, const ContainerGeometry& g) {
    const Vec3 h = g.half_size;
    if (std::fabs(local.z) > h.z - r) return false;
    return std::fabs(local.x) <= h.x - r && std::fabs(local.y) <= h.y - r;
  }
  static double volume(const ContainerGeometry& g) {  // m^3
    return 8 * g.half_size.x * g.half_size.y * g.half_size.z;
  }
  // The narrowest inside width, m: a particle must be narrower.
  static double smallest_inner_size(const ContainerGeometry& g) {
    return 2 * std::min({g.half_size.x, g.half_size.y, g.half_size.z});
  }
  // The edges in the container frame: points and pairs of point indices (OUT.xdmf, plots).
  static void wireframe(const ContainerGeometry& g, std::vector<Vec3>& points,
                        std::vector<int>& segments) {
    const Vec3 h = g.half_size;
    for (int k = 0; k < 8; ++k)
      points.push_back({k & 1 ? h.x : -h.x, k & 2 ? h.y : -h.y, k & 4 ? h.z : -h.z});
    for (int k = 0; k < 8; ++k)
      for (int bit : {1, 2, 4})
        if (!(k & bit)) segments.insert(segments.end(), {k, k | bit});
  }
};

}  // namespace pdsim
