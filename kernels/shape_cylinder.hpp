// The cylinder container: a curved wall of radius `radius` about the container's z axis and
// two flat end caps at +-half_size.z (half_size = (radius, radius, half height)). Laid along
// another axis by the container's orientation (dem_types.hpp), not here.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "kernels/shape_box.hpp"

namespace pdsim {

struct CylinderShape {
  static constexpr const char* name = "cylinder";
  static constexpr bool kKeyed = false;    // walls() names fixed slots
  static constexpr int kRimSegments = 32;  // the rims drawn as polygons

  // `radius` and `height`, m.
  template <class Spec>
  static ContainerGeometry geometry(const Spec& c) {
    ContainerGeometry g;
    g.half_size = {c.radius, c.radius, 0.5 * c.height};
    g.radius = c.radius;
    return g;
  }

  template <class Wall, class Escaped>
  PDSIM_HOT static void walls(Vec3 local, double r, const ContainerGeometry& g, Wall&& wall,
                              Escaped&& escaped) {
    const double rho_sq = local.x * local.x + local.y * local.y;
    const double inner = g.radius - r;
    if (rho_sq > inner * inner) {
      const double rho = sqrt(rho_sq);
      wall(0, g.radius - rho, Vec3{-local.x / rho, -local.y / rho, 0});
      escaped(rho - g.radius);
    }
    BoxShape::slab(local.z, g.half_size.z, r, 4, {0, 0, 1}, {0, 0, -1}, wall, escaped);  // caps
  }

  // What decides it, for the scene's identity (src/identity.cpp): add(name, value, unit); its
  // axis is the container's orientation, which the identity holds apart.
  template <class Add>
  static void identity(const ContainerGeometry& g, Add&& add) {
    add("radius", g.radius, "m");
    add("height", 2 * g.half_size.z, "m");
  }

  template <class Spec>
  static std::string describe(const Spec& c) {
    std::ostringstream s;
    s << name << ", radius " << c.radius << " m, length " << c.height << " m, axis [" << c.axis.x
      << ", " << c.axis.y << ", " << c.axis.z << "]";
    return s.str();
  }

  PDSIM_HOT static bool near(Vec3 local, double r, const ContainerGeometry& g) {
    bool near = fabs(local.z) > g.half_size.z - r;
    const double inside = g.radius - r;
    near |= local.x * local.x + local.y * local.y > inside * inside;
    return near;
  }

  static bool inside(Vec3 local, double r, const ContainerGeometry& g) {
    if (std::fabs(local.z) > g.half_size.z - r) return false;
    return std::hypot(local.x, local.y) <= g.radius - r;
  }
  static double volume(const ContainerGeometry& g) {
    return kPi * g.radius * g.radius * (2 * g.half_size.z);
  }
  static double smallest_inner_size(const ContainerGeometry& g) {
    return 2 * std::min(g.radius, g.half_size.z);
  }
  static void wireframe(const ContainerGeometry& g, std::vector<Vec3>& points,
                        std::vector<int>& segments) {
    const Vec3 h = g.half_size;
    for (int rim = 0; rim < 2; ++rim)
      for (int k = 0; k < kRimSegments; ++k) {
        const double a = 2 * kPi * k / kRimSegments;
        points.push_back({h.x * std::cos(a), h.y * std::sin(a), rim ? h.z : -h.z});
        const int base = rim * kRimSegments;
        segments.insert(segments.end(), {base + k, base + (k + 1) % kRimSegments});
      }
    for (int k = 0; k < kRimSegments; k += kRimSegments / 4)
      segments.insert(segments.end(), {k, k + kRimSegments});
  }
};

}  // namespace pdsim
