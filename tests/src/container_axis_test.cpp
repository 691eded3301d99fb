// A cylinder laid along any axis: the same damper turned as a whole (its axis, gravity and the
// structure's direction) is the same physics, so a horizontal cylinder is the z-cylinder
// rotated, and both run the same ball and bed.
#include <doctest/doctest.h>

#include <cmath>
#include <iomanip>
#include <string>

#include "src/run.hpp"
#include "src/scene.hpp"

using namespace pdsim;

namespace {

// Axis, gravity and the SDOF's direction as "[x, y, z]"; 20 Hz sine, 25 soft spheres, bed
// settled first so that the pile and its impacts are the ones a damper has.
std::string deck(const std::string& axis, const std::string& gravity, const std::string& direction,
                 int count = 25) {
  return R"(title = "cylinder axis"
[structure]
kind = "sdof"
mass = 0.5
stiffness = 8000.0
damping_ratio = 0.02
direction = )" +
         direction +
         R"(
[[damper]]
container = { shape = "cylinder", radius = 0.012, height = 0.03, axis = )" +
         axis + R"( }
particles = { count = )" +
         std::to_string(count) + R"(, diameter = 0.005, density = 7800.0, seed = 4 }
[contact]
model = "linear"
tangential = "history"
stiffness = 4000.0
young = 2.0e8
restitution = 0.5
friction = 0.3
[gravity]
vector = )" +
         gravity +
         R"(
[bed]
max_time = 0.6
[excitation]
kind = "sine"
input = "force"
amplitude = 3.0
frequency = 20.0
duration = 0.2
[output]
file = "axis.h5"
[solver]
threads = 1
)";
}

Results run(const std::string& text) {
  const Deck d = parse_deck(text, "axis.toml");
  return simulate(d, build_scene(d));
}

}  // namespace

TEST_CASE("a cylinder's axis turns its frame: z goes to the axis, the fill turns with it") {
  const Deck along_z = parse_deck(deck("[0, 0, 1]", "[0, 0, -9.81]", "[0, 0, 1]"), "z.toml");
  const Deck along_x = parse_deck(deck("[2, 0, 0]", "[-9.81, 0, 0]", "[1, 0, 0]"), "x.toml");
  CHECK(along_x.dampers[0].container.axis.x == 1.0);  // normalised
  const Scene z = build_scene(along_z), x = build_scene(along_x);
  const Orientation& o = x.dampers[0].engine.orientation;
  CHECK(z.dampers[0].engine.orientation.identity());
  CHECK(!z.dampers[0].engine.rotating);  // a z-cylinder pays nothing for the option
  CHECK(x.dampers[0].engine.rotating);
  // The shortest turn from z to x is a quarter turn about y: x -> -z, y -> y, z -> x.
  CHECK(o.x.z == -1.0);
  CHECK(o.y.y == 1.0);
  CHECK(o.z.x == 1.0);
  const auto& pz = z.dampers[0].engine.particles;
  const auto& px = x.dampers[0].engine.particles;
  REQUIRE(pz.size() == px.size());
  for (std::size_t i = 0; i < pz.size(); ++i) {
    CHECK(px[i].position.x == pz[i].position.z);
    CHECK(px[i].position.y == pz[i].position.y);
    CHECK(px[i].position.z == -pz[i].position.x);
  }
  // Any direction: the turn keeps lengths and right-handedness.
  const Deck slanted = parse_deck(deck("[1, -2, 0.5]", "[0, 0, -9.81]", "[0, 0, 1]"), "s.toml");
  const Orientation& s = build_scene(slanted).dampers[0].engine.orientation;
  CHECK(norm(cross(s.x, s.y) - s.z) < 1e-15);
  CHECK(std::fabs(dot(s.x, s.y)) < 1e-15);
  CHECK(norm(s.z - (1 / std::sqrt(5.25)) * Vec3{1, -2, 0.5}) < 1e-15);
}

TEST_CASE("the horizontal cylinder (axis along x) is the z-cylinder turned: same ball, same bed") {
  // The turned run computes in container axes (the Rotating variant), so it differs by rounding
  // only, which the impacts of a bed amplify: here the settled 25-sphere bed's amplitude and
  // phase agree to 1e-5 after 4 periods, its dissipated energy (chaotic) to 4e-3. A wrong frame
  // (walls, gravity or drive not turned alike) differs at first order.
  struct Case {
    int count;
    double motion, energy;  // relative tolerances
  };
  for (const Case& c : {Case{1, 1e-9, 1e-9}, Case{25, 1e-4, 2e-2}}) {
    const int count = c.count;
    CAPTURE(count);
    const Results z = run(deck("[0, 0, 1]", "[0, 0, -9.81]", "[0, 0, 1]", count));
    const Results x = run(deck("[1, 0, 0]", "[-9.81, 0, 0]", "[1, 0, 0]", count));
    REQUIRE(z.frf.frequency.size() == 1);
    REQUIRE(x.frf.frequency.size() == 1);
    MESSAGE(std::setprecision(12) << "amplitude z " << z.frf.amplitude[0] << " m, x "
                                  << x.frf.amplitude[0] << " m; phase z " << z.frf.phase[0]
                                  << ", x " << x.frf.phase[0] << " rad; energy z "
                                  << z.frf.dissipated_energy[0] << ", x "
                                  << x.frf.dissipated_energy[0] << " J; bed "
                                  << z.meta_text.at("bed"));
    CHECK(x.meta_text.at("kernel_variant").find("/cylinder/rotating") != std::string::npos);
    CHECK(z.meta_text.at("kernel_variant").find("/rotating") == std::string::npos);
    CHECK(std::fabs(x.frf.amplitude[0] / z.frf.amplitude[0] - 1) < c.motion);
    CHECK(std::fabs(x.frf.phase[0] / z.frf.phase[0] - 1) < c.motion);
    CHECK(std::fabs(x.frf.dissipated_energy[0] / z.frf.dissipated_energy[0] - 1) < c.energy);
  }
}
