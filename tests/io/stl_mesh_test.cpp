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
#include "tests/support/stl_files.hpp"
#include "kernels/errors.hpp"

using namespace pdsim;
namespace fs = std::filesystem;
using namespace pdsim::stl_files;

namespace {

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

TEST_CASE(
    "stl: open, flipped, self-intersecting, nested, empty and NaN meshes are refused by name") {
  std::vector<Triangle> open = box(1, 1, 1);
  open.pop_back();
  refused(ascii(open, "open.stl"), "not closed: the edge from");
  std::vector<Triangle> flipped = box(1, 1, 1);
  std::swap(flipped[4][1], flipped[4][2]);
  refused(ascii(flipped, "flipped.stl"), "not consistently oriented: triangle");
  std::vector<Triangle> crossing = box(1, 1, 1);
  for (const Triangle& t : box(1, 1, 1, {0.5, 0.5, 0.5})) crossing.push_back(t);
  refused(ascii(crossing, "crossing.stl"), "cross each other");
  // A box inside a box, faced alike, and two boxes side by side: one cavity is a container.
  std::vector<Triangle> nested = box(1, 1, 1);
  for (const Triangle& t : box(0.5, 0.5, 0.5, {0.25, 0.25, 0.25})) nested.push_back(t);
  refused(ascii(nested, "nested.stl"), "its triangles form 2 separate closed surfaces (of 12, 12");
  std::vector<Triangle> apart = box(1, 1, 1);
  for (const Triangle& t : box(1, 1, 1, {3, 0, 0})) apart.push_back(t);
  refused(binary(apart, "apart.stl"), "2 separate closed surfaces");
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
