// STL files for the tests: boxes, spheres and capped cylinders as triangles, written as ASCII
// or binary STL in a scratch folder of the test process.
#pragma once

#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "kernels/vec3.hpp"

namespace pdsim::stl_files {

namespace fs = std::filesystem;

using Triangle = std::array<Vec3, 3>;

// The 12 triangles of the box [0, a] x [0, b] x [0, c] plus `shift`, counter-clockwise seen from
// outside.
inline std::vector<Triangle> box(double a, double b, double c, Vec3 shift = {}) {
  std::vector<Vec3> v;
  for (int k = 0; k < 8; ++k)
    v.push_back(Vec3{k & 1 ? a : 0, k & 2 ? b : 0, k & 4 ? c : 0} + shift);
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  std::vector<Triangle> t;
  for (const auto& q : quads) {
    t.push_back({v[q[0]], v[q[1]], v[q[2]]});
    t.push_back({v[q[0]], v[q[2]], v[q[3]]});
  }
  return t;
}

// A sphere of radius r: a UV mesh of `rings` x 2 `rings` quads, each two triangles.
inline std::vector<Triangle> sphere(double r, int rings) {
  auto at = [&](int i, int j) {  // the poles and the seam exact, so that they are shared
    if (i == 0 || i == rings) return Vec3{0, 0, i == 0 ? r : -r};
    const double theta = kPi * i / rings, phi = kPi * (j % (2 * rings)) / rings;
    return Vec3{r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi),
                r * std::cos(theta)};
  };
  std::vector<Triangle> t;
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < 2 * rings; ++j) {
      const Vec3 a = at(i, j), b = at(i + 1, j), c = at(i + 1, j + 1), d = at(i, j + 1);
      if (i > 0) t.push_back({a, b, d});          // not at the north pole
      if (i < rings - 1) t.push_back({b, c, d});  // nor at the south pole
    }
  return t;
}

inline fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_stl_test_" + std::to_string(getpid()));
  fs::create_directories(dir);
  return dir / name;
}

inline std::string ascii(const std::vector<Triangle>& triangles, const std::string& name) {
  const fs::path path = scratch(name);
  std::ofstream out(path);
  out.precision(17);
  out << "solid test\n";
  for (const Triangle& t : triangles) {
    out << "facet normal 0 0 0\nouter loop\n";
    for (const Vec3& v : t) out << "vertex " << v.x << " " << v.y << " " << v.z << "\n";
    out << "endloop\nendfacet\n";
  }
  out << "endsolid test\n";
  return path.string();
}

inline std::string binary(const std::vector<Triangle>& triangles, const std::string& name) {
  const fs::path path = scratch(name);
  std::ofstream out(path, std::ios::binary);
  const std::string header(80, ' ');
  out.write(header.data(), 80);
  const auto count = static_cast<std::uint32_t>(triangles.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  for (const Triangle& t : triangles) {
    float record[12] = {};
    for (int k = 0; k < 3; ++k) {
      record[3 + 3 * k] = static_cast<float>(t[k].x);
      record[4 + 3 * k] = static_cast<float>(t[k].y);
      record[5 + 3 * k] = static_cast<float>(t[k].z);
    }
    out.write(reinterpret_cast<const char*>(record), sizeof record);
    out.write("\0\0", 2);
  }
  return path.string();
}

// A closed cylinder of radius r and length h along z, centred at the origin: `segments` facets
// around, each a quad of two triangles, and fans for the end caps.
inline std::vector<Triangle> cylinder(double r, double h, int segments) {
  auto rim = [&](int k, double z) {
    const double a = 2 * kPi * (k % segments) / segments;
    return Vec3{r * std::cos(a), r * std::sin(a), z};
  };
  const Vec3 top{0, 0, 0.5 * h}, bottom{0, 0, -0.5 * h};
  std::vector<Triangle> t;
  for (int k = 0; k < segments; ++k) {
    const Vec3 a = rim(k, -0.5 * h), b = rim(k + 1, -0.5 * h), c = rim(k + 1, 0.5 * h),
               d = rim(k, 0.5 * h);
    t.push_back({a, b, c});
    t.push_back({a, c, d});
    t.push_back({d, c, top});
    t.push_back({b, a, bottom});
  }
  return t;
}

// A prism: the polygon `outline` (counter-clockwise in the xy plane, seen by every other vertex
// from its first, so that a fan from it covers it) from z = z0 to z = z1.
inline std::vector<Triangle> prism(const std::vector<Vec3>& outline, double z0, double z1) {
  auto at = [](Vec3 p, double z) { return Vec3{p.x, p.y, z}; };
  const std::size_t n = outline.size();
  std::vector<Triangle> t;
  for (std::size_t k = 0; k < n; ++k) {
    const Vec3 a = outline[k], b = outline[(k + 1) % n];
    t.push_back({at(a, z0), at(b, z0), at(b, z1)});
    t.push_back({at(a, z0), at(b, z1), at(a, z1)});
  }
  for (std::size_t k = 1; k + 1 < n; ++k) {
    t.push_back({at(outline[0], z1), at(outline[k], z1), at(outline[k + 1], z1)});
    t.push_back({at(outline[0], z0), at(outline[k + 1], z0), at(outline[k], z0)});
  }
  return t;
}

// A funnel: a regular `sides`-gon prism of circumradius r from z = 0 to z = h over a pyramid
// with its apex at z = -depth on the axis.
inline std::vector<Triangle> funnel(double r, double h, double depth, int sides) {
  auto rim = [&](int k, double z) {
    const double a = 2 * kPi * (k % sides) / sides;
    return Vec3{r * std::cos(a), r * std::sin(a), z};
  };
  const Vec3 top{0, 0, h}, apex{0, 0, -depth};
  std::vector<Triangle> t;
  for (int k = 0; k < sides; ++k) {
    const Vec3 a = rim(k, 0), b = rim(k + 1, 0), c = rim(k + 1, h), d = rim(k, h);
    t.push_back({a, b, c});
    t.push_back({a, c, d});
    t.push_back({d, c, top});
    t.push_back({b, a, apex});
  }
  return t;
}

}  // namespace pdsim::stl_files
