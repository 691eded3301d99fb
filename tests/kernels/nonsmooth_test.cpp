// Rigid (non-smooth) contacts against what a rigid body must do: Newton's restitution at an
// impact, rest under gravity (a ball, a pile), rolling and sliding down an incline at the
// accelerations of rigid-body mechanics.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "kernels/engine.hpp"
#include "tests/kernels/dem_fixtures.hpp"

namespace pdsim {
namespace {

constexpr double kG = 9.81;

// Steel spheres in a box with rigid contacts, their constants as a scene derives them for a
// particle speed `speed`, solved to 1e-12 m/s.
EngineConfig rigid_box(Vec3 half_size, double restitution, double friction, double dt, double speed,
                       Vec3 gravity = {0, 0, -kG}) {
  EngineConfig c;
  c.backend = Backend::cpu;
  c.threads = 1;
  c.geometry.half_size = half_size;
  c.density = fixtures::kSteelDensity;
  c.gravity = gravity;
  c.contact.friction = friction;
  c.nonsmooth = nonsmooth_params(restitution, friction, speed, dt, norm(gravity));
  c.nonsmooth->tolerance = 1e-12;
  c.nonsmooth->max_iterations = 500;
  c.dt = dt;
  return c;
}

TEST_CASE("a ball dropped on a rigid floor rebounds at e times its impact speed at every step") {
  const double r = 0.0025, e = 0.6;
  // From a tenth of the auto step's reach to past its default (0.1 r / v), up to the limit.
  for (double dt : {1e-6, 1e-5, 5e-5, 1e-4, 2.5e-4}) {
    CAPTURE(dt);
    const double drop = 0.02;  // m above the floor
    EngineConfig c = rigid_box({0.02, 0.02, 0.03}, e, 0.3, dt, std::sqrt(2 * kG * drop));
    fixtures::add_particle(c, r, {0, 0, -0.03 + r + drop}, {});
    auto engine = make_engine(c);
    // Fall until the step that reverses the velocity: that step's rebound is e times the speed
    // it started with (the impact's), exactly to rounding.
    double before = 0;
    int impacts = 0;
    for (int k = 0; k < 2000000 && impacts < 2; ++k) {
      const double v0 = engine->particles()[0].velocity.z;
      fixtures::step(*engine, dt);
      const double v1 = engine->particles()[0].velocity.z;
      if (v0 < 0 && v1 > 0) {
        CHECK(v1 == doctest::Approx(-e * v0).epsilon(1e-9));
        if (impacts == 0) before = -v0;
        ++impacts;
      }
    }
    REQUIRE(impacts == 2);
    // The first impact is at sqrt(2 g h) to O(dt) (semi-implicit Euler's fall).
    CHECK(before == doctest::Approx(std::sqrt(2 * kG * 0.02)).epsilon(0.002 + 20 * dt));
    CHECK(engine->particles()[0].velocity.x == 0);
  }
}

TEST_CASE("a resting ball stays at rest, its weight on the floor, for 10 s") {
  const double r = 0.0025, dt = 1e-4;
  EngineConfig c = rigid_box({0.02, 0.02, 0.02}, 0.6, 0.3, dt, 1.0);
  fixtures::add_particle(c, r, {0.001, -0.002, -0.02 + r}, {});
  auto engine = make_engine(c);
  const double weight = fixtures::ball_mass(r, c.density) * kG;
  for (int k = 0; k < 100000; ++k) {
    const StepTotals& t = fixtures::step(*engine, dt);
    // The container takes the ball's weight at every step (the force on it is downwards).
    REQUIRE(-t.wall_force.z == doctest::Approx(weight).epsilon(1e-9));
    REQUIRE(t.kinetic < 1e-20);
  }
  const ParticleState p = engine->particles()[0];
  CHECK(std::fabs(p.position.z - (-0.02 + r)) < 1e-9);
  CHECK(p.position.x == doctest::Approx(0.001).epsilon(1e-12));
}

// Random spheres dropped into a box, settled, then held for `hold` s: the pile's kinetic
// energy stays below that of a particle moving at the rest speed, and the floor carries the
// pile's weight.
TEST_CASE("a pile of 200 spheres stays at rest for 10 s, the walls carrying its weight") {
  const double r = 0.002, dt = 2e-4;
  EngineConfig c = rigid_box({0.015, 0.015, 0.03}, 0.6, 0.4, dt, 1.0);
  c.nonsmooth->tolerance = 1e-5;  // m/s
  std::mt19937_64 gen(7);
  std::uniform_real_distribution<double> u(-1, 1);
  // A loose lattice with a little noise, so that the pile settles into no lattice.
  for (int k = 0; c.particles.size() < 200; ++k) {
    const int ix = k % 6, iy = k / 6 % 6, iz = k / 36;
    fixtures::add_particle(c, r,
                           {-0.0125 + 0.005 * ix + 3e-4 * u(gen),
                            -0.0125 + 0.005 * iy + 3e-4 * u(gen), -0.027 + 0.0052 * iz},
                           {});
  }
  auto engine = make_engine(c);
  const double weight = 200 * fixtures::ball_mass(r, c.density) * kG;
  for (int k = 0; k < 10000; ++k) fixtures::step(*engine, dt);  // 2 s to settle
  const double rest = c.nonsmooth->rest_speed;
  const double bound = 0.5 * 200 * fixtures::ball_mass(r, c.density) * rest * rest;
  double force = 0, kinetic_max = 0;
  const int hold = 50000;  // 10 s
  const std::vector<ParticleState> settled = engine->particles();
  for (int k = 0; k < hold; ++k) {
    const StepTotals& t = fixtures::step(*engine, dt);
    force += -t.wall_force.z / hold;
    kinetic_max = std::max(kinetic_max, t.kinetic);
  }
  CHECK(kinetic_max < bound);
  CHECK(force == doctest::Approx(weight).epsilon(1e-3));
  double moved = 0;
  const std::vector<ParticleState> after = engine->particles();
  for (std::size_t i = 0; i < after.size(); ++i)
    moved = std::max(moved, norm(after[i].position - settled[i].position));
  // Velocities are met to the solver's tolerance, so the pile creeps at some multiple of it
  // (measured over the 10 s: 0.91 mm at 1e-5 m/s, 0.19 mm at 1e-6 m/s), its kinetic energy
  // 300 times below the bound above. It does not flow: no sphere moves half its radius.
  CHECK(moved < 0.5 * r);
}

// A sphere on a floor with gravity tilted by theta is a sphere on an incline of theta.
double incline_acceleration(double theta, double mu) {
  const double r = 0.0025, dt = 1e-4;
  const Vec3 g{kG * std::sin(theta), 0, -kG * std::cos(theta)};
  EngineConfig c = rigid_box({0.5, 0.02, 0.02}, 0.6, mu, dt, 1.0, g);
  fixtures::add_particle(c, r, {-0.45, 0, -0.02 + r}, {});
  auto engine = make_engine(c);
  const int steps = 2000;  // 0.2 s
  for (int k = 0; k < steps; ++k) fixtures::step(*engine, dt);
  const ParticleState p = engine->particles()[0];
  // On the floor: rolling exactly; sliding, the convex cone's relaxation lifts it by
  // mu |u_t| dt (kernels/nonsmooth.hpp), which does not accumulate.
  const double lift = std::fabs(p.position.z - (-0.02 + r));
  CHECK(lift <= mu * std::fabs(p.velocity.x - r * p.spin.y) * dt + 1e-12);
  return p.velocity.x / (steps * dt);
}

TEST_CASE("a sphere on an incline rolls at 5/7 g sin(theta), or slides at g (sin - mu cos)") {
  const double theta = 0.3;
  // mu >= 2/7 tan(theta) = 0.0883: rolling without slipping.
  CHECK(incline_acceleration(theta, 0.1) ==
        doctest::Approx(5.0 / 7.0 * kG * std::sin(theta)).epsilon(1e-6));
  CHECK(incline_acceleration(theta, 0.5) ==
        doctest::Approx(5.0 / 7.0 * kG * std::sin(theta)).epsilon(1e-6));
  // Below it: sliding.
  for (double mu : {0.02, 0.05, 0.08}) {
    CAPTURE(mu);
    CHECK(incline_acceleration(theta, mu) ==
          doctest::Approx(kG * (std::sin(theta) - mu * std::cos(theta))).epsilon(1e-6));
  }
}

}  // namespace
}  // namespace pdsim

namespace pdsim {
namespace {

// 600 spheres falling into a box (three blocks of particles, so that two threads share them).
EngineConfig falling_bed(int threads) {
  const double r = 0.002, dt = 2e-4;
  EngineConfig c = rigid_box({0.02, 0.02, 0.05}, 0.6, 0.3, dt, 1.0);
  c.threads = threads;
  c.nonsmooth->tolerance = 1e-4;
  for (int k = 0; k < 600; ++k)
    fixtures::add_particle(
        c, r,
        {-0.017 + 0.0049 * (k % 8), -0.017 + 0.0049 * (k / 8 % 8), -0.047 + 0.0049 * (k / 64)},
        {0.01 * (k % 3), 0, 0});
  return c;
}

bool same_state(const DemEngine& a, const DemEngine& b) {
  const auto p = a.particles(), q = b.particles();
  auto same = [](Vec3 u, Vec3 v) { return u.x == v.x && u.y == v.y && u.z == v.z; };
  for (std::size_t i = 0; i < p.size(); ++i)
    if (!same(p[i].position, q[i].position) || !same(p[i].velocity, q[i].velocity) ||
        !same(p[i].spin, q[i].spin))
      return false;
  return true;
}

TEST_CASE("rigid contacts: the same state on one thread and two, and after a checkpoint") {
  auto one = make_engine(falling_bed(1));
  auto two = make_engine(falling_bed(2));
  for (int k = 0; k < 300; ++k) {
    fixtures::step(*one, 2e-4);
    fixtures::step(*two, 2e-4);
  }
  CHECK(same_state(*one, *two));
  // Saved and restored (warm starts and lists included), then both go on: bitwise equal.
  const StateArrays saved = one->save();
  auto restored = make_engine(falling_bed(1));
  restored->restore(saved);
  for (int k = 0; k < 200; ++k) {
    fixtures::step(*one, 2e-4);
    fixtures::step(*restored, 2e-4);
  }
  CHECK(same_state(*one, *restored));
}

}  // namespace
}  // namespace pdsim

namespace pdsim {
namespace {

TEST_CASE(
    "rigid contacts: spheres of three sizes settle in a cylinder, which carries their weight") {
  const double dt = 2e-4;
  EngineConfig c = rigid_box({0.012, 0.012, 0.03}, 0.5, 0.3, dt, 1.0);
  c.shape = WallShape::cylinder;
  c.geometry.radius = 0.012;
  c.nonsmooth->tolerance = 1e-5;
  double mass = 0;
  for (int k = 0; k < 60; ++k) {
    const double r = 0.0015 + 0.0005 * (k % 3);
    const double angle = 2.39996 * k, rho = 0.006 * ((k % 2) + 0.3);
    fixtures::add_particle(c, r,
                           {rho * std::cos(angle), rho * std::sin(angle), -0.025 + 0.0009 * k}, {});
    mass += fixtures::ball_mass(r, c.density);
  }
  auto engine = make_engine(c);
  CHECK(engine->variant() == "nonsmooth/coulomb/gravity/poly/cylinder");
  for (int k = 0; k < 10000; ++k) fixtures::step(*engine, dt);  // 2 s
  double force = 0;
  for (int k = 0; k < 5000; ++k) force += -fixtures::step(*engine, dt).wall_force.z / 5000;
  CHECK(force == doctest::Approx(mass * kG).epsilon(1e-3));
  for (const ParticleState& p : engine->particles()) {
    CHECK(std::hypot(p.position.x, p.position.y) < 0.012);
    CHECK(p.position.z > -0.03);
  }
}

}  // namespace
}  // namespace pdsim
