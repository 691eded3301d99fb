// Container meshes from STL files: closed, consistently oriented, not self-intersecting, else
// refused by name; the volume and inside test against the solids' formulas.
#include <doctest/doctest.h>

#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "io/stl_mesh.hpp"
#include "kernels/errors.hpp"

using namespace pdsim;
namespace fs = std::filesystem;

namespace {

using Triangle = std::array<Vec3, 3>;

// The 12 triangles of the box [0, a] x [0, b] x [0, c] plus `shift`, counter-clockwise seen from
// outside.
std::vector<Triangle> box(double a, double b, double c, Vec3 shift = {}) {
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
std::vector<Triangle> sphere(double r, int rings) {
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

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("pdsim_stl_test_" + std::to_string(getpid()));
  fs::create_directories(dir);
  return dir / name;
}

std::string ascii(const std::vector<Triangle>& triangles, const std::string& name) {
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

std::string binary(const std::vector<Triangle>& triangles, const std::string& name) {
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

// The volume the triangles enclose as they are oriented (divergence theorem): positive when
// they face outward.
double signed_volume(const TriangleMesh& m) {
  double v = 0;
  for (const auto& t : m.triangles)
    v += dot(m.vertices[t[0]], cross(m.vertices[t[1]], m.vertices[t[2]])) / 6;
  return v;
}

void refused(const std::string& path, const std::string& words) {
  CAPTURE(path);
  CHECK_THROWS_WITH_AS(read_stl(path, 1.0), doctest::Contains(words.c_str()), InputError);
  try {
    read_stl(path, 1.0);
  } catch (const InputError& e) {
    CHECK(std::string(e.what()).rfind(path + ": ", 0) == 0);  // names the file first
  }
}

}  // namespace

TEST_CASE("stl: a box, ASCII or binary in mm, has the box's volume and bounds, faced outward") {
  const TriangleMesh m = read_stl(ascii(box(0.05, 0.04, 0.03), "box.stl"), 1.0);
  CHECK(m.triangles.size() == 12);
  CHECK(m.vertices.size() == 8);  // corners shared by their triangles
  CHECK(m.volume == doctest::Approx(0.05 * 0.04 * 0.03).epsilon(1e-12));
  CHECK(signed_volume(m) == doctest::Approx(m.volume).epsilon(1e-12));
  CHECK(m.high.x - m.low.x == doctest::Approx(0.05));
  const TriangleMesh mm = read_stl(binary(box(50, 40, 30), "box_mm.stl"), 0.001);
  CHECK(mm.volume == doctest::Approx(0.05 * 0.04 * 0.03).epsilon(1e-6));
  CHECK(mm.high.z == doctest::Approx(0.03));
  // Faced inward throughout: consistent, so turned outward.
  std::vector<Triangle> inward = box(0.05, 0.04, 0.03);
  for (Triangle& t : inward) std::swap(t[1], t[2]);
  const TriangleMesh turned = read_stl(ascii(inward, "inward.stl"), 1.0);
  CHECK(signed_volume(turned) == doctest::Approx(0.05 * 0.04 * 0.03).epsilon(1e-12));
  const MeshInside inside(m);
  CHECK(inside({0.025, 0.02, 0.015}));
  CHECK(inside({0.0499, 0.0001, 0.0299}));
  CHECK_FALSE(inside({0.0501, 0.02, 0.015}));
  CHECK_FALSE(inside({0.025, -0.001, 0.015}));
  fs::remove_all(fs::path(scratch("x")).parent_path());
}

TEST_CASE("stl: a sphere of 2,000+ triangles encloses 4/3 pi r^3 to its facets' error") {
  const double r = 0.02;
  const int rings = 33;  // 2 x 33 x 66 - 2 x 66 = 4,224 triangles
  const TriangleMesh m = read_stl(binary(sphere(r, rings), "sphere.stl"), 1.0);
  CHECK(m.triangles.size() >= 2000);
  // Inscribed: below the sphere by the facets' sagitta, O((pi / rings)^2) of the volume.
  const double exact = 4.0 / 3.0 * kPi * r * r * r;
  CHECK(m.volume < exact);
  CHECK(m.volume > exact * (1 - 1.5 * std::pow(kPi / rings, 2)));
  const MeshInside inside(m);
  CHECK(inside({0, 0, 0}));
  CHECK(inside({0.0195, 0, 0}));
  CHECK_FALSE(inside({0.0201, 0, 0}));
  CHECK_FALSE(inside({0.015, 0.015, 0.0}));  // 21 mm from the centre
  fs::remove_all(fs::path(scratch("x")).parent_path());
}

TEST_CASE("stl: open, flipped, self-intersecting, empty and NaN meshes are refused by name") {
  std::vector<Triangle> open = box(1, 1, 1);
  open.pop_back();
  refused(ascii(open, "open.stl"), "not closed: the edge from");
  std::vector<Triangle> flipped = box(1, 1, 1);
  std::swap(flipped[4][1], flipped[4][2]);
  refused(ascii(flipped, "flipped.stl"), "not consistently oriented: triangle");
  std::vector<Triangle> crossing = box(1, 1, 1);
  for (const Triangle& t : box(1, 1, 1, {0.5, 0.5, 0.5})) crossing.push_back(t);
  refused(ascii(crossing, "crossing.stl"), "cross each other");
  std::ofstream(scratch("empty.stl"));
  refused(scratch("empty.stl").string(), "empty (0 bytes)");
  std::ofstream(scratch("none.stl")) << "solid none\nendsolid none\n";
  refused(scratch("none.stl").string(), "no triangles");
  std::vector<Triangle> nan = box(1, 1, 1);
  nan[0][0].x = std::numeric_limits<double>::quiet_NaN();
  refused(binary(nan, "nan.stl"), "not a number");
  refused(scratch("missing.stl").string(), "no such STL file");
  fs::remove_all(fs::path(scratch("x")).parent_path());
}
