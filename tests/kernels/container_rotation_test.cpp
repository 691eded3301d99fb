// A container that turns with its attachment (a damper on a beam node): walls follow the
// container axes, and the wall torque about the centre is reduced for the structure.
#include <doctest/doctest.h>

#include <cmath>

#include "tests/kernels/dem_fixtures.hpp"

using namespace pdsim;
using namespace pdsim::fixtures;

namespace {

constexpr double kRadius = 0.0025, kStiffness = 1e5, kG = 9.81;

// Container axes turned by angle `alpha` about +y.
ContainerKinematics tilted(double alpha) {
  ContainerKinematics k;
  k.axis_x = {std::cos(alpha), 0, -std::sin(alpha)};
  k.axis_y = {0, 1, 0};
  k.axis_z = {std::sin(alpha), 0, std::cos(alpha)};
  return k;
}

EngineConfig resting_on_floor(double alpha, Vec3 local_position, double friction,
                              TangentialModel tangential) {
  const Vec3 half{0.02, 0.02, 0.02};
  EngineConfig c = steel_box(half, NormalModel::linear, tangential,
                             linear_contact(kStiffness, 0.3, friction), 2e-6);
  c.rotating = true;
  c.gravity = Vec3{0, 0, -kG};
  // Start at the static overlap m g cos(alpha) / k above the floor, in the turned frame.
  const double mass = ball_mass(kRadius, kSteelDensity);
  const double gap = kRadius - mass * kG * std::cos(alpha) / kStiffness;
  const Vec3 p{local_position.x, local_position.y, -half.z + gap};
  const ContainerKinematics k = tilted(alpha);
  add_particle(c, kRadius, p.x * k.axis_x + p.y * k.axis_y + p.z * k.axis_z, {});
  return c;
}

}  // namespace

TEST_CASE("a frictionless sphere slides down a tilted container floor at g sin(alpha)") {
  const double alpha = 0.2, dt = 2e-6, duration = 0.02;
  auto engine = make_engine(resting_on_floor(alpha, {}, 0.0, TangentialModel::none));
  CHECK(engine->variant() == "linear/none/gravity/mono/box/rotating");
  const ContainerKinematics k = tilted(alpha);
  const int steps = static_cast<int>(std::lround(duration / dt));
  for (int n = 0; n < steps; ++n) {
    REQUIRE(engine->compute(k, dt).flags == 0);
    engine->accept();
  }
  const ParticleState p = engine->particles()[0];
  // The floor normal is axis_z; axis_x = (cos, 0, -sin) points downhill, along which gravity
  // has the component g sin(alpha).
  CHECK(dot(p.velocity, k.axis_x) ==
        doctest::Approx(kG * std::sin(alpha) * duration).epsilon(2e-3));
  CHECK(std::fabs(dot(p.velocity, k.axis_z)) < 1e-3 * kG * duration);
}

TEST_CASE("a sphere resting off-centre puts the torque x0 m g on the container") {
  const double x0 = 0.01, dt = 2e-6;
  auto engine = make_engine(resting_on_floor(0.0, {x0, 0, 0}, 0.5, TangentialModel::history));
  StepTotals totals;
  for (int n = 0; n < 20000; ++n) {
    totals = engine->compute(ContainerKinematics{}, dt);
    engine->accept();
  }
  const double weight = ball_mass(kRadius, kSteelDensity) * kG;
  // The floor carries the weight at (x0, 0, -h): torque (x0, 0, -h) x (0, 0, -W) = (0, x0 W, 0).
  CHECK(totals.wall_force.z == doctest::Approx(-weight).epsilon(1e-6));
  CHECK(totals.wall_torque.y == doctest::Approx(x0 * weight).epsilon(1e-6));
  CHECK(std::fabs(totals.wall_torque.x) < 1e-9 * x0 * weight);
  CHECK(std::fabs(totals.wall_torque.z) < 1e-9 * x0 * weight);
}
