// Contact counts of a state (kernels/contact_count.hpp) against configurations built with known
// contacts and against the definition tested pair by pair.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "io/stl_mesh.hpp"
#include "kernels/contact_count.hpp"
#include "tests/support/stl_files.hpp"

namespace {

using namespace pdsim;

ContainerGeometry box(Vec3 half_size) {
  ContainerGeometry g;
  g.half_size = half_size;
  return g;
}

}  // namespace

TEST_CASE("contact counts: a chain touching a wall, a corner, a free particle") {
  const double r = 0.001, h = 0.01, overlap = 1e-7;
  const ContainerGeometry g = box({h, h, h});
  // A chain along x from the -x wall; a particle in the +x +y +z corner (three walls); one free.
  const std::vector<Vec3> centre{{-h + r - overlap, 0, 0},
                                 {-h + 3 * r - 2 * overlap, 0, 0},
                                 {-h + 5 * r - 3 * overlap, 0, 0},
                                 {h - r + overlap, h - r + overlap, h - r + overlap},
                                 {0.003, -0.004, 0.002}};
  const std::vector<double> radius(centre.size(), r);
  const auto counts = contact_counts(centre, radius, WallShape::box, g, ContainerKinematics{});
  CHECK(counts == std::vector<std::int32_t>{2, 2, 1, 3, 0});
  // Each gap opened to 1e-6 m instead of closed by 1e-7 m: nothing touches.
  const double gap = 1e-6;
  const std::vector<Vec3> apart{{-h + r + gap, 0, 0},
                                {-h + 3 * r + 2 * gap, 0, 0},
                                {-h + 5 * r + 3 * gap, 0, 0},
                                {h - r - gap, h - r - gap, h - r - gap},
                                {0.003, -0.004, 0.002}};
  CHECK(contact_counts(apart, radius, WallShape::box, g, ContainerKinematics{}) ==
        std::vector<std::int32_t>(centre.size(), 0));
  // The same box as 12 triangles: a face, the corner's three faces (not its edges or corner).
  ContainerSpec spec;
  const std::string stl =
      stl_files::ascii(stl_files::box(2 * h, 2 * h, 2 * h, {-h, -h, -h}), "counts.stl");
  spec.mesh = load_mesh(stl, 1.0, kDefaultCurvature);
  std::filesystem::remove(stl);
  const ContainerGeometry mesh = MeshShape::geometry(spec);
  CHECK(contact_counts(centre, radius, WallShape::mesh, mesh, ContainerKinematics{}) ==
        std::vector<std::int32_t>{2, 2, 1, 3, 0});
  CHECK(contact_counts(apart, radius, WallShape::mesh, mesh, ContainerKinematics{}) ==
        std::vector<std::int32_t>(centre.size(), 0));
}

TEST_CASE("contact counts: walls of a turned, moved cylinder") {
  // The container turned 90 degrees about x (its axis along world -y) and moved: a particle
  // touching its curved wall and one touching a cap, in world coordinates.
  ContainerGeometry g;
  g.radius = 0.01;
  g.half_size = {0.01, 0.01, 0.02};
  ContainerKinematics c;
  c.position = {0.1, 0.2, 0.3};
  c.axis_x = {1, 0, 0};
  c.axis_y = {0, 0, 1};
  c.axis_z = {0, -1, 0};
  const double r = 0.001;
  const std::vector<Vec3> centre{c.position + Vec3{0.01 - r + 1e-7, 0, 0},     // curved wall
                                 c.position + Vec3{0, -(0.02 - r + 1e-7), 0},  // the +z cap
                                 c.position + Vec3{0, 0, 0.01 - r - 1e-6}};    // near, apart
  const auto counts = contact_counts(centre, std::vector<double>(3, r), WallShape::cylinder, g, c);
  CHECK(counts == std::vector<std::int32_t>{1, 1, 0});
}

TEST_CASE("contact counts of a random polydisperse cloud equal the pair-by-pair definition") {
  // 3,000 spheres placed at random (overlapping freely) in a box, several to a grid cell: the
  // grid must find every overlapping pair that the O(N^2) test finds, and no other.
  const ContainerGeometry g = box({0.02, 0.015, 0.01});
  std::uint64_t state = 7;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  std::vector<Vec3> centre;
  std::vector<double> radius;
  for (int i = 0; i < 3000; ++i) {
    radius.push_back(0.0005 + 0.001 * uniform());
    centre.push_back(
        {(2 * uniform() - 1) * 0.02, (2 * uniform() - 1) * 0.015, (2 * uniform() - 1) * 0.01});
  }
  std::vector<std::int32_t> expected(centre.size(), 0);
  long long pairs = 0;
  for (std::size_t i = 0; i < centre.size(); ++i) {
    for (std::size_t j = i + 1; j < centre.size(); ++j) {
      const Vec3 d = centre[i] - centre[j];
      if (std::sqrt(dot(d, d)) < radius[i] + radius[j]) ++expected[i], ++expected[j], ++pairs;
    }
    const Vec3 x = centre[i];
    for (double gap : {x.x + 0.02, 0.02 - x.x, x.y + 0.015, 0.015 - x.y, x.z + 0.01, 0.01 - x.z})
      expected[i] += gap < radius[i];
  }
  REQUIRE(pairs > 3000);
  CHECK(contact_counts(centre, radius, WallShape::box, g, ContainerKinematics{}) == expected);
}
