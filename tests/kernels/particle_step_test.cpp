// The per-particle step (kernels/particle_step.hpp): container walls (box and cylinder), the
// blow-up guard flags, the vectorised neighbour-slot test and slot addressing at the largest
// engine accepted.
#include "kernels/particle_step.hpp"

#include <doctest/doctest.h>
#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "kernels/engine_core.hpp"
#include "kernels/neighbours.hpp"
#include "tests/kernels/dem_fixtures.hpp"

namespace pdsim {
namespace {

using namespace fixtures;

constexpr double kRadius = 2.5e-3;  // m

EngineConfig steel_cylinder(double radius, double half_height, const ContactParams& contact,
                            TangentialModel tangential, double dt_s) {
  EngineConfig c =
      steel_box({radius, radius, half_height}, NormalModel::hertz, tangential, contact, dt_s);
  c.shape = WallShape::cylinder;
  c.geometry.radius = radius;
  return c;
}

TEST_CASE("cylinder side wall: normal along the radius, deck restitution") {
  // A ball moving through the axis hits the side wall head-on (the wall normal is radial): it
  // must come back along the same line at e times its speed (Hertz at dt = tc/100, see
  // contact_normal_test.cpp for the discretisation error).
  const double cylinder_radius = 0.02, speed = 1.0;
  const double mass = ball_mass(kRadius, kSteelDensity);
  for (double e : {0.3, 0.6, 0.9}) {
    CAPTURE(e);
    const ContactParams contact = hertz_contact(kSteelYoung, kSteelPoisson, e, 0);
    const double dt = hertz_contact_time(mass, kRadius, contact.hertz_modulus_pw, speed) / 100;
    EngineConfig c = steel_cylinder(cylinder_radius, 0.02, contact, TangentialModel::none, dt);
    const Vec3 direction{std::cos(0.5), std::sin(0.5), 0};
    add_particle(c, kRadius, {0, 0, 0.003}, speed * direction);
    auto engine = make_engine(c);
    const auto overlap = [&](const std::vector<ParticleState>& p) {
      const Vec3 x = p[0].position;
      return std::hypot(x.x, x.y) + kRadius - cylinder_radius;
    };
    const ImpactRecord r = follow_impact(*engine, dt, overlap, 1000000);
    const Vec3 v = r.after[0].velocity;
    const double rebound = -dot(v, direction);
    CHECK(std::fabs(rebound / speed - e) < 5e-3);
    CHECK(norm(v + rebound * direction) < 1e-9 * speed);
  }
}

TEST_CASE("cylinder: a ball thrown in under gravity stays inside") {
  // Soft Hertz (E = 1e8 Pa) so that many wall impacts fit in a short run; e = 0.9, Mindlin
  // friction 0.3. No wall overlap may exceed Hertz's impact overlap at the largest speed the
  // energy allows, (15 m v^2 / (16 E* sqrt(R)))^(2/5) (Johnson 1985, ch. 11).
  const double cylinder_radius = 0.015, half_height = 0.02, young = 1e8, gravity = 9.81;
  const double dt = 0.15 * rayleigh_time(kRadius, kSteelDensity, young, kSteelPoisson);
  const ContactParams contact = hertz_contact(young, kSteelPoisson, 0.9, 0.3);
  EngineConfig c =
      steel_cylinder(cylinder_radius, half_height, contact, TangentialModel::history, dt);
  c.gravity = Vec3{0, 0, -gravity};
  const Vec3 v0{1.2, -0.7, 0.3};
  add_particle(c, kRadius, {0.004, 0.006, 0.01}, v0);
  auto engine = make_engine(c);
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double v_max_sq = dot(v0, v0) + 2 * gravity * (0.01 + half_height);
  const double overlap_bound = std::pow(
      15 * mass * v_max_sq / (16 * contact.hertz_modulus_pw * std::sqrt(kRadius)), 2.0 / 5.0);
  double worst_side = -1, worst_floor = -1;
  int side_impacts = 0;
  bool touching = false;
  int flags = 0;
  for (int n = 0; n < 40000; ++n) {
    flags |= step(*engine, dt).flags;
    const Vec3 x = engine->particles()[0].position;
    const double side = std::hypot(x.x, x.y) + kRadius - cylinder_radius;
    worst_side = std::max(worst_side, side);
    worst_floor = std::max(worst_floor, kRadius - (x.z + half_height));
    if (side > 0 && !touching) ++side_impacts;
    touching = side > 0;
  }
  CHECK(flags == 0);
  CHECK(side_impacts >= 5);
  CHECK(worst_side < overlap_bound);
  CHECK(worst_floor < overlap_bound);
  CHECK(worst_side > 0.1 * overlap_bound);  // the bound is not vacuous
}

// A steel ball resting on the floor of a box under gravity (linear law at its equilibrium
// overlap, undamped, Mindlin friction 0.3), with rolling resistance mu_r; one step a fiftieth of
// the contact time.
struct RollingBall {
  double mass, dt, gravity = 9.81;
  std::unique_ptr<DemEngine> engine;
  RollingBall(double rolling_friction, Vec3 velocity, Vec3 spin) {
    const double stiffness = 1e5, half = 0.05;
    mass = ball_mass(kRadius, kSteelDensity);
    dt = linear_contact_time(stiffness, mass, 1.0) / 50;
    ContactParams contact = linear_contact(stiffness, 1.0, 0.3);
    contact.rolling_friction = rolling_friction;
    EngineConfig c =
        steel_box({half, half, half}, NormalModel::linear, TangentialModel::history, contact, dt);
    c.rolling = true;
    c.gravity = Vec3{0, 0, -gravity};
    add_particle(c, kRadius, {0, 0, -half + kRadius - mass * gravity / stiffness}, velocity, spin);
    engine = make_engine(c);
  }
  double kinetic() const {
    const ParticleState p = engine->particles()[0];
    return 0.5 * mass *
           (dot(p.velocity, p.velocity) + 0.4 * kRadius * kRadius * dot(p.spin, p.spin));
  }
};

TEST_CASE("rolling resistance: a rolling ball stops in the analytic distance, tallied") {
  // The torque mu_r R m g takes mu_r m g per unit distance rolled from the kinetic energy
  // 7/10 m v0^2: the ball stops after 7 v0^2 / (10 mu_r g). Rolling resistance is the only
  // dissipative element here (undamped contact, no slip), so its tally is all the energy lost.
  const double mu_r = 0.05, v0 = 0.05;
  RollingBall ball(mu_r, {v0, 0, 0}, {0, v0 / kRadius, 0});
  const double distance = 0.7 * v0 * v0 / (mu_r * ball.gravity);
  const double stop_time = 1.4 * v0 / (mu_r * ball.gravity);
  const double x0 = ball.engine->particles()[0].position.x, kinetic0 = ball.kinetic();
  double rolling = 0, other = 0;
  for (int n = 0; n < static_cast<int>(1.2 * stop_time / ball.dt); ++n) {
    const StepTotals& t = step(*ball.engine, ball.dt);
    rolling += t.tally.rolling;
    other += std::fabs(t.tally.normal) + std::fabs(t.tally.tangential);
  }
  const ParticleState p = ball.engine->particles()[0];
  CHECK((p.position.x - x0) / distance == doctest::Approx(1).epsilon(1e-4));  // -3e-5
  CHECK(ball.kinetic() < 1e-6 * kinetic0);
  CHECK(rolling == doctest::Approx(kinetic0 - ball.kinetic()).epsilon(1e-9));
  CHECK(other == 0);
}

TEST_CASE("rolling resistance: spin about the normal is not resisted") {
  // Torsion is not rolling: a ball spinning about the floor's normal keeps its spin.
  RollingBall ball(0.05, {}, {0, 0, 30});
  double rolling = 0;
  for (int n = 0; n < 2000; ++n) rolling += step(*ball.engine, ball.dt).tally.rolling;
  CHECK(ball.engine->particles()[0].spin.z == 30);
  CHECK(rolling == 0);
}

TEST_CASE("blow-up guard flags") {
  const double stiffness = 1e5;
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double tc = linear_contact_time(stiffness, 0.5 * mass, 0.9);
  const Vec3 half{0.01, 0.01, 0.01};
  auto two_balls = [&](double dt) {
    EngineConfig c = steel_box(half, NormalModel::linear, TangentialModel::none,
                               linear_contact(stiffness, 0.9, 0), dt);
    add_particle(c, kRadius, {-0.004, 0.001, 0}, {1, 0, 0});
    add_particle(c, kRadius, {0.004, 0, 0}, {-1, 0, 0});
    return c;
  };
  auto flags_within = [](const EngineConfig& c, int steps) {
    auto engine = make_engine(c);
    int flags = 0;
    for (int n = 0; n < steps && !flags; ++n) flags = step(*engine, c.dt).flags;
    return flags;
  };
  SUBCASE("dt far above the stability limit") {
    // omega dt = 5 pi > 2: the explicit step amplifies every contact until a ball leaves.
    CHECK((flags_within(two_balls(5 * tc), 1000) & (kNonFinite | kEscaped)) != 0);
    // The same scene at a stable step raises nothing.
    CHECK(flags_within(two_balls(tc / 50), 20000) == 0);
  }
  SUBCASE("a ball outside the box") {
    EngineConfig c = two_balls(tc / 50);
    c.particles[1].position = {0.02, 0, 0};
    CHECK(flags_within(c, 1) == kEscaped);
  }
  SUBCASE("a ball outside the cylinder") {
    EngineConfig c = steel_cylinder(0.01, 0.01, hertz_contact(kSteelYoung, kSteelPoisson, 0.9, 0),
                                    TangentialModel::none, 1e-7);
    add_particle(c, kRadius, {0.01, 0.01, 0}, {});
    CHECK(flags_within(c, 1) == kEscaped);
  }
  SUBCASE("a non-finite velocity") {
    EngineConfig c = two_balls(tc / 50);
    c.particles[0].velocity.y = std::numeric_limits<double>::quiet_NaN();
    CHECK((flags_within(c, 1) & kNonFinite) != 0);
  }
}

}  // namespace
}  // namespace pdsim

namespace pdsim {
namespace {

// The vectorised slot test against distances computed directly, on random clouds with padded
// lists of every length 0..max (partial groups included), for equal and unequal radii.
template <class V>
void check_touching_slots(bool polydisperse) {
  constexpr int kCount = 40, kMax = 16;
  std::vector<double> x(kCount), y(kCount), z(kCount), radius(kCount);
  std::uint64_t seed = 12345;
  auto uniform = [&seed] {  // a fixed linear congruential sequence in [0, 1)
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(seed >> 11) * 0x1.0p-53;
  };
  for (int i = 0; i < kCount; ++i) {
    x[i] = 0.02 * uniform(), y[i] = 0.02 * uniform(), z[i] = 0.02 * uniform();
    radius[i] = polydisperse ? 0.002 + 0.003 * uniform() : 0.004;
  }
  std::vector<std::int32_t> neighbours(kCount * kMax), count(kCount);
  for (int i = 0; i < kCount; ++i) {
    count[i] = i % (kMax + 1);  // every list length, 0 to kMax
    for (int k = 0; k < count[i]; ++k) neighbours[i * kMax + k] = (i + 1 + 3 * k) % kCount;
    pad_slots(neighbours.data() + i * kMax, count[i], i);
  }
  ParticleStepArgs a{};
  a.in.x = x.data(), a.in.y = y.data(), a.in.z = z.data();
  a.radius = radius.data();
  a.mono_radius = 0.004;
  a.neighbours = neighbours.data();
  a.neighbour_count = count.data();
  std::vector<std::int32_t> start(kCount + 1);
  for (int i = 0; i <= kCount; ++i) start[i] = i * kMax;
  a.slot_start = start.data();
  int contacts = 0;
  for (int i = 0; i < kCount; ++i) {
    std::uint64_t expected = 0;
    for (int k = 0; k < count[i]; ++k) {
      const int j = neighbours[i * kMax + k];
      const double d = std::hypot(x[i] - x[j], y[i] - y[j], z[i] - z[j]);
      if (d < radius[i] + radius[j]) expected |= std::uint64_t{1} << k;
    }
    contacts += __builtin_popcountll(expected);
    CHECK(touching_slots<V>(i, {x[i], y[i], z[i]}, radius[i], a) == expected);
  }
  CHECK(contacts > 20);  // the clouds are dense enough for the test to mean something
}

TEST_CASE("neighbour slot test agrees with direct distances") {
  check_touching_slots<Variant<HertzNormal, NoTangential, false, false, false, WallShape::box>>(
      false);
  check_touching_slots<Variant<HertzNormal, NoTangential, false, false, true, WallShape::box>>(
      true);
}

// The largest engine check_particle_count accepts (kMaxParticles particles of 64 slots, the
// most a list holds) puts its last slot's values 3 x 2^31 and 9 x 2^31 doubles from the start
// of its history and pair-load arrays: past int32, where a 32-bit product wraps. The arrays
// are address space only (MAP_NORESERVE); the pages around the last slot are touched.
TEST_CASE("the last slot of the largest engine accepted holds its history and pair loads") {
  constexpr int kSlots = 64;
  REQUIRE_NOTHROW(check_particle_count(kMaxParticles, kSlots));
  CHECK_THROWS_AS(check_particle_count(kMaxParticles + 1, kSlots), SimulationError);
  const std::int64_t slots = std::int64_t{kMaxParticles} * kSlots;
  REQUIRE(slots == 2147483584);  // 2^31 - 64
  const int last = static_cast<int>(slots - 1);
  using V = Variant<HertzNormal, MindlinHistory, false, false, true, WallShape::box>;
  static_assert(pair_doubles<V>() == 9, "the widest pair loads");
  const std::size_t bytes = static_cast<std::size_t>(slots) * 9 * sizeof(double);
  void* memory = mmap(nullptr, bytes, PROT_READ | PROT_WRITE,
                      MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
  REQUIRE(memory != MAP_FAILED);
  double* values = static_cast<double*>(memory);

  store3(values, last, {1, 2, 3});  // a history slot: 3 values
  CHECK(values[3 * std::int64_t{last}] == 1);
  CHECK(values[3 * std::int64_t{last} + 2] == 3);
  CHECK(load3(values, last).y == 2);

  ParticleStepArgs a{};
  a.pair_load = values;
  store_slot_loads<V>(last, a, {{4, 5, 6}, {7, 8, 9}, {10, 11, 12}});
  CHECK(values[9 * std::int64_t{last}] == 4);
  CHECK(values[9 * std::int64_t{last} + 8] == 12);
  CHECK(slot_loads<V>(last, a).partner_torque.z == 12);
  munmap(memory, bytes);
}

}  // namespace
}  // namespace pdsim
