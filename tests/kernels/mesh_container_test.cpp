// A container given as a triangle mesh against the analytic container of the same shape: a box
// as 12 triangles follows the analytic box's trajectories (impacts on a face, an edge and a
// corner; a ball rolling across the diagonal that splits a face), and the impacts give the
// restitution and contact time of the formulas.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <vector>

#include "io/stl_mesh.hpp"
#include "kernels/engine.hpp"
#include "tests/kernels/dem_fixtures.hpp"
#include "tests/support/stl_files.hpp"
#include "tests/support/validation_row.hpp"

using namespace pdsim;
using namespace pdsim::fixtures;

namespace {

constexpr double kHalf = 0.02;     // m, the box's half edge
constexpr double kRadius = 0.004;  // m

// The box as an STL mesh, in an engine config otherwise `c`'s.
struct MeshBox {
  ContainerSpec spec;
  explicit MeshBox(const std::string& name) {
    spec.shape = WallShape::mesh;
    const std::string path = stl_files::ascii(
        stl_files::box(2 * kHalf, 2 * kHalf, 2 * kHalf, {-kHalf, -kHalf, -kHalf}), name);
    spec.mesh = load_mesh(path, 1.0, kDefaultCurvature);
    std::filesystem::remove(path);
  }
  EngineConfig config(EngineConfig c) const {
    c.shape = WallShape::mesh;
    c.geometry = MeshShape::geometry(spec);
    return c;
  }
};

// The particle's state after `steps` steps.
ParticleState after(const EngineConfig& c, int steps) {
  auto engine = make_engine(c);
  for (int k = 0; k < steps; ++k) step(*engine, c.dt);
  return engine->particles()[0];
}

double relative(Vec3 a, Vec3 b) {
  return norm(a - b) / std::max(norm(b), 1e-300);
}

}  // namespace

TEST_CASE("a box as 12 triangles: face, edge and corner impacts as the analytic box and Hertz") {
  const MeshBox mesh("impacts.stl");
  const double speed = 1.0, e = 0.6;
  const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, e, 0);
  const double mass = ball_mass(kRadius, kSteelDensity);
  double worst_e = 0, worst_path = 0;
  // Towards a face (-z), an edge (-x, -z) and a corner (-x, -y, -z), the normal speed `speed`
  // on each wall it meets.
  for (const Vec3 towards : {Vec3{0, 0, -1}, Vec3{-1, 0, -1}, Vec3{-1, -1, -1}}) {
    CAPTURE(towards.x);
    CAPTURE(towards.y);
    const double tc = hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, speed);
    const double dt = tc / 1000;
    const double gap = 0.25 * speed * tc;  // a quarter contact time of flight
    Vec3 start{0.003, -0.002, 0.001};      // off the diagonals and centre
    if (towards.x < 0) start.x = -kHalf + kRadius + gap;
    if (towards.y < 0) start.y = -kHalf + kRadius + gap;
    start.z = -kHalf + kRadius + gap;
    EngineConfig box =
        steel_box({kHalf, kHalf, kHalf}, NormalModel::hertz, TangentialModel::none, contact, dt);
    add_particle(box, kRadius, start, speed * towards);
    const int steps = static_cast<int>((2 * gap / speed + 1.5 * tc) / dt);
    const ParticleState analytic = after(box, steps), meshed = after(mesh.config(box), steps);
    CHECK(relative(meshed.position, analytic.position) < 1e-12);
    CHECK(relative(meshed.velocity, analytic.velocity) < 1e-9);
    worst_path = std::max(worst_path, relative(meshed.velocity, analytic.velocity));
    // Each wall met reverses its normal component by e; the others keep theirs.
    const Vec3 v = meshed.velocity;
    for (const double component : {v.x, v.y, v.z})
      if (component != 0) {
        CHECK(std::fabs(component / speed - e) < 5e-4);
        worst_e = std::max(worst_e, std::fabs(component / speed - e));
      }
  }
  validation_bound("mesh box (12 triangles): face, edge and corner impacts, |e - e_set|",
                   "Tsuji's restitution of the Hertz law", 5e-4, worst_e, "");
  validation_bound("mesh box against the analytic box: the same impacts, |v_mesh / v_box - 1|",
                   "the analytic box", 1e-9, worst_path, "");
}

TEST_CASE("a ball rolling across the diagonal that splits the mesh box's floor keeps its history") {
  // Mindlin history with friction: the ball rolls down a tilted floor, static friction (the
  // history's spring) holding its contact point still, across the floor's two triangles. The
  // history follows it across the diagonal (one surface), so the trajectory is the analytic
  // floor's.
  const MeshBox mesh("rolling.stl");
  const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, 0.6, 0.3);
  const double tc =
      hertz_contact_time(ball_mass(kRadius, kSteelDensity), kRadius, contact.hertz_modulus_pw, 1);
  const double dt = tc / 50;
  EngineConfig box =
      steel_box({kHalf, kHalf, kHalf}, NormalModel::hertz, TangentialModel::history, contact, dt);
  box.gravity = Vec3{2.0, 1.0, -9.5};  // a tilted floor: down along (2, 1)
  // Resting on the floor (its static overlap), moving along +x +y across the diagonal x = y.
  const double rest = std::pow(9 * std::pow(ball_mass(kRadius, kSteelDensity) * 9.5, 2) /
                                   (16 * kRadius * std::pow(contact.hertz_modulus_pw, 2)),
                               1.0 / 3);
  add_particle(box, kRadius, {-0.014, -0.010, -kHalf + kRadius - rest}, {});
  const int steps = static_cast<int>(0.15 / dt);  // 20 mm along x: across the diagonal
  const ParticleState analytic = after(box, steps), meshed = after(mesh.config(box), steps);
  REQUIRE(analytic.position.x > analytic.position.y + 0.001);  // it crossed
  // The same floor to the last bit (its plane is z = -kHalf either way); a history dropped once
  // midway moves the ball by 1.6e-8 of its position (measured when this test was written).
  CHECK(relative(meshed.position, analytic.position) < 1e-12);
  CHECK(relative(meshed.velocity, analytic.velocity) < 1e-12);
  CHECK(relative(meshed.spin, analytic.spin) < 1e-12);
  // Rolling down the slope: a = 5/7 g along it, and the contact point at rest (v = omega x r).
  const double t = steps * dt;
  CHECK(std::fabs(meshed.velocity.x / (5.0 / 7 * 2.0 * t) - 1) < 1e-2);
  CHECK(std::fabs(meshed.velocity.x - meshed.spin.y * kRadius) < 1e-3 * meshed.velocity.x);
}

TEST_CASE("an L-shaped cavity: a ball meeting its re-entrant edge bounces off the edge alone") {
  // The cavity's re-entrant edge (along z at x = y = a) is convex seen from inside: a ball coming
  // at it along the bisector touches the edge, not the faces beside it, and the edge acts as a
  // wall normal to the bisector: restitution e and Hertz's contact time along it.
  const double a = 0.02, speed = 1.0, e = 0.6;
  ContainerSpec spec;
  spec.shape = WallShape::mesh;
  const std::string path = stl_files::ascii(
      stl_files::prism(
          {{0, 0, 0}, {2 * a, 0, 0}, {2 * a, a, 0}, {a, a, 0}, {a, 2 * a, 0}, {0, 2 * a, 0}},
          -0.5 * a, 0.5 * a),
      "l_cavity.stl");
  spec.mesh = load_mesh(path, 1.0, kDefaultCurvature);
  std::filesystem::remove(path);
  const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, e, 0);
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double tc = hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, speed);
  const double dt = tc / 1000;
  EngineConfig c = steel_box({a, a, a}, NormalModel::hertz, TangentialModel::none, contact, dt);
  c.shape = WallShape::mesh;
  c.geometry = MeshShape::geometry(spec);
  const Vec3 bisector{std::sqrt(0.5), std::sqrt(0.5), 0};
  const double gap = 0.25 * speed * tc;
  add_particle(c, kRadius, Vec3{a, a, 0} - (kRadius + gap) * bisector, speed * bisector);
  auto engine = make_engine(c);
  const ImpactRecord r = follow_impact(
      *engine, dt,
      [&](const std::vector<ParticleState>& p) {
        return kRadius - norm(Vec3{a - p[0].position.x, a - p[0].position.y, 0});
      },
      100000);
  const Vec3 v = r.after[0].velocity;
  CHECK(std::fabs(dot(v, bisector) / speed + e) < 5e-4);
  CHECK(std::fabs(v.x - v.y) < 1e-12 * speed);  // straight back along the bisector
  CHECK(std::fabs(v.z) < 1e-12 * speed);
  validation_bound("mesh L cavity: a ball on its convex inner edge, |e - e_set|",
                   "Tsuji's restitution of the Hertz law", 5e-4,
                   std::fabs(dot(v, bisector) / speed + e), "");
}

TEST_CASE("a surface wrapped round a sphere: facets that cancel leave the deepest one's normal") {
  // A tube of 64 facets joined into one surface (curvature 10 deg > its 5.6 deg folds), 1 %
  // narrower than a ball at its centre (a neck no fill would put it in: the walls are asked
  // directly): every facet touches it and their normals sum to about zero. The surface gives
  // one contact (io/decks.md: one surface counts once) along the deepest facet's normal, never
  // along a normal of length zero.
  const double tube = 0.99 * kRadius;
  ContainerSpec spec;
  const std::string path =
      stl_files::ascii(stl_files::cylinder(tube, 10 * kRadius, 64), "tube.stl");
  spec.mesh = load_mesh(path, 1.0, 10.0);
  std::filesystem::remove(path);
  REQUIRE(spec.mesh->regions == 3);  // the tube and its two caps
  ContainerGeometry g = MeshShape::geometry(spec);
  const auto bins = mesh_bins(*spec.mesh, kRadius);
  g.mesh = mesh_view(*spec.mesh, *bins);
  int contacts = 0;
  Vec3 normal;
  double gap = 0;
  MeshShape::walls(
      {1e-9, 0, 0}, kRadius, g, [&](int, double g_, Vec3 n) { ++contacts, gap = g_, normal = n; },
      [](double) {});
  CHECK(contacts == 1);
  CHECK(std::fabs(gap - tube * std::cos(kPi / 64)) < 2e-9);  // the nearest facet's plane
  // A facet's own normal: facet k faces outward at (k + 1/2) 2 pi / 64 (the normals' weighted
  // sum would point along -x, the side the ball is pushed off centre to).
  CHECK(std::fabs(norm(normal) - 1) < 1e-12);
  CHECK(std::fabs(normal.z) < 1e-12);
  const double facet = std::atan2(-normal.y, -normal.x) / (2 * kPi / 64) - 0.5;
  CHECK(std::fabs(facet - std::round(facet)) < 1e-6);
}

TEST_CASE("a ball seated in a funnel of more faces than its history slots stops the run") {
  // A ball dropped on the axis of a pyramid-bottomed funnel seats against every sloped face at
  // once (each its own surface: neighbours bend by more than the curvature). With 5 faces it
  // rests; with 8 it touches more features than its kWallSlots histories hold, with 20 more
  // than walls() gathers (MeshShape::kCandidates), and the step says so (the run stops with
  // the kWallOverflow message) instead of dropping contacts.
  static_assert(kWallSlots == 6 && MeshShape::kCandidates == 16, "5 fit, 8 and 20 do not");
  const double r = 0.02;
  const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, 0.3, 0);
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double dt = hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, 0.5) / 50;
  for (const int sides : {5, 8, 20}) {
    CAPTURE(sides);
    ContainerSpec spec;
    const std::string path = stl_files::ascii(stl_files::funnel(r, 2 * r, r, sides), "funnel.stl");
    spec.mesh = load_mesh(path, 1.0, kDefaultCurvature);
    std::filesystem::remove(path);
    REQUIRE(spec.mesh->regions == 2 * sides + 1);  // prism faces, funnel faces, the top
    EngineConfig c =
        steel_box({r, r, r}, NormalModel::hertz, TangentialModel::history, contact, dt);
    c.shape = WallShape::mesh;
    c.geometry = MeshShape::geometry(spec);
    c.gravity = Vec3{0, 0, -9.81};
    add_particle(c, kRadius, {0, 0, 0.5 * r}, {});
    auto engine = make_engine(c);
    int flags = 0;
    const int steps = static_cast<int>(0.15 / dt);  // falls ~10 mm in 45 ms, then settles
    for (int n = 0; n < steps && !flags; ++n) flags = step(*engine, dt).flags;
    if (sides == 5) {
      CHECK(flags == 0);
      const ParticleState p = engine->particles()[0];
      CHECK(norm(p.velocity) < 1e-3);  // at rest in the funnel's tip
      CHECK(p.position.z < 0);
    } else {
      CHECK(flags == kWallOverflow);
    }
  }
}

TEST_CASE(
    "a particle's memo of the slivers of a cylinder finds the walls that its whole bin does") {
  // 2,560 segments: side facets 0.03 radii wide, of which a memo holds a few of its bin's
  // entries. A ball wanders along the side wall and round the rims, touching them and not, in
  // steps of 0.002 radii (a memo lasts a few) and now and then a jump; walls() through the
  // memo must give every feature, gap and normal that the scan of the whole bin gives.
  const double r = 0.0025, radius = 0.028, h = 0.05;
  const std::string path =
      stl_files::binary(stl_files::cylinder(radius, h, 2560), "memo_cylinder.stl");
  const auto surface = load_mesh(path, 1.0, kDefaultCurvature);
  std::filesystem::remove(path);
  const auto bins = mesh_bins(*surface, r);
  ContainerGeometry whole;
  whole.mesh = mesh_view(*surface, *bins);
  std::vector<std::int32_t> memo(kMemoInts, -1);
  std::vector<double> memo_at(4);
  ContainerGeometry memoised = whole;
  memoised.mesh.memo = memo.data();
  memoised.mesh.memo_at = memo_at.data();
  struct Touch {
    int key;
    double gap;
    Vec3 normal;
  };
  auto walls = [&](Vec3 p, const ContainerGeometry& g, int particle) {
    std::vector<Touch> t;
    const bool held = MeshShape::walls(
        p, r, g,
        [&](int key, double gap, Vec3 n) {
          t.push_back({key, gap, n});
        },
        [](double) {}, particle);
    CHECK(held);
    return t;
  };
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(-1, 1), chance(0, 1);
  double rho = radius - r, angle = 0, z = -0.5 * h + r;
  int calls = 0, touching = 0, replays = 0, mismatches = 0;
  for (int k = 0; k < 20000; ++k) {
    const double step = chance(random) < 0.01 ? 0.5 * r : 0.002 * r;
    rho = std::clamp(rho + step * unit(random), radius - 1.1 * r, radius - 0.97 * r);
    angle += step * unit(random) / rho;
    z = std::clamp(z + step * unit(random), -0.5 * h + 0.95 * r, 0.5 * h - 0.95 * r);
    const Vec3 p{rho * std::cos(angle), rho * std::sin(angle), z};
    const double made_at = memo_at[0];
    const std::vector<Touch> a = walls(p, whole, -1), b = walls(p, memoised, 0);
    ++calls;
    touching += a.empty() ? 0 : 1;
    replays += memo_at[0] == made_at ? 1 : 0;
    bool same = a.size() == b.size();
    for (std::size_t c = 0; same && c < a.size(); ++c)
      same = a[c].key == b[c].key && std::fabs(a[c].gap - b[c].gap) <= 1e-12 * r &&
             norm(a[c].normal - b[c].normal) <= 1e-12;
    mismatches += same ? 0 : 1;
  }
  CHECK(mismatches == 0);
  CHECK(touching > calls / 4);  // the walk keeps touching the wall
  CHECK(replays > calls / 2);   // and the memo served most calls
}
